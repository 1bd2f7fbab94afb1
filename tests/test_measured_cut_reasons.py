"""The reasons a long run's cut gives for what it leaves out, where the QA of stop 68 found
them wrong or missing: a noisy speed under a tight tolerance shown as a transition alone."""

import numpy as np

from railsusp.measured.run import MeasuredRun
from railsusp.measured.sections import SectionRules, cut_sections, sections_table
from test_measured_run import synthetic_run


def test_a_noisy_speed_under_a_tight_tolerance_is_the_reason_not_a_transition():
    """60 km/h with 1 % noise over a tangent, a transition and an R600 curve, cut with a
    1 % tolerance: every piece is under a second, and they were all folded away as band
    edges, the row shown as a "transition" alone. The speed is the reason now, with its
    range and the tolerance, and the row's kind is its track's ("mixed")."""
    rng = np.random.default_rng(4)
    t = np.arange(3300) / 50.0
    speed = 60.0 * (1.0 + 0.01 * rng.standard_normal(t.size))
    run = synthetic_run(speed, np.interp(t, [36.0, 48.0], [0.0, 1e3 / 600]), 0 * t)
    (row,) = sections_table(cut_sections(run, SectionRules(speed_tolerance=0.01))).itertuples()
    assert row.kept == "no" and row.kind == "mixed"
    parts = row.reason.split("; ")
    assert [p.split(":")[0].split(" (")[0] for p in parts] == [
        "tangent",
        "transition",
        "curve R600",
    ]
    for p in (parts[0], parts[2]):
        assert " pieces of 0-3 m, each shorter than the 150 m minimum (speed varies from 5" in p
        assert p.endswith("there, beyond the 1 % tolerance)")
    # with 5 %: the same row, its pieces longer, still not a transition
    (row,) = sections_table(cut_sections(run, SectionRules(speed_tolerance=0.05))).itertuples()
    assert row.kind == "mixed" and "beyond the 5 % tolerance" in row.reason


def _canted_run(curvature_per_km: float | None) -> MeasuredRun:
    """60 s at 54 km/h (both leading wheels), cant 0 for 30 s and then 60 mm, a constant
    curvature (None: no curvature channel)."""
    run = synthetic_run(np.full(3000, 54.0), np.full(3000, curvature_per_km or 0.0), np.zeros(3000))
    run.cant = np.where(np.arange(3000) < 1500, 0.0, 0.06)
    run.curvature = None if curvature_per_km is None else run.curvature
    return run


def test_cant_without_any_curvature_is_left_out_and_a_tangent_shows_the_cant_it_writes():
    """QA: a run with cant but no curvature channel showed a "tangent" of cant 60 mm in the
    table and sections.csv, its written condition cant 0 without a word (a line description
    with cant on a tangent row is refused). The stretch is left out, naming its cant."""
    secs = cut_sections(_canted_run(None))
    kept = [s for s in secs if s.kept]
    (out,) = [s for s in secs if not s.kept]
    assert out.reason.startswith("cant 60 mm without a curvature (no curvature channel, line")
    assert out.start_m > 440.0 and kept and all(s.end_m < 460.0 for s in kept)
    for s in kept:  # shown as written
        assert s.cant_mm == s.condition(10.0, 50.0).cant_mm == 0.0


def test_a_wide_curve_taken_as_tangent_says_its_cant_is_written_as_0():
    """An R4000 (wider than the 3000 m tangent radius) with 60 mm cant: a tangent, kept, its
    row's cant the condition's 0 (it showed 60), the reason saying so."""
    run = _canted_run(1e3 / 4000)
    run.cant = np.full(3000, 0.06)
    (sec,) = cut_sections(run)
    assert sec.kept and sec.cant_mm == 0.0 == sec.condition(10.0, 50.0).cant_mm
    assert sec.reason == (
        "kept as tangent (radius over 3000 m), its cant of 60 mm written as 0: a condition "
        "has cant in a curve only"
    )
    assert sections_table([sec]).cant_mm.tolist() == [0.0]


def _run_of(t: np.ndarray, v: np.ndarray, **kw) -> MeasuredRun:
    """A tangent run of signed speed ``v`` (m/s) at times ``t``, both leading wheels."""
    x = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    rng = np.random.default_rng(1)
    z = np.zeros(t.size)
    return MeasuredRun(
        "r.csv", t, {w: 5e3 + 1e3 * rng.standard_normal(t.size) for w in ("w1R", "w1L")},
        {w: 120e3 + 5e3 * rng.standard_normal(t.size) for w in ("w1R", "w1L")},
        np.abs(v), x, z, z, z, **kw,
    )  # fmt: skip


