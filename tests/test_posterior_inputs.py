"""The posterior commands' inputs and outputs (the docs audit of stop 58): a result written
over an input, a joint posterior inside an estimator's folder, a condition given twice, a
calibration record of another content, the last line of a training whose fused checks
failed."""

import json
import logging

import pytest
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.estimate.posterior_settings import PosteriorSettings

runner = CliRunner()


def test_an_estimate_is_not_written_over_its_inputs_or_a_foreign_file(tmp_path):
    measured, estimator = tmp_path / "field", tmp_path / "runs" / "post"
    (estimator / "posterior").mkdir(parents=True)
    measured.mkdir()
    (measured / "index.json").write_text('{"recordings": []}')
    args = ["posterior", "estimate", "--measured", str(measured), "--estimator", str(estimator)]
    for inside, option in (
        (measured / "index.json", "--measured"),
        (estimator / "posterior" / "calibration.json", "--estimator"),
    ):
        result = runner.invoke(app, [*args, "--out", str(inside)])
        assert result.exit_code == 2, result.output
        assert f"inside {option}" in result.output and "Traceback" not in result.output
    mine = tmp_path / "notes.json"
    mine.write_text('{"mine": 1}')
    result = runner.invoke(app, [*args, "--out", str(mine)])
    assert result.exit_code == 2 and "not a posterior result" in result.output
    assert json.loads(mine.read_text()) == {"mine": 1}
    assert (measured / "index.json").read_text() == '{"recordings": []}'


def test_a_joint_posterior_is_not_put_inside_an_estimators_folder(tmp_path):
    from railsusp.estimate import posterior_joint

    a, b = tmp_path / "a", tmp_path / "b"
    with pytest.raises(RailsuspInputError, match="an estimator's folder"):
        posterior_joint.train([a, b], b / "posterior")


def test_a_condition_given_twice_is_refused():
    straight = get_condition("straight")
    with pytest.raises(RailsuspInputError, match=r"conditions: names repeat \(straight\)"):
        PosteriorSettings((straight, straight))


def test_a_calibration_record_of_another_content_is_made_again(tmp_path, caplog):
    """It was a KeyError traceback on every later estimate and train."""
    from railsusp.estimate import posterior_check

    (tmp_path / "calibration.json").write_text("{}")

    class Remade(Exception):
        pass

    class Estimator:
        @property
        def settings(self):
            raise Remade  # the check is being made again

    with caplog.at_level(logging.WARNING), pytest.raises(Remade):
        posterior_check.calibrate(Estimator(), tmp_path)
    assert "is not a calibration record" in caplog.text


def test_product_cases_without_product_sections_is_refused(tmp_path):
    result = runner.invoke(
        app, ["posterior", "train", "--out", str(tmp_path / "p"), "--product-cases", "50"]
    )
    assert result.exit_code == 2, result.output
    assert "--product-cases 50: counts the cases of --product-sections" in result.output
    assert not (tmp_path / "p").exists()


def test_join_names_a_missing_estimator_folder(tmp_path):
    from railsusp.estimate import posterior_joint

    (tmp_path / "a").mkdir()
    with pytest.raises(RailsuspInputError, match="nosuch: no such folder"):
        posterior_joint.train([tmp_path / "a", tmp_path / "nosuch"], tmp_path / "joint")


def test_training_cases_whose_statistics_are_undefined_are_one_line_not_sbis_traceback():
    """Statistics undefined in most training cases (a lag as long as the section) reached
    sbi, which failed with a 50-line traceback (the command-line audit of stop 60)."""
    import numpy as np

    from railsusp.conditions import get_condition
    from railsusp.estimate import posterior
    from railsusp.estimate.posterior_settings import PosteriorSettings

    s = PosteriorSettings(
        (get_condition("straight"),), parameters=("X13",), n_train=20, n_check=10,
        n_calibration=0,
    )  # fmt: skip
    u = np.random.default_rng(0).random((20, 10))
    x = np.ones((20, len(s.summary_names)))
    x[:15, 3] = np.nan
    with pytest.raises(RailsuspInputError) as err:
        posterior._build(s, u, x)
    assert "15 of 20 training cases have undefined statistics (straight:Q_p0.15)" in str(err.value)
    x[:15, 3] = 1.0
    assert len(posterior._build(s, u, x)[3]) == 20
