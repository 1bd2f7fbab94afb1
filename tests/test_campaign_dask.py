"""Campaigns on Dask (the Dask audit): the workers simulate the client's measured track, the
cluster's own failures are one line with the resume hint, campaign.json says how each run
went, run_campaign's arguments are type-checked, and an unreachable scheduler is named as the
setting the user gave."""

from __future__ import annotations

import errno
import json
import os
import sys
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

import railsusp.campaign.dask_cluster as cluster_mod
import railsusp.campaign.run as run_mod
from railsusp.campaign import CampaignError, load_campaign, make_config, run_campaign
from railsusp.campaign.dask_cluster import RESUME_HINT, ClusterError
from railsusp.campaign.design import batch_paths
from railsusp.conditions import get_condition

BASE = get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0)
SCHEDULER = "tcp://h:8786"


def _track(folder, scale: float = 1.0) -> str:
    """A measured track file ``folder/geo.csv`` (the base condition's own irregularities,
    times ``scale``); returns its name relative to ``folder``."""
    from railsusp.vehicle.track_geometry import write_track_geometry
    from railsusp.vehicle.track_grid import section_irregularities
    from railsusp.vehicle.wagon import load_wagon

    folder.mkdir(parents=True, exist_ok=True)
    path = write_track_geometry(
        folder / "geo.csv",
        section_irregularities(BASE, [BASE.seed], load_wagon()),
        origin_m=BASE.lead_in_m,
    )
    if scale != 1.0:
        table = pd.read_csv(path)
        table[[c for c in table.columns if c != "distance_m"]] *= scale
        table.to_csv(path, index=False)
    return path.name


def _measured_config():
    return make_config(
        [BASE.with_changes(track_geometry="geo.csv")], 4, batch_size=2, parameters=("X14",)
    )


def test_workers_simulate_the_clients_track_not_one_in_their_own_folder(tmp_path, monkeypatch):
    """Workers read a condition's track file from their own disk, relative to their own
    working folder: with another file of that name there, every batch was simulated on
    that track while campaign.json recorded the client's file's hash. The LocalCluster's
    processes start here in a folder holding such a decoy; the batches must be the serial
    run's, bit for bit."""
    client, worker = tmp_path / "client", tmp_path / "worker"
    _track(client)
    _track(worker, scale=3.0)  # a stale copy on a node: another track of the same name
    monkeypatch.chdir(client)
    cfg = _measured_config()
    serial = run_campaign(cfg, tmp_path / "serial")
    real = run_mod.run_on_dask

    def on_workers_elsewhere(*args, **kwargs):
        here = os.getcwd()
        os.chdir(worker)  # the cluster's processes start (and work) in the worker folder
        try:
            return real(*args, **kwargs)
        finally:
            os.chdir(here)

    monkeypatch.setattr(run_mod, "run_on_dask", on_workers_elsewhere)
    dask_out = run_campaign(cfg, tmp_path / "dask", workers=1)
    for b in range(cfg.n_batches):
        for a, d in zip(
            batch_paths(serial, "straight", b), batch_paths(dask_out, "straight", b), strict=True
        ):
            pd.testing.assert_frame_equal(pd.read_parquet(d), pd.read_parquet(a))
    meta = json.loads((dask_out / "campaign.json").read_text())
    assert (
        meta["track_geometry_files"]
        == json.loads((serial / "campaign.json").read_text())["track_geometry_files"]
    )


def test_a_track_file_edited_before_its_batches_ran_is_refused(tmp_path, monkeypatch):
    """campaign.json records the track file's hash when the campaign is prepared; the
    contents simulated are read after: edited in between, the hash would be of another
    track. Refused in one line, nothing simulated."""
    _track(tmp_path)
    monkeypatch.chdir(tmp_path)
    prepare = run_mod.prepare_run_directory

    def prepare_then_edit(*args):
        design = prepare(*args)
        (tmp_path / "geo.csv").write_text((tmp_path / "geo.csv").read_text() + "\n")
        return design

    monkeypatch.setattr(run_mod, "prepare_run_directory", prepare_then_edit)
    with pytest.raises(CampaignError, match="track_geometry geo.csv changed while the campaign"):
        run_campaign(_measured_config(), tmp_path / "r")
    assert not list((tmp_path / "r").glob("batches/*/batch-*.parquet"))


