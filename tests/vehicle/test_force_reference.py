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


#: the reference forces of revision 2026-12-02.1, before the track-following frames turned
#: in the bodies' equations and the primary took the design twist
FRAME_ROTATION_REFERENCE = (
    Path(__file__).resolve().parents[1] / "data" / "force_reference_2026-12-02.1.npz"
)


#: the reference forces of revision 2026-12-03.1, before the side frames' yaw moved the
#: cross-bracing pins (and axle boxes off their centreline) longitudinally
BAR_PINS_REFERENCE = (
    Path(__file__).resolve().parents[1] / "data" / "force_reference_2026-12-03.1.npz"
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
@pytest.mark.parametrize(
    ("revision", "switches", "reference"),
    [
        ("2026-11-30.1", "FORCE_LAWS_BEFORE_2026_11_30_2", ROLL_MOMENTS_REFERENCE),
        ("2026-11-30.2", "FORCE_LAWS_BEFORE_2026_12_02_1", BOWL_PITCH_REFERENCE),
        ("2026-12-02.1", "FORCE_LAWS_BEFORE_2026_12_03_1", FRAME_ROTATION_REFERENCE),
        ("2026-12-03.1", "FORCE_LAWS_BEFORE_2026_12_03_2", BAR_PINS_REFERENCE),
    ],
)
def test_the_switches_of_an_earlier_revision_reproduce_its_forces(
    condition, revision, switches, reference
):
    """The wagon fields that restore an earlier revision's force laws give its forces: equal
    to that revision's stored reference to 1e-9 of the largest, and today's differ from it
    (the check is not blind). ``FORCE_LAWS_BEFORE_2026_11_30_2``: side frames not rolling
    with their wheelsets, no gravity roll moment, the coupler angle at its pivot (and the
    later switches); ``FORCE_LAWS_BEFORE_2026_12_02_1``: the bowl's pitch moment against
    the track, with no reaction, the side frames free to pitch against the bolster, a
    bogie's wheels loaded alike on a grade (today's forces 2-7 % of the largest off);
    ``FORCE_LAWS_BEFORE_2026_12_03_1``: the frames not turning in the bodies' equations, the
    primary blind to the design twist (on tangent they change nothing: the straight
    condition's forces are today's to 2e-13, so there the check that today's differ is the
    curve's, 1.6-3.3 % of the largest); ``FORCE_LAWS_BEFORE_2026_12_03_2``: the side frames'
    yaw blind to the cross-bracing pins' lateral offset."""
    from railsusp.vehicle import wagon as wagons

    fr = _bench()
    ref = np.load(reference)
    assert str(ref["model_revision"]) == revision
    earlier = wagons.load_wagon().with_values(getattr(wagons, switches))
    y, q = fr.reference_forces(condition, earlier)
    assert fr.relative_difference(y, ref[f"{condition}_Y"]) < 1e-9
    assert fr.relative_difference(q, ref[f"{condition}_Q"]) < 1e-9
    if switches == "FORCE_LAWS_BEFORE_2026_12_03_1" and condition == "straight":
        return  # tangent: nothing turns, nothing twists
    y_now, q_now = fr.reference_forces(condition)
    moved = max(
        fr.relative_difference(y_now, ref[f"{condition}_Y"]),
        fr.relative_difference(q_now, ref[f"{condition}_Q"]),
    )
    assert moved > 1e-3  # (the bars' pins: Y 0.8-9 % of the largest, Q 0.08-0.3 %)
