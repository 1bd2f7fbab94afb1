"""The bench scripts' command line (bench/_cli.py): bad input is refused before any work,
as one line naming the option and what is accepted, with exit status 2 (argparse's own
message for the counts it parses), never a traceback with exit 1 or a run that reports
nonsense. Each script runs in-process as ``python bench/SCRIPT.py ARGS`` would run it."""

import runpy
import sys

import numpy as np
import pytest

from conftest import BENCH, bench_script


def run_script(monkeypatch, capsys, name: str, *argv: str) -> tuple[int, str, str]:
    """(exit status, stdout, stderr) of bench/NAME.py run as a script with ``argv``."""
    path = str(BENCH / f"{name}.py")
    monkeypatch.setattr(sys, "argv", [path, *argv])
    monkeypatch.syspath_prepend(str(BENCH))
    code = 0
    try:
        runpy.run_path(path, run_name="__main__")
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def test_the_wrapper_turns_bad_input_into_one_line_and_exit_2(monkeypatch, capsys):
    cli = bench_script("_cli")
    from railsusp.errors import RailsuspInputError

    def bad(exc):
        def main():
            raise exc

        return main

    for exc, line in [
        (RailsuspInputError("--x 3: accepted\n  1 to 2"), "--x 3: accepted 1 to 2"),
        (FileNotFoundError(2, "No such file or directory", "/nonexistent"), "'/nonexistent'"),
        (SystemExit("error: --y 0: accepted 1 or more"), "--y 0: accepted 1 or more"),
        (SystemExit("--z: no line"), "--z: no line"),  # a message without the prefix gets it
    ]:
        with pytest.raises(SystemExit) as got:
            cli.run_main(bad(exc))
        assert got.value.code == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("error: ") and "error: error" not in err
        assert err.rstrip().endswith(line)
    with pytest.raises(SystemExit) as got:
        cli.run_main(lambda: 3)  # an int returned is the exit status
    assert got.value.code == 3
    cli.run_main(lambda: {"rows": []})  # anything else: a normal end
    with pytest.raises(RuntimeError):  # not bad input: the traceback stays
        cli.run_main(bad(RuntimeError("bug")))
    with pytest.raises(ValueError, match="operands could not be broadcast"):  # NumPy's, a fault
        cli.run_main(bad(ValueError("operands could not be broadcast together")))


def test_count_and_list_types_name_what_is_accepted():
    import argparse

    cli = bench_script("_cli")
    assert cli.positive_int("3") == 3 and cli.non_negative_int("0") == 0
    assert cli.number_list(cli.positive_int)("1, 16,256") == [1, 16, 256]
    assert cli.non_negative_float("0") == 0.0 and cli.positive_float("2.5") == 2.5
    for parse, text in [
        (cli.positive_int, "0"),
        (cli.positive_int, "abc"),
        (cli.non_negative_int, "-1"),
        (cli.non_negative_float, "-1"),
        (cli.non_negative_float, "nan"),
        (cli.positive_float, "0"),
        (cli.positive_float, "inf"),
        (cli.number_list(cli.positive_int), "1,0"),
        (cli.number_list(cli.positive_float), "abc"),
        (cli.number_list(cli.positive_int), " , "),
    ]:
        with pytest.raises(argparse.ArgumentTypeError, match="accepted"):
            parse(text)


ARGPARSE_REFUSED = [
    ("track", ["--length", "-5"], "--length"),
    ("track", ["--length", "nan"], "--length"),
    ("simulator", ["--sizes", "0"], "--sizes"),
    ("simulator", ["--sizes", "abc"], "--sizes"),
    ("simulator", ["--flange-substeps", "0"], "--flange-substeps"),
    ("simulator", ["--rounds", "0"], "--rounds"),
    ("campaign", ["--samples", "0"], "--samples"),
    ("emulator_reading", ["--points", "0"], "--points"),
    ("emulator_reading", ["--threads", "0"], "--threads"),
    ("credibility", ["--seeds", "0"], "--seeds"),
    ("settled_start", ["--sets", "0"], "--sets"),
    ("settled_start", ["--repeat", "0"], "--repeat"),
    ("posterior", ["--train", "0"], "--train"),
    ("posterior", ["--hidden", "0"], "--hidden"),
    ("posterior", ["--section", "0"], "--section"),
    ("rhs_profile", ["--reps", "0"], "--reps"),
    ("rhs_profile", ["--repeats", "0"], "--repeats"),
    ("rhs_profile", ["--reps", "-5"], "--reps"),
    ("critical_speed", ["--step", "0"], "--step"),
    ("critical_speed", ["--step", "-10"], "--step"),
    ("critical_speed", ["--kink-mm", "abc"], "--kink-mm"),
    ("critical_speed", ["--from", "250"], "--from 250: accepted up to 200 km/h"),
    ("surrogate", ["--throughput-only", "--repeats", "0"], "--repeats"),
    ("surrogate", ["--throughput-only", "--threads", "0"], "--threads"),
    ("sequence_predict", ["--repeats", "0"], "--repeats"),
    ("sequence_predict", ["--pop", "0"], "--pop"),
    ("sequence_predict", ["--threads", "1,0"], "--threads"),
    ("estimate_tracks", ["RUN", "--sets", "0"], "--sets"),
    ("estimate_tracks", ["RUN", "--pop-size", "0"], "--pop-size"),
    ("estimate_tracks", ["RUN", "--threads", "0"], "--threads"),
    ("estimate_tracks", ["RUN", "--duration", "0"], "--duration"),
    ("estimate_tracks", ["RUN", "--track-noise", "-1"], "--track-noise"),
    ("estimate_tracks", ["RUN", "--noise", "-1"], "--noise"),
    ("estimate_tracks", ["RUN", "--limit", "-1"], "--limit"),
]


