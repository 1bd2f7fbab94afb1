"""bench/posterior_synthetic.py: it loads next to bench/posterior.py (whose scoring it
reuses) and prints the coverage and width of a stored check per record length."""

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
    bench._coverage_table(rows, ["X13", "X18"], 20.0)
    out = capsys.readouterr().out.splitlines()
    assert any(line.split() == ["20", "100", "0.91", "0.90", "2/2"] for line in out)
    assert any(line.split() == ["600", "100", "0.91", "0.80", "1/2"] for line in out)
    assert any(line.split() == ["600", "100", "1.3", "0.4"] for line in out)
