"""NSGA-II's preview generations: the first generations compare each recording's first
seconds (:meth:`Recording.head`), the rest the whole records from the preview's Pareto set;
one result over all generations; the settings checked where they are given (API,
configuration file, command line)."""

from dataclasses import replace

import numpy as np
import pytest
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.errors import RailsuspInputError
from railsusp.estimate import NSGAConfig, estimate
from railsusp.measured import Recording
from railsusp.params import bounds
from railsusp.pipeline_config import load_config
from railsusp.pipeline_inputs import stage_section
from test_estimate import ON_TRACK, PARAMS, WaveForces

LONG = ON_TRACK.with_duration(4.0)  # 200 steps at 50 Hz
TRUTH = np.array([16.1e6, 8.3e6])


def long_recording(noise: float = 0.05) -> Recording:
    s = WaveForces().series(TRUTH[None], LONG)[0]
    s = s + noise * s.std(axis=0) * np.random.default_rng(7).standard_normal(s.shape)
    t = np.arange(LONG.n_steps) * LONG.sample_interval
    return Recording(t, {"w1L": s[:, 0]}, {"w1L": s[:, 1]}, LONG, {"source": "test"})


class Counting(WaveForces):
    """Counts the record length (steps) of every prediction asked for."""

    def __init__(self):
        self.steps: list[int] = []

    def series(self, x_si, condition):
        self.steps.append(condition.n_steps)
        return super().series(x_si, condition)


def test_the_head_of_a_recording_is_its_first_seconds_on_the_same_track():
    rec = long_recording()
    short = rec.head(1.0)
    assert short.time.size == short.condition.n_steps == 50
    assert short.condition.duration_s == 1.0
    np.testing.assert_array_equal(short.Y["w1L"], rec.Y["w1L"][:50])
    np.testing.assert_array_equal(short.Q["w1L"], rec.Q["w1L"][:50])
    assert short.condition.track_geometry == rec.condition.track_geometry == "measured-track.csv"
    assert short.meta == rec.meta and short.meta is not rec.meta
    assert rec.head(4.0) is rec and rec.head(30.0) is rec  # as long or longer: the record


def test_the_head_of_a_recording_at_its_own_rate_is_cut_by_time():
    """A table sampled at another rate than its condition (the reader allows it) is cut at
    the same time, not at the condition's step count."""
    rec = long_recording()
    fast = Recording(
        np.arange(400) * 0.01, {"w1L": np.zeros(400)}, {"w1L": np.ones(400)}, rec.condition, {}
    )
    short = fast.head(1.5)
    assert short.time.size == 150 and short.time[-1] == pytest.approx(1.49)
    assert short.condition.duration_s == pytest.approx(1.5)


def test_the_preview_generations_predict_the_first_seconds_then_the_whole_records():
    model = Counting()
    cfg = NSGAConfig(pop_size=8, n_gen=5, statistic="aligned", preview_generations=3, preview_s=1)
    res = estimate(model, [long_recording()], PARAMS, cfg)
    short = [n for n in model.steps if n == 50]
    whole = [n for n in model.steps if n == 200]
    assert short and whole and len(short) + len(whole) == len(model.steps)
    first_whole = model.steps.index(200)
    assert all(n == 200 for n in model.steps[first_whole:])  # no preview after the switch
    # one result over all generations, the setting kept
    assert len(res.log) == 5 and res.history.shape == (5, 2)
    assert list(res.log["n_gen"]) == [1, 2, 3, 4, 5]
    assert list(res.log["record"]) == ["first 1 s"] * 3 + ["whole"] * 2
    assert res.log["n_eval"].is_monotonic_increasing
    assert res.config == cfg
    assert "its first 3 of 5 generations on each record's first 1 s" in res.route


def test_the_preview_is_two_estimates_chained_and_finds_the_truth():
    """The preview is the bench's two-stage search (stop 59) made an option: bit-identical to
    NSGA-II on the heads, then on the whole records from that Pareto set."""
    rec = long_recording()
    cfg = NSGAConfig(pop_size=16, n_gen=20, statistic="aligned", seed=4)
    with_preview = estimate(
        WaveForces(), [rec], PARAMS, replace(cfg, preview_generations=12, preview_s=1.0)
    )
    first = estimate(WaveForces(), [rec.head(1.0)], PARAMS, replace(cfg, n_gen=12))
    rest = estimate(WaveForces(), [rec], PARAMS, replace(cfg, n_gen=8), first.pareto_x)
    np.testing.assert_array_equal(with_preview.pareto_x, rest.pareto_x)
    np.testing.assert_array_equal(with_preview.history[:12], first.history)
    lo, hi = bounds(PARAMS)
    assert np.all(np.abs(with_preview.chosen_x - TRUTH) / (hi - lo) < 0.05)


