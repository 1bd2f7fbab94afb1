"""The bench scripts write their results atomically (railsusp.store: a temporary file
renamed into place), so that a run killed while writing leaves the previous file, not a
truncated one: the JSON results, the packaged example data and the tests' force
reference."""

import re

import numpy as np
import pytest

from conftest import BENCH, bench_script


def test_no_script_writes_a_result_in_place():
    """Path.write_text, json.dump to an open file and np.savez to a path write in place;
    the scripts go through railsusp.store (write_json, atomic_write_text/bytes)."""
    in_place = re.compile(r"\.write_text\(|json\.dump\(|np\.savez(_compressed)?\((?!buf\b)")
    found = [
        f"{path.name}:{n}"
        for path in sorted(BENCH.glob("*.py"))
        for n, line in enumerate(path.read_text().splitlines(), 1)
        if in_place.search(line)
    ]
    assert found == []


def test_a_failed_reference_write_leaves_the_stored_forces(monkeypatch, tmp_path):
    """force_reference.py --write: the forces are stored by renaming a complete file over
    the reference; a write that fails leaves the stored one as it was."""
    bench = bench_script("force_reference")
    ref = tmp_path / "force_reference.npz"
    monkeypatch.setattr(bench, "REFERENCE", ref)
    old = {"straight_Y": np.zeros((3, 8, 4))}
    np.savez_compressed(ref, model_revision=np.array("1999-01-01.1"), **old)
    before = ref.read_bytes()
    real = np.savez_compressed

    def fails(file, **arrays):
        real(file, **arrays)
        raise OSError("disk full")

    monkeypatch.setattr(bench.np, "savez_compressed", fails)
    with pytest.raises(OSError, match="disk full"):
        bench.write_reference({"straight_Y": np.ones((3, 8, 4))})
    assert ref.read_bytes() == before
    monkeypatch.setattr(bench.np, "savez_compressed", real)
    inode = ref.stat().st_ino
    bench.write_reference({"straight_Y": np.ones((3, 8, 4))})
    with np.load(ref) as f:
        assert str(f["model_revision"]) == bench.MODEL_REVISION
        assert f["straight_Y"].sum() == 96.0
    assert ref.stat().st_ino != inode  # renamed into place, not rewritten
    assert not list(tmp_path.glob(".*.tmp"))
