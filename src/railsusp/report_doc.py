"""The report's document: sections, tables and figures collected once and written as a
self-contained HTML page (figures embedded) and a Markdown twin (figures linked).

Tables follow one convention: readable headers with units, errors in %, three significant
figures, and a wrapper that scrolls sideways inside the page when a table is wider than it.
"""

from __future__ import annotations

import base64
import html
import re
from pathlib import Path

import pandas as pd

from railsusp.numbers import sig3

CSS = """body{font-family:system-ui,sans-serif;max-width:1100px;margin:0 auto;padding:.5em 1em;
color:#222}table{border-collapse:collapse;margin:.4em 0;font-size:.9em}
td,th{border:1px solid #ccc;padding:2px 7px;text-align:right}th{background:#f2f2f2}
td:first-child,th:first-child{text-align:left}td.text,th.text{text-align:left}
.scroll{max-width:100%;overflow-x:auto}img{max-width:100%;border:1px solid #eee}
h1{font-size:1.35em;margin:.3em 0}h2{border-bottom:2px solid #ddd;padding-bottom:.2em;
margin-top:2em}.note{color:#555}figcaption{color:#555;font-size:.9em}
.card{border:2px solid #345;border-radius:6px;padding:.3em .8em .5em;background:#f8fafc}
.card h2{margin:.2em 0 .3em;border:none;font-size:1.15em}.card p{margin:.25em 0}
.card table{font-size:.82em;margin:.3em 0}.card td,.card th{padding:1px 6px}
.card ul{margin:.2em 0;padding-left:1.2em;font-size:.9em}
.v-degraded{color:#a40000;font-weight:bold}.v-within{color:#176317}
.v-unknown{color:#8a5a00}.v-held{color:#666}"""

#: marks every image that decoded (``data-ok="true"``), for the headless-browser test
IMG_CHECK = (
    "<script>window.addEventListener('load',()=>{for(const i of "
    "document.images){i.dataset.ok=String(i.complete&&i.naturalWidth>0)}});</script>"
)

#: readable headers for the columns of the run directory's tables
HEADERS = {
    "parameter": "parameter",
    "unit": "unit",
    "initial": "nominal",
    "estimated": "estimate",
    "nsga_estimate": "NSGA-II's estimate",
    "polished": "simulator polish",
    "polish_standard_error_pct_range": "polish standard error (% of range)",
    "pareto_spread_pct_range": "Pareto spread (% of range)",
    "seed_spread_pct_range": "spread over seeds (% of range)",
    "standard_error_pct_range": "standard error (% of range)",
    "refinement_standard_error_pct_range": "of it noise and geometry (% of range)",
    "geometry_error_pct_range": "of which track geometry (% of range)",
    "nsga_choice": "NSGA-II's choice, before the geometry bias or expected-forces polish",
    "geometry_bias_pct_range": "track geometry error's bias (% of range)",
    "geometry_scatter_pct_range": "track geometry error's scatter (% of range)",
    "cramer_rao_pct_range": "Cramér-Rao bound (% of range)",
    "measured_kN": "measured (kN)",
    "before_kN": "nominal parameters (kN)",
    "before_error": "error, nominal (%)",
    "after_kN": "estimate (kN)",
    "after_error": "error, estimate (%)",
    "truth_kN": "true parameters (kN)",
    "truth_error": "error, true parameters (%)",
    "error_pct_of_value": "error (% of value)",
    "error_pct_of_range": "error (% of range)",
    "why_not": "why not identified",
    "identified": "identified",
    # recovery.csv's older name of 'identified' (the name said more than it held)
    "identifiable": "identified (older column 'identifiable')",
    "role": "role in this run",
    "verdict": "verdict",
    "interval_low": "interval low",
    "interval_high": "interval high",
    "interval_width_pct_range": "interval width (% of range)",
    "interval_method": "interval",
    "truth_in_interval": "truth in interval",
    "our_rank": "our rank",
    "our_max_ST": "our largest total index ST",
    "where": "where (feature)",
    "ours_key": "key parameter (ours)",
    "study_lateral": "key in the study (lateral)",
    "study_vertical": "key in the study (vertical)",
    "n_gen": "generation",
    "n_eval": "evaluations",
    "n_nds": "non-dominated",
    "eps": "ε (change of front)",
    "indicator": "indicator",
}


