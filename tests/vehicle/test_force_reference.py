"""The simulator's forces against stored reference forces (bench/force_reference.py): a speed
change of the right-hand side must leave them unchanged to 1e-9 of the largest force."""

from pathlib import Path

import numpy as np
import pytest

from conftest import bench_script

#: the reference forces of the model before the wedges' warp friction (2026-11-24), whose
#: wedge pair acted at the nest centre: tests/data/force_reference.npz of commit 2192499
WEDGE_PAIR_REFERENCE = (
    Path(__file__).resolve().parents[1] / "data" / "force_reference_wedge_pair.npz"
)
#: the reference forces of revision 2026-11-30.1, before the side frames' roll couple, the
#: car body's gravity roll moment and the coupler line halfway between cars
ROLL_MOMENTS_REFERENCE = (
    Path(__file__).resolve().parents[1] / "data" / "force_reference_2026-11-30.1.npz"
)

#: the reference forces of revision 2026-11-30.2, before the centre bowl's pitch reaction on
#: the side frames and the bogies' own pitch moment on a grade
BOWL_PITCH_REFERENCE = (
    Path(__file__).resolve().parents[1] / "data" / "force_reference_2026-11-30.2.npz"
)


def _bench():
    return bench_script("force_reference")


@pytest.mark.parametrize("condition", ["straight", "curve"])
def test_forces_match_the_stored_reference(condition):
    fr = _bench()
    ref = np.load(fr.REFERENCE)
    y, q = fr.reference_forces(condition)
    assert fr.relative_difference(y, ref[f"{condition}_Y"]) < 1e-9
    assert fr.relative_difference(q, ref[f"{condition}_Q"]) < 1e-9


def test_the_reference_check_sees_a_changed_force():
    """The comparison is sensitive: one force changed by 1e-6 of the largest fails it."""
    fr = _bench()
    ref = np.load(fr.REFERENCE)["straight_Q"]
    changed = ref.copy()
    changed[0, 0, 100] += 1e-6 * np.max(np.abs(ref))
    assert fr.relative_difference(changed, ref) > 1e-9


def test_the_reference_is_of_this_model_revision():
    """Forces and revision go together: a physics change writes new forces under a new
    railsusp.vehicle.MODEL_REVISION, which re-simulates the run directories of the old one."""
    from railsusp.vehicle import MODEL_REVISION

    assert _bench().stored_revision() == MODEL_REVISION


def test_writing_changed_forces_under_the_stored_revision_is_refused(tmp_path, monkeypatch):
    fr = _bench()
    path = tmp_path / "ref.npz"
    monkeypatch.setattr(fr, "REFERENCE", path)
    forces = {"straight_Q": np.full((1, 8, 4), 1.0e5)}
    fr.write_reference(forces)
    assert fr.stored_revision() == fr.MODEL_REVISION
    fr.write_reference(forces)  # the same forces again: fine
    moved = {"straight_Q": forces["straight_Q"] * (1 + 1e-6)}
    with pytest.raises(SystemExit, match="give railsusp.vehicle.MODEL_REVISION a new value"):
        fr.write_reference(moved)
    monkeypatch.setattr(fr, "MODEL_REVISION", "next")
    fr.write_reference(moved)
    assert fr.stored_revision() == "next"


@pytest.mark.parametrize("condition", ["straight", "curve"])
def test_wedges_at_the_nest_centre_reproduce_the_forces_before_the_warp_friction(condition):
    """``[secondary] wedge_half_spacing = 0`` is the model before the front and rear wedges
    were split (one wedge pair at the nest centre, no warp friction): its forces equal those
    stored with that model to 1e-9 of the largest force (measured: bit for bit against a
    fresh run of that model, 3e-14 against the stored file, the machine's round-off)."""
    from railsusp.vehicle.wagon import FORCE_LAWS_BEFORE_2026_11_30_2, load_wagon

    fr = _bench()
    wagon = load_wagon().with_values(
        {**FORCE_LAWS_BEFORE_2026_11_30_2, "secondary.wedge_half_spacing": 0.0}
    )
    y, q = fr.reference_forces(condition, wagon)
    ref = np.load(WEDGE_PAIR_REFERENCE)
    assert fr.relative_difference(y, ref[f"{condition}_Y"]) < 1e-9
    assert fr.relative_difference(q, ref[f"{condition}_Q"]) < 1e-9


@pytest.mark.parametrize("condition", ["straight", "curve"])
def test_the_switches_of_revision_2026_11_30_1_reproduce_its_forces(condition):
    """``FORCE_LAWS_BEFORE_2026_11_30_2`` (side frames not rolling with their wheelsets, no
    gravity roll moment, the coupler angle at its pivot) is the model of revision
    2026-11-30.1: its forces equal that revision's stored reference to 1e-9 of the largest
    (and the model of today differs from it: the check is not blind)."""
    from railsusp.vehicle.wagon import FORCE_LAWS_BEFORE_2026_11_30_2, load_wagon

    fr = _bench()
    ref = np.load(ROLL_MOMENTS_REFERENCE)
    assert str(ref["model_revision"]) == "2026-11-30.1"
    y, q = fr.reference_forces(condition, load_wagon().with_values(FORCE_LAWS_BEFORE_2026_11_30_2))
    assert fr.relative_difference(y, ref[f"{condition}_Y"]) < 1e-9
    assert fr.relative_difference(q, ref[f"{condition}_Q"]) < 1e-9
    _, q_now = fr.reference_forces(condition)
    assert fr.relative_difference(q_now, ref[f"{condition}_Q"]) > 1e-3


@pytest.mark.parametrize("condition", ["straight", "curve"])
def test_the_switches_of_revision_2026_11_30_2_reproduce_its_forces(condition):
    """``FORCE_LAWS_BEFORE_2026_12_02_1`` (the bowl's pitch moment against the track, with no
    reaction; a bogie's wheels loaded alike on a grade) is the model of revision
    2026-11-30.2: its forces equal that revision's stored reference to 1e-9 of the largest,
    and today's differ from it (by 2-7 % of the largest: the check is not blind)."""
    from railsusp.vehicle.wagon import FORCE_LAWS_BEFORE_2026_12_02_1, load_wagon

    fr = _bench()
    ref = np.load(BOWL_PITCH_REFERENCE)
    assert str(ref["model_revision"]) == "2026-11-30.2"
    y, q = fr.reference_forces(condition, load_wagon().with_values(FORCE_LAWS_BEFORE_2026_12_02_1))
    assert fr.relative_difference(y, ref[f"{condition}_Y"]) < 1e-9
    assert fr.relative_difference(q, ref[f"{condition}_Q"]) < 1e-9
    _, q_now = fr.reference_forces(condition)
    assert fr.relative_difference(q_now, ref[f"{condition}_Q"]) > 1e-3
