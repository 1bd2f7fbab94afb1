"""What a campaign varies from sample to sample besides the sampled (key) parameters.

Two things a surrogate must not mistake for constants:

* **the track**: with ``independent_seeds`` each sample runs on its own irregularity
  realisation; a :class:`TrackFamily` also draws, per sample, the FRA class within a range
  and, in curve conditions, the radius and cant within a family (e.g. R 250-400 m, cant
  0-100 mm). A surrogate trained on such a campaign has to read the track from its inputs,
  and its held-out samples run on tracks it never saw.
* **the parameters not estimated**: ``other_parameters`` samples the main-suspension
  parameters outside the key set over their Table 2 range, or a narrower user prior,
  instead of holding them at nominal, so that their effect shows as spread in the training
  data rather than as a bias of the estimate.

Every per-sample value is a pure function of the campaign configuration (its seed and the
condition's seed), so a run directory can always be read back without extra files;
:func:`sample_tracks` is also written to ``tracks.parquet`` for inspection.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd
from pydantic import BaseModel, ConfigDict, model_validator
from scipy.stats import qmc

from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.params import MAIN_SUSPENSION, spec

#: accepted FRA classes and curve-family limits (those of :class:`WorkingCondition`)
CLASS_RANGE = (1, 6)
RADIUS_RANGE_M = (50.0, 100_000.0)
CANT_RANGE_MM = (0.0, 200.0)


def _check_range(name: str, value: tuple[float, float], accepted: tuple[float, float], unit: str):
    lo, hi = value
    a, b = accepted
    u = f" {unit}" if unit else ""
    if not (a <= lo <= hi <= b):
        raise ValueError(
            f"{name} = {lo:g}-{hi:g}{u}: accepted a range lo <= hi within [{a:g}, {b:g}]{u}"
        )


class TrackFamily(BaseModel):
    """Per-sample track variation within a condition family (all bounds inclusive).

    ``irregularity_classes``: FRA classes drawn uniformly from lo..hi per sample (conditions
    on synthesised track). ``curve_radius_m`` / ``cant_mm``: radius and cant of the arc drawn
    per sample, stratified (Latin hypercube), in every curve condition; tangent and grade
    conditions keep their layout.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    irregularity_classes: tuple[int, int] | None = None
    curve_radius_m: tuple[float, float] | None = None
    cant_mm: tuple[float, float] | None = None

    @model_validator(mode="after")
    def _ranges(self) -> TrackFamily:
        if self.irregularity_classes is not None:
            _check_range("irregularity_classes", self.irregularity_classes, CLASS_RANGE, "")
        if self.curve_radius_m is not None:
            _check_range("curve_radius_m", self.curve_radius_m, RADIUS_RANGE_M, "m")
        if self.cant_mm is not None:
            _check_range("cant_mm", self.cant_mm, CANT_RANGE_MM, "mm")
        return self

    @property
    def varies_layout(self) -> bool:
        """Whether radius or cant vary (every sample of a curve condition then needs its own
        simulator call: the layout is shared within one batched call)."""
        return self.curve_radius_m is not None or self.cant_mm is not None

    def ranges(self) -> dict[str, list[float]]:
        """The varied fields and their ranges (JSON-friendly)."""
        return {k: list(v) for k, v in self.model_dump().items() if v is not None}


def check_other_parameters(
    others: Mapping[str, Sequence[float]], sampled: Sequence[str]
) -> dict[str, tuple[float, float]]:
    """Validate the ranges (SI) of the parameters varied but not estimated: main-suspension
    symbols (X11..X20, or their names), not among ``sampled``, lo <= hi within Table 2."""
    out: dict[str, tuple[float, float]] = {}
    for key, rng in others.items():
        ps = spec(key)
        if not ps.is_sampled:
            raise ValueError(f"{ps.symbol} is a fixed parameter; varied ones are X11..X20")
        if ps.symbol in sampled:
            raise ValueError(f"{ps.symbol} is sampled as a key parameter already")
        if ps.symbol in out:
            raise ValueError(f"{ps.symbol} repeats")
        lo, hi = (float(v) for v in rng)
        a, b = ps.bounds
        tol = 1e-9 * max(abs(a), abs(b))
        if not (a - tol <= lo <= hi <= b + tol):
            d = ps.to_display
            raise ValueError(
                f"{ps.symbol} range {d(lo):g}-{d(hi):g} {ps.display_unit}: accepted lo <= hi "
                f"within {ps.range_text()}"
            )
        out[ps.symbol] = (max(lo, a), min(hi, b))
    return out


