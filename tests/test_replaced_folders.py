"""Output folders that a command writes as one artefact (atomic_folder: the old folder
renamed aside, the new one put in its place) are refused before any work where the swap
would lose what they hold (the QA of stop 73): the folder the command runs in (``--out .``
failed after the whole estimate, the result lost; ``--out "$PWD"`` renamed the shell's
folder away), and a user's folder or a run directory given to estimate or validate, whose
files were replaced or dropped without a word."""

import pytest
from typer.testing import CliRunner

from railsusp.cli import app
from railsusp.errors import RailsuspInputError
from railsusp.input_checks import check_replaced_folder

runner = CliRunner()


def _one_line(result) -> str:
    assert result.exit_code == 2, result.output
    text = " ".join(result.output.split())
    assert "Traceback" not in result.output
    return text


def test_the_folder_one_runs_in_and_those_above_it_are_refused(tmp_path, monkeypatch):
    (tmp_path / "a" / "b").mkdir(parents=True)
    monkeypatch.chdir(tmp_path / "a")
    for given, said in [(".", "is the folder you are in"), ("..", "is a folder above")]:
        with pytest.raises(RailsuspInputError, match=f"--out {given} {said}"):
            check_replaced_folder(given, "--out", "estimate")
    with pytest.raises(RailsuspInputError, match="is the folder you are in"):
        check_replaced_folder(str(tmp_path / "a"), "--out", "estimate")
    assert check_replaced_folder("b", "--out", "estimate").name == "b"  # below it: taken


def test_a_folder_of_other_files_is_refused_its_own_and_an_empty_one_taken(tmp_path):
    user = tmp_path / "mine"
    (user / "validation").mkdir(parents=True)
    (user / "notes.txt").write_text("important")
    with pytest.raises(
        RailsuspInputError, match="--out .*mine holds notes.txt, validation and no estimate.json"
    ):
        check_replaced_folder(user, "--out", "estimate", own=("estimate.json",))
    (user / "estimate.json").write_text("{}")  # an earlier estimate's folder: replaced
    check_replaced_folder(user, "--out", "estimate", own=("estimate.json",))
    (tmp_path / "empty").mkdir()
    check_replaced_folder(tmp_path / "empty", "--out", "estimate", own=("estimate.json",))
    check_replaced_folder(tmp_path / "new", "--out", "estimate", own=("estimate.json",))


def test_the_commands_refuse_before_any_work(tmp_path, monkeypatch):
    user = tmp_path / "mine"
    user.mkdir()
    (user / "notes.txt").write_text("important")
    out = _one_line(
        runner.invoke(
            app,
            ["estimate", "--measured", str(tmp_path / "none"), "--simulator", "--out", str(user)],
        )
    )
    assert "holds notes.txt and no estimate.json: estimate would replace the folder" in out
    out = _one_line(runner.invoke(app, ["validate", str(tmp_path / "none"), "--out", str(user)]))
    assert "holds notes.txt and no validation.json or estimate.json: validate would" in out
    assert (user / "notes.txt").read_text() == "important"
    # without --out, ESTIMATE_DIR/validation is checked the same way, before any work (it
    # was not: a user's folder there was replaced, or the command failed after simulating)
    est = tmp_path / "est"
    (est / "validation").mkdir(parents=True)
    (est / "validation" / "notes.txt").write_text("important")
    out = _one_line(runner.invoke(app, ["validate", str(est)]))
    assert f"--out (default) {est / 'validation'} holds notes.txt and no validation.json" in out
    assert (est / "validation" / "notes.txt").read_text() == "important"
    monkeypatch.chdir(user)
    out = _one_line(runner.invoke(app, ["synth-field", "--out", ".", "--duration", "5"]))
    assert "--out . is the folder you are in: synth-field replaces its output folder" in out
    assert sorted(p.name for p in user.iterdir()) == ["notes.txt"]