def test_a_bad_track_file_is_named_as_the_user_named_it(tmp_path, monkeypatch):
    """The batch simulates a copy of the file's contents; a problem found while simulating
    (a track too short for the condition) names the user's file, not the copy."""
    from railsusp.errors import RailsuspInputError

    _track(tmp_path)
    table = pd.read_csv(tmp_path / "geo.csv")
    table[table.distance_m < 10.0].to_csv(tmp_path / "geo.csv", index=False)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(RailsuspInputError) as info:
        run_campaign(_measured_config(), tmp_path / "r", max_batches=1)
    assert str(info.value).startswith("track geometry file geo.csv covers distance_m")
    assert "railsusp-track-" not in str(info.value)


class _Future:
    """A Dask future run here: its task's result, or the cluster error given."""

    def __init__(self, fn, args, error: BaseException | None) -> None:
        self.fn, self.args, self.error = fn, args, error

    def result(self):
        if self.error is not None:
            raise self.error
        return self.fn(*self.args)


class _Client:
    """A Dask client whose futures after the first ``ok`` fail with ``error``."""

    def __init__(self, ok: int = 0, error: BaseException | None = None) -> None:
        self.ok, self.error, self.submitted, self.closed = ok, error, 0, False

    def submit(self, fn, *args, pure: bool = True):
        self.submitted += 1
        return _Future(fn, args, self.error if self.submitted > self.ok else None)

    def close(self) -> None:
        self.closed = True


@pytest.fixture
def fake_cluster(monkeypatch):
    """Connecting to ``SCHEDULER`` gives the client ``fake_cluster.client``."""
    import dask.distributed

    made = SimpleNamespace(client=_Client())
    monkeypatch.setattr(
        cluster_mod, "connect_scheduler", lambda address, setting="--scheduler": made.client
    )
    monkeypatch.setattr(dask.distributed, "as_completed", lambda futures: iter(list(futures)))
    return made


def _cluster_failures() -> list[BaseException]:
    from distributed.client import FutureCancelledError
    from distributed.comm.core import CommClosedError
    from distributed.scheduler import KilledWorker

    return [
        FutureCancelledError("simulate_task-1", reason="scheduler-connection-lost"),
        KilledWorker("simulate_task-1", SimpleNamespace(address="tcp://10.0.0.5:4001"), 0),
        CommClosedError("in <TCP (closed) ConnectionPool.gather local=tcp://127.0.0.1:1>"),
    ]


@pytest.mark.parametrize("error", _cluster_failures(), ids=lambda e: type(e).__name__)
def test_the_cluster_failing_is_one_line_and_keeps_the_batches_stored(
    error, fake_cluster, tmp_path
):
    """A scheduler lost or a batch's workers killed was a 40-line traceback of
    distributed's error. Now: one line naming it, ending with the resume hint, an OSError
    of EIO (the machines' failure: exit status 1, not 2), the batches finished kept."""
    from railsusp.cli.common import exit_code
    from railsusp.pipeline import StageError

    fake_cluster.client = _Client(ok=1, error=error)
    cfg = make_config([BASE], 6, batch_size=2, parameters=("X14",))
    with pytest.raises(ClusterError) as info:
        run_campaign(cfg, tmp_path / "r", scheduler=SCHEDULER)
    text = str(info.value)
    assert text.startswith(f"the Dask cluster failed during the campaign ({type(error).__name__}")
    assert text.endswith(RESUME_HINT) and "\n" not in text
    assert isinstance(info.value, OSError) and info.value.errno == errno.EIO
    assert fake_cluster.client.closed
    assert len(list((tmp_path / "r").glob("batches/*/batch-?????.parquet"))) == 1  # kept
    try:  # as railsusp run wraps a stage's error
        raise StageError(f"stage 'campaign' failed: {info.value}") from info.value
    except StageError as wrapped:
        assert exit_code(wrapped) == 1


def test_a_tasks_own_error_is_not_taken_for_the_clusters(fake_cluster, tmp_path):
    """Only distributed's errors are the cluster's: a task's bad input comes through."""
    fake_cluster.client = _Client(error=CampaignError("condition 'x': bad"))
    with pytest.raises(CampaignError, match="condition 'x': bad"):
        run_campaign(
            make_config([BASE], 2, parameters=("X14",)), tmp_path / "r", scheduler=SCHEDULER
        )


