"""The pipeline's configuration: the whole of a run's TOML as one pydantic model
(:class:`PipelineConfig`), reading and validating a file (:func:`load_config`), and the
embedded demo (:func:`demo_config`).

Its sections, ``[campaign]`` to ``[estimate]``, are the models of
:mod:`railsusp.config_sections`, each typing and range-checking its fields and refusing
unknown keys; :mod:`railsusp.config` adds the checks of the configuration as a whole. The
stages that run it are in :mod:`railsusp.pipeline`, which imports this module and re-exports
:class:`PipelineConfig`, :func:`load_config` and :func:`demo_config`; this module imports
nothing of the pipeline, so imports flow one way and a configuration can be read without
loading the stages.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from pydantic import Field, ValidationError, field_validator

from railsusp.conditions import WorkingCondition, get_condition, make_condition
from railsusp.config_sections import (
    CampaignSection,
    EstimateSection,
    FieldSection,
    SensitivitySection,
    StrictConfigModel,
    SurrogateSection,
    not_empty,
)
from railsusp.errors import ConditionError, RailsuspInputError


class PipelineConfig(StrictConfigModel):
    """The whole configuration of a run (examples/quick.toml, examples/study.toml)."""

    name: str = "railsusp run"
    wagon: str | None = Field(None, description="wagon data TOML (default: C80/K6)")
    conditions: tuple[str | dict[str, Any], ...] = ("straight", "curve", "uphill")
    campaign: CampaignSection = CampaignSection()
    sensitivity: SensitivitySection = SensitivitySection()
    surrogate: SurrogateSection = SurrogateSection()
    field: FieldSection = FieldSection()
    estimate: EstimateSection = EstimateSection()
    scheduler: str | None = Field(None, description="Dask scheduler tcp://host:port")

    @field_validator("name")
    @classmethod
    def _one_line_name(cls, v: str) -> str:
        """The report's title: one line of printable text (an empty name titled the report
        with nothing, a newline split every line that names the run)."""
        if not v.strip() or not v.isprintable() or len(v) > 200:
            raise ValueError(f"{v!r}: accepted one line of printable text, 1 to 200 characters")
        return v

    @field_validator("wagon", mode="before")
    @classmethod
    def _wagon_path(cls, v: Any) -> Any:
        """A ``Path`` stands for the file's string (as in ``railsusp.run``'s dicts); an empty
        string is refused (it was read as the working folder)."""
        return not_empty(
            os.fspath(v) if isinstance(v, os.PathLike) else v,
            "a wagon data TOML or a packaged name (loaded, tare)",
        )

    @field_validator("conditions", mode="before")
    @classmethod
    def _condition_objects(cls, v: Any) -> Any:
        """A :class:`~railsusp.conditions.WorkingCondition` stands for its fields (what
        ``railsusp.get_condition`` returns, accepted by ``railsusp.run``'s dicts; the
        constructor refused it with pydantic's seven-line error)."""
        if isinstance(v, list | tuple):
            return tuple(
                c.model_dump(mode="json", exclude_none=True)
                if isinstance(c, WorkingCondition)
                else c
                for c in v
            )
        return v

    def run_source(self) -> Any:
        """The long run of ``[field] recording`` and how to cut it
        (:class:`~railsusp.measured.cut.RunSource`), or None."""
        from railsusp.pipeline_field import run_source

        return run_source(self.field, self.wagon)

    def working_conditions(self) -> list[WorkingCondition]:
        """The conditions of the run: those given, or with ``[field] recording`` the kept
        sections' conditions of the recording (:mod:`railsusp.measured.cut`); their values
        validated strictly (:func:`railsusp.conditions.make_condition`)."""
        source = self.run_source()
        if source is not None:
            from railsusp.measured.cut import section_conditions

            return section_conditions(source)
        out = []
        for c in self.conditions:
            if isinstance(c, str):
                try:
                    out.append(get_condition(c))
                except ConditionError as exc:  # a file's name: its tables go in the list
                    raise ConditionError(
                        f'{exc}, or a table such as {{base = "curve", name = "tight", '
                        "curve_radius_m = 250} (docs/conditions.md)"
                    ) from None
            else:
                fields = dict(c)
                base = fields.pop("base", None)
                start = get_condition(base).model_dump() if base else {}
                out.append(make_condition({**start, **fields}))
        return out


#: the configurations shipped in the package (``data/examples/``, the repository's
#: ``examples/``), which :func:`load_config` takes by name (``railsusp run quick``): an
#: installed railsusp had none of the files its help and docs name
EXAMPLE_CONFIGS = ("quick", "pretrained", "study", "tiny")


def config_path(path: str | Path) -> Path:
    """The configuration file ``path`` names: itself, or the packaged example of that name
    (:data:`EXAMPLE_CONFIGS`) where it is one and no file of the name is there (a folder
    of the name, such as the run directory of `railsusp run tiny --out tiny`, is none)."""
    from importlib import resources

    if str(path) in EXAMPLE_CONFIGS and not Path(path).is_file():
        return Path(str(resources.files("railsusp").joinpath(f"data/examples/{path}.toml")))
    return Path(path)


def load_config(path: str | Path) -> PipelineConfig:
    """Read and validate a pipeline TOML, or the packaged example ``path`` names
    (:func:`config_path`); errors name the field (one line)."""
    from railsusp.config import check_config, read_config, validation_message
    from railsusp.input_checks import validate_document

    path = config_path(path)
    if not path.exists():
        raise RailsuspInputError(
            f"configuration {path} does not exist; accepted a pipeline TOML file or a "
            f"packaged example's name ({', '.join(EXAMPLE_CONFIGS)}: `railsusp run quick`)"
        )
    try:
        cfg = validate_document(PipelineConfig, read_config(path))
    except ValidationError as exc:
        raise RailsuspInputError(validation_message(path, exc, PipelineConfig)) from None
    cfg = _beside(cfg, path.parent)
    check_config(cfg, str(path))
    return cfg


#: ``[field]`` files of a long run, named relative to the configuration file's folder
RUN_FILES = ("recording", "channel_map", "line", "sections")


def _beside(cfg: PipelineConfig, folder: Path) -> PipelineConfig:
    """``cfg`` with the long run's relative file names resolved against ``folder`` (the
    configuration file's), so that a configuration travels with its recording."""
    update = {
        k: str(folder / v)
        for k in RUN_FILES
        if (v := getattr(cfg.field, k)) is not None and not Path(v).is_absolute()
    }
    if not update:
        return cfg
    return cfg.model_copy(update={"field": cfg.field.model_copy(update=update)})


#: the hidden truth of the demo: a degraded wagon (display units)
DEMO_TRUTH = {
    "X11": 1.3,
    "X13": 16.1,
    "X14": 8.3,
    "X15": 164.0,
    "X16": 1.7,
    "X17": 1.91,
    "X18": 51.3,
}


def demo_config() -> PipelineConfig:
    """The embedded default (identical to examples/quick.toml, checked by a test)."""
    return PipelineConfig(
        name="quick demo: C80/K6, synthetic field data of a degraded wagon",
        # the study's CNN-GRU trained on many tracks, shipped: nothing trained in the demo
        surrogate=SurrogateSection(model="cnn-gru-seq", pretrained="c80_k6"),
        field=FieldSection(truth=DEMO_TRUTH, with_track=True),
        estimate=EstimateSection(refine=True),
    )
