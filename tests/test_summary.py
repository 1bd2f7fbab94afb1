"""The summary's estimate table and verdicts on hand-made run directories: intervals in
display units from the estimate's standard errors, verdicts against the tolerances, the
force agreement, and the wagon data's [tolerances] table."""

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import railsusp
from railsusp import summary
from railsusp.errors import RailsuspInputError
from railsusp.estimate.intervals import (
    PARETO,
    POSTERIOR,
    STANDARD_ERROR,
    describe,
    from_samples,
    from_standard_errors,
    intervals_of,
)
from railsusp.params import spec
from railsusp.suspension_tolerances import Tolerances, read_tolerances
from railsusp.vehicle.wagon import load_wagon


def write(path: Path, doc: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc))


def make_run(root: Path, estimate: dict, refinement: dict | None, wagon: str | None = None):
    """A run directory with the files the summary reads: X13, X17 estimated (display)."""
    params = ["X13", "X17"]
    pareto = [
        [spec(p).scale * v for p, v in zip(params, row, strict=True)]
        for row in ([12.0, 1.0], [20.0, 1.2], [estimate["X13"], estimate["X17"]])
    ]
    write(root / "pipeline.json", {"config": {"wagon": wagon}, "stages": {}})
    write(
        root / "estimate" / "estimate.json",
        {
            "parameters": params,
            "estimate_display": estimate,
            "pareto_x_si": pareto,
            "pareto_spread_pct_range": {"X13": 10.0, "X17": 3.0},
            "refinement": refinement,
            "cramer_rao_pct_range": {},
        },
    )
    write(
        root / "campaign" / "sensitivity" / "key_parameters.json",
        {"key_parameters": {"keys": params, "max_st": {"X13": 0.5, "X17": 0.4, "X14": 0.2}}},
    )
    write(root / "campaign" / "campaign.json", {"config": {"parameters": ["X13", "X14", "X17"]}})
    return root


def test_refined_estimate_gives_90_percent_intervals_and_verdicts(tmp_path):
    """An estimate.json without stored intervals (saved before they were): X13 nominal
    14 MN/m (range 7-21), estimated 10.5 (-25 %), standard error 2 % of the 14 MN/m range
    = 0.28 MN/m: degraded, 90 % interval 10.5 ± 1.645 x 0.28. X17 nominal 1.8 estimated 1.9
    (+5.6 %): within tolerance. Then standard errors of 7 % (interval 23 % of range wide)
    and infinity: both not identifiable, each saying why."""
    ref = {"standard_error_pct_range": {"X13": 2.0, "X17": 1.0}}
    run = make_run(tmp_path, {"X13": 10.5, "X17": 1.9}, ref)
    t = summary.estimate_table(run)
    x13 = t.loc["X13"]
    lo, hi = spec("X13").bounds_display
    assert x13.standard_error == pytest.approx(0.02 * (hi - lo))
    half = 1.6449 * 0.28
    assert (x13.low, x13.high) == pytest.approx((10.5 - half, 10.5 + half), abs=1e-3)
    assert x13.change_pct == pytest.approx(-25.0)
    assert x13.verdict == summary.DEGRADED
    assert x13.interval == describe(STANDARD_ERROR, 0.9)
    assert t.loc["X17"].verdict == summary.WITHIN
    assert t.loc["X14"].verdict == "not estimated: held at 10.0 MN/m"
    assert t.loc["X14"].note == "not a key parameter of the sensitivity analysis"
    assert t.loc["X11"].note == "not varied in the campaign"
    # a looser tolerance turns X13 into "within", and the interval reaching out is said
    loose = summary.estimate_table(run, Tolerances(25.5))
    assert loose.loc["X13"].verdict == summary.WITHIN
    assert loose.loc["X13"].note == "the interval reaches beyond the tolerance"
    via_api = railsusp.open_run(run, tolerances=railsusp.Tolerances(25.5)).estimate
    assert via_api.equals(loose)
    # a large or infinite standard error: not identifiable, and why
    ref["standard_error_pct_range"] = {"X13": 7.0, "X17": math.inf}
    run = make_run(tmp_path, {"X13": 14.0, "X17": 1.9}, ref)
    t = summary.estimate_table(run)
    assert t.loc["X13"].verdict == summary.NOT_IDENTIFIABLE
    assert t.loc["X13"].note == "90 % interval 23.0 % of range wide"
    assert "interval is the whole range" in t.loc["X17"].note


