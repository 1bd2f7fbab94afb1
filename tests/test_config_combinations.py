"""Settings that cannot work together are refused before any stage runs, naming the
settings that conflict: one line, exit status 2 on the command line, the same error from
the Python API (railsusp.config)."""

from __future__ import annotations

import tomllib

import pytest
from typer.testing import CliRunner

import railsusp
from railsusp.cli import app
from railsusp.conditions import get_condition
from railsusp.config import ConfigError
from railsusp.errors import RailsuspInputError
from railsusp.measured import synthesise_field
from railsusp.params import ParameterSet
from railsusp.pipeline import load_config

runner = CliRunner()

SHORT = '[{base="straight", name="short", duration_s=1.0, n_steps=50, lead_in_m=20.0}]'


@pytest.fixture(scope="module")
def blind_field(tmp_path_factory):
    """A measured-recordings folder whose recording carries no track geometry."""
    root = tmp_path_factory.mktemp("blind")
    cond = get_condition("straight", name="short", duration_s=1.0, n_steps=50, lead_in_m=20.0)
    return synthesise_field(ParameterSet({"X13": 16.1}, units="display"), [cond], root / "f")


def toml(field: str, estimate: str = "", surrogate: str = "") -> str:
    return (
        f'name = "t"\nconditions = {SHORT}\n[campaign]\nsamples = 10\n'
        f"[field]\n{field}\n[estimate]\n{estimate}\n[surrogate]\n{surrogate}\n"
    )


def as_dict(field: dict, estimate: dict | None = None, surrogate: dict | None = None) -> dict:
    return {
        "conditions": [
            {
                "base": "straight",
                "name": "short",
                "duration_s": 1.0,
                "n_steps": 50,
                "lead_in_m": 20.0,
            }
        ],
        "campaign": {"samples": 10},
        "field": field,
        "estimate": estimate or {},
        "surrogate": surrogate or {},
    }


def run_refused(tmp_path, text: str, name: str = "c.toml") -> str:
    """`railsusp run` of the configuration ``text``: exit status 2, one line, and no stage
    run (not even the run directory made); returns the line."""
    cfg = tmp_path / name
    cfg.write_text(text)
    out = tmp_path / "run"
    result = runner.invoke(app, ["run", str(cfg), "--out", str(out)])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1, result.output
    assert not out.exists()
    return lines[0]