def _older_worker(monkeypatch, revision: str = "1999-01-01.1"):
    """Workers of an older railsusp: a simulate_task of five arguments (no track files),
    whose batches carry that model revision."""

    def simulate_task(config_json, condition_index, sample_ids, x, seeds):
        return {**run_mod.simulate_task(config_json, condition_index, sample_ids, x, seeds),
                "model_revision": revision}  # fmt: skip

    class Older(_Client):
        def submit(self, fn, *args, pure: bool = True):
            return super().submit(simulate_task, *args, pure=pure)

    return Older()


def test_a_worker_of_an_older_railsusp_is_told_to_be_the_same(fake_cluster, tmp_path, monkeypatch):
    """Every batch carried a sixth argument (its track files, None without one): a worker
    of the railsusp before failed with a TypeError traceback before the model-revision
    refusal could say what is wrong (the review of stop 65). Without a track file the
    batch's arguments are the old five, and the refusal says it; with one, a worker whose
    task takes five is told to install the same railsusp too."""
    fake_cluster.client = _older_worker(monkeypatch)
    with pytest.raises(CampaignError, match="revision 1999-01-01.1 where this railsusp has"):
        run_campaign(make_config([BASE], 2, parameters=("X14",)), tmp_path / "a",
                     scheduler=SCHEDULER)  # fmt: skip
    _track(tmp_path)
    monkeypatch.chdir(tmp_path)
    fake_cluster.client = _older_worker(monkeypatch)
    with pytest.raises(CampaignError, match="runs another railsusp .*install the same railsusp"):
        run_campaign(_measured_config(), tmp_path / "b", scheduler=SCHEDULER)


def test_the_command_line_reports_a_lost_cluster_in_one_line_exit_1(
    fake_cluster, tmp_path, monkeypatch, capsys
):
    from distributed.client import FutureCancelledError

    import railsusp.cli as cli

    conds = tmp_path / "short.toml"
    conds.write_text(
        '[[condition]]\nbase = "straight"\nname = "short"\nduration_s = 1.0\nn_steps = 50\n'
        "lead_in_m = 20.0\n"
    )
    fake_cluster.client = _Client(
        error=FutureCancelledError("simulate_task-1", reason="scheduler-connection-lost")
    )
    args = ["campaign", "--conditions", str(conds), "--samples", "4", "--batch-size", "2"]
    args += ["--out", str(tmp_path / "r"), "--scheduler", SCHEDULER]
    monkeypatch.setattr(sys, "argv", ["railsusp", *args])
    with pytest.raises(SystemExit) as info:
        cli.main()
    assert info.value.code == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    line = " ".join(err.split("error: ", 1)[1].split())  # (the console wraps long lines)
    assert line.startswith("the Dask cluster failed during the campaign (FutureCancelledError")
    assert line.endswith(RESUME_HINT)


def test_campaign_json_records_how_each_run_went(fake_cluster, tmp_path):
    """campaign.json's provenance was the same for a serial run, local processes and a
    scheduler; a campaign started here and resumed on a cluster said nothing of it."""
    import dask
    import distributed

    cfg = make_config([BASE], 6, batch_size=2, parameters=("X14",))
    out = tmp_path / "r"
    run_campaign(cfg, out, max_batches=1)
    fake_cluster.client = _Client(ok=10)
    run_campaign(cfg, out, scheduler=SCHEDULER)
    run_campaign(cfg, out)  # complete: nothing simulated, nothing recorded
    runs = json.loads((out / "campaign.json").read_text())["runs"]
    assert [{k: v for k, v in r.items() if k != "utc"} for r in runs] == [
        {"executor": "serial", "batches_to_run": 1},
        {
            "executor": "scheduler",
            "scheduler": SCHEDULER,
            "dask": dask.__version__,
            "distributed": distributed.__version__,
            "batches_to_run": 2,
        },
    ]
    assert load_campaign(out).complete
    assert cluster_mod.executor_record(None, 3) == {
        "executor": "local processes",
        "workers": 3,
        "dask": dask.__version__,
        "distributed": distributed.__version__,
    }


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"workers": 2.5}, "--workers = 2.5: accepted an integer >= 1"),
        ({"workers": "2"}, "--workers = '2': accepted an integer >= 1"),
        ({"workers": True}, "--workers = True: accepted an integer >= 1"),
        ({"workers": 0}, "--workers = 0: accepted an integer >= 1"),
        ({"scheduler": 8786}, "--scheduler 8786: accepted an address tcp://host:port"),
        ({"max_batches": 0.5}, "--max-batches = 0.5: accepted an integer >= 0"),
        ({"max_batches": True}, "--max-batches = True: accepted an integer >= 0"),
        ({"max_batches": -1}, "--max-batches = -1: accepted an integer >= 0"),
    ],
)
def test_run_campaign_refuses_arguments_of_the_wrong_type_before_anything(kwargs, needle, tmp_path):
    """A float or text went on to a TypeError from deep in Dask or a slice, after the
    folder was made; max_batches=True ran one batch."""
    with pytest.raises(CampaignError) as info:
        run_campaign(make_config([BASE], 2, parameters=("X14",)), tmp_path / "r", **kwargs)
    assert needle in str(info.value) and "\n" not in str(info.value)
    assert not (tmp_path / "r").exists()