@pytest.mark.parametrize("command", [["posterior", "train"], ["posterior", "join"]])
def test_a_posterior_is_not_written_among_recordings(tmp_path, command):
    """QA of stop 73: estimate and validate refused a field folder as --out, the posterior's
    train and join wrote into one."""
    field = tmp_path / "field"
    field.mkdir()
    (field / "index.json").write_text('{"recordings": []}')
    extra = ["--estimators", f"{tmp_path / 'a'},{tmp_path / 'b'}"] if command[1] == "join" else []
    out = _one_line(runner.invoke(app, [*command, *extra, "--out", str(field)]))
    assert f"--out {field} is a field folder of recordings (index.json)" in out
    assert sorted(p.name for p in field.iterdir()) == ["index.json"]


def test_validate_may_write_beside_its_estimate(tmp_path):
    """The review of stop 73: ``validate EST --out EST`` adds its files beside estimate.json
    (the rest carried over); refused as a folder without validation.json, it is taken."""
    (tmp_path / "estimate.json").write_text("{}")
    own = ("validation.json", "estimate.json")
    assert check_replaced_folder(tmp_path, "--out", "validate", own=own) == tmp_path


def test_a_linked_output_folder_is_written_where_the_link_points(tmp_path):
    """atomic_folder renamed a symbolic link aside (``.NAME.old-*``, left for good: rmtree
    refuses a link) and put a real folder in its place, the link's folder left stale (the
    QA of stop 73). A command's --out, checked through the link, is written where it points,
    the link kept."""
    from railsusp.atomic_files import atomic_folder

    real = tmp_path / "disk" / "est"
    real.mkdir(parents=True)
    (real / "estimate.json").write_text("old")
    (real / "notes.txt").write_text("kept")
    link = tmp_path / "est"
    link.symlink_to(real, target_is_directory=True)
    with atomic_folder(link, drop=("estimate.json",)) as tmp:
        (tmp / "estimate.json").write_text("new")
    assert link.is_symlink() and link.resolve() == real.resolve()
    assert (real / "estimate.json").read_text() == "new"
    assert (real / "notes.txt").read_text() == "kept"  # other files carried, as for a folder
    assert sorted(p.name for p in tmp_path.iterdir()) == ["disk", "est"]  # nothing aside
    assert sorted(p.name for p in (tmp_path / "disk").iterdir()) == ["est"]


def test_a_link_replaced_whole_is_replaced_as_an_entry(tmp_path):
    """Without keep (the copy of shipped networks, the field stage) a swap through a link
    would drop every file of the folder it names: the link is replaced as an entry, a real
    folder in its place, the linked folder as it was (the review of stop 74)."""
    from railsusp.atomic_files import atomic_folder

    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "index.json").write_text('{"recordings": ["real.csv"]}')
    (mine / "real.csv").write_text("measured")
    nets = tmp_path / "run" / "networks"
    nets.parent.mkdir()
    nets.symlink_to(mine, target_is_directory=True)
    with atomic_folder(nets, keep=False) as tmp:
        (tmp / "networks.json").write_text("{}")
    assert not nets.is_symlink() and sorted(p.name for p in nets.iterdir()) == ["networks.json"]
    assert sorted(p.name for p in mine.iterdir()) == ["index.json", "real.csv"]
    assert (mine / "real.csv").read_text() == "measured"
    assert sorted(p.name for p in nets.parent.iterdir()) == ["networks"]  # no link aside


def test_a_link_saved_with_keep_is_written_where_it_points(tmp_path):
    """With keep (a trained network beside its checkpoint) the folder the link names is
    written and its other files carried: de-linked, the network left its checkpoint behind
    on the linked disk (the review of stop 74)."""
    from railsusp.atomic_files import atomic_folder

    disk = tmp_path / "disk" / "straight"
    disk.mkdir(parents=True)
    (disk / "checkpoint.pt").write_text("epochs")
    link = tmp_path / "surrogates" / "straight"
    link.parent.mkdir()
    link.symlink_to(disk, target_is_directory=True)
    with atomic_folder(link) as tmp:
        (tmp / "model.pt").write_text("weights")
    assert link.is_symlink()
    assert sorted(p.name for p in disk.iterdir()) == ["checkpoint.pt", "model.pt"]


