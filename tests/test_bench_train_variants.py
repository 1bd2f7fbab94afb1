"""bench/train_variants.py: the training variants tried against issue 19's gains do what their
descriptions say (the widened network starts at the narrow one's outputs; the band loss sees
the low band only; a FiLM network starts at the network it is warm-started from and then
depends on its modulation)."""

import subprocess
import sys

import numpy as np
import pytest
import torch

from conftest import BENCH, bench_script
from railsusp.surrogate.models import NetConfig, build_network


@pytest.fixture(scope="module")
def variants():
    return bench_script("train_variants")


def _config(rnn=(6, 4, 3), dense=(5, 4)) -> NetConfig:
    return NetConfig(
        kind="cnn-gru-seq",
        n_features=7,
        window=5,
        conv_channels=(5, 12),
        rnn_hidden=rnn,
        dense=dense,
        dropout=0.0,
    )


def test_widened_network_starts_at_the_narrow_ones_outputs(variants):
    torch.manual_seed(1)
    narrow_cfg, wide_cfg = _config(), _config(rnn=(9, 8, 5), dense=(7, 6))
    narrow = build_network(narrow_cfg).eval()
    for p in narrow.parameters():  # weights large enough that every unit matters
        torch.nn.init.uniform_(p, -0.8, 0.8)
    wide = build_network(wide_cfg).eval()
    wide.load_state_dict(variants.widened(narrow, narrow_cfg, wide_cfg))
    x = torch.randn(4, 60, 7)
    with torch.no_grad():
        a, b = narrow.steps(x)[0], wide.steps(x)[0]
        assert a.abs().max() > 0.1
        assert torch.allclose(a, b, atol=1e-5)
        # the new units exist and compute: their hidden states are not all zero
        _, (_, hidden) = wide.steps(x)
        assert hidden[0][0, :, 6:].abs().max() > 1e-3
    # and a gradient reaches the zeroed weights from the new units into the outputs
    wide.train()
    wide.steps(x)[0].pow(2).sum().backward()
    assert wide.head[0].weight.grad[:, 3:].abs().max() > 0


def test_widened_refuses_a_narrower_target(variants):
    with pytest.raises(ValueError, match="accepted at most"):
        variants.widened(build_network(_config()), _config(), _config(rnn=(6, 2, 3)))
    with pytest.raises(ValueError, match="as many"):
        variants.widened(build_network(_config()), _config(), _config(rnn=(6, 4)))


def test_band_loss_sees_the_low_band_only(variants):
    mse = variants.band_mse(5.0, 101)
    t = np.arange(400) / variants.SAMPLING_HZ
    zero = torch.zeros(2, 400, 2)

    def sine(f):
        return torch.tensor(np.sin(2 * np.pi * f * t), dtype=torch.float32)[None, :, None].expand(
            2, 400, 2
        )

    assert float(mse(sine(1.0), zero)) == pytest.approx(0.5, rel=0.02)
    assert float(mse(sine(15.0), zero)) < 1e-4
    assert float(mse(sine(1.0) + sine(15.0), zero)) == pytest.approx(0.5, rel=0.02)


FILM_CHECK = """
import torch
import railsusp.surrogate.sequence as sequence
from railsusp.surrogate.models import NetConfig, build_network
from railsusp.surrogate.sequence_sets import predict_sets_in_step as fast
from railsusp.surrogate.train import seed_weights

cfg = NetConfig(kind="cnn-gru-seq", n_features=7, window=5, conv_channels=(5, 12),
                rnn_hidden=(6, 4, 3), dense=(5, 4), dropout=0.0)
torch.manual_seed(0)
net = build_network(cfg).eval()
assert len(net.film) == 4
seed_weights(net, 3)  # a cold start's seeding leaves the modulation at zero
assert all(float(p.abs().max()) == 0.0 for p in net.film.parameters())
plain = {k: v for k, v in net.state_dict().items() if not k.startswith("film.")}
net.load_state_dict(plain)  # a warm start from a network without modulation
params, track = torch.rand(3, 2), torch.randn(1, 90, 5)
start = sequence.predict_sets_in_step([net], params, [track], segment=40)[0]
assert torch.allclose(start, fast([net], params, [track], segment=40)[0], atol=1e-5)
with torch.no_grad():
    net.film[1].weight.normal_()
moved = sequence.predict_sets_in_step([net], params, [track], segment=40)[0]
assert (moved - start).abs().max() > 1e-3
bad = dict(plain, extra=torch.zeros(1))
try:
    net.load_state_dict(bad)
except KeyError:
    print("film ok")
"""


def _run(*args: str) -> subprocess.CompletedProcess:
    command = [sys.executable, str(BENCH / "train_variants.py"), *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=120)


def test_film_starts_at_the_plain_network_and_then_modulates(tmp_path):
    script = tmp_path / "film_check.py"
    script.write_text(FILM_CHECK)
    out = _run("--variant", "film", "--film-parameters", "2", str(script))
    assert out.returncode == 0, out.stderr[-2000:]
    assert "film ok" in out.stdout


def test_band_refuses_an_even_filter():
    out = _run("--variant", "band", "--band-taps", "100", "x.py")
    assert out.returncode == 2
    assert "--band-taps 100" in out.stderr