def test_unrefined_estimate_interval_is_the_pareto_range_and_never_identifies(tmp_path):
    """NSGA-II alone: the interval is the Pareto set's range, labelled as not a confidence
    interval, and no parameter is called identified from it, however narrow."""
    run = make_run(tmp_path, {"X13": 16.0, "X17": 1.1}, None)
    t = summary.estimate_table(run)
    assert (t.loc["X13"].low, t.loc["X13"].high) == pytest.approx((12.0, 20.0))
    assert t.loc["X13"].interval == describe(PARETO, None)
    assert "not a confidence interval" in t.loc["X13"].interval
    assert math.isnan(t.loc["X13"].standard_error)
    for p in ("X13", "X17"):  # X17's Pareto set 1.0-1.2 is 4 % of its range wide
        # not identified by this route, not "not identifiable from these recordings":
        # refined, the same recordings identify them (stop 61's report audit)
        assert t.loc[p].verdict == summary.NOT_IDENTIFIED
        assert t.loc[p].note.startswith("no confidence interval")


def test_a_polish_beside_nsga_iis_estimate_lends_it_no_standard_error(tmp_path):
    """NSGA-II's estimate (simulator-corrected) with the refinement as a polish beside it:
    its interval is the Pareto range and it has no standard error; the polish's belonged to
    another point (X19 943 kN/m on the audit's pretrained run)."""
    ref = {"standard_error_pct_range": {"X13": 2.0, "X17": 1.0}}
    for source in ("nsga-ii", "nsga-ii, simulator-corrected"):
        run = make_run(tmp_path / source, {"X13": 16.0, "X17": 1.1}, ref)
        path = run / "estimate" / "estimate.json"
        doc = json.loads(path.read_text())
        doc.update(estimate_source=source, polished_display={"X13": 15.0, "X17": 1.2})
        if source == "nsga-ii":  # as saved: the Pareto range stored as its intervals
            doc["intervals"] = intervals_of({**doc, "refinement": None}).to_dict()
        path.write_text(json.dumps(doc))
        t = summary.estimate_table(run)
        assert math.isnan(t.loc["X13"].standard_error), source
        assert t.loc["X13"].interval == describe(PARETO, None)


def test_stored_posterior_intervals_give_the_verdicts(tmp_path):
    """A result carrying its intervals (here a posterior's): the summary shows them, and the
    verdict follows their width; a point 25 % of range off nominal with a wide interval is
    not identified."""
    run = make_run(tmp_path, {"X13": 10.5, "X17": 1.9}, None)
    path = run / "estimate" / "estimate.json"
    doc = json.loads(path.read_text())
    rng = np.random.default_rng(0)
    samples = np.column_stack(
        [
            rng.normal(10.5e6, 0.3e6, 4000),  # X13: 90 % interval ~7 % of its range wide
            rng.normal(2.25e6, 0.3e6, 4000),  # X17: 25 % of range above nominal, ~55 % wide
        ]
    )
    iv = from_samples(("X13", "X17"), samples)
    doc["intervals"] = iv.to_dict()
    doc["estimate_display"] = {i.parameter: i.value for i in iv.items}
    doc["pareto_x_si"] = [list(samples[0])]  # a posterior has no Pareto set to fall back on
    path.write_text(json.dumps(doc))
    t = summary.estimate_table(run)
    assert (t.loc["X13"].low, t.loc["X13"].high) == pytest.approx((iv["X13"].low, iv["X13"].high))
    assert t.loc["X13"].interval == describe(POSTERIOR, 0.9)
    assert t.loc["X13"].verdict == summary.DEGRADED  # -25 % of nominal, interval narrow
    assert t.loc["X17"].verdict == summary.NOT_IDENTIFIABLE
    assert t.loc["X17"].note.startswith("90 % interval 5")


