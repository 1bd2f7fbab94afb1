"""A run directory, read: :class:`RunResult`, whose tables and figures read the run
directory that :func:`railsusp.api.open_run` and :func:`railsusp.api.run` open (the same
tables the report shows), each only where the stage that wrote it is done and its files are
unchanged.

It is apart from :mod:`railsusp.api`, the entry points that make or open a run directory
and check their arguments: this module only reads one (``railsusp.RunResult`` and
``railsusp.api.RunResult`` stay the documented names).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

import railsusp.summary as summary
from railsusp.errors import RailsuspInputError
from railsusp.integrity import changed_files
from railsusp.pipeline_state import STAGES, read_run_state
from railsusp.run_revision import revision_records
from railsusp.store import read_csv, read_json, read_parquet
from railsusp.suspension_tolerances import Tolerances


@dataclass(frozen=True)
class RunResult:
    """A run directory, read: the estimate with intervals and verdicts, the validation, the
    sensitivity, the surrogates' accuracy, the report; ``plot_*`` draw them.

    ``tolerances`` overrides the wagon data's
    (:func:`railsusp.suspension_tolerances.read_tolerances`).
    """

    path: Path
    tolerances: Tolerances | None = None

    def __post_init__(self) -> None:
        """``RunResult(path)`` built directly takes a str as open_run does (open_run also
        checks that the folder is a run directory)."""
        if not isinstance(self.path, str | os.PathLike):
            raise RailsuspInputError(f"path = {self.path!r}: a run directory (str or Path)")
        check_tolerances(self.tolerances)
        object.__setattr__(self, "path", Path(self.path))

    def _need(self, rel: str, stage: str) -> Path:
        """``rel``, an output of ``stage``, where pipeline.json says that stage is done and
        the files it recorded then are there with their sizes and SHA-256 (by size alone in a
        run made before hashes were recorded): a stage that failed, was interrupted or is
        stale (a stage it reads ran again after it) left the outputs of an older run, and a
        file edited since (a number changed in place, its size kept) is no longer what the
        run wrote; neither is this run's answer."""
        p = self.path / rel
        if not p.exists():
            entry = (
                self._stage_entries().get(stage) if (self.path / "pipeline.json").exists() else None
            )
            why = (  # a standalone estimate --out RUN/estimate drops the validation (QA, stop 73)
                "it is gone although pipeline.json records the stage done (a command run "
                "on the folder since removed it)"
                if entry and entry.get("state") == "done" and rel in (entry.get("files") or {})
                else f"the {stage} stage has not run"
            )
            raise RailsuspInputError(f"{self.path}: no {rel}; {why} ({self._resume()})")
        self._check_stage(stage)
        for earlier in self._read_by(stage) if stage in STAGES else ():
            try:
                self._check_stage(earlier)
            except RailsuspInputError as exc:
                raise RailsuspInputError(
                    f"{exc}; {rel} was made from that stage's outputs, so it is not this "
                    "run's answer either"
                ) from None
        return p

    def _read_by(self, stage: str) -> list[str]:
        """The stages whose outputs ``stage`` read, directly or through another
        (:func:`~railsusp.pipeline_inputs.stage_inputs`, by the configuration pipeline.json
        recorded): an estimate's table was read without a word after the field stage's
        recordings changed, which ``report_path`` and ``railsusp run`` found (the QA of
        stop 73)."""
        from railsusp.pipeline_inputs import stage_inputs_trained

        surrogate = self._config().get("surrogate")
        trained = not (isinstance(surrogate, dict) and surrogate.get("pretrained"))
        seen, todo = [], [stage]
        while todo:
            for s in stage_inputs_trained(trained, todo.pop()):
                if s not in seen:
                    seen.append(s)
                    todo.append(s)
        return sorted(seen, key=STAGES.index)

    def _resume(self) -> str:
        """The command that makes the run directory's stages again."""
        return f"railsusp run CONFIG --out {self.path}"

    def _check_stage(self, stage: str) -> None:
        """:meth:`_need`'s check of ``stage`` in pipeline.json: done, its recorded files
        unchanged (a stage without a record passes: a run that lost it)."""
        resume = self._resume()
        entry = self._stage_entries().get(stage)
        if entry is None:  # a run that lost its pipeline.json's record of it
            return
        state = entry.get("state")
        if state != "done":
            why = {
                "failed": f"failed ({entry.get('error', 'no message')})",
                "running": "was interrupted (or is running now)",
                "stale": "is stale: a stage whose outputs it reads ran again after it",
            }.get(state, f"is {state!r}")
            raise RailsuspInputError(
                f"{self.path}: the {stage} stage {why}; its files are an older run's ({resume})"
            )
        changed = changed_files(
            entry.get("files") or {}, self.path, entry.get("sha256"), entry.get("mtime_ns")
        )
        if changed:
            raise RailsuspInputError(
                f"{self.path}: {changed[0].relative_to(self.path)} changed or is gone since the "
                f"{stage} stage wrote it ({resume} writes it again)"
            )

    def _stage_entries(self) -> dict[str, dict]:
        """pipeline.json's table of stages, its structure checked
        (:func:`~railsusp.pipeline_state.check_run_state`: each entry a table, its files'
        tables of paths inside the run directory)."""
        return read_run_state(self.path, str(self.path))["stages"]

    @property
    def estimate(self) -> pd.DataFrame:
        """One row per main suspension parameter (index: symbol), display units: element,
        unit, nominal, estimate, standard_error, low, high (the interval; ``interval`` says
        how it was formed), change_pct (from nominal), tolerance_pct, verdict, note."""
        self._need("estimate/estimate.json", "estimate")
        return summary.estimate_table(self.path, self.tolerances)

    @property
    def validation(self) -> pd.DataFrame:
        """Force statistics before (nominal) and after (estimate) calibration per condition,
        force and statistic, kN; errors in % of the measured value (``*_error_pct``).
        ``statistic_label`` says what the ``*_kN`` columns of each row hold, as the report
        labels them: the statistic of ``|Y|`` or of ``Q``, or for ``aligned`` rows the
        measured series' standard deviation (``measured_kN``) and the RMS of each
        simulation's sample-by-sample difference from it (the others), their errors that
        RMS over the standard deviation."""
        from railsusp.report_estimate import statistic_label

        df = summary.read_validation(self._need("estimate/validation/validation.csv", "validate"))
        for c in [c for c in df.columns if c.endswith("_error")]:
            df[f"{c}_pct"] = 100.0 * df.pop(c)
        if {"statistic", "force"} <= set(df.columns):
            labels = [
                statistic_label(str(st), str(f))
                for st, f in zip(df.statistic, df.force, strict=True)
            ]
            df.insert(df.columns.get_loc("statistic") + 1, "statistic_label", labels)
        return df

    @property
    def agreement(self) -> pd.DataFrame:
        """Per condition, the lateral and vertical force error (%) before and after."""
        self._need("estimate/validation/validation.csv", "validate")
        return summary.force_agreement(self.path)

    @property
    def recovery(self) -> pd.DataFrame | None:
        """For synthetic recordings (a hidden truth in ``field/truth.json``), the error of
        each estimate against it; None for measured ones. Before the field stage is done
        it is not known which they are: refused as the other tables are (a synthetic run
        stopped in its sensitivity stage answered None, "measured recordings")."""
        if not (self.path / "field" / "truth.json").exists():
            self._need("field/index.json", "field")  # done, its files (no truth) unchanged
            return None
        return read_csv(self._need("estimate/validation/recovery.csv", "validate"))

    @property
    def sensitivity(self) -> pd.DataFrame:
        """Sobol indices (S1, ST with confidence) per condition, force, statistic and
        parameter. Indices stamped with another campaign than the run's (its campaign
        replaced by hand since) are refused in one line."""
        from railsusp.key_parameters import check_sensitivity_output

        p = self._need("campaign/sensitivity/indices.parquet", "sensitivity")
        check_sensitivity_output(p)
        return read_parquet(p, f"railsusp run CONFIG --out {self.path} --from sensitivity")

    @property
    def largest_st(self) -> pd.Series:
        """Each parameter's largest total Sobol index ST as the key-parameter rule ranks them
        (over the rule's statistics, features that hardly vary left out: the report's "our
        largest total index ST"), largest first. The largest ST of :attr:`sensitivity` as a
        whole can differ: it also holds the flat features the rule ignores."""
        kp = self._key_parameters()
        st = pd.Series(kp["max_st"], name="ST", dtype=float)
        return st.rename_axis("parameter").sort_values(ascending=False)

    @property
    def key_parameters(self) -> list[str]:
        """The key parameters of the sensitivity step. The estimate estimates these, except
        where the surrogates fix their own inputs (a shipped network set): then
        :attr:`estimated_parameters` says which it estimated."""
        return list(self._key_parameters()["keys"])

    def _key_parameters(self) -> dict:
        """``key_parameters.json``'s selection, where the sensitivity stage is done and the
        analysis is of the run's campaign (:func:`railsusp.key_parameters
        .read_key_parameters`: one that a campaign replaced by hand left beside it is refused
        in one line; one made before the stamp is read as before)."""
        from railsusp.key_parameters import read_key_parameters

        self._need("campaign/sensitivity/key_parameters.json", "sensitivity")
        return read_key_parameters(self.path / "campaign")["key_parameters"]

    @property
    def estimated_parameters(self) -> list[str]:
        """The parameters the estimate stage estimated (the others held or varied: see
        :attr:`estimate`'s verdicts)."""
        p = self._need("estimate/estimate.json", "estimate")
        return list(read_json(p)["parameters"])

    @property
    def surrogate_accuracy(self) -> pd.DataFrame:
        """The surrogates on held-out simulations (study Table 7 layout, errors in %)."""
        from railsusp.surrogate.compare import table7
        from railsusp.surrogate.pretrained import surrogates_run

        s = self._config().get("surrogate", {})
        base = surrogates_run(s.get("pretrained"), s.get("samples", 0))
        return table7(read_csv(self._need(f"{base}/surrogates/compare.csv", "surrogate")))

    @property
    def stages(self) -> pd.DataFrame:
        """Each stage's state and seconds, from ``pipeline.json``."""
        self._need("pipeline.json", "first")
        st = self._stage_entries()
        order = [s for s in STAGES if s in st] + [s for s in st if s not in STAGES]
        return pd.DataFrame(
            [
                {
                    "stage": k,
                    "state": st[k].get("state"),
                    "seconds": st[k].get("seconds"),
                    "error": st[k].get("error"),
                }
                for k in order
            ],
            columns=["stage", "state", "seconds", "error"],
        )

    @property
    def model_revision(self) -> str | None:
        """The force-law revision the run was made with, as its records state it (the first
        of :data:`railsusp.run_revision.REVISION_RECORDS` that states one: its campaign's,
        where it has run); None where none states one (a run made before they were
        recorded, 2026-11-30, with older force laws than any railsusp that records them).
        Another than :data:`railsusp.vehicle.MODEL_REVISION` means that the tables are of
        another model than this railsusp simulates (:func:`~railsusp.api.open_run` warns)."""
        records = revision_records(self.path)
        return next((r for r in records.values() if r is not None), None)

    @property
    def report_path(self) -> Path:
        """The self-contained HTML report, where it still answers for the run directory: the
        report stage done and its files unchanged, and so each stage it summarises (every
        earlier one, :meth:`_need`'s check of the stages a stage reads): a standalone
        ``railsusp estimate --out RUN/estimate`` left the report presenting the estimate it
        replaced, which :attr:`estimate` refused (the concurrency audit)."""
        return self._need("report.html", "report")

    def _config(self) -> dict:
        """The configuration pipeline.json recorded (checked to be a table); {} without one."""
        p = self.path / "pipeline.json"
        return read_run_state(self.path, str(self.path)).get("config", {}) if p.exists() else {}

    def plot_estimate(self, ax=None):
        """Change from nominal (%) of each estimated element with its interval, against the
        tolerance band; returns the matplotlib Axes."""
        import matplotlib.pyplot as plt
        import numpy as np

        est = self.estimate
        est = est[~est.verdict.str.startswith(summary.NOT_ESTIMATED)]
        _check_axes(ax)
        if ax is None:
            _, ax = plt.subplots(figsize=(7, 0.6 + 0.5 * len(est)), constrained_layout=True)
        y = np.arange(len(est))
        nom = est.nominal.to_numpy()
        lo = 100 * (est.low.to_numpy() - nom) / nom
        hi = 100 * (est.high.to_numpy() - nom) / nom
        c = est.change_pct.to_numpy()
        err = np.vstack([c - lo, hi - c])
        colour = {summary.DEGRADED: "C3", summary.WITHIN: "C2"}
        colours = [colour.get(v, "0.5") for v in est.verdict]
        for i in range(len(est)):
            tol = est.tolerance_pct.iloc[i]
            ax.fill_betweenx([i - 0.4, i + 0.4], -tol, tol, color="0.92", zorder=0)
            ax.errorbar(c[i], i, xerr=err[:, i : i + 1], fmt="o", color=colours[i], capsize=3)
        ax.axvline(0, color="0.4", lw=0.8)
        ax.set_yticks(y, [f"{p} ({u})" for p, u in zip(est.index, est.unit, strict=True)])
        ax.set_xlabel("change from nominal (%); grey: tolerance")
        ax.set_title("Estimate and interval per suspension element", fontsize=10)
        ax.grid(axis="x", alpha=0.3)
        return ax

    def plot_validation(self, ax=None):
        """Force error (%) with the nominal and with the estimated parameters, per condition
        and force; returns the Axes."""
        import matplotlib.pyplot as plt
        import numpy as np

        ag = self.agreement
        _check_axes(ax)
        if ax is None:
            _, ax = plt.subplots(figsize=(7, 3.5), constrained_layout=True)
        labels, before, after = [], [], []
        for r in ag.to_dict(orient="records"):
            for name in ("lateral", "vertical"):
                labels.append(f"{r['condition']} {name}")
                before.append(r.get(f"{name}_before_pct", np.nan))
                after.append(r.get(f"{name}_after_pct", np.nan))
        x = np.arange(len(labels))
        ax.bar(x - 0.2, before, 0.4, label="nominal parameters")
        ax.bar(x + 0.2, after, 0.4, label="estimated parameters")
        ax.set_xticks(x, labels, rotation=30, ha="right")
        ax.set_ylabel("force error (%)")
        ax.legend(fontsize=8)
        ax.grid(axis="y", alpha=0.3)
        return ax

    def plot_sensitivity(self, ax=None):
        """Largest total Sobol index ST of each parameter as the key-parameter rule ranks
        them (:attr:`largest_st`), the parameters the estimate estimated in red, key
        parameters it did not estimate (a shipped network set fixes its own inputs) in
        orange; before the estimate stage is done, the key parameters in red. Returns the
        Axes."""
        import matplotlib.pyplot as plt

        st = self.largest_st
        keys = set(self.key_parameters)
        try:
            estimated = set(self.estimated_parameters)
        except RailsuspInputError:  # no estimate of this run (yet): the key parameters
            estimated = None
        _check_axes(ax)
        if ax is None:
            _, ax = plt.subplots(figsize=(7, 3), constrained_layout=True)
        if estimated is None:
            colours = ["C3" if p in keys else "C0" for p in st.index]
            title = "red: key parameters; no estimate yet"
        else:  # it said "key parameters, estimated" of a key parameter it had not estimated
            colours = ["C3" if p in estimated else "C1" if p in keys else "C0" for p in st.index]
            title = "red: estimated" + (
                "; orange: key parameters not estimated" if keys - estimated else ""
            )
        ax.bar(st.index, st.to_numpy(), color=colours)
        ax.set_ylabel("largest total Sobol index ST (-)")
        ax.set_title(f"Sensitivity ({title})", fontsize=10)
        ax.grid(axis="y", alpha=0.3)
        return ax


def _check_axes(ax: Any) -> None:
    """``ax`` of the plot_* methods: None (a new figure) or one matplotlib Axes."""
    from matplotlib.axes import Axes

    if ax is not None and not isinstance(ax, Axes):
        raise RailsuspInputError(
            f"ax = {ax!r:.60}: accepted one matplotlib Axes (e.g. fig.add_subplot()) or None"
        )


def check_tolerances(tolerances: Any) -> None:
    """``tolerances``: None or a :class:`railsusp.Tolerances` (a dict failed later, deep in
    the summary, with an AttributeError)."""
    if tolerances is not None and not isinstance(tolerances, Tolerances):
        raise RailsuspInputError(
            f"tolerances = {tolerances!r}: a railsusp.Tolerances(default_pct, per_parameter) "
            "is needed"
        )