def test_run_campaign_takes_numpy_integers(tmp_path):
    run_campaign(
        make_config([BASE], 2, parameters=("X14",)), tmp_path / "r", max_batches=np.int64(0)
    )
    assert (tmp_path / "r" / "campaign.json").is_file()


def test_an_unreachable_scheduler_is_named_as_the_setting_given(tmp_path, monkeypatch):
    """A pipeline's `scheduler =` was reported as the --scheduler option it never typed."""
    import dask.distributed

    def refused(address, timeout):
        raise OSError(f"Timed out trying to connect to {address} after 10 s")

    monkeypatch.setattr(dask.distributed, "Client", refused)
    cfg = make_config([BASE], 2, parameters=("X14",))
    with pytest.raises(CampaignError) as info:
        run_campaign(cfg, tmp_path / "r", scheduler=SCHEDULER, scheduler_setting="scheduler =")
    assert str(info.value).startswith(f"scheduler = {SCHEDULER}: no Dask scheduler answered")
    with pytest.raises(CampaignError, match=f"^--scheduler {SCHEDULER}: no Dask scheduler"):
        run_campaign(cfg, tmp_path / "r", scheduler=SCHEDULER)


def test_a_pipelines_unreachable_scheduler_is_named_as_its_configuration_setting(
    tmp_path, monkeypatch
):
    """``railsusp run`` with ``scheduler = ...`` in its configuration said ``--scheduler``,
    an option its user never typed (the pipeline's campaign stage passed no setting name)."""
    import dask.distributed

    from railsusp.pipeline import StageError, load_config, run_pipeline

    def refused(address, timeout):
        raise OSError(f"Timed out trying to connect to {address} after 10 s")

    monkeypatch.setattr(dask.distributed, "Client", refused)
    cfg = tmp_path / "c.toml"
    cfg.write_text(
        f'name = "t"\nscheduler = "{SCHEDULER}"\n'
        'conditions = [{base="straight", name="short", duration_s=1.0, n_steps=50, '
        "lead_in_m=20.0}]\n[campaign]\nsamples = 5\nbatch_size = 5\n"
        'parameters = ["X13", "X14"]\n[field]\ntruth = { X13 = 16.1 }\n'
    )
    with pytest.raises(StageError) as info:
        run_pipeline(load_config(cfg), tmp_path / "run")
    assert f"scheduler = {SCHEDULER}: no Dask scheduler answered" in str(info.value)
    assert "--scheduler" not in str(info.value)


def test_a_worker_without_the_tasks_module_is_told_to_be_the_same(fake_cluster, tmp_path):
    """The batch task lives in railsusp.campaign.batch_simulation since stop 67: a worker of
    the railsusp before unpickles it by that name and fails with ModuleNotFoundError, which
    passed up as a traceback. Now the one-line refusal; an ImportError of another package
    (a worker's broken install of a library) stays as it is."""

    def missing(name):
        def simulate_task(*args):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)

        class Older(_Client):
            def submit(self, fn, *args, pure: bool = True):
                return super().submit(simulate_task, *args, pure=pure)

        return Older()

    fake_cluster.client = missing("railsusp.campaign.batch_simulation")
    with pytest.raises(CampaignError, match="runs another railsusp .*install the same railsusp"):
        run_campaign(make_config([BASE], 2, parameters=("X14",)), tmp_path / "a",
                     scheduler=SCHEDULER)  # fmt: skip
    fake_cluster.client = missing("scipy.special")
    with pytest.raises(ModuleNotFoundError, match="scipy.special"):
        run_campaign(make_config([BASE], 2, parameters=("X14",)), tmp_path / "b",
                     scheduler=SCHEDULER)  # fmt: skip
