"""The report's summary card: the answer in the first screen. The wagon, the recordings,
each suspension element's estimate with its interval, change from nominal and verdict
against the wagon's tolerances (what is wrong listed first), and the force agreement before
and after the estimate. A module of its own because it is the one part of the page a reader
must not have to scroll for, and the one with the verdicts against the wagon's tolerances;
it reads the run directory through :mod:`railsusp.summary`, as
:class:`railsusp.api.RunResult` does.
"""

from __future__ import annotations

import html
from pathlib import Path

import pandas as pd

import railsusp.summary as summary
from railsusp.report_doc import Doc, md_paragraph, md_row, md_text, table_html
from railsusp.suspension_tolerances import DEFAULT_TOLERANCE_PCT, Tolerances

#: CSS class of each verdict in the summary card
_VERDICT_CLASS = {
    summary.DEGRADED: "v-degraded",
    summary.WITHIN: "v-within",
    summary.NOT_IDENTIFIABLE: "v-unknown",
    summary.NOT_IDENTIFIED: "v-unknown",
}
#: the card lists what is wrong first
_ORDER = {
    summary.DEGRADED: 0,
    summary.NOT_IDENTIFIABLE: 1,
    summary.NOT_IDENTIFIED: 1,
    summary.WITHIN: 2,
}


def summary_card(doc: Doc, run: Path, read: list | None = None) -> None:
    """The answer in the first screen: wagon, recordings, per-element verdicts, forces
    (``read``: the run's field recordings, where the caller has them already)."""
    est = summary.estimate_table(run)
    tol = summary.run_tolerances(run)
    recs = summary.recordings(run, read)
    synthetic = summary.is_synthetic(run)
    with_track = bool(len(recs)) and bool(recs.measured_track.all())
    rec_text = "; ".join(
        f"{r.recording} ({r.condition}, wheel {r.wheel}, {summary.sig3(r.duration_s)} s)"
        for r in recs.itertuples()
    )
    rec_kind = ("synthetic, from a hidden truth" if synthetic else "measured") + (
        ", with their measured track geometry" if with_track else ", without track geometry"
    )
    est = est.assign(_order=[_ORDER.get(v, 3) for v in est.verdict]).sort_values(
        "_order", kind="stable"
    )
    bases = {b for b in est.interval if b}
    short = "Pareto range" if not bases or any("Pareto" in b for b in bases) else "90 % interval"
    shown = pd.DataFrame(
        {
            "suspension element": [f"{p} {e}" for p, e in zip(est.index, est.element, strict=True)],
            "unit": est.unit,
            "nominal": est.nominal,
            "estimate": [
                v if not str(vd).startswith(summary.NOT_ESTIMATED) else float("nan")
                for v, vd in zip(est.estimate, est.verdict, strict=True)
            ],
            f"interval ({short})": [
                "" if lo != lo else f"{summary.sig3(lo)} – {summary.sig3(hi)}"
                for lo, hi in zip(est.low, est.high, strict=True)
            ],
            "change from nominal (%)": [
                c if not str(vd).startswith(summary.NOT_ESTIMATED) else float("nan")
                for c, vd in zip(est.change_pct, est.verdict, strict=True)
            ],
            "verdict": [
                v + (f" ({n})" if n and v in (summary.WITHIN, summary.DEGRADED) else "")
                for v, n in zip(est.verdict, est.note, strict=True)
            ],
        }
    )
    if "polished" in est:  # NSGA-II's estimate stays the estimate; the polish beside it
        shown.insert(4, "simulator polish", est.polished.to_numpy())
    classes = [_VERDICT_CLASS.get(v, "v-held") for v in est.verdict]
    why = verdict_notes(est)
    tol_text = tolerance_text(tol)
    held: dict[str, list[str]] = {}
    for p, v, n in zip(est.index, est.verdict, est.note, strict=True):
        if str(v).startswith(summary.NOT_ESTIMATED):
            held.setdefault(n, []).append(p)
    held_text = "; ".join(f"{', '.join(ps)}: {n}" for n, ps in held.items())
    basis = "; ".join(sorted(bases)) or "none"
    lines = summary.agreement_lines(summary.force_agreement(run))
    parts = [
        "<section class='card' id='summary'>",
        "<h2>Answer: the suspension of this wagon, from these recordings</h2>",
        f"<p><b>Wagon</b>: {html.escape(summary.wagon_name(run))}. <b>Recordings</b> "
        f"({html.escape(rec_kind)}): {html.escape(rec_text)}.</p>",
        table_html(shown, headers=False, row_class=classes),
        f"<p class='note'>Interval: {html.escape(basis)}. {html.escape(tol_text)}."
        + "".join(f" {html.escape(line)}" for line in why)
        + (f" Not estimated ({html.escape(held_text)})." if held else "")
        + "</p>",
        "<p><b>Force error, nominal → estimated parameters</b></p><ul>",
        *(f"<li>{html.escape(line)}</li>" for line in lines),
        "</ul></section>",
    ]
    md = [
        "\n## Answer: the suspension of this wagon, from these recordings\n",
        md_paragraph(f"Wagon: {summary.wagon_name(run)}. Recordings ({rec_kind}): {rec_text}.")
        + "\n",
        md_row(list(shown.columns)),
        "|" + "---|" * len(shown.columns),
        *(
            md_row([summary.sig3(v) if isinstance(v, float) else str(v) for v in r])
            for r in shown.itertuples(index=False)
        ),
        "",
        md_paragraph(
            f"Interval: {basis}. {tol_text}."
            + "".join(f" {line}" for line in why)
            + (f" Not estimated ({held_text})." if held else "")
        ),
        "",
        "Force error, nominal → estimated parameters:\n",
        *(f"- {md_text(line)}" for line in lines),
        "",
    ]
    doc.raw("\n".join(parts), "\n".join(md))


