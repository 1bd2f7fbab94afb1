"""The bench scripts after a QA pass: bad input refused before any work as one line
``error: ...`` with exit 2 (bench/README.md), a critical speed that is only a bound said so,
the shipped example recording's channel map written by its script, ``--help`` descriptions
that end where their sentence does, and a timing target judged only at its settings.

Each script runs in-process as ``python bench/SCRIPT.py ARGS`` would (test_bench_cli.py's
``run_script``); the library calls that would do the work are replaced by stubs that record
being called, so that "refused before any work" is checked without running any."""

import json
import os
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from conftest import BENCH, bench_script
from test_bench_cli import run_script

DATA = Path(__file__).resolve().parents[1] / "src" / "railsusp" / "data"


def _work_stub(monkeypatch, module: str, name: str) -> list:
    """Replace ``module.name`` by a stub that records its call and fails (no work may run)."""
    import importlib

    calls: list = []

    def stub(*args, **kwargs):
        calls.append(args)
        raise RuntimeError(f"{module}.{name} ran: the work began before the input was checked")

    monkeypatch.setattr(importlib.import_module(module), name, stub)
    return calls


def _one_line_refusal(code: int, err: str, *named: str) -> None:
    assert code == 2, err[-2000:]
    assert err.count("\n") == 1 and err.startswith("error: "), err
    assert "Traceback" not in err and "usage:" not in err
    for text in named:
        assert text in err, err


# 1. critical_speed.py --duration below the measurement's 15 s: refused while parsing


@pytest.mark.parametrize("duration", ["5", "14.9", "601"])
def test_critical_speed_refuses_a_duration_outside_its_range_while_parsing(
    monkeypatch, capsys, duration
):
    calls = _work_stub(monkeypatch, "railsusp.vehicle.stability", "kink_response")
    code, out, err = run_script(
        monkeypatch, capsys, "critical_speed", "--duration", duration, "--wagons", "tare",
        "--kink-mm", "3",
    )  # fmt: skip
    _one_line_refusal(code, err, f"--duration {duration}", "accepted 15 to 600 s")
    assert calls == [] and out == ""


def test_kink_response_refuses_a_short_record_as_bad_input():
    from railsusp.errors import RailsuspInputError
    from railsusp.vehicle.stability import MIN_DURATION_S, kink_response
    from railsusp.vehicle.wagon import load_wagon

    assert MIN_DURATION_S == 15.0
    with pytest.raises(RailsuspInputError, match="duration_s = 10: at least 15 s"):
        kink_response(load_wagon(), 60.0, duration_s=10.0)


# 2. simulator.py --kernel that is not there: refused before the benchmark runs


def test_simulator_refuses_a_missing_kernel_before_any_simulation(monkeypatch, capsys, tmp_path):
    calls = _work_stub(monkeypatch, "railsusp.vehicle.simulate", "simulate_batch")
    out_json = tmp_path / "x.json"
    code, out, err = run_script(
        monkeypatch, capsys, "simulator", "--sizes", "1", "--kernel", "/nonexistent.py",
        "--out", str(out_json),
    )  # fmt: skip
    _one_line_refusal(code, err, "--kernel /nonexistent.py")
    assert calls == [] and out == "" and not out_json.exists()


def test_a_failing_kernel_is_one_line_and_runs_before_the_benchmark(monkeypatch, capsys, tmp_path):
    """A kernel that fails ended the run, after the whole benchmark, in CalledProcessError's
    traceback with no JSON; it runs first now and its failure is one line."""
    calls = _work_stub(monkeypatch, "railsusp.vehicle.simulate", "simulate_batch")
    kernel = tmp_path / "kernel.py"
    kernel.write_text("import sys\nsys.exit('numba: no such target')\n")
    code, out, err = run_script(
        monkeypatch, capsys, "simulator", "--sizes", "1", "--kernel", str(kernel),
        "--out", str(tmp_path / "x.json"),
    )  # fmt: skip
    _one_line_refusal(code, err, f"--kernel {kernel}", "failed (exit 1): numba: no such target")
    assert calls == [] and out == ""


