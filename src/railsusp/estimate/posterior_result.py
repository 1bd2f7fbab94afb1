"""The posterior of a recording (:func:`railsusp.estimate.posterior.estimate`): draws of
the estimated parameters, the verdict of the estimator's calibration and its correction,
how the recording was used; the table in display units and the result JSON (strict JSON:
a number that is not defined, such as the coverage of a length no check covers, is
``null``, never a bare ``NaN``, which JSON parsers other than Python's refuse)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from railsusp.estimate.calibration import LEVEL, ParameterCalibration, SpreadCorrection
from railsusp.estimate.intervals import Intervals, from_samples
from railsusp.params import spec
from railsusp.store import write_json


@dataclass
class PosteriorResult:
    """The posterior of a recording: draws (SI) of the estimated parameters, the verdict
    of the estimator's calibration check and how the recording was used."""

    parameters: tuple[str, ...]
    samples: np.ndarray  # (S, d) SI
    calibration: list[ParameterCalibration]
    sections: dict[str, dict]
    n_sections: int = 1
    warnings: list[str] = field(default_factory=list)
    correction: SpreadCorrection | None = None
    checked_as: int | None = 1  # the number of sections whose check applies; None: none
    long_record: str = (
        "fusion"  # how the sections combine (posterior_synthetic.LONG_RECORD_METHODS)
    )
    #: the statistics of the recording that lie outside the training cases' range
    #: (:class:`~railsusp.estimate.posterior_support.TrainingSupport`): not calibrated
    outside_training: list[str] = field(default_factory=list)

    @property
    def check_passed(self) -> bool:
        """The estimator passed its coverage check after a correction within bounds (what
        :attr:`calibrated` asks besides a check for the number of sections and statistics
        inside the training cases' range)."""
        excessive = self.correction.excessive if self.correction else []
        return all(c.passed for c in self.calibration) and not excessive

    @property
    def calibrated(self) -> bool:
        """A check covers this number of sections, the estimator passed it after a
        correction within bounds, and the recording's statistics lie inside what the
        estimator learnt from (:attr:`outside_training` empty)."""
        return self.check_passed and self.checked_as is not None and not self.outside_training

    def intervals(self, level: float = LEVEL) -> Intervals:
        """Median and central ``level`` credible interval of each parameter (the one
        interval type of every route, :mod:`railsusp.estimate.intervals`)."""
        return from_samples(self.parameters, self.samples, level)

    def to_dataframe(self) -> pd.DataFrame:
        """Per parameter: median and central 90 % interval in display units, the
        interval's width as % of the prior range, and the held-out coverage."""
        rows = []
        lo_q, hi_q = (1 - LEVEL) / 2, (1 + LEVEL) / 2
        iv = self.intervals()
        for j, p in enumerate(self.parameters):
            sp = spec(p)
            lo, hi = sp.bounds
            q = np.quantile(self.samples[:, j], [0.5, lo_q, hi_q])
            rows.append(
                {
                    "parameter": p,
                    "name": sp.name,
                    "unit": sp.display_unit,
                    "median": sp.to_display(q[0]),
                    "lo90": sp.to_display(q[1]),
                    "hi90": sp.to_display(q[2]),
                    "width_pct_range": 100.0 * (q[2] - q[1]) / (hi - lo),
                    # no check applies beyond the checked numbers of sections: none shown
                    "coverage_heldout": self.calibration[j].coverage
                    if self.checked_as is not None
                    else float("nan"),
                    "widening": self.correction.factors[j] if self.correction else 1.0,
                    "calibrated": self.calibration[j].passed
                    and p not in (self.correction.excessive if self.correction else [])
                    and self.checked_as is not None
                    and not self.outside_training,
                    "median [90 % interval]": iv[p].text(),
                }
            )
        return pd.DataFrame(rows)

    def save(self, path: str | Path) -> Path:
        """The table and the verdict as JSON (atomic; numbers that are not defined as
        ``null``)."""
        return write_json(
            path,
            _defined({
                "route": "posterior",
                "parameters": list(self.parameters),
                "estimate_display": {i.parameter: i.value for i in self.intervals().items},
                "intervals": self.intervals().to_dict(),
                "estimates": self.to_dataframe().to_dict(orient="records"),
                "calibrated": self.calibrated,
                "check_passed": self.check_passed,
                "correction": None if self.correction is None else self.correction.to_dict(),
                "sections": self.sections,
                "sections_combined": self.n_sections,
                "checked_as_sections": self.checked_as,
                "long_record": self.long_record,
                "outside_training": self.outside_training,
                "warnings": self.warnings,
            }),
        )  # fmt: skip


def _defined(value: Any) -> Any:
    """``value`` with every float that is not finite (NaN, inf) replaced by None, through
    dicts and lists: ``write_json`` writes them as the bare ``NaN`` that strict JSON
    parsers refuse (``coverage_heldout`` of a record longer than any check)."""
    if isinstance(value, dict):
        return {k: _defined(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_defined(v) for v in value]
    if isinstance(value, float | np.floating) and not math.isfinite(value):
        return None
    return value
