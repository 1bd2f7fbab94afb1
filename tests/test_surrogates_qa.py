"""The QA pass over campaigns and surrogates: a surrogate refuses parameter values outside
the ranges it was trained over, ``compare`` refuses a model named twice, a hand-edited split
that is not a partition of the campaign's samples is refused, and ``campaign``, ``train``,
``compare`` and ``sensitivity`` say what is wrong in the project's words (each test failed
on the code before)."""

from __future__ import annotations

import builtins
import errno
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from railsusp.campaign import load_campaign, make_config, run_campaign
from railsusp.cli import app
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.params import bounds

runner = CliRunner()
SHORT = get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=20.0, name="short")
KEYS = ("X13", "X14")


def _error(args: list) -> str:
    """The one line of a refused command (exit status 2), and nothing else printed."""
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    assert "Traceback" not in result.output
    return lines[0]


@pytest.fixture(scope="module")
def campaign(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("qa") / "run"
    run_campaign(make_config([SHORT], 12, batch_size=12, seed=2, parameters=KEYS), out)
    return out


@pytest.fixture
def run(campaign, tmp_path) -> Path:
    """A copy of the campaign of its own."""
    return shutil.copytree(campaign, tmp_path / "run")


# ------------------------------------------------ 1. predict outside the trained ranges
@pytest.fixture(scope="module")
def shipped():
    """The shipped C80/K6 network of the straight condition, and its reference sets (SI)."""
    from railsusp.surrogate import load
    from railsusp.surrogate.pretrained import read_network_set, resolve_network_set

    networks = read_network_set(resolve_network_set("c80_k6"))
    sur = load(networks.bundle("straight"))
    return sur, np.asarray(networks.references["straight"]["params_si"], dtype=float)


def _display(sur, x_si: np.ndarray) -> np.ndarray:
    """``x_si`` in each parameter's display unit (kN·s/m, MN/m, m, ...)."""
    from railsusp.params import spec

    return x_si / np.array([spec(p).scale for p in sur.spec.parameters])


@pytest.mark.parametrize("slip", ["display units", "negative", "ten times", "NaN", "inf"])
def test_predict_refuses_values_outside_the_trained_ranges(shipped, slip):
    """All were predicted as plausible forces (NaN: sklearn's multi-line "Input X contains
    NaN" from the record correction's GP); now one line naming the parameter, the value in
    SI with its unit, and the range, before any work."""
    sur, ref = shipped
    x = {
        "display units": _display(sur, ref),
        "negative": -ref,
        "ten times": 10 * ref,
        "NaN": np.where(np.arange(ref.shape[1]) == 2, np.nan, ref),
        "inf": np.where(np.arange(ref.shape[1]) == 2, np.inf, ref),
    }[slip]
    with pytest.raises(RailsuspInputError) as info:
        sur.predict(x)
    text = str(info.value)
    assert "\n" not in text
    first = sur.spec.parameters[0] if slip not in ("NaN", "inf") else sur.spec.parameters[2]
    from railsusp.params import spec

    s = spec(first)
    lo, hi = s.bounds
    assert text.startswith(f"params: {first} ({s.description}) = ")
    assert f"the range this surrogate was trained over, [{lo:g}, {hi:g}] {s.si_unit}" in text
    if slip in ("NaN", "inf"):
        assert f"= {x[0, 2]} (row 0 of 2) is not finite" in text
    else:
        assert f"= {x[0, 0]:g} {s.si_unit} (row 0 of 2) is outside" in text
    if slip == "display units":  # the range in display units too: the slip is seen
        assert f"({s.range_text()})" in text


def test_predict_names_the_row_and_refuses_parameter_sets_alike(shipped):
    sur, ref = shipped
    x = np.vstack([ref, ref[:1] * [1, 1, 1, 1, 2]])  # the last set's X19 twice its value
    with pytest.raises(RailsuspInputError, match=r"^params: X19 .*\(row 2 of 3\) is outside"):
        sur.predict(x)
    with pytest.raises(RailsuspInputError, match=r"^params: X19 .* is outside"):  # one set: no row
        sur.predict(x[2])


def test_values_on_the_range_ends_are_predicted_round_off_included(shipped):
    """The ends themselves, SI values made back from fractions of the range (lo + u (hi -
    lo), as NSGA-II, the refinement's steps and evaluate do), and float32 ones: taken, as a
    finite-difference step inwards at a bound is; a step out of the range by a thousandth
    of it is refused."""
    sur, _ = shipped
    lo, hi = bounds(sur.spec.parameters)
    u = np.array([0.0, 1.0, 0.3, 1.0 - 1e-17, 0.7])
    x = np.vstack(
        [lo, hi, lo + (hi - lo) * u, lo + (hi - lo) * np.float32(1.0), hi.astype(np.float32)]
    )
    n_track = sur.spec.n_features - len(sur.spec.parameters)
    track = np.random.default_rng(0).standard_normal((120, n_track))
    out = sur.predict(x, track=track)
    assert out.shape == (5, 120, 2) and np.isfinite(out[:, sur.spec.window :]).all()
    with pytest.raises(RailsuspInputError, match="is outside the range"):
        sur.predict(hi + 1e-3 * (hi - lo), track=track)
    with pytest.raises(RailsuspInputError, match="is outside the range"):
        sur.predict(lo - 1e-3 * (hi - lo), track=track)


def test_the_internal_finite_difference_points_lie_in_the_ranges():
    """The callers that step from a point (the Cramér-Rao slopes, the refinement's forward
    differences, the simulator correction's slopes) step inwards at a bound: every point
    they ask a surrogate for passes its check (a guard for the refusal above)."""
    from railsusp.estimate.output_error import REFINE_STEP
    from railsusp.surrogate.bundle import check_trained_range
    from railsusp.surrogate.data import params_to_unit

    lo, hi = bounds(KEYS)
    for u in (np.zeros(2), np.ones(2), np.array([1.0, 0.0]), np.array([1 - 1e-3, 1e-3])):
        h = np.where(u + REFINE_STEP <= 1.0, REFINE_STEP, -REFINE_STEP)
        x = lo + (np.vstack([u, u + np.diag(h)])) * (hi - lo)
        check_trained_range(x, params_to_unit(x, KEYS), KEYS)
        x_si = lo + u * (hi - lo)
        step = 0.05 * (hi - lo)
        stepped = x_si[None] + np.diag(np.where(x_si + step > hi, -step, step))
        check_trained_range(stepped, params_to_unit(stepped, KEYS), KEYS)


# ------------------------------------------------ 2. compare --models with a repeat
def test_compare_refuses_a_model_named_twice(run):
    """``--models rbf,rbf`` trained it twice and repeated its rows in compare.csv and the
    table; refused as ``campaign --parameters X13,X13`` is, before any training."""
    line = _error(["compare", run, "--models", "rbf,gp-stats,rbf"])
    assert line == "error: --models rbf,gp-stats,rbf: models repeat (rbf); accepted each once"
    assert not (run / "surrogates").exists()


# ------------------------------------------------ 3. a hand-edited split
def _edit_split(run: Path, edit) -> Path:
    from railsusp.surrogate.split import campaign_split, split_path

    campaign_split(load_campaign(run))
    path = split_path(run, 0)
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize(
    ("edit", "why"),
    [
        (
            lambda d: d["test"].append(999),
            "samples [999] are not the campaign's, whose samples are",
        ),
        (lambda d: d["train"].pop(), "are in no part"),
        (lambda d: d["val"].append(d["val"][0]), "are named twice in one part"),
    ],
    ids=["unknown sample", "sample in no part", "sample twice"],
)
def test_a_split_that_is_no_partition_of_the_samples_is_refused(run, edit, why):
    """A sample that does not exist was accepted, and one in no part dropped without a word
    (train exited 0, its test runs one fewer); now refused as parts sharing a sample are."""
    from railsusp.surrogate.split import campaign_split

    path = _edit_split(run, edit)
    with pytest.raises(RailsuspInputError) as info:
        campaign_split(load_campaign(run))
    text = str(info.value)
    assert text.startswith(f"{path}: corrupt split (") and why in text and "\n" not in text
    assert text.endswith("delete it to draw the split again")


def test_train_refuses_a_split_naming_a_sample_the_campaign_lacks(run):
    path = _edit_split(run, lambda d: d["test"].append(999))
    quick = ["--epochs", "1", "--batches-per-epoch", "1", "--batch-size", "8"]
    line = _error(["train", run, "--model", "bp", *quick])
    assert line.startswith(f"error: {path}: corrupt split (samples [999] are not the campaign's")


# ------------------------------------------------ 4a. campaign: check first, then announce
def test_a_campaign_refused_for_another_configuration_announces_nothing(run):
    """It printed "2 simulations (2 sets x 1 conditions) into RUN" first, then refused."""
    line = _error(["campaign", "--out", run, "--conditions", "straight", "--samples", "2"])
    assert "holds a campaign with another configuration" in line


def test_a_campaign_on_a_scheduler_that_does_not_answer_announces_nothing(tmp_path, monkeypatch):
    import dask.distributed

    def refused(address, timeout):
        raise OSError(f"Timed out trying to connect to {address} after 10 s")

    monkeypatch.setattr(dask.distributed, "Client", refused)
    out = tmp_path / "r"
    scheduler = ["--scheduler", "tcp://127.0.0.1:8786"]
    line = _error(
        ["campaign", "--out", out, "--conditions", "straight", "--samples", "2", *scheduler]
    )
    assert line.startswith("error: --scheduler tcp://127.0.0.1:8786: no Dask scheduler answered")
    assert not out.exists()  # refused before the folder was prepared


def test_an_accepted_campaign_still_says_what_it_simulates(tmp_path):
    args = ["campaign", "--out", str(tmp_path / "r"), "--conditions", "straight"]
    args += ["--samples", "16", "--design", "sobol", "--parameters", "X13,X14"]
    result = runner.invoke(app, [*args, "--max-batches", "0"])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[0] == "Saltelli design: N(D+2) = 16 x 4 = 64 simulations per condition"
    assert lines[1] == f"64 simulations (64 sets x 1 conditions) into {tmp_path / 'r'}"


# ------------------------------------------------ 4b. a folder that cannot be written
@pytest.mark.parametrize(
    "args",
    [
        ["train", "{run}", "--model", "bp"],
        ["compare", "{run}", "--models", "rbf"],
        ["sensitivity", "{run}"],
    ],
    ids=["train", "compare", "sensitivity"],
)
@pytest.mark.parametrize(
    "case", ["read-only file system", "not ours, no lock file", "not ours, another's lock file"]
)
def test_a_read_only_run_folder_is_named_as_not_writable(run, monkeypatch, args, case):
    """It said "error: RUN/.railsusp.lock: Read-only file system": the lock file the system
    refused, not the folder, and not that it cannot be written; where another user's lock
    file was there, the command went on to fail on its first write (the tests run as root:
    the refusals are simulated)."""
    import railsusp.run_lock as rl

    failure = errno.EROFS if case == "read-only file system" else errno.EACCES
    if case == "not ours, no lock file":
        (run / rl.LOCK_NAME).unlink()
    assert (run / rl.LOCK_NAME).exists() == (case != "not ours, no lock file")

    def no_write(path, mode="r", *a, **kw):
        if Path(path).parent == run and ("a" in mode or "w" in mode):
            raise OSError(failure, os.strerror(failure), str(path))
        return builtins.open(path, mode, *a, **kw)

    real_access = os.access

    def access(path, mode, **kw):  # the folder readable, not writable
        return not (Path(path) == run and mode & os.W_OK) and real_access(path, mode, **kw)

    monkeypatch.setattr(rl, "open", no_write, raising=False)
    monkeypatch.setattr(os, "access", access)
    line = _error([a.format(run=run) for a in args])
    assert line == (
        f"error: the folder {run} is not writable ({os.strerror(failure)}); this command "
        "writes its results there"
    )
    assert not (run / "surrogates").exists() and not (run / "sensitivity").exists()


def test_a_reader_of_a_read_only_folder_still_reads_it_unlocked(tmp_path, monkeypatch):
    """A shared lock where no lock file can be made stays the OSError :func:`hold_shared`
    takes as a folder to read without a lock (a guard)."""
    from contextlib import ExitStack

    import railsusp.run_lock as rl

    def no_write(path, mode="r", *a, **kw):
        if "a" in mode or "w" in mode:
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(path))
        return builtins.open(path, mode, *a, **kw)

    monkeypatch.setattr(rl, "open", no_write, raising=False)
    with pytest.raises(OSError) as info, rl.run_lock(tmp_path, "--measured", shared=True):
        pass
    assert info.value.errno == errno.EROFS and not isinstance(info.value, RailsuspInputError)
    with ExitStack() as stack:
        rl.hold_shared(stack, tmp_path, "--measured")  # read unlocked, no error
    with pytest.raises(RailsuspInputError, match=f"^--out {tmp_path}: the folder {tmp_path} is"):
        with rl.run_lock(tmp_path, "--out"):
            pass