CASES = [
    (  # used to fail after NSGA-II, with a message about statistic 'aligned'
        "refine-without-track",
        ("truth = {X13 = 16.1}\nwith_track = false", "refine = true", ""),
        ({"truth": {"X13": 16.1}}, {"refine": True}, {}),
        "estimate.refine = true with field.with_track = false",
    ),
    (
        "aligned-without-track",
        ("truth = {X13 = 16.1}", 'statistic = "aligned"', ""),
        ({"truth": {"X13": 16.1}}, {"statistic": "aligned"}, {}),
        'estimate.statistic "aligned" with field.with_track = false',
    ),
    (
        "aligned-with-gp-stats",
        (
            "truth = {X13 = 16.1}\nwith_track = true",
            'statistic = "mean+aligned"',
            'model = "gp-stats"',
        ),
        (
            {"truth": {"X13": 16.1}, "with_track": True},
            {"statistic": "mean+aligned"},
            {"model": "gp-stats"},
        ),
        'estimate.statistic "aligned" compares force series sample by sample; the statistics '
        'GPs of surrogate.model = "gp-stats"',
    ),
    (
        "p99.85-with-gp-stats",
        ("truth = {X13 = 16.1}", 'statistic = "p99.85"', 'model = "gp-stats"'),
        ({"truth": {"X13": 16.1}}, {"statistic": "p99.85"}, {"model": "gp-stats"}),
        'estimate.statistic "p99.85" (EN 14363) is computed from force series',
    ),
    (
        "noise-weighting-without-gp-stats",
        ("truth = {X13 = 16.1}", 'weighting = "noise"', 'model = "bp"'),
        ({"truth": {"X13": 16.1}}, {"weighting": "noise"}, {"model": "bp"}),
        'estimate.weighting = "noise" needs the predictive SD of surrogate.model = "gp-stats"',
    ),
    (
        "channel-gains-without-aligned",
        ("truth = {X13 = 16.1}", 'statistic = "mean+p99"\nchannel_gains = true', ""),
        ({"truth": {"X13": 16.1}}, {"statistic": "mean+p99", "channel_gains": True}, {}),
        "estimate.channel_gains = true profiles the gains out of the time-aligned comparison; "
        'estimate.statistic = "mean+p99" has none',
    ),
    (
        "expected-draws-without-aligned",
        ("truth = {X13 = 16.1}", 'statistic = "mean"\nexpected_draws = 8', ""),
        ({"truth": {"X13": 16.1}}, {"statistic": "mean", "expected_draws": 8}, {}),
        "estimate.expected_draws = 8 compares mean predictions over drawn tracks; "
        "estimate.statistic = \"mean\": accepted 'aligned' alone (the polish is the "
        "time-aligned least squares; 'aligned+mean' with expected_generations)",
    ),
    (
        "expected-draws-with-mean-outside-the-generations",
        (
            "truth = {X13 = 16.1}\nwith_track = true",
            'statistic = "aligned+mean"\nexpected_draws = 8',
            "",
        ),
        (
            {"truth": {"X13": 16.1}, "with_track": True},
            {"statistic": "aligned+mean", "expected_draws": 8},
            {},
        ),
        "estimate.statistic = \"aligned+mean\": accepted 'aligned' alone",
    ),
    (
        "simulator-corrections-without-aligned",
        ("truth = {X13 = 16.1}", 'statistic = "mean"\nsimulator_corrections = 1', ""),
        ({"truth": {"X13": 16.1}}, {"statistic": "mean", "simulator_corrections": 1}, {}),
        "estimate.simulator_corrections = 1 corrects the time-aligned least squares; "
        'estimate.statistic = "mean": accepted "aligned" alone',
    ),
    (
        "correction-slopes-without-corrections",
        (
            "truth = {X13 = 16.1}\nwith_track = true",
            'statistic = "aligned"\ncorrection_slopes = true',
            "",
        ),
        (
            {"truth": {"X13": 16.1}, "with_track": True},
            {"statistic": "aligned", "correction_slopes": True},
            {},
        ),
        "estimate.correction_slopes = true makes each simulator correction first order; "
        "estimate.simulator_corrections = 0 asks for none",
    ),
    (
        "slope-update-without-correction-slopes",
        (
            "truth = {X13 = 16.1}\nwith_track = true",
            'statistic = "aligned"\nsimulator_corrections = 1\nslope_update = "broyden"',
            "",
        ),
        (
            {"truth": {"X13": 16.1}, "with_track": True},
            {"statistic": "aligned", "simulator_corrections": 1, "slope_update": "broyden"},
            {},
        ),
        'estimate.slope_update = "broyden" updates the slopes of first-order corrections; '
        "estimate.correction_slopes = false asks for none",
    ),
    (
        "expected-generations-without-draws",
        (
            "truth = {X13 = 16.1}\nwith_track = true",
            'statistic = "aligned"\nexpected_generations = true',
            "",
        ),
        (
            {"truth": {"X13": 16.1}, "with_track": True},
            {"statistic": "aligned", "expected_generations": True},
            {},
        ),
        "estimate.expected_generations = true compares expected forces in NSGA-II's "
        "generations; estimate.expected_draws = 0 draws none",
    ),
    (  # used to fail in the estimate stage, after the campaign, sensitivity and surrogates
        "aligned-with-the-surrogates-trained-here",
        (
            "truth = {X13 = 16.1}\nwith_track = true",
            'refine = true\nstatistic = "mean+aligned"',
            "",
        ),
        (
            {"truth": {"X13": 16.1}, "with_track": True},
            {"refine": True, "statistic": "mean+aligned"},
            {},
        ),
        'estimate.statistic "aligned" needs surrogate.pretrained: the surrogates a run trains',
    ),
    (  # used to fail in the surrogate stage, after the campaign and the sensitivity analysis
        "sequence-network-on-a-short-condition",
        ("truth = {X13 = 16.1}", "", 'model = "cnn-gru-seq"'),
        ({"truth": {"X13": 16.1}}, {}, {"model": "cnn-gru-seq"}),
        'surrogate.model = "cnn-gru-seq" reads 100 steps before its first prediction; the '
        "conditions short have no more steps than that: accepted n_steps > 100",
    ),
    (
        "track-noise-without-track",
        ("truth = {X13 = 16.1}\ntrack_noise_mm = 0.5", "", ""),
        ({"truth": {"X13": 16.1}, "track_noise_mm": 0.5}, {}, {}),
        "field.track_noise_mm needs field.with_track = true",
    ),
]


