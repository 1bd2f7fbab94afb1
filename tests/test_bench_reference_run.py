"""bench/reference_run.py: an A/B's reference run imports the railsusp of the ``src`` it is
given, or refuses. A wrong path (no railsusp under it) fell through to the installed
railsusp, and the A/B then compared today's code with itself (ratio 1.0, exit 0)."""

import pytest

from conftest import bench_script
from railsusp.errors import RailsuspInputError

#: a bench script's stand-in: writes the JSON of its --out with one row naming the railsusp
#: it imported
SCRIPT = """
import argparse, json
import railsusp
ap = argparse.ArgumentParser()
ap.add_argument("--n", type=int)
ap.add_argument("--out")
a = ap.parse_args()
json.dump({"rows": [{"n": a.n, "railsusp": railsusp.__file__}]}, open(a.out, "w"))
"""


@pytest.fixture(scope="module")
def bench():
    return bench_script("reference_run")


def _package(folder):
    (folder / "railsusp").mkdir(parents=True)
    (folder / "railsusp" / "__init__.py").write_text("")
    return folder


def test_a_src_without_railsusp_is_refused(bench, tmp_path):
    script = tmp_path / "script.py"
    script.write_text(SCRIPT)
    for src in (tmp_path / "nonexistent", tmp_path):  # a typo; a worktree's root, not src
        with pytest.raises(RailsuspInputError, match="no railsusp/__init__.py under it"):
            bench.reference_rows(str(script), ["--n", "1"], str(src))


def test_the_reference_run_imports_the_given_src(bench, tmp_path, capsys):
    src = _package(tmp_path / "old" / "src")
    script = tmp_path / "scripts" / "script.py"
    script.parent.mkdir()
    script.write_text(SCRIPT)
    rows = bench.reference_rows(str(script), ["--n", "3"], str(src))
    assert rows == [{"n": 3, "railsusp": str(src / "railsusp" / "__init__.py")}]
    assert f"reference railsusp: {src / 'railsusp' / '__init__.py'}" in capsys.readouterr().err


def test_a_railsusp_imported_from_elsewhere_fails_the_run(bench, tmp_path):
    """The child checks what it imported: here the script's own folder (first on the path,
    as with ``python SCRIPT``) holds another railsusp, which shadows the given src."""
    src = _package(tmp_path / "old" / "src")
    scripts = _package(tmp_path / "scripts")
    script = scripts / "script.py"
    script.write_text(SCRIPT)
    with pytest.raises(RailsuspInputError, match="imported .*scripts/railsusp/__init__.py, not"):
        bench.reference_rows(str(script), ["--n", "1"], str(src))
