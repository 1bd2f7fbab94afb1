"""Tests that close gaps found by the mutation review of stop 74: behaviours of the measured
data (a truth told to belong to its recordings, the field folders a writer may replace, the
sign check of a curve's outer wheel, the distance channel's jumps) and of the atomic folder
write that no test checked, so that a mutation of each survived the suite."""

import hashlib
import json
import shutil

import numpy as np
import pytest

from railsusp.atomic_files import atomic_folder
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.measured import RecordingError, check_truth_of, synthesise_field
from railsusp.measured.breaks import jump_steps
from railsusp.measured.field_folder import check_field_output, folder_kind, source_fingerprint
from railsusp.measured.run import MeasuredRun
from railsusp.measured.sections import cut_sections
from railsusp.params import ParameterSet


# ---------------------------------------------------------------- 1. truth.check_truth_of
def test_a_truth_is_refused_for_a_folder_mixing_its_recording_with_a_foreign_one(tmp_path):
    """Every recording table of the folder must be one the truth was written with: one
    foreign table among the truth's own is refused, naming it (not only a folder whose
    tables are all foreign)."""
    cond = get_condition("straight", duration_s=1.0, n_steps=50, lead_in_m=30.0)
    a = synthesise_field(ParameterSet({"X13": 18.0}, units="display"), [cond], tmp_path / "a")
    b = synthesise_field(
        ParameterSet({"X13": 9.0}, units="display"), [cond], tmp_path / "b", seed=11
    )
    check_truth_of(a / "truth.json", a)  # its own recordings: accepted
    mixed = tmp_path / "mixed"
    shutil.copytree(a, mixed)
    shutil.copyfile(b / "straight.csv", mixed / "other.csv")
    sidecar = json.loads((b / "straight.json").read_text("utf-8"))
    (mixed / "other.json").write_text(json.dumps(sidecar), "utf-8")
    index = json.loads((mixed / "index.json").read_text("utf-8"))
    index["recordings"] = ["straight.csv", "other.csv"]
    (mixed / "index.json").write_text(json.dumps(index), "utf-8")
    with pytest.raises(RailsuspInputError, match="other.csv is none of the tables") as info:
        check_truth_of(a / "truth.json", mixed)
    assert "(other.csv is none of the tables it was written with" in str(info.value)


# ---------------------------------------------------------------- 2. atomic_folder(keep=)
def test_an_atomic_folder_without_keep_drops_the_old_entries_and_with_keep_carries_them(
    tmp_path,
):
    dest = tmp_path / "out"
    dest.mkdir()
    (dest / "old.txt").write_text("old")
    with atomic_folder(dest, keep=False) as t:
        (t / "new.txt").write_text("x")
    assert sorted(p.name for p in dest.iterdir()) == ["new.txt"]
    assert (dest / "new.txt").read_text() == "x"

    (dest / "old.txt").write_text("old")
    with atomic_folder(dest, keep=True) as t:
        (t / "newer.txt").write_text("y")
    assert sorted(p.name for p in dest.iterdir()) == ["new.txt", "newer.txt", "old.txt"]
    assert (dest / "old.txt").read_text() == "old"


# ---------------------------------------------------------------- 3. field_folder._same_source
def _sections_folder(folder, index):
    folder.mkdir(parents=True)
    (folder / "sections.csv").write_text("section,kept\ns1,True\n", "utf-8")
    (folder / "index.json").write_text(json.dumps(index), "utf-8")
    return folder


def test_a_run_of_the_same_size_but_other_contents_is_another_run(tmp_path):
    """The same run is told by its size AND its SHA-256: a run of the same byte size whose
    contents differ (one digit) is another run, refused; the run itself is accepted."""
    run = tmp_path / "day1" / "run.csv"
    other = tmp_path / "day2" / "run.csv"
    run.parent.mkdir()
    other.parent.mkdir()
    run.write_text("t,x\n0.0,1.5\n", "utf-8")
    other.write_text("t,x\n0.0,1.6\n", "utf-8")
    assert run.stat().st_size == other.stat().st_size
    fingerprint = source_fingerprint(run)
    assert fingerprint["source_sha256"] == hashlib.sha256(run.read_bytes()).hexdigest()
    folder = _sections_folder(tmp_path / "cut", {**fingerprint, "recordings": ["s1.csv"]})
    assert folder_kind(folder) == "sections"
    assert check_field_output(folder, "sections", "--write", source=run) == folder
    with pytest.raises(RailsuspInputError, match="holds the sections of another run") as info:
        check_field_output(folder, "sections", "--write", source=other)
    assert f"{run.stat().st_size} bytes" in str(info.value)