@pytest.mark.parametrize(("name", "text", "mapping", "needle"), CASES, ids=[c[0] for c in CASES])
def test_conflicting_settings_are_refused_before_any_stage(tmp_path, name, text, mapping, needle):
    assert needle in run_refused(tmp_path, toml(*text))
    out = tmp_path / "run"
    with pytest.raises(ConfigError) as info:  # the Python API: the same one-line error
        railsusp.run(as_dict(*mapping), out=out)
    assert needle in str(info.value) and "\n" not in str(info.value)
    assert not out.exists()


def test_refine_or_aligned_on_a_measured_folder_without_track_geometry(tmp_path, blind_field):
    """Recordings from a folder: the sidecars say whether they carry track geometry; this
    used to pass the configuration and fail in the estimate stage, after the campaign,
    the sensitivity analysis and the surrogates."""
    for estimate, what in (
        ("refine = true", "estimate.refine = true"),
        ('statistic = "aligned"', 'estimate.statistic "aligned"'),
    ):
        line = run_refused(tmp_path, toml(f'measured = "{blind_field}"', estimate))
        assert f"{what} with field.measured = '{blind_field}': short carry no track" in line
        out = tmp_path / "run"
        with pytest.raises(ConfigError, match="short carry no track geometry"):
            railsusp.run(
                as_dict({"measured": str(blind_field)}, {"refine": "refine" in estimate}
                        | ({"statistic": "aligned"} if "aligned" in estimate else {})),
                out=out,
            )  # fmt: skip
    # the same folder without the settings that need track geometry is accepted
    cfg = tmp_path / "ok.toml"
    cfg.write_text(toml(f'measured = "{blind_field}"'))
    assert load_config(cfg).field.measured == str(blind_field)


def test_settings_that_work_together_are_accepted(tmp_path):
    for text in (
        ("truth = {X13 = 16.1}\nwith_track = true", "refine = true", ""),
        ("truth = {X13 = 16.1}", 'statistic = "mean+p99"', 'model = "gp-stats"'),
        ("truth = {X13 = 16.1}", 'weighting = "noise"', 'model = "gp-stats"'),
    ):
        cfg = tmp_path / "c.toml"
        cfg.write_text(toml(*text))
        load_config(cfg)


@pytest.mark.parametrize(
    ("entry", "needle"),
    [
        ("X13 = 101", "tolerances.X13 = 101: accepted a number in (0, 100]"),
        ("X9 = 10", "tolerances.X9: accepted default_pct or a main suspension parameter"),
        ("default_pct = -5", "tolerances.default_pct = -5"),
    ],
)
def test_a_bad_tolerance_in_the_wagon_file_is_refused_before_any_stage(tmp_path, entry, needle):
    """The wagon file's [tolerances] serve only the report's verdicts, so before stop 56 a
    bad entry passed the configuration's checks and stopped the run in its last stage, after
    the campaign, the surrogates and the estimate."""
    from importlib import resources

    wagon = tmp_path / "w.toml"
    text = resources.files("railsusp").joinpath("data/c80_k6.toml").read_text("utf-8")
    wagon.write_text(f"{text}\n[tolerances]\n{entry}\n")
    line = run_refused(tmp_path, f'wagon = "{wagon}"\n' + toml("truth = {X13 = 16.1}"))
    assert needle in line and "wagon: " in line


def test_a_packaged_wagon_named_in_the_configuration_has_the_default_tolerances(tmp_path):
    """``wagon = "tare"`` (a packaged wagon, as load_wagon takes it) failed the report stage
    with "wagon file tare does not exist", after every other stage: the tolerances were read
    from a file of that name. They are now read from the packaged file, before any stage."""
    from railsusp.suspension_tolerances import DEFAULT_TOLERANCE_PCT, read_tolerances

    for name in ("tare", "loaded", "c80_k6_tare"):
        assert read_tolerances(name).default_pct == DEFAULT_TOLERANCE_PCT
    cfg = tmp_path / "c.toml"
    cfg.write_text('wagon = "tare"\n' + toml("truth = {X13 = 16.1}"))
    assert load_config(cfg).wagon == "tare"
    with pytest.raises(railsusp.RailsuspInputError, match="wagon file nowhere does not exist"):
        read_tolerances("nowhere")


def test_a_cuda_device_is_refused_before_any_stage_where_there_is_none(tmp_path):
    """Refused before the campaign where the surrogates are still to train; a run whose
    surrogates were trained on a GPU is still estimated again on a machine without one (the
    review of stop 57 found the first version refusing that too)."""
    import torch

    from railsusp.config import check_cuda
    from railsusp.pipeline import run_pipeline

    if torch.cuda.is_available():
        pytest.skip("this machine has a CUDA device")
    cfg = tmp_path / "c.toml"
    cfg.write_text(toml("truth = {X13 = 16.1}", "", 'device = "cuda"'))
    config = load_config(cfg)  # the file itself is fine
    out = tmp_path / "run"
    with pytest.raises(ConfigError, match='surrogate.device = "cuda": no CUDA device'):
        run_pipeline(config, out)
    assert not out.exists()
    check_cuda(config, "c.toml", surrogate_done=True)  # trained: nothing to refuse


