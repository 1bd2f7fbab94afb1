"""Which parameters a campaign's surrogates take as inputs, and which they leave to vary:
the key parameters of the run's sensitivity analysis (or the study's six), the sampled
parameters the surrogates cannot explain, and what an estimate assumed of the parameters
it does not estimate."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from railsusp.errors import RailsuspInputError
from railsusp.params import STUDY_KEY_PARAMETERS
from railsusp.store import read_json
from railsusp.variation import assumed_parameters


def key_parameters(run: str | Path) -> tuple[str, ...]:
    """The run's key parameters from its sensitivity analysis; without one, the study's six
    when the campaign sampled them all, else the campaign's sampled parameters (a campaign
    over chosen parameters, e.g. on a recording's measured track). An analysis made from
    another campaign than the one in ``run`` is refused (its keys are the other's)."""
    from railsusp.key_parameters import read_key_parameters

    p = Path(run) / "sensitivity" / "key_parameters.json"
    if p.exists():
        kp = read_key_parameters(run)["key_parameters"]
        if kp["keys"]:
            return tuple(kp["keys"])
        # none kept: the study's six (or the sampled ones) were estimated and called key
        # parameters (stop 61's API audit); say so and how to get keys instead
        st = kp.get("max_st") or {}
        top = max(st, key=lambda k: st[k]) if st else None
        raise RailsuspInputError(
            f"{p}: the sensitivity analysis kept no key parameter: no total Sobol index "
            f"reached sensitivity.threshold = {kp.get('threshold', '?')}"
            + (f" (the largest: {top} {st[top]:.3g})" if top else "")
            + "; lower the threshold, or vary the parameters more (campaign.samples)"
        )
    camp = Path(run) / "campaign.json"
    if camp.exists():
        sampled = tuple(read_json(camp)["config"]["parameters"])
        if not set(STUDY_KEY_PARAMETERS) <= set(sampled):
            return sampled
    return STUDY_KEY_PARAMETERS


def unexplained_parameters(run: str | Path) -> tuple[str, ...]:
    """Parameters sampled in the run's campaign that its surrogates do not take as inputs,
    when no sensitivity analysis chose the inputs (the study's six are used then): they
    vary from run to run and act as noise the surrogate cannot explain."""
    if (Path(run) / "sensitivity" / "key_parameters.json").exists():
        return ()
    camp = Path(run) / "campaign.json"
    if not camp.exists():
        return ()
    keys = key_parameters(run)
    return tuple(p for p in read_json(camp)["config"]["parameters"] if p not in keys)


def not_estimated(folder: str | Path | None, estimated: Sequence[str]) -> list[dict]:
    """The main-suspension parameters an estimate does not estimate and what its force model
    assumed of them (:func:`railsusp.variation.assumed_parameters`): from a surrogate folder
    (``RUN/surrogates/<model>``, window or statistics bundles; their training campaign when
    the bundles predate the record), or held at nominal for the simulator (``None``)."""
    from railsusp.params import spec

    est = {spec(p).symbol for p in estimated}
    rows = None
    if folder is not None:
        for meta_path in sorted(Path(folder).glob("*/*.json")):
            if meta_path.name not in ("surrogate.json", "statistics.json"):
                continue
            meta = read_json(meta_path).get("meta", {})
            rows = meta.get("assumed_parameters")
            camp = Path(meta.get("campaign", "")) / "campaign.json"
            if rows is None and meta.get("campaign") and camp.exists():
                cfg = read_json(camp)["config"]
                rows = assumed_parameters(
                    tuple(est), cfg.get("other_parameters", {}), cfg["parameters"]
                )
            if rows is not None:
                break
    if rows is None:
        rows = assumed_parameters(tuple(est), {}, ())
    return [r for r in rows if r["symbol"] not in est]
