"""The API's figures say what they show: the sensitivity figure's red bars are the
parameters the estimate estimated (a shipped network set fixes its own inputs, so a key
parameter may not be one of them)."""

import json
from pathlib import Path

from railsusp.api import RunResult


def write(path: Path, doc: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc))


def colours(ax) -> dict[str, str]:
    """Each bar's parameter and colour."""
    from matplotlib.colors import to_hex

    names = [t.get_text() for t in ax.get_xticklabels()]
    return {n: to_hex(b.get_facecolor()) for n, b in zip(names, ax.patches, strict=True)}


def test_plot_sensitivity_reds_the_estimated_parameters_not_every_key_one(tmp_path):
    """The demo's case: X12 is key but not an input of the shipped networks, so not
    estimated; the figure coloured it red under the title "key parameters, estimated"."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.colors import to_hex

    write(tmp_path / "pipeline.json", {"config": {}, "stages": {}})
    st = {"X13": 0.96, "X11": 0.29, "X12": 0.078, "X19": 0.074, "X17": 0.03}
    keys = ["X13", "X11", "X12", "X19"]
    write(
        tmp_path / "campaign" / "sensitivity" / "key_parameters.json",
        {"key_parameters": {"keys": keys, "max_st": st}},
    )
    run = RunResult(tmp_path)
    # before the estimate: the key parameters are red, and the title says no more
    ax = run.plot_sensitivity()
    red = to_hex("C3")
    assert {p for p, c in colours(ax).items() if c == red} == set(keys)
    assert "estimated" not in ax.get_title().replace("no estimate", "")
    # the estimate estimated four of them: X12, key but not estimated, is not red
    write(tmp_path / "estimate" / "estimate.json", {"parameters": ["X13", "X11", "X19"]})
    ax = run.plot_sensitivity()
    shown = colours(ax)
    assert {p for p, c in shown.items() if c == red} == {"X13", "X11", "X19"}
    assert shown["X12"] == to_hex("C1") != shown["X17"]
    assert "red: estimated" in ax.get_title() and "orange: key parameters not" in ax.get_title()
