"""Candidate geometry-free statistics of one section of an instrumented wheelset's forces,
for bench/statistics_information.py (issue 20: do richer statistics than the EN 14363 17
carry more about X13, X11 and X14?). The statistics themselves are the posterior's
families (:mod:`railsusp.estimate.statistic_families`); this maps the bench's groups onto
them:

- ``today``: the EN 14363 summary of the measured wheel (family ``en14363``);
- ``third_octave``: log10 RMS of Y and Q in 18 third-octave bands (``third-octave``);
- ``both_wheels``: the partner wheel's own 17, and the wheelset's track-shifting force
  (Y less the partner's, stop 62; the sum Y + Y_partner before) and difference of Q
  (``wheelset``);
- ``cross``: coherencies and lagged correlations (``coherence``);
- ``spectra``: the four channels' cross-spectral matrix in 1 Hz bands (``cross-spectra``).
"""

from __future__ import annotations

import numpy as np

from railsusp.estimate.statistic_families import family_names, family_statistics

#: the channels of one section, in this order: measured wheel Y, Q, partner Y, Q
CHANNELS = ("Y", "Q", "Y_partner", "Q_partner")
#: the bench's groups and the posterior's families they are
FAMILY_OF = {"today": "en14363", "third_octave": "third-octave", "both_wheels": "wheelset",
             "cross": "coherence", "spectra": "cross-spectra"}  # fmt: skip
GROUPS = tuple(FAMILY_OF)
#: the groups of the first measurement (stop 24), the sets "all groups" of its tables
FIRST_GROUPS = ("today", "third_octave", "both_wheels", "cross")


def group_names(group: str) -> list[str]:
    """Names of the entries of ``group`` (:data:`GROUPS`), in the order of
    :func:`section_statistics`."""
    if group not in FAMILY_OF:
        raise ValueError(f"group {group!r}: accepted {', '.join(GROUPS)}")
    return family_names(FAMILY_OF[group])


def section_statistics(signals: np.ndarray, fs: float, speed_ms: float) -> dict[str, np.ndarray]:
    """Every group's statistics (:func:`group_names`) of one section, ``signals`` (4, T) the
    channels of :data:`CHANNELS` in kN."""
    Y, Q, Yp, Qp = (np.asarray(s, dtype=float) for s in signals)
    return {g: family_statistics(f, Y, Q, fs, speed_ms, Yp, Qp) for g, f in FAMILY_OF.items()}