@pytest.mark.parametrize("damage", ["index", "table"])
def test_a_damaged_measured_folder_is_refused_before_any_stage(tmp_path, blind_field, damage):
    """Before stop 57 a measured folder's recordings were first read in the field stage,
    after the campaign, the sensitivity analysis and the surrogates had run."""
    import shutil

    folder = tmp_path / "measured"
    shutil.copytree(blind_field, folder)
    if damage == "index":
        (folder / "index.json").write_text("{garbage")
        needle = "index.json: not valid JSON"
    else:
        (folder / "short.csv").unlink()
        needle = "short"
    line = run_refused(tmp_path, toml(f'measured = "{folder}"'))
    assert "field.measured: " in line and needle in line, line


def test_a_missing_wagon_beside_a_measured_folder_is_named_as_the_wagons(tmp_path, blind_field):
    """The folder's recordings are read as the run's wagon before the wagon's own check: a
    wagon file that does not exist was said as "field.measured: wagon file ... does not
    exist", naming the folder, which was fine."""
    line = run_refused(tmp_path, 'wagon = "nowhere.toml"\n' + toml(f'measured = "{blind_field}"'))
    assert "wagon: wagon file nowhere.toml does not exist" in line, line
    assert "field.measured" not in line, line


def test_a_condition_file_named_in_the_list_is_pointed_to_a_table(tmp_path):
    """The message offered "or a TOML file", which the configuration's list then refused."""
    cfg = tmp_path / "c.toml"
    cfg.write_text(
        toml("truth = {X13 = 16.1}").replace(f"conditions = {SHORT}", 'conditions = ["my.toml"]')
    )
    with pytest.raises(ConfigError) as info:
        load_config(cfg)
    text = str(info.value)
    assert "unknown condition 'my.toml'; accepted: straight, curve, uphill, or a table" in text
    assert "TOML file" not in text


@pytest.mark.parametrize(
    ("section", "line", "needle"),
    [
        ("campaign", "samples = 2", "campaign.samples = 2: accepted [5, 1000000] (Input should"),
        ("campaign", "sample = 10", "campaign.sample: accepted keys: samples, design, seed,"),
        ("field", "rate_hz = 9000", "field.rate_hz = 9000: accepted [50, 5000] (Input should"),
    ],
)
def test_a_value_out_of_range_or_an_unknown_key_says_what_is_accepted(
    tmp_path, section, line, needle
):
    """pydantic's message gives one bound ("Input should be greater than or equal to 4") and
    no keys for a misspelt one; the configuration's rule is the field and its range."""
    text = toml("truth = {X13 = 16.1}").replace(f"[{section}]\n", f"[{section}]\n{line}\n", 1)
    if line.startswith("sample"):
        text = text.replace("samples = 10\n", "", 1)
    cfg = tmp_path / "c.toml"
    cfg.write_text(text)
    with pytest.raises(RailsuspInputError) as info:
        load_config(cfg)
    assert needle in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(RailsuspInputError) as info:  # the Python API says the same
        railsusp.run(tomllib.loads(text), out=tmp_path / "run")
    assert needle in str(info.value)


@pytest.mark.parametrize("text", ["", "# only a comment\n"])
def test_an_empty_configuration_is_refused(tmp_path, text):
    """It ran the whole default pipeline for minutes and exited 0 (stop 57's audit)."""
    line = run_refused(tmp_path, text, "empty.toml")
    cfg = tmp_path / "empty.toml"
    assert f"configuration {cfg} is empty: accepted a file with at least one setting" in line


# ---- the configuration audit of stop 64: settings that passed and failed a later stage ----


def _field_of(root, cond, **kw):
    return synthesise_field(ParameterSet({"X13": 16.1}, units="display"), [cond], root, **kw)


