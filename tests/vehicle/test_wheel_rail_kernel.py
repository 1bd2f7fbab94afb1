"""Compiled contact and track look-up kernels against independent solutions."""

import numpy as np
import pytest
from scipy.optimize import brentq

from railsusp.vehicle.normal_contact import hertz_rail_solve
from railsusp.vehicle.track_lookup import track_frame, track_point, track_rate, track_value


@pytest.mark.parametrize("G", [2e-8, 4.2e-8, 5.8e-8, 2e-6])
@pytest.mark.parametrize("krn", [2e7, 4e7, 1.5e8, 1e10])
def test_hertz_rail_solve_matches_a_root_finder(G, krn):
    """dn = G N^(2/3) + N / krn solved to round-off for loads from 10 N to 1 MN, in both the
    rail-dominated and the Hertz-dominated regime (the two starts of the Newton solve)."""
    for n_true in np.geomspace(10.0, 1e6, 25):
        dn = G * n_true ** (2.0 / 3.0) + n_true / krn
        n, u = hertz_rail_solve(dn, G, krn)
        ref = brentq(lambda x, dn=dn: G * x ** (2.0 / 3.0) + x / krn - dn, 0.0, 2.0 * n_true,
                     xtol=1e-300, rtol=1e-15)  # fmt: skip
        assert n == pytest.approx(ref, rel=1e-12)
        assert u**3 == pytest.approx(n, rel=1e-14)
    assert hertz_rail_solve(0.0, G, krn) == (0.0, 0.0)
    assert hertz_rail_solve(-1e-4, G, krn) == (0.0, 0.0)


def test_track_lookup_interpolates_and_holds_the_ends():
    rng = np.random.default_rng(3)
    s0, ds, n = -5.0, 0.25, 41
    trk = rng.normal(size=(8, n))
    grid = s0 + ds * np.arange(n)
    V = 16.0
    for s in np.concatenate([rng.uniform(s0 - 3.0, grid[-1] + 3.0, 200), grid]):
        i, f, inside = track_point(s, s0, 1.0 / ds, n)
        for ch in range(8):
            assert track_value(trk, ch, i, f) == pytest.approx(
                np.interp(s, grid, trk[ch]), abs=1e-13
            )
            rate = track_rate(trk, ch, i, inside, V / ds)
            if s <= s0 or s >= grid[-1]:
                assert rate == 0.0
            else:
                k = min(int((s - s0) / ds), n - 2)
                assert rate == pytest.approx(V * (trk[ch, k + 1] - trk[ch, k]) / ds, rel=1e-12)
        frame = track_frame(trk, i, f)
        assert len(frame) == 4
