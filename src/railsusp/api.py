"""The Python entry points: ``railsusp.run(config, out=...)`` runs the whole method and
``railsusp.open_run(path)`` opens a finished run directory; both give a :class:`RunResult`,
whose tables and figures read the run directory (the same tables the report shows).

This module makes or opens the run directory and checks the arguments; reading it is
:mod:`railsusp.run_result`'s :class:`RunResult` (importable from here too, as documented).

>>> result = railsusp.open_run("runs/demo")           # doctest: +SKIP
>>> result.estimate[["estimate", "low", "high", "unit", "verdict"]]  # doctest: +SKIP
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from railsusp.errors import RailsuspInputError
from railsusp.pipeline_state import read_run_state
from railsusp.run_result import RunResult as RunResult  # documented as railsusp.api.RunResult
from railsusp.run_result import check_tolerances
from railsusp.run_revision import outdated_model
from railsusp.suspension_tolerances import Tolerances as Tolerances  # railsusp.Tolerances

__all__ = ["OutdatedModelWarning", "RunResult", "Tolerances", "open_run", "run"]


class OutdatedModelWarning(UserWarning):
    """:func:`open_run` of a run directory made with other force laws than this railsusp
    simulates: its tables are read as they are (a record of that model), but ``railsusp
    run`` on the folder would simulate every stage again."""


def open_run(path: str | Path, *, tolerances: Tolerances | None = None) -> RunResult:
    """A finished (or partly finished) run directory, read. One made with other force laws
    than this railsusp simulates (:attr:`RunResult.model_revision`) is read all the same,
    with an :class:`OutdatedModelWarning` naming both revisions: ``railsusp run`` on it
    would simulate every stage again."""
    if not isinstance(path, str | os.PathLike):
        raise RailsuspInputError(f"path = {path!r}: a run directory (str or Path) is needed")
    check_tolerances(tolerances)
    path = Path(path).resolve()
    if not (path / "pipeline.json").is_file():
        raise RailsuspInputError(f"{path}: not a run directory (no pipeline.json)")
    read_run_state(path, str(path))
    result = RunResult(path, tolerances)
    outdated = outdated_model(path)
    if outdated:  # read all the same: old runs are kept as records of what they found
        warnings.warn(outdated, OutdatedModelWarning, stacklevel=2)
    return result


def _rechecked(config: Any) -> Any:
    """A :class:`~railsusp.pipeline_config.PipelineConfig` checked again as its constructor
    and the configuration checks would: ``model_copy(update=...)``, the way to change one
    setting of a frozen model, checks nothing (``pop_size = 2`` failed the estimate stage
    after four stages had run; a plain dict for a section failed with an AttributeError)."""
    from pydantic import ValidationError

    from railsusp.config import check_config, validation_message
    from railsusp.pipeline_config import PipelineConfig

    with warnings.catch_warnings():  # a section given as a dict: serialised as it is
        warnings.simplefilter("ignore", UserWarning)
        doc = config.model_dump(exclude_unset=True)
    try:
        cfg = PipelineConfig.model_validate(doc)
    except ValidationError as exc:
        raise RailsuspInputError(validation_message("configuration", exc, PipelineConfig)) from None
    check_config(cfg, "configuration")
    return cfg


def run(
    config: str | Path | Mapping[str, Any] | Any,
    out: str | Path | None = None,
    *,
    start_from: str | None = None,
    progress: Callable[[str, str], None] | None = None,
) -> RunResult:
    """Run the whole method (stages that are up to date are skipped) and open the result.

    ``config``: a pipeline TOML path, a :class:`~railsusp.pipeline_config.PipelineConfig`, or a
    dict of the same sections; ``out``: the run directory (default ``runs/<TOML stem>``).
    """
    from railsusp.pipeline import run_pipeline
    from railsusp.pipeline_config import PipelineConfig, config_path, load_config

    if out is not None and not isinstance(out, str | os.PathLike):
        raise RailsuspInputError(f"out = {out!r}: a folder path (str or Path) is needed")
    if progress is not None and not callable(progress):
        raise RailsuspInputError(f"progress = {progress!r}: a function (stage, message) or None")
    source = "configuration"
    if isinstance(config, PipelineConfig):
        cfg = _rechecked(config)
    elif isinstance(config, Mapping):  # the sections of a TOML file: checked as strictly
        from pydantic import ValidationError

        from railsusp.config import check_config, validation_message
        from railsusp.input_checks import validate_document

        if not config:  # an empty file is refused; so is an empty dict (the whole default)
            raise RailsuspInputError(
                "configuration: an empty dict; accepted at least one setting or section "
                "(examples/quick.toml; `railsusp demo` runs the default without one)"
            )
        try:
            cfg = validate_document(PipelineConfig, dict(config))
        except ValidationError as exc:
            raise RailsuspInputError(
                validation_message("configuration", exc, PipelineConfig)
            ) from None
        except (TypeError, ValueError) as exc:  # a value or a key JSON cannot hold
            raise RailsuspInputError(f"configuration: {exc}") from None
        check_config(cfg, "configuration")
    elif isinstance(config, str | Path):
        cfg = load_config(config)
        source = str(config_path(config))  # its errors name the file, as load_config's do
        out = out if out is not None else Path("runs") / Path(config).stem
    else:
        raise RailsuspInputError(
            f"config: a TOML path, a PipelineConfig or a dict, not {type(config).__name__}"
        )
    if out is None:
        raise RailsuspInputError("out: the run directory is needed for a configuration object")
    run_pipeline(
        cfg,
        out,
        start_from=start_from,
        progress=progress,
        options=("out", "start_from"),
        checked=cfg is not config,  # a file or a dict: load_config or the lines above checked it
        source=source,
    )
    return open_run(out)