def test_measured_recordings_the_runs_surrogates_cannot_serve_are_refused(tmp_path):
    """A measured folder's recording of a condition the run does not train, or of its
    condition at another speed, failed at the estimate stage after four stages ("no
    surrogate of that condition ... --from surrogate remakes it")."""
    other = _field_of(
        tmp_path / "other",
        get_condition("straight", name="other", duration_s=1.0, n_steps=50, lead_in_m=20.0),
    )
    line = run_refused(tmp_path, toml(f'measured = "{other}"'))
    assert line.endswith(
        f"field.measured = '{other}': recording 'other' is of none of the run's conditions "
        "(short), whose surrogates it trains; accepted recordings named as a condition of the "
        "run (set conditions to the recordings' conditions)"
    )
    fast = _field_of(
        tmp_path / "fast",
        get_condition(
            "straight", name="short", duration_s=1.0, n_steps=50, lead_in_m=20.0, speed_kmh=40.0
        ),
    )
    line = run_refused(tmp_path, toml(f'measured = "{fast}"'))
    assert "recording 'short' has speed_kmh = 40.0, the run's condition 'short' 60.0" in line
    # the statistics GPs the same, by their own check (skipped before stop 77: the run
    # failed at the estimate stage after four stages)
    line = run_refused(tmp_path, toml(f'measured = "{fast}"', "", 'model = "gp-stats"'))
    assert line.endswith(
        f"field.measured = '{fast}': recording 'short': the statistics surrogate of its "
        "condition is trained on another one, which differs in speed_kmh (speed_kmh 40.0 "
        "against 60.0); accepted recordings that differ from it only in the track and the "
        "record length"
    )
    # another record length and another track are what a recording may differ in
    longer = _field_of(
        tmp_path / "longer",
        get_condition("straight", name="short", duration_s=2.0, n_steps=100, lead_in_m=20.0),
        seed=11,
    )
    (tmp_path / "ok.toml").write_text(toml(f'measured = "{longer}"'))
    assert load_config(tmp_path / "ok.toml").field.measured == str(longer)


def test_a_measured_recording_sampled_otherwise_than_its_condition_is_refused_for_refine(
    tmp_path,
):
    """A sidecar whose condition.n_steps is not its table's rows: the refinement and the
    statistic "aligned" compare sample by sample, so that failed at the estimate stage,
    after the campaign, the sensitivity, the surrogates and the field (stop 77's hunt)."""
    import json

    cond = get_condition("straight", name="short", duration_s=1.0, n_steps=50, lead_in_m=20.0)
    field = _field_of(tmp_path / "f", cond, with_track=True)
    sidecar = field / "short.json"
    doc = json.loads(sidecar.read_text())
    doc["condition"]["n_steps"] = 100
    sidecar.write_text(json.dumps(doc))
    conditions = 'conditions = [{base="straight", name="short", duration_s=1.0, n_steps=100, '
    conditions += "lead_in_m=20.0}]"
    for estimate, use in (
        ("refine = true", "estimate.refine (the output-error refinement)"),
        ('statistic = "aligned"', "the time-aligned comparison (statistic 'aligned')"),
    ):
        text = toml(f'measured = "{field}"', estimate).replace(f"conditions = {SHORT}", conditions)
        line = run_refused(tmp_path, text)
        assert (
            f"field.measured = '{field}': recording 'short': condition.n_steps 100 samples its "
            "1 s at 100 Hz, its table has 50 rows at 50 Hz; " + use
        ) in line
    # without a sample-by-sample comparison the recording is read at its own rate
    ok = tmp_path / "ok.toml"
    ok.write_text(toml(f'measured = "{field}"').replace(f"conditions = {SHORT}", conditions))
    assert load_config(ok).field.measured == str(field)


def test_measured_recordings_outside_a_network_sets_training_are_refused(tmp_path):
    """The same with ``surrogate.pretrained``: the set was checked on the configured
    conditions only, not on the recordings the estimate compares."""
    cond = get_condition("straight", duration_s=2.0, n_steps=100, speed_kmh=40.0)
    folder = _field_of(tmp_path / "m40", cond, with_track=True)
    text = (
        'name = "t"\nconditions = [{base = "straight", duration_s = 2.0, n_steps = 100}]\n'
        '[surrogate]\nmodel = "cnn-gru-seq"\npretrained = "c80_k6"\n'
        f'[field]\nmeasured = "{folder}"\n[estimate]\nstatistic = "aligned"\n'
    )
    line = run_refused(tmp_path, text)
    assert "field.measured: surrogate.pretrained = 'c80_k6': condition 'straight' has " in line
    assert "speed_kmh = 40.0, outside what its network was trained on" in line


