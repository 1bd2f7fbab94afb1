"""Figures (matplotlib, headless) for the command line and the run report.

Each figure function takes data objects and an output path, and writes the file atomically
(temporary file, then rename) so that an interrupted run never leaves half a PNG behind.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from scipy.signal import welch

from railsusp.errors import RailsuspInputError
from railsusp.store import atomic_write_figure
from railsusp.vehicle.track import COMPONENTS, Irregularities, fra_psd

_LABELS = {
    "vertical": "vertical profile",
    "alignment": "alignment",
    "crosslevel": "cross-level",
    "gauge": "gauge",
}


def save_figure(fig: plt.Figure, path: str | Path, dpi: int = 120) -> Path:
    """Save ``fig`` atomically to ``path`` (format from the suffix) and close it."""
    try:
        return atomic_write_figure(fig, path, dpi=dpi, bbox_inches="tight")
    finally:
        plt.close(fig)


def welch_psd(x: np.ndarray, dx: float, segment_m: float = 400.0) -> tuple[np.ndarray, np.ndarray]:
    """One-sided spatial PSD of ``x`` (m) sampled every ``dx`` m: (Ω rad/m, S m²/(rad/m))."""
    nper = int(min(len(x), max(64, round(segment_m / dx))))
    f, p = welch(x, fs=1.0 / dx, nperseg=nper, detrend="constant")
    return 2 * np.pi * f, p / (2 * np.pi)


def plot_track_irregularities(irr: Irregularities, path: str | Path, seed_index: int = 0):
    """Irregularity traces (mm vs distance) and their Welch PSD against the FRA spectrum of
    their class (none drawn for a measured geometry file without a class). A track of fewer
    than two samples has no grid step, trace or PSD: refused in one line."""
    if irr.s.size < 2:  # was an IndexError (`railsusp track --length 0.1 --plot`)
        raise RailsuspInputError(
            f"track of {irr.s.size} sample(s), {irr.s[-1] - irr.s[0] if irr.s.size else 0:g} m: "
            "accepted at least two to plot (a section of at least its shortest wavelength)"
        )
    fig, axes = plt.subplots(len(COMPONENTS), 2, figsize=(12, 10), constrained_layout=True)
    dx = float(irr.s[1] - irr.s[0])
    omega_a = np.geomspace(2 * np.pi / irr.wavelength_max, 2 * np.pi / irr.wavelength_min, 200)
    measured = irr.source is not None  # a condition's track_geometry file: no seed
    for row, comp in enumerate(COMPONENTS):
        x = irr.component(comp)[seed_index]
        ax = axes[row, 0]
        ax.plot(irr.s, x * 1e3, lw=0.6)
        ax.set_ylabel(f"{_LABELS[comp]} (mm)")
        ax.grid(alpha=0.3)
        ax = axes[row, 1]
        om, s = welch_psd(x, dx)
        keep = om > 0
        label = "measured (Welch)" if measured else "synthesised (Welch)"
        ax.loglog(om[keep], s[keep] * 1e4, lw=0.8, label=label)
        if irr.track_class is not None:
            ref = fra_psd(comp, omega_a, irr.track_class) * 1e4
            ax.loglog(omega_a, ref, "k--", lw=1.2, label=f"FRA class {irr.track_class}")
            ax.set_ylim(ref.min() / 100.0, ref.max() * 10.0)
        ax.axvspan(
            2 * np.pi / irr.wavelength_max, 2 * np.pi / irr.wavelength_min, color="0.9", zorder=0
        )
        ax.set_ylabel("PSD (cm²/(rad/m))")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
    axes[-1, 0].set_xlabel("distance (m)")
    axes[-1, 1].set_xlabel("spatial frequency Ω (rad/m)")
    which = f"measured ({Path(irr.source).name})" if measured else f"seed {irr.seeds[seed_index]}"
    fra = "" if irr.track_class is None else f"FRA class {irr.track_class}, "
    fig.suptitle(
        f"Track irregularities, {fra}{which}, "
        f"wavelengths {irr.wavelength_min:g}-{irr.wavelength_max:g} m"
    )
    return save_figure(fig, path)


def plot_forces(result, path: str | Path, set_index: int = 0, wheel: str | int = "auto"):
    """Lateral and vertical wheel-rail forces of one run: the measured wheel highlighted,
    the other wheels faint; a third panel with the derailment quotient Y/Q."""
    from railsusp.vehicle.simulation_result import WHEEL_NAMES

    j = result.measured_wheel(wheel)
    t = result.time
    fig, axes = plt.subplots(3, 1, figsize=(11, 8), sharex=True, constrained_layout=True)
    for k, name in enumerate(WHEEL_NAMES):
        style = {"lw": 1.2, "color": "C3", "zorder": 3} if k == j else {"lw": 0.5, "alpha": 0.35}
        label = f"{name} (measured)" if k == j else None
        axes[0].plot(t, result.Y[set_index, k] / 1e3, label=label, **style)
        axes[1].plot(t, result.Q[set_index, k] / 1e3, label=label, **style)
    axes[2].plot(t, result.derailment_quotient[set_index, j], color="C3", lw=1.0)
    axes[0].set_ylabel("lateral force Y (kN)")
    axes[1].set_ylabel("vertical force Q (kN)")
    axes[2].set_ylabel(f"Y/Q {WHEEL_NAMES[j]}")
    axes[2].set_xlabel("time in record (s)")
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    c = result.condition
    fig.suptitle(f"{result.wagon_name}, condition '{c.name}': {c.describe()}", fontsize=9)
    return save_figure(fig, path)


def plot_sobol(
    indices, path: str | Path, statistic: str = "mean", left_out: dict[str, str] | None = None
):
    """Bar chart of first-order S1 and total ST Sobol indices with confidence intervals, one
    panel per condition and force (the study's Figure 2, per condition and with errors).

    ``left_out``: the features the key-parameter rule left out ("condition quantity
    statistic", as ``key_parameters.json``'s ``ignored_features`` and
    ``unfitted_features`` name them) with the reason; their panels are greyed and titled so
    (a panel of the tangent track's flat vertical force showed X17 at ST 0.32, above the
    rule's threshold, beside "X17 not key" and no word why)."""
    left_out = left_out or {}
    sel = indices[indices.statistic == statistic]
    panels = sel[["condition", "quantity"]].drop_duplicates().to_numpy().tolist()
    ncols = 2
    nrows = -(-len(panels) // ncols)
    fig, axes = plt.subplots(
        nrows, ncols, figsize=(12, 3.2 * nrows), squeeze=False, constrained_layout=True
    )
    names = {"Y": "lateral force Y", "Q": "vertical force Q"}
    for ax, (cond, q) in zip(axes.flat, panels, strict=False):
        g = sel[(sel.condition == cond) & (sel.quantity == q)]
        why = left_out.get(f"{cond} {q} {statistic}")
        alpha = 0.35 if why else 1.0
        x = np.arange(len(g))
        ax.bar(x - 0.2, g.S1, 0.4, yerr=g.S1_conf, capsize=2, label="S1 (first order)", alpha=alpha)
        ax.bar(x + 0.2, g.ST, 0.4, yerr=g.ST_conf, capsize=2, label="ST (total)", alpha=alpha)
        ax.set_xticks(x, g.parameter)
        cv = f", CV {g.cv.iloc[0]:.1%}" if "cv" in g else ""
        title = f"{cond}: {names.get(q, q)} ({statistic}{cv})"
        if why:
            ax.set_facecolor("0.94")
            title += f"\nLEFT OUT of the key rule: {why}"
        ax.set_title(title, fontsize=10 if not why else 8.5, color="0.35" if why else "k")
        ax.set_ylim(bottom=min(0.0, float(np.nanmin(g.S1 - g.S1_conf))))
        ax.set_ylabel("Sobol index (-)")
        ax.grid(axis="y", alpha=0.3)
    for ax in axes.flat[len(panels) :]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=8)
    method = sel.method.iloc[0] if len(sel) else ""
    shown = {f"{c} {q} {statistic}" for c, q in panels}
    marked = "; grey: features the key rule left out" if shown & set(left_out) else ""
    fig.suptitle(f"Sobol sensitivity indices ({method}), 95 % bootstrap intervals{marked}")
    return save_figure(fig, path)


#: longer records are shown as an excerpt of this length (s), beside their statistics
EXCERPT_S = 5.0


def excerpt(t: np.ndarray, length_s: float = EXCERPT_S) -> tuple[slice, str]:
    """The slice of a record's first ``length_s`` seconds, and a caption fragment saying
    which part is shown ('' when the whole record fits)."""
    t = np.asarray(t, dtype=float)
    if t.size < 2 or t[-1] - t[0] <= 1.5 * length_s:
        return slice(None), ""
    n = int(np.searchsorted(t, t[0] + length_s, side="right"))
    return slice(0, n), f"first {length_s:g} s of {t[-1] - t[0]:.0f} s"


def plot_surrogate_overlay(
    simulated, predictions: dict, targets, dt: float, path: str | Path, title: str = ""
):
    """Predicted vs simulated force series of one held-out run, one panel per target (the
    study's Figures 10 and 11); a long record is shown as its first :data:`EXCERPT_S`
    seconds, so that the series stay readable (the statistics are in Table 7)."""
    names = {"Y": "lateral force Y (kN)", "Q": "vertical force Q (kN)"}
    fig, axes = plt.subplots(
        len(targets),
        1,
        figsize=(11, 3.3 * len(targets)),
        sharex=True,
        constrained_layout=True,
        squeeze=False,
    )
    t = np.arange(simulated.shape[0]) * dt
    part, shown = excerpt(t)
    for j, name in enumerate(targets):
        ax = axes[j, 0]
        ax.plot(t[part], simulated[part, j], color="k", lw=1.4, label="simulated")
        for k, (model, pred) in enumerate(predictions.items()):
            ax.plot(t[part], pred[part, j], lw=0.9, color=f"C{k}", label=model)
        ax.set_ylabel(names.get(name, name))
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8, ncol=3)
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle(f"{title} ({shown})" if shown else title)
    return save_figure(fig, path)


def _final(result) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """The final estimate (SI; NSGA-II's after its geometry step and the simulator's
    corrections, where taken) and, when refined, its confidence interval's low and high (SI;
    None without refinement, or when the refinement is a polish beside NSGA-II's estimate:
    the Pareto set is drawn instead)."""
    ref = result.refinement
    if ref is None or not result.refined:
        return result.chosen_x, None, None
    iv = result.intervals()
    return (
        ref.estimate_si,
        np.array([i.low_si for i in iv.items]),
        np.array([i.high_si for i in iv.items]),
    )


def plot_pareto(result, path: str | Path):
    """Pareto front of the calibration (the study's Figure 9) with NSGA-II's choice, and
    beside it each parameter's Pareto set, NSGA-II's choice and the final estimate (with
    its confidence interval when refined), in % of the parameter's range: the front's spread
    is what the objectives cannot tell apart, the interval what the refinement can."""
    from railsusp.params import bounds

    f = result.pareto_f
    refined = result.refined
    fig, (ax, bx) = plt.subplots(
        1, 2, figsize=(12, 5), constrained_layout=True, gridspec_kw={"width_ratios": [1, 1.2]}
    )
    # "relative": errors as fractions, shown in %; "noise": in predictive standard
    # deviations of the statistics GPs, shown as they are
    noise = getattr(result.config, "weighting", "relative") == "noise"
    scale, unit = (1.0, "predictive s.d.") if noise else (100.0, "%")
    ax.scatter(scale * f[:, 0], scale * f[:, 1], s=18, label="Pareto front")
    c = result.chosen
    star = (
        f"NSGA-II's choice (the refinement started from {result.refinement.start_origin})"
        if refined and not result.refinement.from_choice
        else "NSGA-II's choice (then refined)"
        if refined
        else "NSGA-II's choice (then corrected by the simulator)"
        if result.corrections
        else "NSGA-II's choice (its geometry bias taken off: final estimate)"
        if result.geometry_bias_removed
        else "NSGA-II's choice (polished on expected forces: final estimate)"
        if result.expected_polish is not None
        else "NSGA-II's choice = estimate"
    )
    ax.scatter(scale * f[c, 0], scale * f[c, 1], s=80, marker="*", color="C3", label=star)
    ax.set_xlabel(f"objective 1: lateral force error ({unit})")
    ax.set_ylabel(f"objective 2: vertical force error ({unit})")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(
        f"NSGA-II Pareto front ({result.config.statistic}, "
        f"{result.config.n_gen} generations x {result.config.pop_size})",
        fontsize=10,
    )
    lo, hi = bounds(result.parameters)
    span = hi - lo
    y = np.arange(len(result.parameters))
    pct = 100 * (result.pareto_x - lo) / span
    for i in y:
        bx.scatter(pct[:, i], np.full(len(pct), i), s=12, color="C0", alpha=0.5)
    bx.scatter([], [], s=12, color="C0", alpha=0.5, label="Pareto set (NSGA-II's)")
    bx.scatter(pct[c], y, s=80, marker="*", color="C3", label="NSGA-II's choice", zorder=3)
    x, low, high = _final(result)
    xf = 100 * (x - lo) / span
    err = None
    if low is not None and high is not None:
        err = np.vstack([xf - 100 * (low - lo) / span, 100 * (high - lo) / span - xf])
        err = np.clip(err, 0.0, None)
    bx.errorbar(
        xf,
        y,
        xerr=err,
        fmt="D",
        color="k",
        ms=6,
        capsize=3,
        zorder=4,
        label="final estimate"
        + (f" and {100 * result.intervals().level:g} % interval" if err is not None else ""),
    )
    if result.polished_x is not None:
        polished = 100 * (result.polished_x - lo) / span
        bx.scatter(polished, y, s=50, marker="x", color="C2", zorder=5, label="simulator polish")
    bx.set_yticks(y, result.parameters)
    bx.set_xlim(-5, 105)
    bx.set_xlabel("position in the parameter's range (%)")
    bx.grid(alpha=0.3)
    bx.legend(fontsize=8, loc="best")
    bx.set_title("Parameters: Pareto set and final estimate", fontsize=10)
    return save_figure(fig, path)


def plot_convergence(result, path: str | Path):
    """Per-parameter convergence over the NSGA-II generations (the study's Fig. 8), then over
    the refinement's iterations when refined, ending at the final estimate (solid line)."""
    from railsusp.params import spec

    k = len(result.parameters)
    fig, axes = plt.subplots(
        k, 1, figsize=(8, 1.9 * k), sharex=True, constrained_layout=True, squeeze=False
    )
    n_gen = result.history.shape[0]
    gens = np.arange(1, n_gen + 1)
    ref = result.refinement
    steps = np.zeros((0, k)) if ref is None else np.atleast_2d(ref.history_si).reshape(-1, k)
    final = _final(result)[0]
    # a polish beside NSGA-II's estimate is not what the final estimate came from
    steps_label = "polish (beside the estimate)" if result.polished_x is not None else "refinement"
    for i, p in enumerate(result.parameters):
        s = spec(p)
        ax = axes[i, 0]
        ax.plot(gens, result.history[:, i] / s.scale, lw=1.2, label="NSGA-II")
        if len(steps):
            xs = n_gen + np.arange(1, len(steps) + 1)
            ax.plot(xs, steps[:, i] / s.scale, "o-", ms=3, lw=1.0, color="C2", label=steps_label)
            ax.axvline(n_gen + 0.5, color="0.7", lw=0.8)
        ax.axhline(s.nominal_display, color="0.5", ls="--", lw=0.8, label="nominal")
        ax.axhline(final[i] / s.scale, color="C3", lw=1.4, ls=":", zorder=1, label="final estimate")
        ax.set_ylabel(f"{p} ({s.display_unit})")
        ax.set_ylim(*s.bounds_display)
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7, ncol=4, loc="upper right")
    axes[-1, 0].set_xlabel(
        f"NSGA-II generation, then {steps_label.split(' ')[0]} iteration"
        if len(steps)
        else "NSGA-II generation"
    )
    fig.suptitle("Convergence of the estimate (dashed: nominal; red dotted: final estimate)")
    return save_figure(fig, path)