def test_force_agreement_prefers_the_time_aligned_comparison(tmp_path):
    rows = []
    for st, b, a in (("mean", 0.2, 0.05), ("aligned", 0.9, 0.3)):
        for force in ("Y", "Q"):
            rows.append(
                {
                    "condition": "curve",
                    "force": force,
                    "statistic": st,
                    "before_error": b,
                    "after_error": a / (2 if force == "Q" else 1),
                }
            )
    out = tmp_path / "estimate" / "validation"
    out.mkdir(parents=True)
    pd.DataFrame(rows).to_csv(out / "validation.csv", index=False)
    ag = summary.force_agreement(tmp_path)
    assert ag.statistic.tolist() == ["aligned"]
    assert ag.lateral_before_pct[0] == pytest.approx(90.0)
    assert ag.vertical_after_pct[0] == pytest.approx(15.0)
    (line,) = summary.agreement_lines(ag)
    assert line.startswith("curve: lateral Y 90.0 % → 30.0 %, vertical Q 90.0 % → 15.0 %")
    assert "time-aligned" in line


def test_wagon_tolerances_are_read_and_checked(tmp_path):
    wagon = tmp_path / "wagon.toml"
    base = (Path(summary.__file__).parent / "data" / "c80_k6.toml").read_text("utf-8")
    wagon.write_text(base + "\n[tolerances]\ndefault_pct = 10.0\nX13 = 30\n")
    tol = read_tolerances(wagon)
    assert (tol.of("X13"), tol.of("X17")) == (30.0, 10.0)
    assert load_wagon(wagon).name == load_wagon().name  # the model ignores the table
    run = make_run(tmp_path / "run", {"X13": 10.5, "X17": 1.9}, None, wagon=str(wagon))
    assert summary.estimate_table(run).loc["X13"].tolerance_pct == 30.0
    assert read_tolerances(None) == Tolerances()
    for bad, msg in (
        ("X13 = 0", r"tolerances\.X13 = 0: accepted a number in \(0, 100\]"),
        ("X99 = 5.0", r"tolerances\.X99: accepted default_pct or a main suspension"),
        ('default_pct = "a"', r"tolerances\.default_pct = 'a'"),
    ):
        wagon.write_text(base + f"\n[tolerances]\n{bad}\n")
        with pytest.raises(RailsuspInputError, match=msg):
            read_tolerances(wagon)


def test_held_parameters_are_listed_with_the_range_the_intervals_assumed(tmp_path):
    """A refined estimate's intervals record what they assumed of each held parameter: the
    value held and the range it is taken uniform over, the user's (estimate.held_prior) or
    Table 2's; the summary says it."""
    from railsusp.estimate.config import HeldPrior
    from railsusp.estimate.intervals import REFINEMENT, from_standard_errors
    from railsusp.estimate.refine_intervals import held_assumptions

    run = make_run(tmp_path, {"X13": 10.5, "X17": 1.9}, None)
    path = run / "estimate" / "estimate.json"
    doc = json.loads(path.read_text())
    prior = HeldPrior.from_display({"X19": [20000, 40000]})
    details = {"held_parameters_assumed": held_assumptions(("X13", "X17"), prior)}
    iv = from_standard_errors(
        ("X13", "X17"), np.array([10.5e6, 1.9e6]), np.array([0.1e6, 0.01e6]), 0.9, 50.0,
        REFINEMENT, details,
    )  # fmt: skip
    doc["intervals"] = iv.to_dict()
    path.write_text(json.dumps(doc))
    t = summary.estimate_table(run)
    assert t.loc["X19"].verdict == (
        "not estimated: held at 30000 kN/m, in the intervals anywhere in 20000-40000 kN/m "
        "(estimate.held_prior)"
    )
    assert t.loc["X14"].verdict == (
        "not estimated: held at 10.0 MN/m, in the intervals anywhere in 5.00-15.0 MN/m "
        "(Table 2 range)"
    )