@pytest.mark.parametrize("steps", [50, 100])
def test_records_no_longer_than_a_network_sets_window_are_refused(tmp_path, steps):
    """A network set's sequence networks read 100 steps before their first prediction: a
    condition of no more steps (1 s at 50 Hz) was accepted, the campaign, sensitivity,
    surrogate and field stages ran, and the estimate stage failed on predictions of NaN
    alone with pymoo's "Invalid progress was set by the TerminationCriterion"."""
    text = (
        f'name = "t"\nconditions = [{{base = "straight", duration_s = {steps / 50}, '
        f"n_steps = {steps}}}]\n"
        '[surrogate]\nmodel = "cnn-gru-seq"\npretrained = "c80_k6"\n'
        "[field]\ntruth = {X13 = 16.1}\nwith_track = true\n"
    )
    line = run_refused(tmp_path, text)
    assert (
        "surrogate.pretrained = 'c80_k6': its networks read 100 steps before their first "
        f"prediction; the conditions straight (n_steps = {steps}) have no more steps than "
        "that: accepted n_steps > 100"
    ) in line
    ok = tmp_path / "ok.toml"  # one step more predicts: accepted
    ok.write_text(
        text.replace(f"n_steps = {steps}", "n_steps = 101").replace(
            f"duration_s = {steps / 50}", "duration_s = 2.02"
        )
    )
    assert load_config(ok).conditions[0]["n_steps"] == 101


PRETRAINED = 'model = "cnn-gru-seq"\npretrained = "c80_k6"'
# a network set predicts past its networks' 100-step washout: more steps than that
THREE_SECONDS = 'conditions = [{base = "straight", duration_s = 3.0, n_steps = 150}]'


@pytest.mark.parametrize(
    ("field", "estimate", "surrogate", "said"),
    [
        (  # nsga's seed spread refused it at the estimate stage
            "truth = {X13 = 16.1}",
            "seed = 4294967295\nseeds = 3",
            "",
            "estimate.seed = 4294967295 with estimate.seeds = 3: accepted seed + seeds - 1 at "
            "most 4294967295",
        ),
        (  # the estimate warned and went on unpolished
            "truth = {X13 = 16.1}\nwith_track = true",
            'statistic = "aligned"\nexpected_draws = 2',
            PRETRAINED,
            "estimate.expected_draws = 2 draws true tracks about the recordings' measured one "
            "by its stated accuracy; field.track_noise_mm = 0 gives the synthetic recordings "
            "exact geometry, so none would be drawn: set field.track_noise_mm > 0",
        ),
    ],
)
def test_estimate_settings_that_failed_or_were_ignored_at_the_estimate_stage(
    tmp_path, field, estimate, surrogate, said
):
    text = toml(field, estimate, surrogate).replace(f"conditions = {SHORT}", THREE_SECONDS)
    assert said in run_refused(tmp_path, text)


def test_a_measured_folder_without_a_stated_accuracy_refuses_expected_draws(tmp_path):
    cond = get_condition("straight", duration_s=2.0, n_steps=100)
    folder = _field_of(tmp_path / "exact", cond, with_track=True)  # track_accuracy_mm 0
    text = (
        'name = "t"\nconditions = [{base = "straight", duration_s = 2.0, n_steps = 100}]\n'
        '[surrogate]\nmodel = "cnn-gru-seq"\npretrained = "c80_k6"\n'
        f'[field]\nmeasured = "{folder}"\n[estimate]\nstatistic = "aligned"\nexpected_draws = 2\n'
    )
    assert (
        f"no recording of field.measured = '{folder}' states its geometry's track_accuracy_mm"
        in run_refused(tmp_path, text)
    )


@pytest.mark.parametrize(
    ("field", "sensitivity", "said"),
    [
        ("", 'statistics = ["mean", "mean"]', "sensitivity.statistics: 'mean' is given twice"),
        (
            "",
            "base_samples = 100",
            "sensitivity.base_samples: 100 is not a power of 2; accepted a power of 2 from 64 to "
            "65536 (near it: 64 or 128)",
        ),
        ("rate_hz = 10", "", "field.rate_hz = 10: accepted [50, 5000]"),
    ],
)
def test_settings_that_a_later_stage_refused_or_warned_of(tmp_path, field, sensitivity, said):
    """Repeated statistics made duplicate rows of indices; a base sample that is not a
    power of 2 unbalanced the Sobol' points with a scipy warning naming no setting; a long
    run's sections at 10-49 Hz were written and then refused by the field stage."""
    text = toml(f"truth = {{X13 = 16.1}}\n{field}") + f"[sensitivity]\n{sensitivity}\n"
    assert said in run_refused(tmp_path, text)