def header(column: str) -> str:
    """A readable column header: the table above, else snake_case words with units."""
    if column in HEADERS:
        return HEADERS[column]
    text = re.sub(r"_pct(_|$)", r" (%)\1", column)
    text = re.sub(r"(_| )kN$", " (kN)", text)
    text = re.sub(r" %$", " (%)", text)
    text = re.sub(r"_s$", " (s)", text)
    return text.replace("_", " ")


def fraction_errors_to_pct(df: pd.DataFrame) -> pd.DataFrame:
    """Columns ``*_error`` hold fractions in the run directory; the report shows %."""
    df = df.copy()
    for c in df.columns:
        if c.endswith("_error"):
            df[c] = 100.0 * df[c]
    return df


def cell(v: object) -> str:
    """One table cell as text: numbers to three significant figures, blanks for missing."""
    if v is None:
        return ""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return sig3(v)
    return str(v)


#: characters that start Markdown inline syntax (emphasis, code, links, images, HTML, raw
#: HTML entities, strikethrough, headings' closing marks), each escaped by a backslash
#: except ``<``, ``>`` and ``&``, which become HTML entities (a backslash does not stop a
#: renderer from reading ``<img ...>`` as HTML in every Markdown dialect); a ``]`` only
#: where a link, an image or a link's definition would follow (``](``, ``][``, ``]:``):
#: "[tolerances]" alone is text
_MD_ENTITIES = {"&": "&amp;", "<": "&lt;", ">": "&gt;"}
_MD_SPECIAL = re.compile(r"[\\`*#~&<>_]|\](?=[(\[:])")


def md_text(text: str) -> str:
    """``text`` as literal Markdown inline text: ``<``, ``>`` and ``&`` as HTML entities,
    the characters of emphasis, code and headings (``\\ ` * _ # ~``) escaped by a
    backslash, ``_`` only where it could start or end emphasis (not inside a word:
    ``remove_geometry_bias`` stays as it is), and a ``]`` that would close a link or an
    image (``[x](javascript:...)``). The report's texts hold no Markdown of their
    own; a run's name, a wagon's, a recording's or a condition's (the user's) was written
    through unescaped, so ``name = "<img src=x onerror=alert(1)>"`` made raw HTML in
    report.md (report.html escapes it with :func:`html.escape`, from the unescaped text:
    neither is escaped twice)."""

    def escape(m: re.Match) -> str:
        ch = m.group()
        if ch in _MD_ENTITIES:
            return _MD_ENTITIES[ch]
        if ch == "_":
            before = text[m.start() - 1] if m.start() > 0 else ""
            after = text[m.end()] if m.end() < len(text) else ""
            if before.isalnum() and after.isalnum():  # intraword: no emphasis there
                return ch
        return "\\" + ch

    return _MD_SPECIAL.sub(escape, text)


def md_paragraph(text: str) -> str:
    """``text`` as one literal Markdown paragraph (:func:`md_text`): its line breaks made
    spaces (as the HTML page shows them; a blank line ended the paragraph), and a start that
    would make it a list item (``- ``, ``+ ``, ``1. ``) escaped."""
    out = re.sub(r"\s*[\r\n]+\s*", " ", md_text(text))
    m = re.match(r"\s*(?:[-+]|\d{1,9}[.)])(?=\s|$)", out)
    if m:  # the backslash before the marker's last character: "\-", "1\."
        return out[: m.end() - 1] + "\\" + out[m.end() - 1 :]
    return out


def md_cell(text: str) -> str:
    """One cell of a Markdown table row as literal text (:func:`md_text`): a ``|`` inside it
    escaped (``\\|``) and a line break made a space, so that neither ends the cell or the row
    (the validation's "mean of |Y|" shifted every later column of its row under the wrong
    header)."""
    return re.sub(r"\s*[\r\n]+\s*", " ", md_text(text)).replace("|", "\\|")


