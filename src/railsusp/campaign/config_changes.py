"""What differs between a stored campaign configuration and the one asked for, as the
refusals of a run directory (:mod:`railsusp.campaign.run_directory`) and of its nominal
twins (:mod:`railsusp.campaign.twins`) name it: a hash alone ("another configuration (hash
14abf..., now c02ce...)") left the user to guess which option differed."""

from __future__ import annotations

import json

from railsusp.campaign.design import CampaignConfig

#: the most differences a refusal names (then how many more)
_SHOWN_CHANGES = 4


def config_changes(stored: object, config: CampaignConfig) -> str:
    """What differs between a stored campaign configuration (``campaign.json``'s
    ``config``, as JSON) and ``config``, as a refusal says it, stored value first:
    ``samples 8, now 9``; ``conditions straight,curve, now curve,straight``; conditions'
    fields as ``conditions straight,curve: duration_s 4, now 5``; a setting inside a group
    (solver, wagon, track family) by its path, ``solver.rtol 1e-06, now 1e-05``. At most
    four, then how many more; '' where nothing differs that the stored one states (none
    stored)."""
    if not isinstance(stored, dict):
        return ""
    now = config.model_dump(mode="json")
    found: list[str] = []
    for key in [*now, *(k for k in stored if k not in now)]:
        old, new = stored.get(key), now.get(key)
        if key == "conditions" and isinstance(old, list) and isinstance(new, list):
            found.extend(_condition_changes(old, new))
        else:
            found.extend(f"{k} {a}, now {b}" for k, a, b in _leaf_changes(key, old, new))
    more = len(found) - _SHOWN_CHANGES
    return "; ".join(found[:_SHOWN_CHANGES]) + (f"; and {more} more" if more > 0 else "")


def _leaf_changes(path: str, old: object, new: object) -> list[tuple[str, str, str]]:
    """(dotted path, stored, now) of each differing value under ``path``, into mappings."""
    if old == new:
        return []
    if isinstance(old, dict) and isinstance(new, dict):
        return [
            change
            for k in [*new, *(k for k in old if k not in new)]
            for change in _leaf_changes(f"{path}.{k}", old.get(k), new.get(k))
        ]
    return [(path, _shown(old), _shown(new))]


def _condition_changes(old: list, new: list) -> list[str]:
    """The conditions' differences: their names in order where those differ, else each
    changed field once, with the conditions it changed in alike."""
    names = [[c.get("name") if isinstance(c, dict) else c for c in cs] for cs in (old, new)]
    if names[0] != names[1]:
        return [f"conditions {_shown(names[0])}, now {_shown(names[1])}"]
    where: dict[tuple[str, str, str], list[str]] = {}
    for a, b, name in zip(old, new, names[1], strict=True):
        for change in _leaf_changes("", a, b):
            where.setdefault(change, []).append(str(name))
    return [
        f"condition{'s' if len(at) > 1 else ''} {','.join(at)}: {k.lstrip('.')} {a}, now {b}"
        for (k, a, b), at in where.items()
    ]


def _shown(value: object) -> str:
    """A configuration value as a refusal shows it: numbers with %g, lists comma-joined,
    none for null, anything longer cut to 40 characters."""
    if value is None:
        return "none"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, int | float):
        return f"{value:g}"
    if isinstance(value, list) and all(isinstance(v, str | int | float) for v in value):
        text = ",".join(_shown(v) for v in value)
    else:
        text = json.dumps(value, separators=(",", ":")) if not isinstance(value, str) else value
    return text if len(text) <= 40 else text[:37] + "..."
