"""Mode names where the audit of the modes code (2026-12) found them wrong, and what the
``railsusp modes`` tables show for them: roots in which no body moves (the sliding
variant's friction states relaxing) were named "car body bounce"; every bogie warp mode was
named "bogie 2" although both bogies warp in it; the free-decay table under a sliding modes
table compared with the stuck linearisation without saying so."""

from __future__ import annotations

import re

import numpy as np
import pytest
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.vehicle import layout as L
from railsusp.vehicle.modes import NO_MOTION_GROUP, NO_MOTION_NAME, modal_analysis


@pytest.fixture(scope="module")
def stuck():
    return modal_analysis()


@pytest.fixture(scope="module")
def sliding():
    return modal_analysis(friction="sliding")


def test_a_root_without_motion_is_no_car_body_mode(sliding):
    """The sliding linearisation has 24 roots at λ = -500 1/s in which only the zero-limit
    sliders' auxiliary states relax: no kinetic energy anywhere. The largest share of an
    all-zero energy vector had named each "car body bounce"; now each is a
    friction-state relaxation, no car-body mode, and every mode named after a body carries
    kinetic energy."""
    still = np.flatnonzero(sliding.energy.sum(axis=1) == 0.0)
    assert still.size == 24
    assert {sliding.names[i] for i in still} == {NO_MOTION_NAME}
    assert {sliding.groups[i] for i in still} == {NO_MOTION_GROUP}
    np.testing.assert_allclose(sliding.eigenvalues[still], -500.0, rtol=1e-6)
    assert not set(still) & set(sliding.car_body_modes(f_max=1000.0, min_share=0.0))
    moving = np.setdiff1d(np.arange(len(sliding)), still)
    assert all(sliding.groups[i] != NO_MOTION_GROUP for i in moving)
    assert [sliding.names[i] for i in moving].count("car body bounce") == 1


def test_the_modes_table_leaves_the_friction_states_out_and_counts_them():
    """`modes --friction sliding --fmax 100` listed the 24 roots as car-body bounce modes
    at 79.6 Hz; now they are left out of the table and counted under it."""
    result = CliRunner().invoke(app, ["modes", "--friction", "sliding", "--fmax", "100"])
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    assert "24 roots below 100 Hz left out: friction-state relaxation (no motion)" in text
    assert NO_MOTION_NAME not in result.output.split("roots below")[0]
    assert text.count("car body bounce") == 1


def _side_frame_x(result, i: int) -> tuple[np.ndarray, np.ndarray]:
    """Each bogie's share of mode i's kinetic energy in the side frames' longitudinal
    motion, and each bogie's warp coordinate (left minus right side frame's x)."""
    e = result.energy[i, L.SF0 : L.WS0].reshape(4, 5)[:, 0]
    q = result.shapes[i]
    warp = np.array([q[L.SF0] - q[L.SF0 + 5], q[L.SF0 + 10] - q[L.SF0 + 15]])
    return e.reshape(2, 2).sum(axis=1), warp


def _mark(result, i: int) -> str:
    """The mark a real root's name ends in (docs/model.md, modal analysis)."""
    return ", overdamped" if result.overdamped[i] else ""


def test_bogie_warp_modes_name_both_bogies_and_their_phase(stuck):
    """Four warp modes of the loaded wagon (two pairs, 24.7 and 92.7 Hz) carry 29-36 % of
    their energy in each bogie's side frames; all four were named "bogie 2 warp". Each pair
    is the two bogies warping in phase and anti-phase, and is named so (the phase read from
    the shapes' warp coordinates here, independently of the naming code)."""
    warps = [i for i, n in enumerate(stuck.names) if n.startswith("bogie warp")]
    assert len(warps) == 4, stuck.names
    for i in warps:
        per_bogie, warp = _side_frame_x(stuck, i)
        assert per_bogie.min() > 0.2, (stuck.names[i], per_bogie)
        phase = "in phase" if (warp[0] * np.conj(warp[1])).real > 0 else "anti-phase"
        want = f"bogie warp (bogies {phase}){_mark(stuck, i)}"
        assert stuck.names[i] == want, (stuck.names[i], warp)
    pairs = sorted(warps, key=lambda i: stuck.frequency_hz[i])
    for a, b in (pairs[:2], pairs[2:]):
        assert {stuck.names[a], stuck.names[b]} == {
            f"bogie warp (bogies in phase){_mark(stuck, a)}",
            f"bogie warp (bogies anti-phase){_mark(stuck, a)}",
        }


def test_one_bogies_longitudinal_modes_name_that_bogie(stuck):
    """A side-frame longitudinal mode with 80 % or more of that energy in one bogie names it
    (front: bogie 1)."""
    longitudinal = [i for i, n in enumerate(stuck.names) if "side frames longitudinal" in n]
    assert longitudinal
    for i in longitudinal:
        per_bogie, _ = _side_frame_x(stuck, i)
        share = per_bogie / per_bogie.sum()
        if share.max() > 0.8:
            which = "front bogie" if share[0] > 0.8 else "rear bogie"
            want = f"side frames longitudinal ({which}){_mark(stuck, i)}"
            # (a rank among like-named roots: near-equal overdamped roots swap at round-off)
            assert re.sub(r", (second|third|\d+th)$", "", stuck.names[i]) == want, share


