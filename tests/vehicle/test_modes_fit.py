"""The damped-sinusoid fit of the free decay (decay.fit_damped_sinusoid) on records with a
known answer: a record that does not oscillate has no frequency or damping ratio (NaN), a
non-finite or uneven record is refused with a one-line error, and a decay of any size or
damping below about 0.95 is recovered."""

from __future__ import annotations

import math

import numpy as np
import pytest

from railsusp.errors import RailsuspInputError
from railsusp.vehicle.decay import fit_damped_sinusoid

T = np.arange(0.0, 6.0, 0.01)
W = 2.0 * math.pi * 2.0


def damped(zeta: float, amplitude: float = 1.0) -> np.ndarray:
    return amplitude * np.exp(-zeta * W * T) * np.cos(W * math.sqrt(1 - zeta**2) * T + 0.3)


@pytest.mark.parametrize(
    ("label", "y"),
    [
        ("exponential decay (overdamped)", np.exp(-3.0 * T)),
        ("ramp (drift)", T.copy()),
        ("overdamped with one overshoot", np.exp(-T) - 2.0 * np.exp(-2.0 * T)),
        ("exponential decay with noise", np.exp(-3.0 * T) + 1e-4 * np.sin(97.0 * T**2)),
    ],
)
def test_a_record_that_does_not_oscillate_has_no_frequency(label, y):
    """Before, exp(-3 t) came out as a 0.495 Hz mode with ζ 0.98 and R² 0.9999, a ramp as
    0.094 Hz: any record got a frequency. A sum of two decaying exponentials (what an
    overdamped mode gives) crosses any level at most twice, so nothing in these
    records is a cycle: frequency, damping ratio and R² NaN."""
    f, zeta, _, r2 = fit_damped_sinusoid(T, y)
    assert math.isnan(f) and math.isnan(zeta) and math.isnan(r2), (label, f, zeta, r2)


@pytest.mark.parametrize("zeta", [0.0, 0.05, 0.3, 0.7, 0.9])
def test_a_damped_oscillation_is_recovered_up_to_heavy_damping(zeta):
    """The non-oscillation test does not take real modes: up to ζ 0.9 (the loaded wagon's
    bogie kinematic modes have 0.89, gone within one cycle) the fit returns the record's
    frequency and damping ratio."""
    f, z, _, r2 = fit_damped_sinusoid(T, damped(zeta))
    assert f == pytest.approx(2.0, rel=1e-6)
    assert z == pytest.approx(zeta, rel=1e-6, abs=1e-9)
    assert r2 > 0.999999


@pytest.mark.parametrize("amplitude", [1e-12, 1.0, 1e6])
def test_the_fit_does_not_depend_on_the_records_units(amplitude):
    """A decay of 1e-12 (a modal coordinate in small units) came out at 2.09 Hz, ζ 0.29,
    R² -1498: the least-squares tolerances were absolute. The record is scaled first."""
    f, z, amp, r2 = fit_damped_sinusoid(T, damped(0.05, amplitude) + 3.0 * amplitude)
    assert f == pytest.approx(2.0, rel=1e-6) and z == pytest.approx(0.05, rel=1e-5)
    assert amp == pytest.approx(amplitude, rel=1e-5) and r2 > 0.999999


def test_a_constant_record_has_no_oscillation():
    assert fit_damped_sinusoid(T, np.full(T.size, 2.0))[:2] == pytest.approx(
        (math.nan, math.nan), nan_ok=True
    )


@pytest.mark.parametrize(
    ("t", "y", "message"),
    [
        (T, np.where(np.arange(T.size) == 100, np.nan, damped(0.05)), "y: 1 of 600 samples not"),
        (np.where(np.arange(T.size) >= 500, np.inf, T), damped(0.05), "t: 100 of 600 samples"),
        (T[:3], damped(0.05)[:3], "t, y: 3 samples; accepted at least 6"),
        (T, damped(0.05)[:-1], "t, y: shapes (600,) and (599,)"),
        (T**1.1, damped(0.05), "t: steps from"),
        (T[::-1], damped(0.05), "t: steps from"),
    ],
)
def test_a_record_the_fit_cannot_take_is_refused_in_one_line(t, y, message):
    """A NaN sample raised LinAlgError with LAPACK's complaint on stderr; an uneven time
    grid (the linear prediction and the spectrum assume a uniform one) gave garbage."""
    with pytest.raises(RailsuspInputError) as info:
        fit_damped_sinusoid(t, y)
    assert "\n" not in str(info.value) and str(info.value).startswith(message), info.value


def test_a_friction_decay_that_one_sinusoid_fits_poorly_is_still_an_oscillation():
    """Coulomb friction takes a fixed amount off every cycle until the motion stops (as a
    30 mm dip makes the wedges slide): one damped sinusoid fits it poorly, which R² below
    FIT_R2_MIN shows, but it crosses its offset at every half cycle, so it keeps its
    frequency for the fit check to compare."""
    y = np.maximum(1.0 - 0.1 * 2.0 * T, 0.0) * np.cos(W * T)
    f, zeta, _, r2 = fit_damped_sinusoid(T, y)
    assert f == pytest.approx(2.0, rel=1e-3) and 0.0 < zeta < 0.1
    assert 0.9 < r2 < 0.99