@pytest.mark.parametrize(("name", "argv", "named"), ARGPARSE_REFUSED)
def test_bad_counts_are_refused_while_parsing(monkeypatch, capsys, name, argv, named):
    code, out, err = run_script(monkeypatch, capsys, name, *argv)
    assert code == 2, err[-2000:]
    last = err.strip().splitlines()[-1]
    assert named in last and "accepted" in last and "Traceback" not in err
    assert out == ""  # nothing ran


LIBRARY_REFUSED = [
    ("simulator", ["--condition", "nosuch"], "unknown condition 'nosuch'"),
    ("simulator", ["--contact", "bogus"], "contact.model = 'bogus'"),
    ("simulator", ["--sizes", "1", "--reference-src", "/nonexistent"], "--reference-src"),
    ("posterior", ["--lengths", "abc"], "--lengths abc: accepted"),
    ("posterior", ["--long", "-3"], "--long -3: accepted"),
    ("surrogate", ["--throughput-only", "--models", "bogus,cnn-gru-seq"], "bogus unknown"),
    ("surrogate", ["--throughput-only", "--models", "rbf"], "one or more of cnn-gru"),
    ("credibility", ["--summarise", "/nonexistent.json"], "/nonexistent.json"),
    ("estimate_stage", ["--run", "/nonexistent"], "--run /nonexistent: no pipeline.json"),
    ("estimate_tracks", ["/nonexistent"], "/nonexistent"),
]


@pytest.mark.parametrize(("name", "argv", "named"), LIBRARY_REFUSED)
def test_bad_input_found_later_is_one_line_with_exit_2(monkeypatch, capsys, name, argv, named):
    code, _, err = run_script(monkeypatch, capsys, name, *argv)
    assert code == 2, err[-2000:]
    assert err.count("\n") == 1 and err.startswith("error: ") and named in err


def test_an_empty_speed_sweep_is_refused(monkeypatch):
    """critical_speed() of no speeds said "not found up to 200 km/h" with nothing run."""
    from railsusp.errors import RailsuspInputError
    from railsusp.vehicle.wagon import load_wagon

    bench = bench_script("critical_speed")
    monkeypatch.setattr(bench, "kink_response", None)  # never called
    with pytest.raises(RailsuspInputError, match="sweep is empty"):
        bench.critical_speed(load_wagon("loaded"), np.arange(250.0, 200.0, 10.0), 30.0, 0.01)


def test_track_scores_every_band_and_says_how_many(monkeypatch, capsys):
    """A section too short for the Welch segment is refused; a series with empty 1/3-octave
    bands gives NaN and the count of bands scored, not a worst over the bands left."""
    code, _, err = run_script(monkeypatch, capsys, "track", "--length", "10")
    assert code == 2 and "--length 10: accepted 1024 m or more" in err
    track = bench_script("track")
    bands = len(track.third_octave_edges()) - 1
    x = np.random.default_rng(0).normal(size=400)  # 50 m at 1/8 m
    worst, scored = track.psd_worst_ratio(x, 0.125, "vertical", 5)
    assert np.isnan(worst) and 0 < scored < bands
    from railsusp.vehicle.track import synthesise

    irr = synthesise(2000.0, 5, 0)
    worst, scored = track.psd_worst_ratio(irr.component("vertical")[0], 0.125, "vertical", 5)
    assert np.isfinite(worst) and scored == bands
    assert track.limited_share(np.zeros(10), 1) == 0.0
    assert track.limited_share(np.array([0.0, 0.03, -0.01, 0.0]), 1) == 0.5  # beyond 2/3


def test_settled_start_says_where_it_wrote(monkeypatch, capsys, tmp_path):
    """Its JSON's path is printed like every other script's ("wrote PATH")."""
    import railsusp.vehicle.simulate as simulate

    class Result:
        def __init__(self, n):
            self.time = np.linspace(0.0, 10.0, 50)
            self.Y = np.ones((n, 8, 50))
            self.Q = np.ones((n, 8, 50))
            self.settled_start = np.ones(n, bool)

        def measured_wheel(self):
            return 0

    monkeypatch.setattr(simulate, "simulate_batch", lambda sets, *a, **k: Result(len(sets)))
    out = tmp_path / "settled.json"
    code, stdout, _ = run_script(
        monkeypatch, capsys, "settled_start", "--sets", "2", "--repeat", "1", "--out", str(out)
    )
    assert code == 0 and out.exists()
    assert stdout.strip().splitlines()[-1] == f"wrote {out}"