def test_synthetic_recordings_below_the_rate_the_estimate_reads_are_refused(tmp_path):
    """50 steps over 1.2 s: the campaign, the sensitivity, the surrogates and the field ran,
    and the estimate refused the generated file at 41.67 Hz (the audit of stop 64)."""
    text = toml("truth = {X13 = 16.1}").replace("duration_s=1.0", "duration_s=1.2")
    assert run_refused(tmp_path, text).endswith(
        "conditions[0] ('short'): n_steps = 50 over duration_s = 1.2 s gives synthetic "
        "recordings of 41.67 Hz, below the 50 Hz the estimate reads; accepted n_steps at "
        "least 60 (or a shorter duration_s)"
    )


@pytest.mark.parametrize(
    ("value", "said"),
    [
        ("[1]", "conditions.0 = 1: a string or a table is needed, not an integer"),
        (
            '[["straight"]]',
            "conditions.0 = ['straight']: a string or a table is needed, not a list",
        ),
    ],
)
def test_a_condition_of_neither_kind_is_one_error_without_pydantics_member_names(
    tmp_path, value, said
):
    """A condition is a name or a table: a value of neither kind was told once per union
    member, under pydantic's internal names (``conditions.0.str``,
    ``conditions.0.'dict[str,any]'``)."""
    line = run_refused(tmp_path, f"conditions = {value}\n")
    assert line.endswith(said) and "dict[" not in line


@pytest.mark.parametrize(("value", "shown"), [('""', "''"), ('"a\\nb"', "'a\\nb'")])
def test_a_run_name_is_one_line_of_text(tmp_path, value, shown):
    """The name titles the report: an empty one was accepted, and one with a newline split
    every line that names the run (the configuration audit of stop 64)."""
    line = run_refused(tmp_path, f"name = {value}\n")
    assert line.endswith(f"name: {shown}: accepted one line of printable text, 1 to 200 characters")


# ---- stop 78's hunt: combinations that passed the check and failed at the estimate stage ----


def _other_wheel(field, old: str = "w1L", new: str = "w1R") -> None:
    """The recording of ``field`` made one of wheel ``new`` (its columns and sidecar)."""
    import json

    table = field / "short.csv"
    table.write_text(table.read_text().replace(f"_{old}_", f"_{new}_"))
    sidecar = field / "short.json"
    doc = json.loads(sidecar.read_text())
    doc["wheels"] = [new if w == old else w for w in doc["wheels"]]
    sidecar.write_text(json.dumps(doc))


def test_a_recording_of_another_wheel_than_the_force_models_is_refused_before_any_stage(
    tmp_path,
):
    """On tangent a recording of the right wheel (the model gives the left) passes NSGA-II
    on record statistics, but the refinement compares sample by sample: it failed after
    NSGA-II had run ("measures w1R, the simulator force model wheel 'auto' gives w1L").
    Refused now, before any stage; the same recording without the refinement is read."""
    cond = get_condition("straight", name="short", duration_s=1.0, n_steps=50, lead_in_m=20.0)
    field = _field_of(tmp_path / "f", cond, with_track=True)
    _other_wheel(field)
    line = run_refused(tmp_path, toml(f'measured = "{field}"', "refine = true"))
    assert (
        f"field.measured = '{field}': recording 'short': its first wheel is w1R, the force "
        "model gives w1L in this condition"
    ) in line
    ok = tmp_path / "ok.toml"
    ok.write_text(toml(f'measured = "{field}"'))
    assert load_config(ok).field.measured == str(field)


def test_a_rate_dependent_statistic_of_a_recording_at_another_rate_is_refused_before_any_stage(
    tmp_path,
):
    """A measured recording at 100 Hz of a condition the run trains at 50 Hz, with p99: the
    surrogate predicts its training record at 50 Hz, and the estimate stage refused it after
    the campaign, the sensitivity and the surrogates. Refused now; the mean is read."""
    cond = get_condition("straight", name="short", duration_s=1.0, n_steps=100, lead_in_m=20.0)
    field = _field_of(tmp_path / "f", cond)
    line = run_refused(tmp_path, toml(f'measured = "{field}"', 'statistic = "p99"'))
    assert (
        f"field.measured = '{field}': recording 'short': statistic 'p99' depends on the "
        "sampling rate; its condition samples at 100 Hz"
    ) in line
    assert "the surrogate this run trains on condition 'short' predicts its training" in line
    ok = tmp_path / "ok.toml"
    ok.write_text(toml(f'measured = "{field}"', 'statistic = "mean"'))
    assert load_config(ok).field.measured == str(field)