def validation_caption(measured_track: bool) -> str:
    """What a before/after overlay can be read for: phases only on the measured track."""
    if measured_track:
        return "recorded on measured track: measured and simulated series are time-aligned"
    return "the measured track is unknown, so compare levels, not phases"


def plot_validation_overlay(series: dict, path: str | Path, title: str = ""):
    """Measured vs simulated forces before and after calibration (the study's Figs 12/13):
    a readable excerpt of the series (the whole record when short) and, beside it, the
    record's statistics (mean, RMS, 99th percentile of |Y| and of Q) of the three."""
    from railsusp.vehicle.simulation_result import record_statistic

    fig, axes = plt.subplots(
        2,
        2,
        figsize=(12, 6.5),
        constrained_layout=True,
        gridspec_kw={"width_ratios": [2.4, 1]},
    )
    t = np.asarray(series["time"])
    part, shown = excerpt(t)
    runs = (
        ("measured", "k", "measured"),
        ("before", "C0", "nominal parameters"),
        ("after", "C3", "estimated parameters"),
    )
    stats = ("mean", "rms", "p99")
    for j, label in enumerate(("lateral force Y (kN)", "vertical force Q (kN)")):
        ax, bx = axes[j]
        for key, color, name in runs:
            x = np.asarray(series[key])[: t.size]
            n = min(t[part].size, len(x))
            lw = 1.0 if key == "measured" else 0.8
            ax.plot(t[part][:n], x[part][:n, j], color=color, lw=lw, alpha=0.85, label=name)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        pos = np.arange(len(stats))
        for k, (key, color, name) in enumerate(runs):
            x = np.asarray(series[key])[:, j]
            vals = [float(record_statistic(x, st, j == 0)) for st in stats]
            # markers, not bars: a few % apart on a large level, which bars from 0 would hide
            bx.plot(pos + (k - 1) * 0.2, vals, "o", ms=7, color=color, label=name)
        names = "|Y|" if j == 0 else "Q"
        bx.set_xticks(pos, [f"{st} {names}" for st in ("mean", "RMS", "p99")])
        bx.set_ylabel(f"{label.split(' (')[0]} statistic (kN)")
        bx.grid(axis="y", alpha=0.3)
    axes[0, 0].legend(fontsize=8, ncol=3)
    axes[1, 0].set_xlabel("time (s)" + (f", {shown}" if shown else ""))
    axes[0, 1].set_title("whole record", fontsize=9)
    caption = validation_caption(bool(series.get("measured_track", False)))
    fig.suptitle(f"{title}: {caption}" if title else caption)
    return save_figure(fig, path)