def md_row(cells: list[str]) -> str:
    """A Markdown table row of the texts ``cells`` (:func:`md_cell`)."""
    return "| " + " | ".join(md_cell(c) for c in cells) + " |"


class Doc:
    """Collects sections; renders HTML (embedded images) and Markdown (linked images)."""

    def __init__(self, root: Path):
        self.root = root
        self.html: list[str] = []
        self.md: list[str] = []
        self.figures: list[Path] = []

    def h(self, text: str, level: int = 2) -> None:
        self.html.append(f"<h{level}>{html.escape(text)}</h{level}>")
        self.md.append(f"\n{'#' * level} {md_cell(text)}\n")  # one line, literal

    def p(self, text: str) -> None:
        self.html.append(f"<p class='note'>{html.escape(text)}</p>")
        self.md.append(f"{md_paragraph(text)}\n")

    def raw(self, html_text: str, md_text: str) -> None:
        """Pre-rendered HTML and its Markdown, each escaped by the caller (:func:`html.escape`;
        :func:`md_text`, :func:`md_row`)."""
        self.html.append(html_text)
        self.md.append(md_text)

    def table(self, df: pd.DataFrame, headers: bool = True) -> None:
        """A table with readable headers (:func:`header`), scrolling inside its wrapper."""
        self.html.append(table_html(df, headers))
        self.md.append(md_row([header(c) if headers else str(c) for c in df.columns]))
        self.md.append("|" + "---|" * len(df.columns))
        for r in df.itertuples(index=False):
            self.md.append(md_row([cell(v) for v in r]))
        self.md.append("")

    def figure(self, path: Path, caption: str) -> None:
        if not path.exists():
            self.p(f"(figure missing: {path.name})")
            return
        data = base64.b64encode(path.read_bytes()).decode()
        self.html.append(
            f"<figure><img alt='{html.escape(caption)}' "
            f"src='data:image/png;base64,{data}'><figcaption>"
            f"{html.escape(caption)}</figcaption></figure>"
        )
        target = path.relative_to(self.root).as_posix()
        # every bracket of the alt text escaped: a lone "]" ended the image's text early
        alt = re.sub(r"(?<!\\)([\[\]])", r"\\\1", md_cell(caption))
        self.md.append(f"![{alt}](<{target}>)\n")
        self.figures.append(path)

    def page(self, title: str) -> str:
        return (
            "<!doctype html><html><head><meta charset='utf-8'>"
            "<meta name='viewport' content='width=device-width, initial-scale=1'>"
            f"<title>{html.escape(title)}</title><style>{CSS}</style></head><body>"
            + "\n".join(self.html)
            + IMG_CHECK
            + "</body></html>"
        )


def table_html(df: pd.DataFrame, headers: bool = True, row_class: list[str] | None = None) -> str:
    """The HTML of a table inside a sideways-scrolling wrapper; text columns left-aligned;
    ``row_class`` gives each row's last cell a CSS class (the verdicts)."""
    text_cols = [not pd.api.types.is_numeric_dtype(df[c]) for c in df.columns]
    head = "".join(
        f"<th{' class=text' if t else ''}>{html.escape(header(c) if headers else str(c))}</th>"
        for c, t in zip(df.columns, text_cols, strict=True)
    )
    rows = []
    for i, r in enumerate(df.itertuples(index=False)):
        cells = []
        for k, (v, t) in enumerate(zip(r, text_cols, strict=True)):
            cls = " class=text" if t else ""
            if row_class is not None and k == len(r) - 1 and row_class[i]:
                cls = f" class='text {row_class[i]}'"
            cells.append(f"<td{cls}>{html.escape(cell(v))}</td>")
        rows.append("<tr>" + "".join(cells) + "</tr>")
    return f"<div class='scroll'><table><tr>{head}</tr>{''.join(rows)}</table></div>"
