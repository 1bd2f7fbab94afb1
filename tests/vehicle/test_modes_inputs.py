"""The modal, free-decay and energy-audit functions check their inputs (the audit of the
modes code, 2026-12): each bad value is a one-line RailsuspInputError naming the argument
and its accepted range, from the same limits the ``railsusp modes`` command checks, instead
of a silent result (an amplitude of 0 fitted a "bounce" to the settling transient, a
negative step returned a passing energy audit of nothing), an unrelated error (argmax of an
empty sequence, a matmul mismatch, "flange climb" for a NaN amplitude, ZeroDivisionError)
or a refusal of a documented value (a window of 1 s, a run from an initial state)."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.errors import RailsuspInputError
from railsusp.params import ParameterSet
from railsusp.vehicle import layout as L
from railsusp.vehicle.decay import fit_damped_sinusoid, free_decay, modal_filters
from railsusp.vehicle.decay_runs import (
    AMPLITUDE_RANGE_M,
    DecayRunError,
    decay_run,
    input_passed_s,
)
from railsusp.vehicle.energy import energy_audit
from railsusp.vehicle.modes import linearisation_point, modal_analysis


@pytest.fixture(scope="module")
def stuck():
    return modal_analysis()


@pytest.fixture(scope="module")
def point():
    return linearisation_point()


def one_line(info: pytest.ExceptionInfo) -> str:
    text = str(info.value)
    assert "\n" not in text, text
    return text


# ---------------------------------------------------------------- window and initial state
def test_the_shortest_documented_window_runs(stuck):
    """window_s = 1 s is the documented minimum: it used to be refused always (decay_run
    asked a duration strictly more than 1 s past the input, and free_decay asks exactly 1 s
    more), with a message about a duration_s the caller never gave. One second holds five
    bounce cycles: the bounce is still its stuck eigenvalue."""
    result = free_decay(window_s=1.0, excitations=("dip",), modal=stuck)
    assert result.window_s == 1.0
    run = result.runs[0]
    assert run.time[-1] - run.free_from == pytest.approx(1.0, abs=0.011)
    row = result.row("car body bounce")
    assert row["fit_ok"]
    assert row["frequency_Hz"] == pytest.approx(row["linear_frequency_Hz"], rel=1e-3)


def test_a_window_out_of_range_names_window_s(stuck):
    with pytest.raises(RailsuspInputError) as info:
        free_decay(window_s=0.5, excitations=("dip",), modal=stuck)
    assert one_line(info) == "window_s = 0.5 s: accepted 1 to 60 s"


def test_a_run_too_short_for_its_input_says_what_duration_is_accepted(point):
    """decay_run over an input: the duration from the moment the input has passed plus the
    window's 1-60 s (the same range free_decay's window_s accepts)."""
    passed = input_passed_s(point, 2.0)
    with pytest.raises(RailsuspInputError) as info:
        decay_run(point, "dip", duration_s=passed + 0.5)
    text = one_line(info)
    assert text.startswith(f"duration_s = {passed + 0.5:g} s: the dip has passed at ")
    assert f"accepted {passed + 1:.2f} to {passed + 60:.2f} s" in text
    run = decay_run(point, "dip", duration_s=passed + 1.0)  # exactly 1 s of free decay
    assert run.free_from == passed


def test_a_run_from_an_initial_state_decays_as_its_eigenvalue(stuck, point):
    """excitation="none" with x0 could never run (free_from = 0 failed 0 < free_from). From
    the bounce's own shape (0.5 mm of car body) on ideal track the modal coordinate decays
    at the stuck bounce's eigenvalue: frequency and damping ratio within 1e-4 (measured 1e-6
    and 3e-6: the stuck model is linear at that amplitude)."""
    i = stuck.car_body_kinds()["bounce"]
    w, v = modal_filters(stuck, [i])
    x0 = v[:, 0].real / np.abs(v[: L.CB_YAW + 1, 0].real).max() * 5e-4
    run = decay_run(point, "none", x0=x0, duration_s=3.0)
    assert run.free_from == 0.0 and run.time[-1] == pytest.approx(3.0)
    eta = (run.state @ np.conj(w))[:, 0].real
    f, zeta, _, r2 = fit_damped_sinusoid(run.time, eta)
    assert f == pytest.approx(stuck.frequency_hz[i], rel=1e-4)
    assert zeta == pytest.approx(stuck.damping_ratio[i], rel=1e-4)
    assert r2 > 0.9999


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"duration_s": 0.0}, "duration_s = 0 s: accepted (0, 60] s"),
        ({"duration_s": 61.0}, "duration_s = 61 s: accepted (0, 60] s"),
        ({"duration_s": 2.0, "dt": 0.0}, "dt = 0 s: accepted 1e-05 to 0.001 s"),
        ({"duration_s": 2.0, "sample_dt": 0.0}, "sample_dt = 0 s: accepted 0.001 to 1 s"),
        ({"duration_s": 2.0, "x0": np.full(L.N_STATE, np.nan)}, "x0: 122 values not finite"),
    ],
)
def test_decay_run_bad_input(point, kwargs, message):
    with pytest.raises(RailsuspInputError) as info:
        decay_run(point, "none", **kwargs)
    assert one_line(info).startswith(message)


# ---------------------------------------------------------------- free_decay's arguments
EXCITATION_TEXT = "accepted a non-empty tuple of dip, cross-level, kink, each once"


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"amplitude_m": 0.0}, "amplitude_m = 0 m: accepted 0.0005 to 0.05 m"),
        ({"amplitude_m": -0.005}, "amplitude_m = -0.005 m: accepted 0.0005 to 0.05 m"),
        ({"amplitude_m": float("nan")}, "amplitude_m = nan m: accepted 0.0005 to 0.05 m"),
        ({"amplitude_m": "5"}, "amplitude_m = '5': a number is needed; accepted 0.0005"),
        ({"length_m": 0.0}, "length_m = 0 m: accepted 1 to 20 m"),
        ({"length_m": -2.0}, "length_m = -2 m: accepted 1 to 20 m"),
        ({"excitations": ()}, f"excitations = (): {EXCITATION_TEXT}"),
        ({"excitations": "dip"}, f"excitations = 'dip': {EXCITATION_TEXT}"),
        ({"excitations": ("dip", "dip")}, f"excitations: dip given twice; {EXCITATION_TEXT}"),
        ({"excitations": ("bump",)}, f"excitations: 'bump' unknown; {EXCITATION_TEXT}"),
        ({"f_max": 0.0}, "f_max = 0 Hz: accepted (0, 1000] Hz"),
        ({"f_max": -1.0}, "f_max = -1 Hz: accepted (0, 1000] Hz"),
        ({"f_max": 0.5}, "f_max = 0.5 Hz: no oscillating mode below it has 20% of its"),
        ({"speed_kmh": 0.0, "modal": None}, "speed_kmh = 0 km/h: accepted 1 to 200 km/h"),
        ({"friction": "wet", "modal": None}, "friction = 'wet': accepted stuck, sliding"),
    ],
)
def test_free_decay_bad_input(stuck, kwargs, message):
    """Each checked before anything runs; before, amplitude 0 returned a "fit ok" bounce,
    a negative amplitude or length garbage, NaN a flange climb, () an argmax error, "dip"
    the excitation 'd', f_max <= 0 a matmul error, speed 0 a ZeroDivisionError."""
    kwargs = {"modal": stuck, "excitations": ("dip",), **kwargs}
    with pytest.raises(RailsuspInputError) as info:
        free_decay(**kwargs)
    assert one_line(info).startswith(message)


def test_a_modal_result_of_other_runs_is_refused(stuck):
    """The modal filters of another linearisation read the state of another wagon: every
    fit failed, silently (R² down to -675). Another friction variant, speed or parameter set
    is refused, naming ``modal``."""
    sliding = modal_analysis(friction="sliding")
    with pytest.raises(RailsuspInputError) as info:
        free_decay(excitations=("dip",), modal=sliding)
    assert one_line(info).startswith("modal: linearised at 60 km/h, friction sliding; the runs")
    with pytest.raises(RailsuspInputError, match="modal: linearised at 60 km/h, friction stuck"):
        free_decay(speed_kmh=80.0, excitations=("dip",), modal=stuck)
    softer = ParameterSet.nominal().replace({"X13": 0.9 * ParameterSet.nominal()["X13"]})
    with pytest.raises(RailsuspInputError) as info:
        free_decay(softer, excitations=("dip",), modal=stuck)
    assert one_line(info).startswith("modal: linearised with other parameters or wagon data")


def test_a_kink_the_wagon_cannot_take_names_the_amplitude(stuck):
    """A 50 mm kink makes the loaded wagon's wheelset climb its flange at 60 km/h (45 mm
    runs): the error names the amplitude and the excitation, and is still a RuntimeError
    (the run failed; the input is in range)."""
    with pytest.raises(DecayRunError) as info:
        free_decay(amplitude_m=AMPLITUDE_RANGE_M[1], excitations=("kink",), modal=stuck)
    text = one_line(info)
    assert text.startswith("amplitude_m = 0.05 m: the free-decay run over the kink stopped (")
    assert "flange climb" in text and "accepted a smaller amplitude_m" in text
    assert isinstance(info.value, RuntimeError) and info.value.excitation == "kink"


def test_the_command_names_amplitude_when_a_run_stops(monkeypatch):
    """`modes --decay --amplitude 50`: the error named --decay; it names --amplitude, what
    stopped and what is accepted, one line, status 2."""
    import railsusp.vehicle.decay as decay

    def climbs(*args, **kwargs):
        raise DecayRunError("kink", kwargs["amplitude_m"], "wheelset lateral shift (flange climb)")

    monkeypatch.setattr(decay, "free_decay", climbs)
    result = CliRunner().invoke(app, ["modes", "--decay", "--amplitude", "50", "--fmax", "5"])
    assert result.exit_code == 2, result.output
    text = " ".join(result.output.split())
    assert text.startswith(
        "error: --amplitude = 50 mm: the free-decay run over the kink stopped (wheelset "
        "lateral shift (flange climb)) on this wagon at 60 km/h; accepted a smaller "
        "--amplitude, from 0.5 mm"
    ), text
    assert "--decay:" not in text


# ---------------------------------------------------------------- modal analysis, energy audit
@pytest.mark.parametrize("speed", [0.0, -10.0, float("nan"), 201.0])
def test_modal_analysis_checks_the_speed_before_dividing_by_it(speed):
    with pytest.raises(RailsuspInputError) as info:
        modal_analysis(speed_kmh=speed)
    assert one_line(info) == f"speed_kmh = {speed:g} km/h: accepted 1 to 200 km/h"


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"duration_s": -1.0}, "duration_s = -1 s: accepted (0, 60] s"),
        ({"duration_s": 0.0}, "duration_s = 0 s: accepted (0, 60] s"),
        ({"duration_s": float("nan")}, "duration_s = nan s: accepted (0, 60] s"),
        ({"dt": -1e-3}, "dt = -0.001 s: accepted 1e-05 to 0.001 s"),
        ({"dt": 0.0}, "dt = 0 s: accepted 1e-05 to 0.001 s"),
        ({"x0": np.zeros(5)}, "x0: 5 values given, the state has 122"),
        ({"speed_kmh": 0.0}, "speed_kmh = 0 km/h: accepted 1 to 200 km/h"),
    ],
)
def test_energy_audit_bad_input(kwargs, message):
    """A negative duration or step returned a passing audit of nothing, a zero step a
    ZeroDivisionError, a short state a matmul error."""
    kwargs = {"x0": np.zeros(L.N_STATE), **kwargs}
    with pytest.raises(RailsuspInputError) as info:
        energy_audit(**kwargs)
    assert one_line(info) == message