def test_a_link_left_aside_by_an_older_railsusp_is_removed(tmp_path):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "kept.txt").write_text("the link's folder is not emptied")
    out = tmp_path / "est"
    out.mkdir()
    stale = tmp_path / ".est.old-abc123"
    stale.symlink_to(elsewhere, target_is_directory=True)
    from railsusp.atomic_files import atomic_folder

    with atomic_folder(out) as tmp:
        (tmp / "estimate.json").write_text("new")
    assert not stale.is_symlink() and not stale.exists()
    assert (elsewhere / "kept.txt").exists()


def test_a_dangling_link_left_aside_neither_stops_a_save_nor_is_put_back(tmp_path):
    """put_back_aside read a set-aside link's time through it: a dangling one stopped every
    save with FileNotFoundError, and a live one was put back as the output (the review of
    stop 74)."""
    from railsusp.atomic_files import atomic_folder, put_back_aside

    stale = tmp_path / ".est.old-dead1234"
    stale.symlink_to(tmp_path / "gone", target_is_directory=True)  # dangling
    assert put_back_aside(tmp_path / "est") is False
    with atomic_folder(tmp_path / "est") as tmp:
        (tmp / "estimate.json").write_text("new")
    assert (tmp_path / "est" / "estimate.json").read_text() == "new"
    assert not stale.is_symlink()


def test_temporaries_in_a_carried_subfolder_are_not_carried(tmp_path):
    from railsusp.atomic_files import atomic_folder

    out = tmp_path / "est"
    (out / "validation").mkdir(parents=True)
    (out / "validation" / ".validation.json.abcd1234.tmp").write_text("half")
    (out / "validation" / "validation.json").write_text("{}")
    with atomic_folder(out) as tmp:
        (tmp / "estimate.json").write_text("new")
    assert sorted(p.name for p in (out / "validation").iterdir()) == ["validation.json"]


def test_an_output_folder_in_a_folder_that_cannot_be_written_is_refused(tmp_path, monkeypatch):
    """The swap makes the new version beside the old one: in a read-only folder (or beside
    a link's folder there) the command failed with a PermissionError naming a hidden
    temporary after all its work (the review of stop 74). Refused before any work."""
    import os

    out = tmp_path / "ro" / "est"
    out.mkdir(parents=True)
    real = os.access

    def read_only(path, mode, **kw):  # the tests run as root, who writes anywhere
        if os.path.abspath(path) == str(out.parent) and mode & os.W_OK:
            return False
        return real(path, mode, **kw)

    monkeypatch.setattr(os, "access", read_only)
    with pytest.raises(RailsuspInputError, match="which cannot be written"):
        check_replaced_folder(out, "--out", "estimate")
    (tmp_path / "rw" / "est").mkdir(parents=True)
    assert check_replaced_folder(tmp_path / "rw" / "est", "--out", "estimate")  # writable


def test_a_nested_swaps_leftovers_are_not_carried(tmp_path):
    """A killed swap of a folder inside the one saved (its validation) left
    ``.validation.old-*`` / ``.new-*``: carried into every later save, the old validation
    came back at the next one (the review of stop 74)."""
    from railsusp.atomic_files import atomic_folder

    out = tmp_path / "est"
    (out / ".validation.old-abcd1234").mkdir(parents=True)
    (out / ".validation.new-efgh5678").mkdir()
    (out / "validation" / ".figures.new-ijkl9012").mkdir(parents=True)
    with atomic_folder(out, drop=("validation",)) as tmp:
        (tmp / "estimate.json").write_text("new")
    assert sorted(p.name for p in out.iterdir()) == ["estimate.json"]
    with atomic_folder(out) as tmp:
        (tmp / "validation").mkdir()
    (out / "validation" / ".figures.new-ijkl9012").mkdir()
    with atomic_folder(out) as tmp:
        (tmp / "estimate.json").write_text("newer")
    assert list((out / "validation").iterdir()) == []
