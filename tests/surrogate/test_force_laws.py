"""Surrogates remember the force laws they learnt: a bundle trained on a campaign of another
force-law revision is refused where it is opened as the estimate's force model (the
interrupt/resume audit of stop 60 trained on such a campaign and estimated with the result
beside today's simulator), in one line; so is a bundle that records no revision (trained
before revisions were recorded, so on older force laws: the upgrade audit's H2)."""

import json

import pytest

from railsusp.errors import RailsuspInputError
from railsusp.estimate import SurrogateForces
from railsusp.vehicle import MODEL_REVISION
from test_estimate_aligned import tiny_surrogate


def _stamp(folder, revision):
    path = folder / "straight" / "surrogate.json"
    doc = json.loads(path.read_text())
    if revision is None:
        doc["meta"].pop("model_revision", None)
    else:
        doc["meta"]["model_revision"] = revision
    path.write_text(json.dumps(doc))


def test_surrogates_of_other_force_laws_are_refused(tmp_path):
    folder = tiny_surrogate(tmp_path / "s")
    _stamp(folder, MODEL_REVISION)
    assert SurrogateForces(folder).conditions == ["straight"]
    _stamp(folder, None)  # saved before the revision was recorded
    with pytest.raises(RailsuspInputError, match="straight: .* older than any recorded"):
        SurrogateForces(folder)
    _stamp(folder, "2000-01-01.1")
    with pytest.raises(RailsuspInputError) as err:
        SurrogateForces(folder)
    text = str(err.value)
    assert (
        "trained on a campaign simulated with force-law revision 2000-01-01.1, older than "
        f"this railsusp's {MODEL_REVISION}: run the campaign again"
    ) in text and "\n" not in text
    _stamp(folder, "2099-01-01.1")  # a newer railsusp's: used there, not trained again here
    with pytest.raises(RailsuspInputError, match=r"newer than .*: use it with the railsusp"):
        SurrogateForces(folder)