def test_a_reversal_is_said_as_such_not_as_a_stop():
    """QA: a backwards stretch's zero crossings (the run's speed is its magnitude) showed as
    "standing (0 s)" beside "running backwards"."""
    v = np.concatenate([np.full(2000, 15.0), np.linspace(15, -5, 500), np.full(1000, -5.0),
                        np.linspace(-5, 15, 500), np.full(2000, 15.0)])  # fmt: skip
    back = (np.abs(v) >= 0.5) & (v < 0)
    run = _run_of(np.arange(v.size) / 50.0, v, backwards=back)
    (out,) = [s for s in cut_sections(run) if not s.kept]
    assert "standing" not in out.reason
    assert (
        "; reversing (1.0 s under 1.8 km/h between running forward and backwards); running "
        "backwards (wheelset 1 trailing"
    ) in out.reason


def test_a_dropout_has_a_row_of_its_own():
    """QA: a dropout cut the run (600 -> 609 m) without a row, where a NaN gap has one."""
    t = np.arange(4000) / 50.0
    t[2000:] += 0.6  # 30 samples lost
    secs = cut_sections(_run_of(t, np.full(4000, 15.0), breaks=np.array([2000])))
    assert [s.kept for s in secs] == [True, False, True]
    assert (secs[1].start, secs[1].end) == (2000, 2000)  # no samples
    row = sections_table(secs).iloc[1]
    assert (row.kind, row.from_m, row.to_m) == ("dropout", 599.7, 609.0)
    assert row.reason == "no samples: a dropout of the logger (0.6 s of samples lost)"


def test_check_recording_shows_a_backwards_stretch_as_negative_speeds():
    """QA: check-recording's "speed 0-65 km/h" of a run with a backwards stretch (its speed
    is the magnitude) read as a stop; the range is signed in the run's sense now."""
    from railsusp.cli.recordings import _speed_range

    v = np.concatenate([np.full(200, 15.0), np.linspace(15, -5, 50), np.full(100, -5.0)])
    back = (np.abs(v) >= 0.5) & (v < 0)
    assert _speed_range(_run_of(np.arange(v.size) / 50.0, v, backwards=back)) == (
        "-18 to 54 km/h (negative: backwards)"
    )
    assert _speed_range(_run_of(np.arange(200) / 50.0, np.full(200, 15.0))) == "54-54 km/h"


def test_a_section_crowded_with_interpolated_samples_is_left_out():
    """The run passes the missing-sample rule over its whole length (at most 5 %), but its
    short gaps may crowd into one section, which `sections --write` wrote as if measured
    (the field reader cannot tell them, the cells being full): such a section is left out,
    saying so; one under the limit is kept."""
    v = np.full(6000, 15.0)
    crowded = np.zeros(v.size, dtype=bool)
    crowded[100:1000:10] = True  # 90 interpolated samples
    (kept,) = cut_sections(_run_of(np.arange(v.size) / 50.0, v, interpolated={"WS1_Q_R": crowded}))
    assert kept.kept  # 90 of 6000: 1.5 %
    crowded[100:1000:2] = True  # 450 of 6000: 7.5 %
    (out,) = cut_sections(_run_of(np.arange(v.size) / 50.0, v, interpolated={"WS1_Q_R": crowded}))
    assert not out.kept
    assert out.reason == (
        "7.5 % of the samples of channel 'WS1_Q_R' here interpolated across empty values; "
        "accepted at most 5 % in a section (written, they would read as measured forces)"
    )


def test_a_piece_long_enough_but_shorter_than_a_conditions_duration_is_left_out():
    """The bug hunt: with a small --min-length, a piece of 7 m between two breaks (0.5 s at
    54 km/h) was kept, and `sections --write` failed late on its condition ("duration_s =
    0.5: accepted range [1, 600] s"); it is left out with its reason, the others written."""
    from railsusp.measured.sections_out import section_recording

    run = _run_of(np.arange(4000) / 50.0, np.full(4000, 15.0), breaks=np.array([2000, 2025]))
    secs = cut_sections(run, SectionRules(min_length_m=5.0))
    assert [s.kept for s in secs] == [True, False, True]
    assert secs[1].reason == (
        "tangent of 0.5 s, shorter than a working condition's 1 s minimum duration"
    )
    assert sections_table(secs).kind.tolist() == ["tangent"] * 3
    for s in secs[::2]:  # what --write makes of each kept one
        assert section_recording(run, s, 50.0).condition.duration_s >= 1.0