def test_a_parameter_held_at_its_priors_centre_shows_that_value(tmp_path):
    """With a held prior the estimate holds the parameter at its range's centre
    (estimate.json held_at_display): the summary's row shows that value, its change from
    nominal and the verdict's held value, not nominal's (the summary showed nominal, 0 %)."""
    from railsusp.estimate.config import HeldPrior
    from railsusp.estimate.intervals import REFINEMENT, from_standard_errors
    from railsusp.estimate.refine_intervals import held_assumptions
    from railsusp.params import ParameterSet

    run = make_run(tmp_path, {"X13": 10.5, "X17": 1.9}, None)
    path = run / "estimate" / "estimate.json"
    doc = json.loads(path.read_text())
    prior = HeldPrior.from_display({"X19": [15000, 25000]})
    base = ParameterSet.nominal().replace(prior.held_at_si(("X13", "X17")))
    details = {"held_parameters_assumed": held_assumptions(("X13", "X17"), prior, base)}
    iv = from_standard_errors(
        ("X13", "X17"), np.array([10.5e6, 1.9e6]), np.array([0.1e6, 0.01e6]), 0.9, 50.0,
        REFINEMENT, details,
    )  # fmt: skip
    doc["intervals"] = iv.to_dict()
    doc["held_at_display"] = {"X19": 20000.0}
    path.write_text(json.dumps(doc))
    row = summary.estimate_table(run).loc["X19"]
    assert row.estimate == 20000.0
    assert row.change_pct == pytest.approx(-100.0 / 3.0)
    assert row.verdict == (
        "not estimated: held at 20000 kN/m, in the intervals anywhere in 15000-25000 kN/m "
        "(estimate.held_prior)"
    )
    assert summary.estimate_table(run).loc["X20"].change_pct == 0.0


def test_an_estimate_on_the_search_range_bound_says_so(tmp_path):
    """Stop 61's report audit: X14 = 15.0 (+49.9 %) and X19 at -50.0 %, the Table 2
    limits, read as measured changes. On the bound the note says the search stopped there."""
    run = make_run(tmp_path, {"X13": 21.0, "X17": 1.1}, None)  # X13's range is 7-21 MN/m
    t = summary.estimate_table(run)
    assert "on the bound of the search range (Table 2)" in t.loc["X13"].note
    assert "search range" not in t.loc["X17"].note


def test_the_tolerances_know_whether_the_wagon_data_gave_them(tmp_path):
    """The report said "from the wagon data's [tolerances]" for the packaged C80, which has
    none; and compared values with the defaults, so a wagon file stating 15 % was called
    railsusp's default."""
    from importlib import resources

    assert read_tolerances(None).from_wagon is False
    text = (resources.files("railsusp") / "data" / "c80_k6.toml").read_text("utf-8")
    wagon = tmp_path / "w.toml"
    wagon.write_text(text + "\n[tolerances]\ndefault_pct = 15.0\n")
    tol = read_tolerances(wagon)
    assert tol.from_wagon and tol == Tolerances()  # the source is not compared
    assert Tolerances.from_dict(tol.to_dict()).from_wagon
    # a run recorded before the source was: other than the defaults, the wagon's
    assert Tolerances.from_dict({"default_pct": 20.0, "parameters": {}}).from_wagon
    assert not Tolerances.from_dict({"default_pct": 15.0, "parameters": {}}).from_wagon