# 3. every wagon, condition and --reference-src checked before the first simulation


def test_credibility_checks_every_condition_before_simulating(monkeypatch, capsys):
    calls = _work_stub(monkeypatch, "railsusp.vehicle.simulate", "simulate_batch")
    code, out, err = run_script(
        monkeypatch, capsys, "credibility", "--cant-mm", "300", "--seeds", "8"
    )
    _one_line_refusal(code, err, "--cant-mm 300", "cant_mm = 300", "accepted")
    assert calls == [] and out == ""


def test_critical_speed_loads_every_wagon_before_sweeping(monkeypatch, capsys):
    calls = _work_stub(monkeypatch, "railsusp.vehicle.stability", "kink_response")
    code, out, err = run_script(
        monkeypatch, capsys, "critical_speed", "--wagons", "tare,nosuch", "--kink-mm", "3"
    )
    _one_line_refusal(code, err, "--wagons", "nosuch")
    assert calls == [] and out == ""


def test_rhs_profile_checks_the_reference_src_before_timing(monkeypatch, capsys, tmp_path):
    # the script sets NUMBA_NUM_THREADS when it runs: restored after the test
    monkeypatch.setenv("NUMBA_NUM_THREADS", os.environ.get("NUMBA_NUM_THREADS", "1"))
    calls = _work_stub(monkeypatch, "railsusp.vehicle.wagon", "load_wagon")
    code, out, err = run_script(
        monkeypatch, capsys, "rhs_profile", "--reps", "100", "--repeats", "1",
        "--reference-src", str(tmp_path), "--out", str(tmp_path / "r.json"),
    )  # fmt: skip
    _one_line_refusal(code, err, f"--reference-src {tmp_path}", "railsusp/__init__.py")
    assert calls == [] and out == ""


# 4. a critical speed found at the sweep's first speed is a bound, not a value


def _kink_stub(unstable_from: float):
    from railsusp.vehicle.stability import KinkResponse

    def kink_response(wagon, speed_kmh, duration_s, amplitude_m):
        grows = speed_kmh >= unstable_from
        return KinkResponse(speed_kmh, True, 1e3, 2e3 if grows else 1e2, 3e3, 2.0)

    return kink_response


def test_an_unstable_first_speed_reads_as_at_or_below(monkeypatch, capsys, tmp_path):
    import railsusp.vehicle.stability as stability

    monkeypatch.setattr(stability, "kink_response", _kink_stub(138.0))
    out_json = tmp_path / "cs.json"
    code, out, err = run_script(
        monkeypatch, capsys, "critical_speed", "--wagons", "loaded", "--kink-mm", "10",
        "--from", "190", "--out", str(out_json),
    )  # fmt: skip
    assert code == 0, err
    assert (
        "loaded, kink 10 mm: critical speed at or below 190 km/h (unstable at the sweep's first "
        "speed; lower --from)" in out
    )
    assert "critical speed 190 km/h" not in out
    (row,) = json.loads(out_json.read_text())["results"]
    assert row["critical_speed_kmh"] is None and row["at_or_below_kmh"] == 190.0
    assert "first speed" in row["reason"] and "--from" in row["reason"]


def test_a_bracketed_critical_speed_is_a_plain_number(monkeypatch):
    bench = bench_script("critical_speed")
    monkeypatch.setattr(bench, "kink_response", _kink_stub(138.0))
    from railsusp.vehicle.wagon import load_wagon

    found = bench.critical_speed(load_wagon("loaded"), np.arange(100.0, 201.0, 30.0), 30.0, 0.01)
    assert found.speed_kmh is not None and 138.0 <= found.speed_kmh <= 139.0
    assert found.at_or_below is None and found.reason is None
    bound = bench.critical_speed(load_wagon("loaded"), np.array([190.0, 200.0]), 30.0, 0.01)
    assert bound.speed_kmh is None and bound.at_or_below == 190.0 and len(bound.runs) == 1
    stable = bench.critical_speed(load_wagon("loaded"), np.array([40.0, 50.0]), 30.0, 0.01)
    assert stable.speed_kmh is None and stable.at_or_below is None
    assert "decays at every speed" in stable.reason


