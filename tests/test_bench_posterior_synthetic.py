"""bench/posterior_synthetic.py: it loads next to bench/posterior.py (whose scoring it
reuses) and prints the coverage and width of a stored check per record length."""

import numpy as np

from conftest import bench_script


def test_coverage_table_per_length(capsys):
    bench = bench_script("posterior_synthetic")
    rows = [
        {
            "sections": k,
            "cases": 100,
            "parameters": [
                {"parameter": "X13", "coverage": 0.91, "passed": True},
                {"parameter": "X18", "coverage": cov, "passed": cov > 0.85},
            ],
            "width_pct_range": {"X13": 40.0 / k, "X18": 12.0 / k},
        }
        for k, cov in ((1, 0.9), (30, 0.8))
    ]
    bench.coverage_table(rows, ["X13", "X18"], 20.0)
    out = capsys.readouterr().out.splitlines()
    assert any(line.split() == ["20", "100", "0.91", "0.90", "2/2"] for line in out)
    assert any(line.split() == ["600", "100", "0.91", "0.80", "1/2"] for line in out)
    assert any(line.split() == ["600", "100", "1.3", "0.4"] for line in out)


class _Linear:
    """A stand-in likelihood: statistics read as they are, one section's standard
    deviation 1 (2 for the second statistic), mean u plus an error of standard deviation
    ``error`` (in sections' sd) that varies with the third parameter."""

    def __init__(self, error):
        self.error = np.asarray(error, float) * np.array([1.0, 2.0])

    def project(self, x):
        return x

    def mean(self, u):
        return u[:, :2] + self.error * np.sqrt(12.0) * (u[:, 2:3] - 0.5)

    def parts(self, u):
        section = np.broadcast_to(np.diag([1.0, 4.0]), (len(u), 2, 2))
        return self.mean(u), 0 * section, section, 0 * section


def test_replicates_tell_the_emulators_error_from_a_records_randomness():
    """Records of k = 10 independent sections about the true mean u: the two replicates'
    means lie 1/k apart whatever the emulator; an emulator off by 0.5 standard deviations
    (rms over u) in the first statistic lies 1/k + 0.25 from them, and both records'
    distances correlate (0.25 / 0.35).
    A shared random effect per record (sd 0.4) shows in ``between`` as 1/k + 0.16."""
    bench = bench_script("posterior_synthetic")
    rng = np.random.default_rng(1)
    n, k = 4000, 10
    u = rng.random((n, 10))
    scale = np.array([1.0, 2.0])

    def records(shared=0.0):
        per_record = shared * rng.standard_normal((n, 1, 2)) * scale
        return u[:, None, :2] + per_record + rng.standard_normal((n, k, 2)) * scale

    out = bench.replicate_split(_Linear([0.5, 0.0]), u, records(), records())
    assert out["records"] == n and out["sections"] == k
    assert np.allclose(out["between"], 1 / k, rtol=0.08)
    assert np.allclose(out["from_emulator"], [1 / k + 0.25, 1 / k], rtol=0.08)
    assert abs(out["correlation"][0] - 0.25 / 0.35) < 0.05 and abs(out["correlation"][1]) < 0.06
    shared = bench.replicate_split(_Linear([0.0, 0.0]), u, records(0.4), records(0.4))
    assert np.allclose(shared["between"], 1 / k + 0.16, rtol=0.08)