def test_an_interval_beside_its_point_is_said_where_it_lies(tmp_path):
    """A refinement's interval lies beside its point where the held parameters' prior is
    off nominal (stop 77). X13 estimated 10.5 MN/m (within a 25.5 % tolerance of 14) with
    its 90 % interval at 9.0-10.0, wholly below the band: identified (together 10.7 % of
    range) and within tolerance by its point, and the note says the interval lies beyond."""
    from railsusp.estimate.intervals import REFINEMENT, Intervals, ParameterInterval

    run = make_run(tmp_path, {"X13": 10.5, "X17": 1.9}, {})
    doc = json.loads((run / "estimate" / "estimate.json").read_text())
    items = (
        ParameterInterval("X13", 10.5e6, 9.0e6, 10.0e6, 0.9, REFINEMENT),
        ParameterInterval("X17", 1.9e6, 1.85e6, 1.95e6, 0.9, REFINEMENT),
    )
    doc["intervals"] = Intervals(REFINEMENT, 0.9, items).to_dict()
    write(run / "estimate" / "estimate.json", doc)
    t = summary.estimate_table(run, Tolerances(25.5))
    assert t.loc["X13"].verdict == summary.WITHIN
    assert t.loc["X13"].note == "the interval lies wholly beyond the tolerance"


# A run directory's files damaged or edited inside (a field of the right file made text, a
# table made a list) are one line naming the file and the field, from the summary and
# railsusp.open_run's tables: each was a TypeError's, KeyError's or ValueError's traceback
# from the table's rows, and a damaged key_parameters.json was blamed on estimate.json (stop
# 79's report hunt).
def refined_run(root):
    """A run of X13, X17 refined, its intervals stored with their details, X14 held over
    its Table 2 range, X12 a network set's input varied in its training."""
    run = make_run(root, {"X13": 10.5, "X17": 1.9}, {"standard_error_pct_range": {"X13": 2.0}})
    path = run / "estimate" / "estimate.json"
    doc = json.loads(path.read_text())
    x = [spec(p).scale * doc["estimate_display"][p] for p in ("X13", "X17")]
    iv = from_standard_errors(["X13", "X17"], x, [0.28e6, 0.01e6]).to_dict()
    iv["details"] = {
        "total_standard_error_pct_range": {"X13": 2.0, "X17": 1.1},
        "held_parameters_assumed": {
            "X14": {
                "held_at_display": 10.0,
                "low_display": 5.0,
                "high_display": 15.0,
                "range": "Table 2",
                "unit": "MN/m",
            },
        },
    }
    doc["intervals"] = iv
    doc["not_estimated"] = [
        {"symbol": "X12", "assumed": "varied", "low": 6.0, "high": 18.0, "unit": "mm"}
    ]
    path.write_text(json.dumps(doc))
    return run


def edit(path, change):
    doc = json.loads(path.read_text())
    change(doc)
    path.write_text(json.dumps(doc))


