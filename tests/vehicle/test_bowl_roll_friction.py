"""Tests that close gaps found by the mutation review of stop 74: the centre bowl's roll
friction moment on the car body opposes the car body's roll relative to the bolster (a
reversed sign was caught only by the stored reference forces, by no physics test)."""

import numpy as np
import pytest

from railsusp.vehicle.suspension import bowl_ring_forces

R, K_RING, F0, MU = 0.1875, 200e6, 400e3, 0.2
K_STICK, C_STICK = 1e6, 1e3


def _friction(droll_rate, dz=0.0, droll=0.0, dpitch=0.0, state=0.0):
    """The friction roll moment on the car body and its state's rate."""
    d = np.zeros(1)
    *_, m_fr = bowl_ring_forces(
        dz, droll, dpitch, droll_rate, R, K_RING, 1e30, 1e30, F0, MU, K_STICK, C_STICK,
        state, d, 0,
    )  # fmt: skip
    return m_fr, d[0]


@pytest.mark.parametrize("rate", [1e-3, -1e-3])
def test_the_bowls_roll_friction_opposes_the_relative_roll_rate(rate):
    """At zero deflection and no friction state, a small relative roll rate is met by the
    stick damper's moment against it, and the elastic state grows against it too."""
    m_fr, dstate = _friction(rate)
    assert m_fr == pytest.approx(-C_STICK * rate, rel=1e-12)
    assert dstate == pytest.approx(-K_STICK * rate, rel=1e-12)
    assert np.sign(m_fr) == np.sign(dstate) == -np.sign(rate)


def test_the_bowls_roll_friction_slides_against_the_rate_and_never_feeds_power():
    """Sliding (the state at its limit mu N (2/3) R), the moment stays at the limit against
    the rate; from a relaxed state, over random deflections and rates, the friction's power
    on the relative roll (moment x rate) is never positive."""
    limit = MU * F0 * 2.0 / 3.0 * R
    m_fr, _ = _friction(0.05, state=-limit)
    assert m_fr == pytest.approx(-limit)
    m_fr, _ = _friction(-0.05, state=limit)
    assert m_fr == pytest.approx(limit)
    rng = np.random.default_rng(74)
    for _ in range(50):
        dz, droll, dpitch = rng.uniform(-1e-4, 1e-4, 3)
        rate = rng.uniform(-1.0, 1.0)
        m_fr, dstate = _friction(rate, dz, droll, dpitch)
        assert m_fr * rate <= 0.0 and dstate * rate <= 0.0