def test_the_decay_table_under_a_sliding_table_says_it_is_against_the_stuck_one(monkeypatch):
    """`modes --decay --friction sliding`: the decay table's "linear f Hz" was the stuck
    linearisation's (bounce 4.82 Hz) under a sliding modes table (bounce 2.48 Hz), unlabelled.
    The free decay runs the friction as modelled, which sticks at small amplitudes, so the
    stuck linearisation is its reference (the command's docstring): the columns and title
    say so, a line says why under a sliding table, and the decay asks the stuck
    linearisation (no sliding ``modal`` passed, friction as modelled)."""
    import railsusp.vehicle.decay as decay

    calls = []
    inner = decay.free_decay

    def spy(*args, **kwargs):
        calls.append(kwargs)
        return inner(*args, **{**kwargs, "excitations": ("dip",), "window_s": 1.0})

    monkeypatch.setattr(decay, "free_decay", spy)
    result = CliRunner().invoke(
        app, ["modes", "--friction", "sliding", "--decay", "--fmax", "6"], terminal_width=240
    )
    assert result.exit_code == 0, result.output
    assert calls and calls[0].get("modal") is None and "friction" not in calls[0]
    text = " ".join(result.output.split())
    assert "stuck linear f Hz" in text and "stuck linear damping" in text
    assert "against the stuck linearisation" in text
    assert "not the sliding table's above" in text
    stuck_run = CliRunner().invoke(app, ["modes", "--decay", "--fmax", "6"], terminal_width=240)
    assert stuck_run.exit_code == 0, stuck_run.output
    assert calls[1]["modal"] is not None and calls[1]["modal"].friction == "stuck"
    assert "not the sliding table's above" not in " ".join(stuck_run.output.split())


def _plates(result, i: int) -> tuple[complex, complex]:
    """The car body's lateral motion at its front and rear centre plates in mode i (read
    from the shape here, apart from the naming code)."""
    from railsusp.vehicle.operating_point import linearisation_point

    K = linearisation_point().K
    q = result.shapes[i]
    base = q[L.CB_Y] - (K[L.K["h_cp"]] - K[L.K["h_cg_c"]]) * q[L.CB_ROLL]
    arm = K[L.K["l_c"]] * q[L.CB_YAW]
    return base + arm, base - arm


def test_every_mode_of_a_table_has_a_name_of_its_own(stuck):
    """QA: in the loaded wagon's stuck table two rows, 1.67 Hz ζ 0.31 and 1.70 Hz
    ζ 0.50, were both "car body kinematic (hunting-like) lateral". Both are mostly lateral;
    what tells them apart is which end's centre plate leads: the front in the first, the
    rear in the second (the phases read from the shapes here). Every moving mode's name is
    now its own."""
    body = [i for i, n in enumerate(stuck.names) if n.startswith("car body kinematic")]
    assert len(body) == 2, [stuck.names[i] for i in body]
    for i in body:
        front, rear = _plates(stuck, i)
        lead = "front" if np.angle(front * np.conj(rear)) > 0 else "rear"
        assert stuck.names[i] == f"car body kinematic (hunting-like) lateral ({lead} end leading)"
    assert {stuck.names[i] for i in body} == {
        "car body kinematic (hunting-like) lateral (front end leading)",
        "car body kinematic (hunting-like) lateral (rear end leading)",
    }
    moving = [n for n in stuck.names if n != NO_MOTION_NAME]
    assert len(set(moving)) == len(moving)


def test_an_overdamped_root_is_named_so_and_not_hunting_like():
    """QA: `modes --wagon tare --fmax 12` named an oscillating 5.01 Hz mode and a
    22.2 ms real root both "wheelset kinematic (hunting-like) lateral-yaw (bogies in
    phase)". A real root does not oscillate: its name ends in ", overdamped" and does not
    say hunting-like; the oscillating modes' names say neither."""
    from railsusp.vehicle.wagon import load_wagon

    tare = modal_analysis(wagon=load_wagon("tare"))
    for i, name in enumerate(tare.names):
        if name == NO_MOTION_NAME:
            continue
        assert ("overdamped" in name) == bool(tare.overdamped[i]), name
        assert not (tare.overdamped[i] and "hunting-like" in name), name
    oscillating = tare.find("wheelset kinematic (hunting-like) lateral-yaw (bogies in phase)")
    assert tare.frequency_hz[oscillating] == pytest.approx(5.01, abs=0.01)
    assert "wheelset kinematic lateral-yaw (bogies in phase), overdamped" in tare.names
    moving = [n for n in tare.names if n != NO_MOTION_NAME]
    assert len(set(moving)) == len(moving)


def test_an_empty_modes_table_says_which_mode_is_the_lowest():
    """QA: `modes --fmax 0.5` printed an empty table and nothing else; now a line
    says that no mode lies at or below 0.5 Hz and which is the lowest (1.66 Hz; 1.67 before
    revision 2026-12-03.2, whose cross-bracing pins no longer stiffen a rigid yaw)."""
    result = CliRunner().invoke(app, ["modes", "--fmax", "0.5"], terminal_width=240)
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    assert "no mode at or below 0.5 Hz (--fmax): the lowest is car body kinematic" in text
    assert "(front end leading), 1.66 Hz" in text
    assert "┏" not in result.output  # no empty table
