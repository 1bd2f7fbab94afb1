"""The simulation-based posterior of another wagon, and of the force laws it was trained on:
its settings name the wagon they simulate (and hash it), its training cases simulate that
wagon, a recording is checked against that wagon's wheel load, estimators of two wagons
are not joined, and a folder simulated with other force laws (MODEL_REVISION) is refused,
not mixed with new simulations or read as if it were this model's (stop 60)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.conditions import get_condition
from railsusp.errors import RailsuspInputError
from railsusp.estimate import posterior, posterior_data, posterior_synthetic_run
from railsusp.estimate.posterior_joint import check_parts
from railsusp.estimate.posterior_settings import PosteriorSettings
from railsusp.measured import synthesise_field
from railsusp.params import ParameterSet
from railsusp.store import content_hash, write_json
from railsusp.vehicle import MODEL_REVISION

CONDITION = get_condition("straight").with_changes(lead_in_m=30.0)


def settings(**kw) -> PosteriorSettings:
    base = dict(parameters=("X14",), section_s=1.0, n_train=20, n_check=10, n_calibration=0)
    return PosteriorSettings((CONDITION,), **{**base, **kw})


def test_the_settings_store_the_wagon_they_simulate():
    plain = settings()
    assert plain.wagon is None and "wagon" not in plain.to_dict()  # hashed as before
    for same in ("loaded", "c80_k6"):  # the packaged loaded C80 by name is the default
        assert settings(wagon=same).to_dict() == plain.to_dict()
    tare = settings(wagon="tare")
    assert tare.to_dict()["wagon"]["car_body"]["mass"] < 0.5 * 1e5
    assert content_hash(tare.to_dict()) != content_hash(plain.to_dict())
    assert PosteriorSettings.from_dict(tare.to_dict()) == tare


def test_the_training_cases_simulate_the_estimators_wagon():
    """The tare C80's median wheel load is about a fifth of the loaded one's (24.5 against
    121.9 kN static); before stop 60 every estimator simulated the loaded C80."""
    u = np.full((1, 10), 0.5)
    q50 = settings().summary_names.index("straight:Q_p50")
    loaded = posterior_data.simulate_long_cases(settings(), u, 0, "train", 1)[0, 0, q50]
    tare = posterior_data.simulate_long_cases(settings(wagon="tare"), u, 0, "train", 1)[0, 0, q50]
    assert loaded == pytest.approx(121.9, rel=0.05)
    assert tare == pytest.approx(24.5, rel=0.1)


def stamped(run, s: PosteriorSettings, **stamp) -> None:
    folder = run / "posterior"
    write_json(folder / "settings.json", {"hash": content_hash(s.to_dict()),
                                           "settings": s.to_dict(), **stamp})  # fmt: skip
    for name in ("estimator.pt", "calibration.json"):
        (folder / name).write_bytes(b"")


@pytest.mark.parametrize(
    ("stamp", "said"),
    [({}, "force laws older than any recorded force-law revision (it records none"),
     ({"model_revision": "2026-01-01.1"}, "force-law revision 2026-01-01.1, older than this "
      f"railsusp's {MODEL_REVISION}"),
     ({"model_revision": "2099-01-01.1"}, "force-law revision 2099-01-01.1, newer than this "
      f"railsusp's {MODEL_REVISION}: use it with the railsusp that made it")],
)  # fmt: skip
def test_an_estimator_of_other_force_laws_is_refused(tmp_path, monkeypatch, stamp, said):
    message = f"its simulations were made with {said}"
    _refused_by_train_and_load(tmp_path, monkeypatch, stamp, message)


def _refused_by_train_and_load(tmp_path, monkeypatch, stamp: dict, message: str) -> None:
    """train() and load() of a folder stamped ``stamp`` refuse it in one line holding
    ``message``, before any simulation."""

    def no_simulation(*a, **k):
        raise AssertionError("simulated")

    monkeypatch.setattr(posterior_data, "simulate_long_cases", no_simulation)
    s = settings()
    stamped(tmp_path, s, **stamp)
    for attempt in (lambda: posterior.train(s, tmp_path), lambda: posterior.load(tmp_path)):
        with pytest.raises(RailsuspInputError) as err:
            attempt()
        assert message in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize(
    ("version", "said"),
    [(None, "a version before 2026-11-30.2 (none recorded)"),
     ("2026-01-01.1", "version 2026-01-01.1")],
)  # fmt: skip
def test_an_estimator_of_other_statistics_is_refused(tmp_path, monkeypatch, version, said):
    """Statistics cached under other definitions (stop 62 changed sumY's sign, Y/Q and the
    percentiles' ends) were matched by their draws alone and mixed with new ones."""
    from railsusp.estimate.summaries import STATISTICS_VERSION

    stamp = {"model_revision": MODEL_REVISION}
    if version is not None:
        stamp["statistics_version"] = version
    message = f"its summary statistics are of the definitions of {said}, this railsusp "
    _refused_by_train_and_load(
        tmp_path, monkeypatch, stamp, message + f"computes version {STATISTICS_VERSION}"
    )


def test_a_fresh_estimator_folder_records_its_force_laws(tmp_path, monkeypatch):
    """train() stamps settings.json with the revision before it simulates anything."""

    def stop(*a, **k):
        raise RuntimeError("stop before simulating")

    monkeypatch.setattr(posterior_data, "simulate_long_cases", stop)
    with pytest.raises(RuntimeError, match="stop before"):
        posterior.train(settings(), tmp_path)
    from railsusp.store import read_json

    stamp = read_json(tmp_path / "posterior" / "settings.json")
    assert stamp["model_revision"] == MODEL_REVISION
    from railsusp.estimate.summaries import STATISTICS_VERSION

    assert stamp["statistics_version"] == STATISTICS_VERSION


def test_a_synthetic_likelihood_of_other_force_laws_is_refused(tmp_path):
    folder = tmp_path / "posterior" / "synthetic"
    folder.mkdir(parents=True)
    write_json(folder / "settings.json", {"hash": "x", "settings": settings().to_dict()})
    for name in ("emulator.npz", "scales.json", "check.json"):
        (folder / name).write_bytes(b"")
    with pytest.raises(RailsuspInputError, match=r"\(it records none"):
        posterior_synthetic_run.load(tmp_path)


def test_estimators_of_two_wagons_are_not_joined():
    parts = [SimpleNamespace(settings=settings()), SimpleNamespace(settings=settings(wagon="tare"))]
    with pytest.raises(RailsuspInputError, match="estimator 2 simulated another wagon"):
        check_parts(parts)


def test_posterior_estimate_checks_recordings_against_the_estimators_wagon(tmp_path, monkeypatch):
    """A tare C80's recordings pass the wheel-load check of a tare estimator (before, they
    were checked against the loaded C80's 121.9 kN and refused)."""
    synthesise_field(
        ParameterSet.nominal(), [CONDITION], tmp_path / "f", duration_s=1.0, wagon="tare"
    )
    tare = settings(wagon="tare")
    monkeypatch.setattr(posterior, "load", lambda run: SimpleNamespace(settings=tare))

    def reached(est, recordings, seed=0):
        q = np.mean(recordings[0].Q[recordings[0].wheels[0]])
        raise RailsuspInputError(f"reached with {len(recordings)} recording(s), Q {q:.0f} kN")

    monkeypatch.setattr(posterior, "estimate", reached)
    args = ["posterior", "estimate", "--measured", str(tmp_path / "f"), "--estimator", "RUN"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2
    assert "reached with 1 recording(s), Q 2" in result.output  # about 24.5 kN


def test_posterior_train_names_a_wagon_that_cannot_be_read(tmp_path):
    args = ["posterior", "train", "--out", str(tmp_path / "run"), "--wagon", "nowhere.toml"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2
    assert "nowhere.toml" in result.output and len(result.output.strip().splitlines()) == 1