def sample_others(others: Mapping[str, tuple[float, float]], n: int, seed: int) -> pd.DataFrame:
    """The varied non-key parameters of ``n`` samples (SI): a Latin hypercube of their own,
    independent of the key design, so adding them leaves the key columns unchanged."""
    names = list(others)
    if not names:
        return pd.DataFrame(index=range(n))
    ss = np.random.SeedSequence([seed, 0x07E5])
    unit = qmc.LatinHypercube(d=len(names), rng=np.random.default_rng(ss)).random(n)
    lo = np.array([others[k][0] for k in names])
    hi = np.array([others[k][1] for k in names])
    return pd.DataFrame(lo + (hi - lo) * unit, columns=names)


def sample_tracks(
    family: TrackFamily | None,
    condition: WorkingCondition,
    seeds: np.ndarray | None,
    n: int,
    campaign_seed: int,
) -> pd.DataFrame:
    """Track of every sample of one condition: sample_id, seed, irregularity_class,
    curve_radius_m, cant_mm (the condition's own values where nothing varies)."""
    df = pd.DataFrame(
        {
            "sample_id": np.arange(n, dtype=np.int64),
            "seed": np.full(n, condition.seed, dtype=np.int64) if seeds is None else seeds,
            "irregularity_class": np.full(
                n, -1 if condition.irregularity_class is None else condition.irregularity_class
            ),
            "curve_radius_m": np.full(n, condition.curve_radius_m or np.nan, dtype=float),
            "cant_mm": np.full(n, condition.cant_mm, dtype=float),
        }
    )
    if family is None:
        return df
    rng = np.random.default_rng(np.random.SeedSequence([campaign_seed, condition.seed, 0x7AC]))
    synthesised = condition.track_geometry is None and condition.irregularity_class is not None
    if family.irregularity_classes is not None and synthesised:
        lo, hi = family.irregularity_classes
        df["irregularity_class"] = rng.integers(lo, hi + 1, size=n)
    if condition.curve_radius_m is not None and family.varies_layout:
        unit = qmc.LatinHypercube(d=2, rng=rng).random(n)
        for j, col in enumerate(("curve_radius_m", "cant_mm")):
            rng_ = getattr(family, col)
            if rng_ is not None:
                df[col] = rng_[0] + (rng_[1] - rng_[0]) * unit[:, j]
    return df


def sample_condition(condition: WorkingCondition, row: Mapping[str, Any]) -> WorkingCondition:
    """The condition of one sample (a row of :func:`sample_tracks`): the same condition with
    its seed, FRA class, radius and cant (the seed is passed to the simulator separately)."""
    changes: dict[str, Any] = {"seed": int(row["seed"])}
    cls = int(row["irregularity_class"])
    if cls > 0 and cls != condition.irregularity_class:
        changes["irregularity_class"] = cls
    if condition.curve_radius_m is not None:
        if float(row["curve_radius_m"]) != condition.curve_radius_m:
            changes["curve_radius_m"] = float(row["curve_radius_m"])
        if float(row["cant_mm"]) != condition.cant_mm:
            changes["cant_mm"] = float(row["cant_mm"])
    return condition.with_changes(**changes)


def layout_key(row: Mapping[str, Any]) -> tuple[int, float, float]:
    """What a batched simulator call must share: FRA class, radius, cant (seeds may differ)."""
    radius = float(row["curve_radius_m"])
    return (
        int(row["irregularity_class"]),
        radius if np.isfinite(radius) else -1.0,
        float(row["cant_mm"]),
    )


