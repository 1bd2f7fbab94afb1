"""The report's figures show the final estimate: the refined one where NSGA-II's choice was
refined, with its interval; long records are shown as an excerpt."""

from types import SimpleNamespace

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest

from railsusp import report
from railsusp.estimate import CalibrationResult, NSGAConfig
from railsusp.params import spec


def refined_result() -> CalibrationResult:
    """Two parameters; NSGA-II chose X13 = 16, X17 = 1.2 MN/m; the refinement moved them to
    15 and 1.5 MN/m (the case of the issue: the figures showed the NSGA-II choice)."""
    si = np.array([spec("X13").scale, spec("X17").scale])
    pareto = np.array([[12.0, 1.0], [16.0, 1.2], [20.0, 1.4]]) * si
    res = CalibrationResult(
        ("X13", "X17"),
        pareto,
        np.array([[0.1, 0.3], [0.2, 0.2], [0.3, 0.1]]),
        1,
        pd.DataFrame({"n_gen": [1, 2]}),
        np.array([[14.0, 1.3], [16.0, 1.2]]) * si,
        NSGAConfig(pop_size=4, n_gen=2),
    )
    res.refinement = SimpleNamespace(  # the attributes of railsusp's Refinement the plots read
        parameters=("X13", "X17"),
        estimate_si=np.array([15.0, 1.5]) * si,
        standard_error_si=np.array([0.2, 0.05]) * si,
        geometry_error_si=np.zeros(2),
        channel_gains={},
        history_si=np.array([[16.0, 1.2], [15.2, 1.45], [15.0, 1.5]]) * si,
        problem=None,
        solution=None,
        residuals=None,  # not kept: white residuals, normal quantile
        from_choice=True,  # started from NSGA-II's choice
        start_origin="NSGA-II's choice",
    )
    return res


def test_figures_mark_the_refined_estimate(tmp_path, monkeypatch):
    res = refined_result()
    x, low, high = report._final(res)
    assert x[0] / spec("X13").scale == pytest.approx(15.0)
    # the 90 % interval: 1.5 ± 1.645 x 0.05 MN/m
    assert (low[1], high[1]) == pytest.approx(
        (1.5e6 - 1.645 * 0.05e6, 1.5e6 + 1.645 * 0.05e6), rel=1e-3
    )
    drawn = {}
    monkeypatch.setattr(report, "save_figure", lambda fig, path: drawn.setdefault(path, fig))
    report.plot_convergence(res, tmp_path / "c.png")
    fig = drawn[tmp_path / "c.png"]
    ax13 = fig.axes[0]
    finals = [ln for ln in ax13.lines if ln.get_label() == "final estimate"]
    assert finals and finals[0].get_ydata()[0] == pytest.approx(15.0)
    refine = next(ln for ln in ax13.lines if ln.get_label() == "refinement")
    assert list(refine.get_xdata()) == [3, 4, 5]  # after the two generations
    report.plot_pareto(res, tmp_path / "p.png")
    labels = [t.get_text() for t in drawn[tmp_path / "p.png"].axes[1].get_legend().get_texts()]
    assert "final estimate and 90 % interval" in labels
    plt.close("all")


def test_long_records_are_an_excerpt():
    t = np.arange(0, 20.0, 0.01)
    part, caption = report.excerpt(t)
    assert t[part][-1] == pytest.approx(report.EXCERPT_S) and caption == "first 5 s of 20 s"
    short = np.arange(0, 6.0, 0.01)
    assert report.excerpt(short) == (slice(None), "")