# ---------------------------------------------------------------- 4. field_folder.folder_kind
def test_a_sections_folder_holding_a_truth_is_no_sections_folder(tmp_path):
    """An index naming a run's source beside sections.csv is a sections folder, unless a
    truth.json lies there too: then it is "other" (and sections --write refuses it)."""
    folder = _sections_folder(tmp_path / "cut", {"source": "run.csv", "recordings": ["s1.csv"]})
    assert folder_kind(folder) == "sections"
    (folder / "truth.json").write_text(json.dumps({"parameters_display": {}}), "utf-8")
    assert folder_kind(folder) == "other"
    with pytest.raises(RailsuspInputError, match="holds files of another kind"):
        check_field_output(folder, "sections", "--write")


# ---------------------------------------------------------------- 7. sections._check_y_sign
def _curve_run(y_outer_kn: float, q_outer_kn: float) -> MeasuredRun:
    """60 s at 45 km/h on a right-hand R350 (750 m, one kept section), the outer wheel w1L
    reading Y about ``y_outer_kn`` and Q about ``q_outer_kn``."""
    n, rate = 3000, 50.0
    v = np.full(n, 45.0 / 3.6)
    t = np.arange(n) / rate
    s = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) / rate)])
    rng = np.random.default_rng(2)
    y = {w: 5e3 + 1e3 * rng.standard_normal(n) for w in ("w1R", "w1L")}
    q = {w: 120e3 + 5e3 * rng.standard_normal(n) for w in ("w1R", "w1L")}
    y["w1L"] = y_outer_kn * 1e3 + 0.2e3 * rng.standard_normal(n)
    q["w1L"] = q_outer_kn * 1e3 + 0.5e3 * rng.standard_normal(n)
    curvature = np.full(n, -1.0 / 350.0)  # 1/m, + left-hand: a right-hand R350
    return MeasuredRun("synthetic.csv", t, y, q, v, s, curvature, np.zeros(n), np.zeros(n))


def test_the_sign_margin_of_the_outer_wheel_grows_with_its_wheel_load():
    """The margin below zero is the larger of 5 kN and a tenth of the wheel's median load:
    -8 kN under 120 kN (margin 12 kN) is kept with a note to check the sign; -8 kN under
    40 kN (margin 5 kN) is refused."""
    heavy = _curve_run(-8.0, 120.0)
    assert [s.kept for s in cut_sections(heavy)] == [True]
    (note,) = [x for x in heavy.notes if x.startswith("wheel w1L: Y median -8.0 kN")]
    assert "check its sign" in note
    light = _curve_run(-8.0, 40.0)
    with pytest.raises(RecordingError) as info:
        cut_sections(light)
    (problem,) = info.value.problems
    assert problem.startswith("wheel w1L: Y median -8.0 kN in ")
    assert "where it is the leading outer wheel and flanges" in problem


# ---------------------------------------------------------------- 8. breaks.jump_steps
def test_a_standing_wagons_distance_jitter_is_no_jump_but_a_real_jump_is():
    """Standing (speed 0), a distance channel jittering by 0.1 m covers nothing at the
    speed, yet is no jump: the threshold has a 1 m floor for the channel's resolution. A
    50 m step while standing is one."""
    t = np.arange(400) / 50.0
    speed = np.zeros(400)
    jitter = np.tile([0.0, 0.1], 200)
    assert jump_steps(jitter, t, speed).size == 0
    x = np.where(np.arange(400) < 200, 0.0, 50.0)
    assert jump_steps(x, t, speed).tolist() == [199]
    assert jump_steps(jitter + x, t, speed).tolist() == [199]
