"""The command line's global options: --version, --quiet / --verbose, warnings said once on
one line, and each pipeline stage's finish with its elapsed time."""

import logging
import warnings

from typer.testing import CliRunner

from railsusp import __version__
from railsusp.cli import app


def test_version_option():
    result = CliRunner().invoke(app, ["--version"])
    assert result.exit_code == 0 and result.output.strip() == f"railsusp {__version__}"
    # the command says the same (it printed the bare number)
    assert CliRunner().invoke(app, ["version"]).output.strip() == f"railsusp {__version__}"


def test_quiet_and_verbose_together_is_an_error():
    result = CliRunner().invoke(app, ["--quiet", "--verbose", "params"])
    assert result.exit_code == 2
    assert "--quiet and --verbose: accepted one of them" in result.output


def test_warnings_are_one_line_once_and_the_stage_log_follows_the_verbosity(monkeypatch):
    """A command that warns twice with the same message says it once, without a source
    line; stage finishes show normally, starts only with --verbose, neither with --quiet."""

    @app.command("probe-warn", hidden=True)
    def probe_warn() -> None:
        for _ in range(2):
            warnings.warn("the record is\n shorter than a segment", UserWarning, stacklevel=1)
        log = logging.getLogger("railsusp.pipeline")
        log.debug("stage field: running")
        log.info("stage field: done in 1.0 s")

    try:
        out = CliRunner().invoke(app, ["probe-warn"]).output
        assert out.count("warning: the record is shorter than a segment") == 1
        assert "warnings.warn" not in out and "UserWarning" not in out
        assert "stage field: done in 1.0 s" in out and "running" not in out
        out = CliRunner().invoke(app, ["--verbose", "probe-warn"]).output
        assert "stage field: running" in out
        out = CliRunner().invoke(app, ["--quiet", "probe-warn"]).output
        assert "stage field" not in out
        monkeypatch.setattr("railsusp.cli.common._said", set())
        out = CliRunner().invoke(app, ["--quiet", "probe-warn"]).output
        assert out.count("warning: the record is shorter than a segment") == 1
    finally:
        app.registered_commands[:] = [c for c in app.registered_commands if c.name != "probe-warn"]


def test_every_command_shows_an_example_in_its_help():
    from typer.testing import CliRunner

    from railsusp.cli import app, command_name

    names = [command_name(info) for info in app.registered_commands]
    assert len(names) >= 19
    for group in app.registered_groups:  # sub-applications: their commands too
        for info in group.typer_instance.registered_commands:
            names.append(f"{group.name} {command_name(info)}")
    missing = []
    for name in names:
        out = CliRunner().invoke(app, [*name.split(), "--help"], terminal_width=200).output
        if "Example:" not in out and "Examples:" not in out:
            missing.append(name)
    assert not missing, f"no example in the help of: {missing}"