# 5. argparse's refusals are one line in every script


def _scripts_with_a_parser() -> list[str]:
    return sorted(
        p.stem for p in BENCH.glob("*.py") if "add_argument(" in p.read_text(encoding="utf-8")
    )


def test_every_script_builds_its_parser_through_cli():
    scripts = _scripts_with_a_parser()
    assert len(scripts) >= 30
    plain = [s for s in scripts if "argparse.ArgumentParser(" in (BENCH / f"{s}.py").read_text()]
    assert plain == [], f"parsers not built by _cli.parser: {plain}"


@pytest.mark.parametrize("name", _scripts_with_a_parser())
def test_an_unknown_option_is_one_line_with_exit_2(monkeypatch, capsys, name):
    code, out, err = run_script(monkeypatch, capsys, name, "--no-such-option")
    _one_line_refusal(code, err)
    assert out == ""


def test_a_scripts_own_parser_error_is_one_line(monkeypatch, capsys):
    code, _, err = run_script(monkeypatch, capsys, "critical_speed", "--from", "250")
    _one_line_refusal(code, err, "--from 250: accepted up to 200 km/h")
    code, _, err = run_script(monkeypatch, capsys, "simulator", "--sizes", "0")
    _one_line_refusal(code, err, "--sizes", "accepted a whole number 1 or more")


# 6. make_example_mdf4.py writes the channel map its docstring names


class _Recording:
    """What recording_from_simulation gives, for the two wheels the script reads."""

    def __init__(self, n: int):
        self.time = np.arange(n) / 200.0
        self.Y = {"w1R": np.zeros(n), "w1L": np.zeros(n)}
        self.Q = {"w1R": np.full(n, 100.0), "w1L": np.full(n, 100.0)}


def test_make_example_mdf4_writes_the_shipped_channel_map(monkeypatch, capsys, tmp_path):
    import railsusp.measured as measured
    import railsusp.vehicle.simulate as simulate

    monkeypatch.setattr(simulate, "simulate", lambda truth, cond: cond)
    monkeypatch.setattr(
        measured,
        "recording_from_simulation",
        lambda cond, wheels: _Recording(round(cond.duration_s * 200)),
    )
    monkeypatch.setattr(measured, "add_sensor_noise", lambda rec, level, seed: rec)
    code, _, err = run_script(monkeypatch, capsys, "make_example_mdf4", "--out", str(tmp_path))
    assert code == 0, err
    written = tmp_path / "example_run.map.toml"
    assert written.read_text() == (DATA / "example_run.map.toml").read_text()
    doc = bench_script("make_example_mdf4").__doc__
    written_by_it = ["example_run.map.toml", "example_line.csv", "example_run.truth.json"]
    for name in ["example_run.mf4", *written_by_it]:  # every file its docstring says it writes
        assert (tmp_path / name).exists() and name in doc, name
    mapping = tomllib.loads(written.read_text())
    from asammdf import MDF

    with MDF(tmp_path / "example_run.mf4") as mdf:
        channels = set(mdf.channels_db)
    named = {v for k, v in mapping.items() if isinstance(v, str)} | set(mapping["ignore"])
    named |= {v for w in mapping["wheels"].values() for v in w.values()}
    assert named <= channels


# 7. the tutorial dates the shipped example recording to this railsusp's force-law revision


def test_the_tutorial_dates_the_example_to_this_revision():
    """docs/tutorial-recording.md said the example was made "at stop 59 with today's model"
    after revision 2026-11-30.2 had changed its forces; it names the revision the shipped
    file was made at, which must be this railsusp's (else make it again with
    bench/make_example_mdf4.py and say so)."""
    from railsusp.vehicle import MODEL_REVISION

    text = (BENCH.parent / "docs" / "tutorial-recording.md").read_text("utf-8")
    said = re.search(r"example recording was made again at force-law revision (\S+)", text)
    assert said is not None and said[1] == MODEL_REVISION


# 8. --help descriptions end where the docstring's first paragraph does