def assumed_parameters(
    inputs: Sequence[str],
    others: Mapping[str, tuple[float, float]],
    sampled: Sequence[str] = (),
) -> list[dict[str, Any]]:
    """What a surrogate with ``inputs`` assumes about every other main-suspension parameter:
    ``varied`` over an SI range (``others``, or a sampled parameter it does not take as
    input: over its Table 2 range, read as noise) or held at ``nominal``. One dict per
    parameter: symbol, name, unit (display), assumed, value or low/high (display units)."""
    rows = []
    for sym in MAIN_SUSPENSION:
        if sym in inputs:
            continue
        ps = spec(sym)
        row: dict[str, Any] = {"symbol": sym, "name": ps.name, "unit": ps.display_unit}
        if sym in others or sym in sampled:
            lo, hi = others[sym] if sym in others else ps.bounds
            row.update(assumed="varied", low=ps.to_display(lo), high=ps.to_display(hi), value=None)
        else:
            row.update(assumed="nominal", value=ps.nominal_display, low=None, high=None)
        rows.append(row)
    return rows


def layout_groups(
    condition: WorkingCondition, tracks: pd.DataFrame
) -> list[tuple[WorkingCondition, np.ndarray]]:
    """Rows of a track table (one batch) that one batched simulator call can take: those of
    equal FRA class, radius and cant, with the condition they share (seeds may differ)."""
    rows = tracks.to_dict("records")
    keys = [layout_key(r) for r in rows]
    groups = []
    for key in dict.fromkeys(keys):
        idx = np.array([i for i, k in enumerate(keys) if k == key])
        groups.append((sample_condition(condition, rows[idx[0]]), idx))
    return groups


def parse_range(text: str, option: str) -> tuple[float, float]:
    """``"LO:HI"`` -> (lo, hi) as given (user units); a one-line error naming ``option``."""
    parts = str(text).split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        lo, hi = float(parts[0]), float(parts[1])
    except ValueError:
        raise RailsuspInputError(
            f"{option} {text!r}: accepted LO:HI, two numbers (e.g. 250:400)"
        ) from None
    if not (np.isfinite(lo) and np.isfinite(hi)) or lo > hi:
        raise RailsuspInputError(f"{option} {text!r}: accepted LO:HI with LO <= HI, finite")
    return lo, hi


def parse_priors(text: str, option: str = "--prior") -> dict[str, tuple[float, float]]:
    """``"X19=20000:40000,X20=800:1200"`` (display units, as ``railsusp params`` shows them)
    -> {symbol: (lo, hi)} in SI; ranges are checked against Table 2 by the campaign."""
    out: dict[str, tuple[float, float]] = {}
    for item in (t.strip() for t in str(text).split(",")):
        if not item:
            continue
        name, sep, rng = item.partition("=")
        if not sep:
            raise RailsuspInputError(
                f"{option} {item!r}: accepted SYMBOL=LO:HI in display units (e.g. X19=20000:40000)"
            )
        ps = spec(name.strip())
        if ps.symbol in out:  # the last one would win, silently
            raise RailsuspInputError(
                f"{option} {text}: {ps.symbol} is given twice; accepted each parameter once"
            )
        lo, hi = parse_range(rng, f"{option} {ps.symbol}")
        out[ps.symbol] = (lo * ps.scale, hi * ps.scale)
    return out


def full_ranges(
    sampled: Sequence[str], priors: Mapping[str, tuple[float, float]] | None = None
) -> dict[str, tuple[float, float]]:
    """Every main-suspension parameter outside ``sampled``, over its Table 2 range (SI), or
    over ``priors`` where given."""
    priors = dict(priors or {})
    return {
        s: priors.get(s, spec(s).bounds)  # type: ignore[misc]
        for s in MAIN_SUSPENSION
        if s not in sampled
    }
