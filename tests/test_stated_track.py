"""A section table's stated curve against the run's own curvature
(:func:`railsusp.measured.track_kinds.stated_track_contradicted`), in both running senses:
the note quotes both as the table writes them (seen towards increasing positions)."""

import dataclasses

import numpy as np
import pandas as pd

from railsusp.measured.run import MeasuredRun
from railsusp.measured.sections import SectionRules
from railsusp.measured.track_kinds import stated_track_contradicted

RATE = 50.0
T = np.arange(int(2000 / 20 * RATE)) / RATE
TABLE = pd.DataFrame({"start_m": [500.0], "end_m": [1500.0], "radius_m": [600.0],
                      "direction": ["left"]})  # fmt: skip


def _run(position, curvature) -> MeasuredRun:
    names = {f.name for f in dataclasses.fields(MeasuredRun)}
    given = {"source": "x", "time": T, "speed": np.full(T.size, 20.0), "position": position,
             "curvature": curvature, "rate_hz": RATE, "forces": {}, "wheels": [], "Y": {},
             "Q": {}}  # fmt: skip
    return MeasuredRun(**{k: v for k, v in given.items() if k in names})


def test_a_contradicted_hand_is_quoted_as_the_table_writes_it_in_both_senses():
    rules = SectionRules()
    left = np.full(T.size, 1 / 600)  # + left, as the wagon sees it
    assert stated_track_contradicted(_run(20 * T, left), TABLE, rules) == []
    # running towards falling positions the table's left-hand curve is seen as right-hand
    assert stated_track_contradicted(_run(2000 - 20 * T, -left), TABLE, rules) == []
    (note,) = stated_track_contradicted(_run(2000 - 20 * T, left), TABLE, rules)
    assert "row 2: it states R 600 m left, the run's curvature channel gives R 600 m right" in note
    assert "both seen towards increasing positions" in note
    (note,) = stated_track_contradicted(_run(20 * T, -left), TABLE, rules)
    assert "it states R 600 m left, the run's curvature channel gives R 600 m right" in note
    assert "both seen" not in note
    spirals = np.interp(20 * T, [0, 500, 600, 1400, 1500, 2000], [0, 0, 1 / 600, 1 / 600, 0, 0])
    assert stated_track_contradicted(_run(20 * T, spirals), TABLE, rules) == []  # mean ~R 670