def test_a_preview_as_long_as_every_record_is_no_restart():
    """A preview of 4 s or more on a 4 s record compared the whole record twice: its
    generations, then the rest restarted from their Pareto set (the population's other
    members dropped), a search other than the plain one. Now it is the plain search of all
    generations, said in a warning, with no preview in its route."""
    rec = long_recording()
    cfg = NSGAConfig(pop_size=8, n_gen=6, statistic="aligned", seed=2)
    plain = estimate(WaveForces(), [rec], PARAMS, cfg)
    with pytest.warns(UserWarning, match="no recording is longer .* there is no preview"):
        asked = estimate(
            WaveForces(), [rec], PARAMS, replace(cfg, preview_generations=3, preview_s=4.0)
        )
    np.testing.assert_array_equal(asked.pareto_x, plain.pareto_x)
    np.testing.assert_array_equal(asked.history, plain.history)
    assert list(asked.log["record"]) == ["whole"] * 6
    assert "generations on each record's first" not in asked.route


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"preview_generations": 5}, "preview_generations 5: accepted 0 to n_gen - 1 (4;"),
        ({"preview_generations": -1}, "preview_generations -1: accepted 0 to 100000"),
        ({"preview_generations": 2, "preview_s": 0.5}, "preview_s 0.5: accepted 1 to 600"),
        ({"preview_generations": 2, "preview_s": float("nan")}, "preview_s nan: accepted"),
    ],
)
def test_bad_preview_settings_are_refused_in_one_line(changes, message):
    with pytest.raises(RailsuspInputError, match=message.replace("(", r"\(")):
        NSGAConfig(n_gen=5, **changes)


def test_the_configuration_file_refuses_a_preview_as_long_as_the_search(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text("[estimate]\nn_gen = 10\npreview_generations = 10\n")
    with pytest.raises(RailsuspInputError) as err:
        load_config(path)
    text = str(err.value)
    assert "estimate.preview_generations = 10: accepted 0 to estimate.n_gen - 1 = 9" in text
    assert "\n" not in text
    path.write_text("[estimate]\npreview_generations = 60\npreview_s = 0.2\n")
    with pytest.raises(RailsuspInputError, match="preview_s"):
        load_config(path)


def test_a_preview_on_record_statistics_alone_is_refused(tmp_path):
    """A record's statistics are predicted at the training length whatever the record's:
    a preview saved nothing there and compared a 20 s record's statistics with the whole
    record's (the configuration audit of stop 64)."""
    with pytest.raises(RailsuspInputError, match="^preview_generations with record statistics"):
        NSGAConfig(n_gen=5, statistic="mean+p99", preview_generations=2)
    path = tmp_path / "c.toml"
    path.write_text("[estimate]\nn_gen = 10\npreview_generations = 6\n")
    with pytest.raises(RailsuspInputError) as err:
        load_config(path)
    assert 'estimate.preview_generations = 6 with estimate.statistic "mean", record ' in str(
        err.value
    )
    assert str(err.value).endswith("; or set preview_generations = 0")


def test_a_run_without_a_preview_hashes_its_estimate_stage_as_before(tmp_path):
    """Without a preview the estimate section has no preview settings (runs made before the
    option stay up to date); with one, the stage's inputs change and it estimates again."""
    from railsusp.pipeline_config import PipelineConfig

    estimate = {"n_gen": 10, "statistic": "aligned"}
    plain = stage_section(PipelineConfig.model_validate({"estimate": estimate}), "estimate")
    assert not {"preview_generations", "preview_s"} & set(plain)
    estimate |= {"preview_generations": 6, "preview_s": 15}
    previewed = stage_section(PipelineConfig.model_validate({"estimate": estimate}), "estimate")
    assert previewed["preview_generations"] == 6 and previewed["preview_s"] == 15.0


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (
            ["--n-gen", "10", "--preview-generations", "10"],
            "--preview-generations 10: accepted 0 to 9",
        ),
        (
            ["--preview-generations", "5", "--preview-s", "700"],
            "--preview-s 700: accepted 1 to 600",
        ),
    ],
)
def test_the_command_line_refuses_a_bad_preview_before_reading_anything(tmp_path, options, message):
    result = CliRunner().invoke(
        app,
        ["estimate", "--simulator", "--measured", str(tmp_path / "none"), "--out",
         str(tmp_path / "out"), *options],
    )  # fmt: skip
    assert result.exit_code == 2
    assert message in result.output
    assert not (tmp_path / "out").exists()


def test_expected_draws_without_a_stated_accuracy_say_they_do_nothing():
    """``expected_draws`` on recordings whose geometry states no accuracy drew nothing and
    polished nothing, without a word (the command-line audit of stop 60): warned once, also
    with preview generations (each search used to check again)."""
    import warnings

    rec = long_recording()
    assert rec.condition.track_accuracy_mm == 0.0
    cfg = NSGAConfig(pop_size=8, n_gen=3, statistic="aligned", expected_draws=2)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        estimate(WaveForces(), [rec], PARAMS, replace(cfg, preview_generations=1, preview_s=1))
    said = [w for w in seen if "no recording states its track geometry's accuracy" in str(w)]
    assert len(said) == 1
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        estimate(WaveForces(), [rec], PARAMS, replace(cfg, expected_draws=0))
    assert not [w for w in seen if "accuracy" in str(w.message)]