CUT_SHORT = [
    "gpu_train_step", "make_example_mdf4", "posterior", "posterior_estimators",
    "posterior_joint", "posterior_synthetic", "projection_information", "spectral_information",
    "statistics_information", "surrogate_data", "train_variants",
]  # fmt: skip


@pytest.mark.parametrize("name", CUT_SHORT)
def test_help_gives_the_whole_first_paragraph(monkeypatch, capsys, name):
    code, out, err = run_script(monkeypatch, capsys, name, "--help")
    assert code == 0, err
    first = bench_script(name).__doc__.strip().split("\n\n")[0]
    # argparse wraps (at blanks and hyphens): compare without the blanks
    assert "".join(first.split()) in "".join(out.split())


def test_first_paragraph_is_one_line():
    cli = bench_script("_cli")
    assert cli.first_paragraph("One\nsentence, two lines.\n\nMore.") == "One sentence, two lines."
    assert cli.first_paragraph(None) == ""


# 9. track.py --length beyond 1e6 m refused in one line


def test_track_refuses_an_enormous_length(monkeypatch, capsys):
    calls = _work_stub(monkeypatch, "railsusp.vehicle.track", "synthesise")
    code, out, err = run_script(monkeypatch, capsys, "track", "--length", "1e12")
    _one_line_refusal(code, err, "--length 1e+12", "accepted 1024 to 1e+06 m")
    assert calls == [] and out == ""


# 10. estimate_tracks.py judges its 60 s target only at the issue's settings


def _set(seconds: float) -> dict:
    err = {"X13": 1.0, "X14": -7.0}
    return {
        "set": 0,
        "error_pct_range": err,
        "identifiable": ["X13", "X14"],
        "identifiable_within": ["X13"],
        "choice_within": ["X13"],
        "within_pct": ["X13"],
        "cramer_rao_pct_range": {"X13": 2.0, "X14": 3.0},
        "seconds": seconds,
        "cpu_seconds": 2 * seconds,
        "predict_seconds_per_generation": 0.1,
    }


def test_the_time_target_is_judged_only_at_the_issues_settings(capsys):
    bench = bench_script("estimate_tracks")
    issue = {"pop_size": 50, "n_gen": 100, "duration_s": 60.0}
    small = {"pop_size": 4, "n_gen": 2, "duration_s": 2.0}
    keys = ["X13", "X14"]
    fast = bench.overall([_set(1.0)], keys, small)["targets"]
    assert fast["seconds_ok"] is None
    assert "50 x 100" in fast["seconds_reason"] and "60 s" in fast["seconds_reason"]
    assert bench.overall([_set(50.0)], keys, issue)["targets"]["seconds_ok"] is True
    slow = bench.overall([_set(70.0)], keys, issue)["targets"]
    assert slow["seconds_ok"] is False and slow["seconds_reason"] is None
    sets = [_set(1.0)]
    bench.print_table(sets, keys, bench.overall(sets, keys, small))
    out = capsys.readouterr().out
    assert "target < 60 s" not in out and "not applicable" in out
    bench.print_table(sets, keys, bench.overall(sets, keys, issue))
    assert "target < 60 s" in capsys.readouterr().out


def test_simulator_rounds_give_the_median_of_each_rounds_ratio():
    """``--rounds``: per batch size the median over rounds of every figure, the ratios the
    median of each round's own ratio (rates measured minutes apart), the rounds kept."""
    sim = bench_script("simulator")
    rounds = [
        [{"sets": 256, "wagon_s_per_wall_s": w, "ratio_to_kernel": w / k, "failed": f}]
        for w, k, f in ((600.0, 1500.0, 0), (700.0, 1800.0, 1), (650.0, 1600.0, 0))
    ]
    (row,) = sim._medians(rounds)
    assert row["sets"] == 256
    assert row["wagon_s_per_wall_s"] == 650.0
    assert row["ratio_to_kernel"] == pytest.approx(np.median([0.4, 700 / 1800, 650 / 1600]))
    assert row["failed"] == 1  # any round's failures are reported
    assert [r["wagon_s_per_wall_s"] for r in row["rounds"]] == [600.0, 700.0, 650.0]
