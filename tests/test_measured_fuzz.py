"""Property-based: whatever bytes or cell values a recording, its sidecar, a field index,
a channel map or an MDF file hold, the readers answer with a Recording or a clear input
error, never a traceback (issue 22)."""

import json
import os
import tempfile
import warnings
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.measured import Recording, read_field, read_recording
from railsusp.measured.channels import read_channel_map
from railsusp.measured.run import read_run

SETTINGS = settings(
    max_examples=int(os.environ.get("RAILSUSP_FUZZ_EXAMPLES", "40")),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
COND = get_condition("straight", duration_s=2.0, n_steps=100)


def good_recording(folder: Path) -> Path:
    t = np.arange(100) / 50.0
    rec = Recording(t, {"w1L": 5 + np.sin(t)}, {"w1L": 120 + np.cos(t)}, COND)
    return rec.write(folder / "rec")


def read_or_refuse(reader, *args):
    """The reader's result, or None when it refused with an input error."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return reader(*args)
        except RailsuspInputError as exc:
            assert str(exc) and "\n" not in str(exc).strip()
            return None


@SETTINGS
@given(st.binary(max_size=400))
@example(b"\r\x00")  # found by this test: the csv module's traceback on a bare carriage return
def test_any_bytes_as_the_table(data):
    with tempfile.TemporaryDirectory() as tmp:
        path = good_recording(Path(tmp))
        path.write_bytes(data)
        read_or_refuse(read_recording, path)


@SETTINGS
@given(st.binary(max_size=400) | st.text(max_size=200).map(str.encode))
def test_any_bytes_as_the_sidecar(data):
    with tempfile.TemporaryDirectory() as tmp:
        path = good_recording(Path(tmp))
        path.with_suffix(".json").write_bytes(data)
        assert read_or_refuse(read_recording, path) is None  # never a valid sidecar


cells = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-(10**30), 10**30).map(str),
    st.text(
        alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters=',\n\r"'),
        max_size=8,
    ),
)


@SETTINGS
@given(st.lists(st.tuples(cells, cells, cells), min_size=0, max_size=30))
def test_any_cell_values(rows):
    with tempfile.TemporaryDirectory() as tmp:
        path = good_recording(Path(tmp))
        lines = ["time_s,Y_w1L_kN,Q_w1L_kN"] + [",".join(r) for r in rows]
        path.write_text("\n".join(lines) + "\n")
        rec = read_or_refuse(read_recording, path)
        if rec is not None:
            assert np.isfinite(rec.Q["w1L"]).all() and np.all(np.diff(rec.time) > 0)


json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=10),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner),
    max_leaves=10,
)


@SETTINGS
@given(json_values)
def test_any_json_as_the_field_index(doc):
    with tempfile.TemporaryDirectory() as tmp:
        good_recording(Path(tmp))
        (Path(tmp) / "index.json").write_text(json.dumps(doc))
        read_or_refuse(read_field, tmp)


@SETTINGS
@given(st.binary(max_size=300))
def test_any_bytes_as_a_channel_map_or_an_mdf_file(data):
    with tempfile.TemporaryDirectory() as tmp:
        m = Path(tmp) / "map.toml"
        m.write_bytes(data)
        read_or_refuse(read_channel_map, m)
        f = Path(tmp) / "run.mf4"
        f.write_bytes(data)
        read_or_refuse(read_run, f)