def test_the_hand_made_refined_run_reads(tmp_path):
    """The run the tests below damage reads whole (so that each refusal is its edit's)."""
    t = summary.estimate_table(refined_run(tmp_path))
    assert t.loc["X14"].verdict.startswith("not estimated: held at 10.0 MN/m, in the intervals")
    assert t.loc["X12"].note == "not an input of the force model (varied in its training)"
    assert t.loc["X13"].standard_error == pytest.approx(0.28)


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (lambda d: d.__setitem__("not_estimated", [1, 2]), "not_estimated = [1, 2]"),
        (
            lambda d: d["not_estimated"][0].pop("low"),
            "not_estimated.X12",
        ),
        (
            lambda d: d["intervals"]["details"]["total_standard_error_pct_range"].update(X13="a"),
            "intervals.details.total_standard_error_pct_range.X13 = 'a'",
        ),
        (
            lambda d: d["intervals"]["details"]["held_parameters_assumed"].update(X14={"a": 1}),
            "intervals.details.held_parameters_assumed.X14",
        ),
        (lambda d: d.__setitem__("polished_display", [1.0]), "polished_display = [1.0]"),
        (lambda d: d.__setitem__("refinement", [1.0]), "refinement = [1.0]"),
    ],
)
def test_a_damaged_estimate_field_is_one_line_naming_it(tmp_path, change, field):
    run = refined_run(tmp_path)
    edit(run / "estimate" / "estimate.json", change)
    for read in (summary.estimate_table, lambda r: railsusp.open_run(r).estimate):
        with pytest.raises(RailsuspInputError) as exc:
            read(run)
        said = str(exc.value)
        assert "estimate.json" in said and field in said and "\n" not in said


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (lambda d: d["key_parameters"]["max_st"].update(X13="a"), "max_st.X13 = 'a'"),
        (lambda d: d["key_parameters"].__setitem__("max_st", [0.5]), "max_st = [0.5]"),
        (lambda d: d["key_parameters"].__setitem__("keys", 5), "keys = 5"),
    ],
)
def test_a_damaged_key_parameters_json_is_named_not_the_estimate(tmp_path, change, field):
    """A number made text in key_parameters.json's max_st read "estimate.json: its intervals
    do not read" (the file that was sound), and ``largest_st`` raised a ValueError."""
    run = refined_run(tmp_path)
    edit(run / "campaign" / "sensitivity" / "key_parameters.json", change)
    result = railsusp.open_run(run)
    reads = [lambda: result.largest_st, lambda: result.key_parameters]
    if "max_st" in field:  # the summary's verdicts read max_st alone
        reads.append(lambda: summary.estimate_table(run))
    for read in reads:
        with pytest.raises(RailsuspInputError) as exc:
            read()
        said = str(exc.value)
        assert "key_parameters.json" in said and field in said
        assert "estimate.json" not in said and "\n" not in said


def test_a_damaged_campaign_json_config_is_one_line(tmp_path):
    run = refined_run(tmp_path)
    edit(run / "campaign" / "campaign.json", lambda d: d.__setitem__("config", []))
    with pytest.raises(RailsuspInputError, match=r"campaign\.json: config: accepted a table"):
        summary.estimate_table(run)


def test_a_number_made_text_in_validation_csv_names_column_and_row(tmp_path):
    rows = [
        {"condition": "curve", "wheel": "w1R", "force": f, "statistic": "mean",
         "measured_kN": 40.0, "before_kN": 41.0, "before_error": 0.025, "after_kN": 40.2,
         "after_error": 0.005}
        for f in ("Y", "Q")
    ]  # fmt: skip
    run = refined_run(tmp_path)
    folder = run / "estimate" / "validation"
    folder.mkdir(parents=True)
    pd.DataFrame(rows).to_csv(folder / "validation.csv", index=False)
    assert railsusp.open_run(run).validation.after_error_pct.tolist() == pytest.approx([0.5, 0.5])
    rows[1]["after_error"] = "abc"
    pd.DataFrame(rows).to_csv(folder / "validation.csv", index=False)
    said = "validation.csv: column after_error = 'abc' in row 3: accepted a number"
    with pytest.raises(RailsuspInputError, match=said):
        summary.force_agreement(run)
    with pytest.raises(RailsuspInputError, match=said):
        _ = railsusp.open_run(run).validation


@pytest.mark.parametrize("kept", [[], {}, "x"])
def test_an_emptied_intervals_record_is_refused_not_formed_again_narrower(tmp_path, kept):
    """An estimate.json whose ``intervals`` was emptied read as one saved before intervals
    were stored: its interval formed again from the refinement's noise part alone (the
    demo's X13: 0.55 % of range instead of the 2.38 % total, four times narrower), without
    a word."""
    run = refined_run(tmp_path)
    edit(run / "estimate" / "estimate.json", lambda d: d.__setitem__("intervals", kept))
    with pytest.raises(RailsuspInputError, match=r"intervals = .*edited or damaged"):
        summary.estimate_table(run)
