"""``read_field`` on a folder that a writer replaces while it reads (an atomic swap, as
``synth-field`` does): read again, so that the recordings are of one generation (the
concurrency audit of stop 66 got recordings of two truths under one ``index.json`` from a
library call, which holds no lock)."""

from __future__ import annotations

import os
import shutil

import pytest

import railsusp.measured.reader as reader
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.measured import read_field, synthesise_field
from railsusp.measured.recording import recordings_digest
from railsusp.params import ParameterSet


def _field(path, x13: float):
    conds = [
        get_condition(name, duration_s=1.0, n_steps=50, lead_in_m=20.0)
        for name in ("straight", "uphill")
    ]
    return synthesise_field(ParameterSet({"X13": x13}, units="display"), conds, path)


def test_a_folder_swapped_during_the_read_is_read_again_whole(tmp_path, monkeypatch):
    folder = _field(tmp_path / "f", 10.0)
    other = _field(tmp_path / "g", 20.0)
    first = read_field(folder)
    newer = read_field(other)
    assert recordings_digest(first) != recordings_digest(newer)
    real = reader.read_recording
    calls = {"n": 0}

    def swap_after_the_first(path, **kwargs):
        calls["n"] += 1
        rec = real(path, **kwargs)
        if calls["n"] == 1:  # the writer's swap, between the first and second recording
            os.rename(folder, tmp_path / ".f.old")
            shutil.copytree(other, folder)
        return rec

    monkeypatch.setattr(reader, "read_recording", swap_after_the_first)
    got = read_field(folder)
    assert calls["n"] == 4  # read once across the swap, then again whole
    assert recordings_digest(got) == recordings_digest(newer)  # all of the new generation


def test_a_folder_swapped_on_every_read_is_refused_in_one_line(tmp_path, monkeypatch):
    folder = _field(tmp_path / "f", 10.0)
    real = reader.read_recording
    n = {"swaps": 0}

    def always_swap(path, **kwargs):
        rec = real(path, **kwargs)
        n["swaps"] += 1
        os.rename(folder, tmp_path / f".f.old{n['swaps']}")
        shutil.copytree(tmp_path / f".f.old{n['swaps']}", folder)
        return rec

    monkeypatch.setattr(reader, "read_recording", always_swap)
    with pytest.raises(RailsuspInputError, match="replaced 3 times while it was read"):
        read_field(folder)


def test_a_missing_folder_is_said_as_before(tmp_path):
    with pytest.raises(RailsuspInputError) as exc:
        read_field(tmp_path / "nowhere")
    assert "replaced" not in str(exc.value)
