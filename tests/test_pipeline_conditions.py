"""Conditions through the synthetic field and the whole pipeline.

A condition that names its own measured track (``track_geometry``): before stop 57 the
field's sidecar named the user's file by a path the reader resolves inside the field folder,
where it was not (the estimate stage failed: "track geometry file .../field/geo.csv not
found"), and with ``with_track`` the report stage failed on the track figure's seed ("tuple
index out of range"). A run folder used again after a condition was renamed kept the old
condition's surrogates, which stopped its estimate stage."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from railsusp.conditions import get_condition
from railsusp.measured import read_field, synthesise_field
from railsusp.params import ParameterSet
from railsusp.pipeline import load_config, run_pipeline

TINY = Path(__file__).resolve().parents[1] / "examples" / "tiny.toml"
SHORT = dict(duration_s=1.0, n_steps=50, lead_in_m=20.0)


@pytest.fixture(scope="module")
def geometry(tmp_path_factory) -> Path:
    """A measured-track file covering the tiny example's 1 s condition: the track a
    synthetic recording ran on, as a geometry car would give it."""
    root = tmp_path_factory.mktemp("geometry")
    cond = get_condition("straight", **SHORT).with_changes(name="short")
    folder = synthesise_field(ParameterSet({}), [cond], root / "f", with_track=True)
    return folder / "short.track.csv"


def test_the_recording_carries_a_copy_of_its_conditions_track(geometry, tmp_path):
    cond = get_condition(
        "straight", track_geometry=str(geometry), track_offset_m=0.5, **SHORT
    ).with_changes(name="short")
    for with_track in (False, True):
        folder = synthesise_field(
            ParameterSet({}), [cond], tmp_path / f"f{with_track}", with_track=with_track
        )
        side = json.loads((folder / "short.json").read_text())["condition"]
        assert side["track_geometry"] == "short.track.csv"  # inside the folder
        assert "track_offset_m" not in side  # applied to the copy's distances
        (rec,) = read_field(folder)  # read back and checked: it covers the record
        copy = pd.read_csv(folder / "short.track.csv")
        original = pd.read_csv(geometry)
        assert np.allclose(copy["distance_m"], original["distance_m"] + 0.5, atol=1e-9)
        for column in ("vertical_mm", "alignment_mm", "crosslevel_mm", "gauge_mm"):
            assert np.allclose(copy[column], original[column], atol=1e-9)  # not faded
        assert rec.condition.track_geometry is not None


def _own_track_config(tmp_path: Path, geometry: Path, field: str, estimate: str) -> Path:
    """The tiny example whose condition names ``geometry`` as its own track, with lines
    ``field`` and ``estimate`` added to those sections."""
    text = TINY.read_text().replace(
        "lead_in_m=20.0}", f'lead_in_m=20.0, track_geometry="{geometry}"}}'
    )
    text = text.replace("[field]\n", f"[field]\n{field}").replace(
        "[estimate]\n", f"[estimate]\n{estimate}"
    )
    cfg = tmp_path / "c.toml"
    cfg.write_text(text)
    return cfg


@pytest.mark.parametrize(
    ("with_track", "statistic"), [(False, "mean"), (True, "mean"), (True, "aligned")]
)
def test_a_run_on_a_condition_with_its_own_track_completes(
    geometry, tmp_path, with_track, statistic
):
    """With ``aligned`` the surrogates trained here (on the condition's one track) predict
    the recording's track, since it is that track (``same_measured_track``): the one
    configuration where ``aligned`` works without a pretrained set."""
    field = "with_track = true\n" if with_track else ""
    cfg = _own_track_config(tmp_path, geometry, field, f'statistic = "{statistic}"\n')
    out = tmp_path / "run"
    state = run_pipeline(load_config(cfg), out)
    assert all(s["state"] == "done" for s in state["stages"].values())
    assert (out / "report_assets" / "track.png").is_file()
    estimate = json.loads((out / "estimate" / "estimate.json").read_text())
    assert estimate["config"]["statistic"] == statistic


def test_a_run_folder_reused_with_a_renamed_condition(tmp_path):
    """The surrogates of a condition the configuration no longer has were left in the run's
    surrogate folder, where the estimate loads every bundle: renaming the condition (and so
    getting other key parameters) stopped the run in its estimate stage, and every later
    run in that folder, even with --from campaign (stop 57's audit)."""
    out = tmp_path / "run"
    first = tmp_path / "a.toml"
    first.write_text(TINY.read_text())
    run_pipeline(load_config(first), out)
    second = tmp_path / "b.toml"
    second.write_text(
        TINY.read_text()
        .replace('name="short"', 'name="renamed"')
        .replace("max_keys = 2", "max_keys = 1")
    )
    state = run_pipeline(load_config(second), out)
    assert all(s["state"] == "done" for s in state["stages"].values())
    for model in (out / "surrogate-campaign" / "surrogates").iterdir():
        if not model.is_dir():
            continue  # figures, the comparison table
        assert sorted(p.name for p in model.iterdir() if p.is_dir()) == ["renamed"], model


def test_own_track_recordings_carry_their_track_and_noise_makes_them_other_tracks(
    geometry, tmp_path
):
    """The review of stop 57: without with_track such recordings still carry their track
    (aligned and refine were refused), and with track_noise_mm their copies are other tracks
    than the surrogates' (aligned was accepted and failed in the estimate stage)."""
    from railsusp.errors import RailsuspInputError

    aligned = 'statistic = "aligned"\n'
    load_config(_own_track_config(tmp_path, geometry, "", aligned))
    load_config(_own_track_config(tmp_path, geometry, "", "refine = true\n"))
    noisy = "with_track = true\ntrack_noise_mm = 1.0\n"
    with pytest.raises(RailsuspInputError, match='statistic "aligned" needs surrogate.pretrained'):
        load_config(_own_track_config(tmp_path, geometry, noisy, aligned))


def test_with_track_on_perfect_track_is_refused_before_any_stage(tmp_path):
    from railsusp.errors import RailsuspInputError

    text = TINY.read_text().replace("lead_in_m=20.0}", 'lead_in_m=20.0, irregularity_class="none"}')
    cfg = tmp_path / "c.toml"
    cfg.write_text(text.replace("[field]\n", "[field]\nwith_track = true\n"))
    with pytest.raises(RailsuspInputError, match="short on perfect track .* no track geometry"):
        load_config(cfg)
    cfg.write_text(text)
    assert load_config(cfg).working_conditions()[0].irregularity_class is None