# ------------------------------------------------ 4c. campaign settings in its own words
@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (
            ["--parameters", ""],
            "error: --parameters '': none given; accepted one or more of X11..X20",
        ),
        (["--samples", "0"], "error: --samples 0: accepted [2, 1000000]"),
        (["--samples", "2000000"], "error: --samples 2000000: accepted [2, 1000000]"),
        (["--batch-size", "0"], "error: --batch-size 0: accepted [1, 10000]"),
        (
            ["--parameters", "X13,foo"],
            "error: --parameters X13,foo: unknown parameter 'foo'; accepted: X1..X20 or their "
            "names (e.g. X13 or primary_longitudinal_stiffness)",
        ),
        (
            ["--parameters", "X1,X13"],
            "error: --parameters X1,X13: X1 is a fixed parameter; sampled ones are X11..X20",
        ),
    ],
)
def test_campaign_settings_are_refused_naming_the_option_and_its_range(tmp_path, args, expected):
    """pydantic's "parameters: Tuple should have at least 1 item after validation, not 0"
    and "--samples 0: Input should be greater than or equal to 2" (one bound)."""
    out = tmp_path / "r"
    assert _error(["campaign", "--out", out, "--conditions", "straight", *args]) == expected
    assert not out.exists()


def test_make_config_says_the_range_of_a_setting(tmp_path):
    with pytest.raises(RailsuspInputError) as info:
        make_config([SHORT], 0, batch_size=0)
    assert str(info.value) == (
        "campaign configuration: samples = 0: accepted [2, 1000000]; batch_size = 0: accepted "
        "[1, 10000]"
    )


