"""The tutorial docs/tutorial-recording.md runs as written: every `railsusp` command in its
``sh`` blocks, in order, in a fresh folder, each exiting 0 with the outputs it promises."""

import json
import re
import shlex
from pathlib import Path

from typer.testing import CliRunner

from railsusp.cli import app

DOC = Path(__file__).parents[1] / "docs" / "tutorial-recording.md"


def tutorial_commands() -> list[list[str]]:
    """The argument lists of the ``railsusp`` lines of the tutorial's ``sh`` blocks."""
    blocks = re.findall(r"```sh\n(.*?)```", DOC.read_text("utf-8"), flags=re.S)
    lines = [ln.strip() for b in blocks for ln in b.splitlines()]
    return [shlex.split(ln)[1:] for ln in lines if ln.startswith("railsusp ")]


def test_the_tutorial_commands_run_in_order(tmp_path, monkeypatch):
    commands = tutorial_commands()
    assert [c[0] for c in commands] == [
        "example-recording",
        "check-recording",
        "sections",
        "sections",
        "check-recording",
        "estimate",
    ]
    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    outputs = []
    for args in commands:
        result = runner.invoke(app, args)
        assert result.exit_code == 0, f"railsusp {' '.join(args)}:\n{result.output}"
        outputs.append(result.output)
    assert "2983 m" in outputs[1] and "40-70 km/h" in outputs[1]
    assert Path("my-run/sections.png").is_file()
    assert "wrote 5 section recording(s)" in outputs[3]
    index = json.loads(Path("my-run/field/index.json").read_text())
    assert len(index["recordings"]) == 5
    est = json.loads(Path("my-run/estimate/estimate.json").read_text())
    assert set(est["parameters"]) == {"X13", "X14"}
