"""The report's stale banner: when a stage of a run directory starts again (``railsusp
run``, or a standalone command writing a stage's folder), the report of the run before must
not go on presenting its estimate as the answer while the new run has not finished. A red
banner goes at the top of ``report.html`` and ``report.md``, bracketed by markers so that a
later marking replaces it; writing the report anew
(:func:`railsusp.report_html.build_report`) drops it.
"""

from __future__ import annotations

import html
import re
from pathlib import Path

from railsusp.store import atomic_write_text

#: bracket the stale banner of :func:`mark_report_stale` (in HTML and Markdown alike), so
#: that a later marking replaces it instead of adding a second
STALE_START, STALE_END = "<!-- railsusp:stale -->", "<!-- /railsusp:stale -->"


def stale_text(stage: str, by: str | None = None) -> str:
    """The stale banner's words: why the report no longer answers for the run directory
    and what to do. ``by``: the standalone command (``railsusp estimate``) started on the
    folder of ``stage`` outside ``railsusp run``; running that command again would not
    remake the report, ``railsusp run`` does."""
    if by is not None:
        return (
            f"STALE: `{by}` was started on the outputs of this run directory's stage "
            f"'{stage}' after this report was made, outside `railsusp run`, so the answer "
            "below may no longer be what the run directory holds. `railsusp run` with the "
            "run directory's configuration on this folder makes the changed stages and this "
            "report again (it replaces that command's outputs with the configuration's)."
        )
    return (
        "STALE: this report was made by an earlier run of this run directory, before its "
        f"stage '{stage}' was started again (a changed configuration, changed files or a "
        "restart from a stage). That run has not finished (it is running, failed or was "
        "interrupted), so the answer below is the earlier run's and may not match the run "
        "directory's configuration. Run the same command again to remake the report "
        "(pipeline.json says which stages are stale)."
    )


def mark_report_stale(run: str | Path, stage: str, by: str | None = None) -> list[Path]:
    """Put a stale banner at the top of ``RUN/report.html`` and ``RUN/report.md``, where
    they exist, when ``stage`` starts to run again: the pipeline marks the report stage
    stale then (every later stage runs again), and the files, which the command line points
    to, must not present the run before's estimate as the answer if the run fails or is
    interrupted. ``by``: a standalone command (``railsusp estimate --out RUN/estimate``)
    about to write the stage's outputs instead (:func:`stale_text`). A banner already there
    is replaced; :func:`~railsusp.report_html.build_report` writes the files anew, without
    it. Returns the files marked."""
    run = Path(run)
    text = stale_text(stage, by)
    marked = []
    banners = {
        "report.html": (
            "<div role='alert' style='border:3px solid #a40000;background:#fff0f0;"
            "color:#a40000;font-weight:bold;padding:.5em .8em;margin:.5em 0'>"
            f"{html.escape(text)}</div>"
        ),
        "report.md": f"> **{text}**\n",  # a blank line after it ends the quote
    }
    for name, banner in banners.items():
        path = run / name
        if not path.is_file():
            continue
        old = path.read_text("utf-8", errors="replace")
        old = re.sub(
            re.escape(STALE_START) + r".*?" + re.escape(STALE_END) + r"\n?", "", old, flags=re.S
        )
        block = f"{STALE_START}\n{banner}\n{STALE_END}\n"  # markers on lines of their own
        body = re.search(r"<body[^>]*>", old) if name.endswith(".html") else None
        new = old[: body.end()] + block + old[body.end() :] if body else block + old
        marked.append(atomic_write_text(path, new))
    return marked