# ------------------------------------------------ 4d. an --out the system cannot make
@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="Linux /proc")
@pytest.mark.parametrize(
    "command",
    [["campaign", "--samples", "2"], ["posterior", "train", "--conditions", "straight"]],
)
def test_an_out_under_proc_is_refused_naming_out(command):
    """It said "error: /proc/foo: No such file or directory", without the option: every
    command that makes its --out (cli.common.hold_folders), not the campaign alone."""
    assert _error([*command, "--out", "/proc/railsusp-qa"]) == (
        "error: --out /proc/railsusp-qa: the folder /proc/railsusp-qa cannot be made (No such "
        "file or directory); accepted a folder that can be made and written"
    )


def test_unmade_folder_names_only_the_folder_asked_for(tmp_path):
    from railsusp.input_checks import unmade_folder

    out = tmp_path / "a" / "b"
    above = OSError(errno.EACCES, "Permission denied", str(tmp_path / "a"))
    made = unmade_folder(above, out, "--out")
    assert str(made) == (
        f"--out {out}: the folder {tmp_path / 'a'} cannot be made (Permission denied); "
        "accepted a folder that can be made and written"
    )
    assert unmade_folder(OSError(errno.EACCES, "Permission denied", "/elsewhere"), out) is None
    assert unmade_folder(OSError(errno.EIO, "I/O error"), out) is None