def verdict_notes(est: pd.DataFrame) -> list[str]:
    """The card's sentences on the parameters that are not identified, one per verdict and
    named by it (:data:`~railsusp.summary.NOT_IDENTIFIED`: this route gave no interval that
    identifies them; :data:`~railsusp.summary.NOT_IDENTIFIABLE`: the recordings do not fix
    them), each parameter with its reason; both were listed under "Not identified"."""
    out = []
    for verdict, label in _VERDICT_SENTENCE.items():
        why = [
            f"{p}: {n}"
            for p, v, n in zip(est.index, est.verdict, est.note, strict=True)
            if v == verdict
        ]
        if why:
            out.append(f"{label}: {'; '.join(why)}.")
    return out


#: how :func:`verdict_notes` opens each verdict's sentence
_VERDICT_SENTENCE = {
    summary.NOT_IDENTIFIED: "Not identified by this route (it gives no confidence interval; "
    "the recordings may still fix them)",
    summary.NOT_IDENTIFIABLE: "Not identifiable from these recordings",
}


def tolerance_text(tol: Tolerances) -> str:
    """The summary card's sentence on the verdicts' tolerances, each number with its source:
    the wagon data's ``[tolerances]`` table, or railsusp's default
    (:data:`~railsusp.suspension_tolerances.DEFAULT_TOLERANCE_PCT`) where the table is absent
    or gives no ``default_pct`` (the default was once named beside the wagon's, as if it were
    the wagon's own)."""
    default = summary.sig3(tol.default_pct)
    listed = ", ".join(f"{p} ±{summary.sig3(v)} %" for p, v in tol.parameters.items())
    text = f"Within tolerance: change from nominal at most ±{default} %"
    in_brackets = f" ({listed})" if listed else ""
    if not tol.from_wagon:
        return (
            text + in_brackets + ", railsusp's default (the wagon data give no [tolerances], "
            "docs/wagon-data.md)"
        )
    if tol.default_pct != DEFAULT_TOLERANCE_PCT:  # the table's own default_pct
        return text + in_brackets + ", all from the wagon data's [tolerances] (docs/wagon-data.md)"
    return (  # railsusp's default, unless the table's default_pct happens to repeat it
        text
        + (f" ({listed}, from the wagon data's [tolerances])" if listed else "")
        + f"; ±{default} % is railsusp's default, which the wagon data's [tolerances] "
        "keep (docs/wagon-data.md)"
    )
