"""The report stage follows the wagon data's [tolerances]: the wagon's hash leaves them out
(no model input), so an edited table left the report judging by the old ones up to date
while pipeline.json and open_run used the new (the rerun audit of stop 65)."""

from __future__ import annotations

from railsusp.pipeline_config import PipelineConfig
from railsusp.pipeline_inputs import stage_section
from railsusp.vehicle.wagon import packaged_wagon_text


def _wagon(path, tolerances: str = ""):
    path.write_text(packaged_wagon_text(None) + tolerances)
    return str(path)


def test_the_report_stage_reruns_when_only_the_tolerances_change(tmp_path):
    plain = PipelineConfig(wagon=_wagon(tmp_path / "a.toml"))
    strict = PipelineConfig(
        wagon=_wagon(tmp_path / "b.toml", "\n[tolerances]\ndefault_pct = 1.0\n")
    )
    other = PipelineConfig(wagon=_wagon(tmp_path / "c.toml", "\n[tolerances]\nX13 = 5.0\n"))
    reports = [stage_section(c, "report") for c in (plain, strict, other)]
    assert reports[0] != reports[1] and reports[1] != reports[2] and reports[0] != reports[2]
    # the simulated stages do not depend on them: the wagon's data hash as before
    model = [stage_section(c, "campaign")["model"] for c in (plain, strict, other)]
    assert model[0] == model[1] == model[2]
    # without a table the report hashes as it did before the tolerances counted
    assert stage_section(plain, "report", legacy=True) == {"name": plain.name}
    assert stage_section(plain, "report") == {"name": plain.name, "method_revision": "2026-11-30"}


def test_a_cuda_run_whose_changed_campaign_must_train_again_is_refused_before_any_stage(
    tmp_path, monkeypatch
):
    """`device = "cuda"` passed the pre-check wherever the surrogate stage was done, though
    a changed campaign reruns it: the campaign simulated again, then the training failed on
    the missing GPU, the finished results left stale (the rerun audit of stop 65)."""
    import pytest
    import torch

    import railsusp.pipeline as pipeline
    from railsusp.errors import RailsuspInputError
    from railsusp.store import write_json

    if torch.cuda.is_available():
        pytest.skip("a CUDA device is here: nothing to refuse")
    base = {
        "conditions": [{"base": "straight", "name": "short", "duration_s": 1.0, "n_steps": 50,
                        "lead_in_m": 20.0}],
        "surrogate": {"device": "cuda", "model": "bp", "samples": 8},
        "field": {"truth": {"X13": 16.1}},
    }  # fmt: skip
    before = PipelineConfig.model_validate({**base, "campaign": {"samples": 10}})
    # a finished run of `before`
    stages = {s: {"hash": h, "state": "done"} for s, h in pipeline.stage_hashes(before).items()}
    out = tmp_path / "run"
    out.mkdir()
    write_json(out / "pipeline.json", {"format": pipeline.PIPELINE_FORMAT, "stages": stages})

    def ran(*args, **kwargs):
        raise AssertionError("a stage ran before the refusal")

    monkeypatch.setattr(pipeline, "_run_stages", ran)
    changed = PipelineConfig.model_validate({**base, "campaign": {"samples": 12}})
    with pytest.raises(RailsuspInputError, match='surrogate.device = "cuda": no CUDA device'):
        pipeline.run_pipeline(changed, out)
    with pytest.raises(RailsuspInputError, match="no CUDA device"):  # a restart from it too
        pipeline.run_pipeline(before, out, start_from="surrogate")
    with pytest.raises(AssertionError, match="a stage ran"):  # unchanged: it passes
        pipeline.run_pipeline(before, out)
