"""Property-based tests: the configuration and condition loaders never give a traceback.

Arbitrary bytes, and arbitrary TOML documents built from the loaders' own field names with
values of any TOML type (NaN, infinities, booleans, huge integers, strings, arrays, tables),
either load or raise the project's input error (one line), nothing else.
"""

from __future__ import annotations

import math

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from railsusp.condition_files import load_conditions
from railsusp.conditions import WorkingCondition
from railsusp.errors import RailsuspInputError
from railsusp.pipeline import PipelineConfig, load_config

SETTINGS = settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


def toml_string(text: str) -> str:
    """A TOML basic string: control characters, quote and backslash escaped."""
    return (
        '"'
        + "".join(f"\\u{ord(ch):04x}" if ord(ch) < 0x20 or ch in '"\\\x7f' else ch for ch in text)
        + '"'
    )


def toml_value(v) -> str:
    """``v`` as an inline TOML value."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return toml_string(v)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return "{" + ", ".join(f"{toml_string(k)} = {toml_value(x)}" for k, x in v.items()) + "}"


def toml_document(doc: dict) -> str:
    return "".join(f"{toml_string(k)} = {toml_value(v)}\n" for k, v in doc.items())


CONDITION_FIELDS = [*WorkingCondition.model_fields, "base"]
SECTION_FIELDS = {
    name: list(info.annotation.model_fields)
    for name, info in PipelineConfig.model_fields.items()
    if isinstance(info.annotation, type) and hasattr(info.annotation, "model_fields")
}
ALL_NAMES = sorted(
    {
        *PipelineConfig.model_fields,
        *CONDITION_FIELDS,
        *(n for v in SECTION_FIELDS.values() for n in v),
    }
    | {"X13", "X99", "X1", "straight", "../../x"}
)

scalars = st.one_of(
    st.booleans(),
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, 1, -1, 2, 60, 1e300, -1e300, 1e-300]),
    st.text(max_size=12),
    st.sampled_from(ALL_NAMES),
)
keys = st.one_of(st.sampled_from(ALL_NAMES), st.text(min_size=1, max_size=8))
values = st.recursive(
    scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(keys, inner, max_size=4)),
    max_leaves=12,
)


def sections():
    """A pipeline configuration's tables with known or unknown keys and any values."""
    return st.fixed_dictionaries(
        {},
        optional={
            name: st.dictionaries(st.one_of(st.sampled_from(fields), keys), values, max_size=4)
            for name, fields in SECTION_FIELDS.items()
        }
        | {
            "conditions": st.lists(
                st.one_of(
                    st.sampled_from(["straight", "curve", "uphill", "loop"]),
                    st.dictionaries(st.sampled_from(CONDITION_FIELDS), values, max_size=5),
                ),
                max_size=3,
            ),
            "name": values,
            "wagon": values,
            "scheduler": values,
        },
    )


def _loads_or_input_error(load, path) -> None:
    try:
        load(path)
    except RailsuspInputError as exc:
        assert "\n" not in str(exc).strip(), str(exc)


@pytest.mark.parametrize(
    "load", [load_config, load_conditions], ids=["configuration", "conditions"]
)
@SETTINGS
@given(data=st.binary(max_size=300))
def test_loader_on_arbitrary_bytes(tmp_path, load, data):
    p = tmp_path / "c.toml"
    p.write_bytes(data)
    _loads_or_input_error(load, p)


@SETTINGS
@given(doc=sections())
@example(doc={"conditions": [{"base": 5}]})  # once an AttributeError
@example(doc={"field": {"truth": {"X99": 1.0}}})  # once failed after three stages
@example(doc={"field": {"measured": "a\x00b"}})
@example(doc={"campaign": {"\n": []}})  # once a two-line message
def test_configuration_loader_on_arbitrary_toml_values(tmp_path, doc):
    p = tmp_path / "c.toml"
    p.write_text(toml_document(doc), encoding="utf-8")
    _loads_or_input_error(load_config, p)


@SETTINGS
@given(
    tables=st.lists(
        st.dictionaries(st.one_of(st.sampled_from(CONDITION_FIELDS), keys), values, max_size=6),
        max_size=3,
    ),
    named=st.booleans(),
)
def test_condition_loader_on_arbitrary_toml_values(tmp_path, tables, named):
    p = tmp_path / "c.toml"
    if named:  # [condition.NAME] tables
        doc = {"condition": {f"c{i}": t for i, t in enumerate(tables)}}
    else:  # [[condition]] tables
        doc = {"condition": tables}
    p.write_text(toml_document(doc), encoding="utf-8")
    _loads_or_input_error(load_conditions, p)
