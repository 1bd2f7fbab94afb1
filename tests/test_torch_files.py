"""Files written by ``torch.save`` read back the same way everywhere (stop 56): a surrogate's
weights, a training checkpoint and the posterior's flows. A file cut short is told apart from
one that reads but holds something else; a pickle that would run code is refused in one line
naming the file, and its code never runs."""

from __future__ import annotations

import json
import pickle
import shutil

import pytest
import torch

from railsusp.errors import RailsuspInputError
from railsusp.integrity import read_torch_file, torch_file_cut_short
from railsusp.surrogate.bundle import load
from railsusp.surrogate.network_set import resolve_network_set

SHIPPED_STRAIGHT = resolve_network_set("c80_k6") / "straight"


def _evil_payload(marker):
    code = f"open({str(marker)!r}, 'w').write('ran')"

    class Evil:
        def __reduce__(self):
            return (exec, (code,))

    return {"weight": Evil()}


def test_cut_short_is_a_short_file_or_a_zip_that_does_not_read(tmp_path):
    f = tmp_path / "w.pt"
    torch.save({"a": torch.ones(100)}, f)
    whole = f.read_bytes()
    assert not torch_file_cut_short(f)
    for damaged in (b"", whole[:3], whole[:-40], whole[:200], bytes(len(whole))):
        f.write_bytes(damaged)  # the last: the zeros a crash can leave
        assert torch_file_cut_short(f), len(damaged)
    f.write_bytes(pickle.dumps({"a": 1}))  # another format: for read_torch_file to judge
    assert not torch_file_cut_short(f)


@pytest.mark.parametrize("zipped", [False, True])
def test_a_crafted_pickle_is_refused_in_one_line_and_runs_no_code(tmp_path, zipped):
    marker = tmp_path / "pwned"
    f = tmp_path / "w.pt"
    if zipped:
        torch.save(_evil_payload(marker), f)
    else:
        f.write_bytes(pickle.dumps(_evil_payload(marker), protocol=2))
    with pytest.raises(RailsuspInputError) as info:
        read_torch_file(f, "surrogate weights", "train it again")
    text = str(info.value)
    assert text.startswith(f"surrogate weights {f} refused: not a plain PyTorch state (")
    assert text.endswith("; train it again") and "\n" not in text
    assert "it holds objects that are not tensors: " in text  # the global it refused
    assert "weights_only" not in text  # torch's advice to load it unsafely is not passed on
    assert not marker.exists()


def test_the_refusal_names_what_torch_found_in_plain_words(tmp_path):
    """The review of stop 56: a NumPy array's refusal carried torch's terminal colour codes
    and its advice to load unsafely; a text file's was a bare "101"."""
    import numpy as np

    f = tmp_path / "w.pt"
    torch.save({"a": np.arange(3)}, f)
    with pytest.raises(RailsuspInputError) as info:
        read_torch_file(f, "checkpoint", "delete it")
    assert "not tensors: numpy." in str(info.value) and "\x1b" not in str(info.value)
    f.write_text("hello world")
    with pytest.raises(RailsuspInputError, match=r"\(no file torch.save writes: KeyError"):
        read_torch_file(f, "checkpoint", "delete it")


def test_a_plain_state_reads_back(tmp_path):
    f = tmp_path / "w.pt"
    torch.save([{"a": torch.arange(3.0)}], f)
    back = read_torch_file(f, "x", "y")
    assert torch.equal(back[0]["a"], torch.arange(3.0))


@pytest.fixture
def network(tmp_path):
    copy = tmp_path / "straight"
    shutil.copytree(SHIPPED_STRAIGHT, copy)
    return copy


def test_a_surrogate_with_crafted_weights_is_refused_naming_the_file(network, tmp_path):
    """Before stop 56 ``bundle.load`` let torch's UnpicklingError through: a traceback."""
    marker = tmp_path / "pwned"
    torch.save(_evil_payload(marker), network / "model.pt")
    with pytest.raises(
        RailsuspInputError,
        match=r"surrogate weights .*model\.pt refused: .*"
        r"train the surrogate again$",
    ):
        load(network)
    assert not marker.exists()


def test_a_surrogate_whose_weights_are_another_network_s_is_refused(network):
    """A state of other layer names or shapes: one line, not load_state_dict's traceback."""
    torch.save({"layer.weight": torch.ones(2, 2)}, network / "model.pt")
    with pytest.raises(RailsuspInputError, match="not the network surrogate.json describes"):
        load(network)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("{not json", "is corrupt: not valid JSON"),
        ("[1, 2]", "unknown surrogate format 'list'"),
        ("[" * 100000 + "]" * 100000, "nested deeper than JSON data is"),
    ],
)
def test_a_damaged_surrogate_json_is_one_line(network, text, message):
    (network / "surrogate.json").write_text(text)
    with pytest.raises(RailsuspInputError, match=message):
        load(network)


def test_the_shipped_network_still_loads(network):
    doc = json.loads((network / "surrogate.json").read_text())
    assert load(network).net_config.kind == doc["net"]["kind"]


def test_a_surrogate_with_weights_cut_short_says_so(network):
    weights = network / "model.pt"
    weights.write_bytes(weights.read_bytes()[:1000])
    with pytest.raises(RailsuspInputError, match=r"model\.pt is cut short or damaged"):
        load(network)


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        (lambda d: d.update(net="cnn"), "not a surrogate description this railsusp reads ("),
        (
            lambda d: d.pop("features"),
            "not a surrogate description this railsusp reads (no 'features')",
        ),
        (lambda d: d.pop("normaliser"), "(no 'normaliser')"),
        (lambda d: d.update(track_seed="x"), "not a surrogate description"),
    ],
)
def test_a_surrogate_json_of_another_shape_is_one_line(network, change, needle):
    """Before: AttributeError or KeyError tracebacks from bundle.load, which `railsusp
    estimate --surrogate` calls directly."""
    doc = json.loads((network / "surrogate.json").read_text())
    change(doc)
    (network / "surrogate.json").write_text(json.dumps(doc))
    with pytest.raises(RailsuspInputError) as info:
        load(network)
    assert needle in str(info.value) and str(info.value).endswith("train the surrogate again")


def test_a_damaged_shipped_set_is_not_told_to_train_again(tmp_path):
    from railsusp.surrogate.pretrained import SET_REMEDY, load_bundle

    copy = tmp_path / "straight"
    shutil.copytree(SHIPPED_STRAIGHT, copy)
    (copy / "model.pt").write_bytes((copy / "model.pt").read_bytes()[:500])
    with pytest.raises(RailsuspInputError) as info:
        load_bundle(copy)
    assert str(info.value).endswith(SET_REMEDY) and "train the" not in str(info.value)