def test_a_held_prior_without_the_refinement_names_both_of_its_needs(tmp_path):
    """With statistic "aligned" and no refinement, the advice "set estimate.refine = true"
    led straight to the next refusal (held_prior with "aligned"); the first names both."""
    text = toml("with_track = true", 'statistic = "aligned"\nheld_prior = {X19 = [20000, 40000]}')
    line = run_refused(tmp_path, text)
    assert (
        'set estimate.refine = true with record statistics (not estimate.statistic "aligned")'
        " or leave held_prior out"
    ) in line


@pytest.mark.parametrize(
    ("field", "estimate", "said"),
    [
        ("rate_hz = 100", "", "field.rate_hz sets how field.recording (a long run) is cut"),
        ("min_length_m = 50", "", "field.min_length_m sets how field.recording (a long run)"),
        ("", "refine_starts = 5", "estimate.refine_starts is read only with estimate.refine = "),
        ("", "refine_screen = 1", "estimate.refine_screen is read only with estimate.refine"),
        ("", "preview_s = 5", "estimate.preview_s is read only with estimate.preview_generations"),
    ],
)
def test_settings_the_route_reads_nowhere_are_refused(tmp_path, field, estimate, said):
    """Stop 78's hunt: the long run's cut settings without a long run, the refinement's
    without the refinement (refine_screen 1 against refine_starts 5 passed, unchecked) and
    the preview's length without a preview were accepted and ignored, where their siblings
    (channel_map, held_prior, correction_slopes) were refused. At their defaults, as a run's
    recorded configuration writes them, they are read."""
    line = run_refused(tmp_path, toml(f"truth = {{ X13 = 16.1 }}\n{field}", estimate))
    assert said in line and "leave" in line
    default = tmp_path / "default.toml"
    default.write_text(
        toml("truth = { X13 = 16.1 }\nrate_hz = 50.0\nmin_length_m = 150.0", "refine_starts = 2")
    )
    assert load_config(default).estimate.refine_starts == 2


@pytest.mark.parametrize(
    ("field", "estimate", "said"),
    [
        (  # record statistics, no refinement: nothing draws the error
            "with_track = true\ntrack_noise_mm = 0.5",
            'statistic = "mean"\ngeometry_draws = 4',
            "estimate.geometry_draws = 4: no step draws the track geometry's error, NSGA-II on "
            'estimate.statistic = "mean" draws none (only "aligned" alone does) and '
            "estimate.refine = false; leave it out",
        ),
        (  # exact geometry: no accuracy to draw by, even with the refinement
            "with_track = true",
            "refine = true\nremove_geometry_bias = false",
            "estimate.remove_geometry_bias = false: no step draws the track geometry's error, "
            "field.track_noise_mm = 0 gives the synthetic recordings exact geometry (it would "
            "with field.track_noise_mm > 0 (with with_track = true)); leave it out",
        ),
        (  # no draws: no bias estimated to keep
            "with_track = true\ntrack_noise_mm = 0.5",
            'statistic = "aligned"\ngeometry_draws = 0\nremove_geometry_bias = false',
            "estimate.remove_geometry_bias = false: no step draws the track geometry's error, "
            "estimate.geometry_draws = 0 draws none, so no bias is estimated to keep",
        ),
        (  # expected forces take the error in instead
            "with_track = true\ntrack_noise_mm = 0.5",
            'statistic = "aligned"\nexpected_draws = 2\ngeometry_draws = 3',
            "estimate.geometry_draws = 3: no step draws the track geometry's error, with "
            "estimate.expected_draws = 2 the geometry's error is in the comparison",
        ),
    ],
)
def test_geometry_draws_where_no_step_draws_them_are_refused(tmp_path, field, estimate, said):
    """Stop 78's note left them accepted and ignored on a record-statistics route without
    the refinement (``railsusp estimate`` warned of it; a run's configuration said
    nothing). Where a step draws them, and at their defaults, they are accepted."""
    text = toml(f"truth = {{ X13 = 16.1 }}\n{field}", estimate, PRETRAINED)
    assert said in run_refused(tmp_path, text.replace(f"conditions = {SHORT}", THREE_SECONDS))
    for field, estimate in (
        ("with_track = true\ntrack_noise_mm = 0.5", 'statistic = "aligned"\ngeometry_draws = 4'),
        ("with_track = true\ntrack_noise_mm = 0.5", "refine = true\nremove_geometry_bias = false"),
        (
            "with_track = true",
            'statistic = "mean"\ngeometry_draws = 0\nremove_geometry_bias = true',
        ),
    ):
        ok = tmp_path / "ok.toml"
        ok.write_text(
            toml(f"truth = {{ X13 = 16.1 }}\n{field}", estimate, PRETRAINED).replace(
                f"conditions = {SHORT}", THREE_SECONDS
            )
        )
        load_config(ok)
