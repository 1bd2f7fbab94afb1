"""Imports flow one way: the pipeline calls the report, the report reads the run directory
and never imports the pipeline (no pipeline <-> report circle); the pipeline imports its
configuration, which never imports the pipeline."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "railsusp"
#: every report module (report*.py, found: a new one is covered as it is added) and the
#: summary they read, with the wagon's tolerances it judges against
REPORT_MODULES = (
    *sorted(p.name for p in SRC.glob("report*.py")),
    "summary.py",
    "suspension_tolerances.py",
)


def imported_modules(path: Path) -> set[str]:
    """Every module a file imports, at module level or inside functions."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text("utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module:
            out.add(node.module)
            out.update(f"{node.module}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
    return out


@pytest.mark.parametrize("name", REPORT_MODULES)
def test_report_modules_do_not_import_the_pipeline(name):
    mods = imported_modules(SRC / name)
    assert not {m for m in mods if m.startswith(("railsusp.pipeline", "railsusp.cli"))}, mods


def test_importing_the_report_loads_neither_pipeline_nor_api():
    code = (
        "import sys, railsusp.report_html, railsusp.summary; "
        "print(sorted(m for m in sys.modules if m in "
        "('railsusp.pipeline', 'railsusp.pipeline_config', 'railsusp.api', 'railsusp.cli')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize("module", ["pipeline_config.py", "config_sections.py"])
def test_the_configuration_does_not_import_the_stages(module):
    mods = imported_modules(SRC / module)
    assert not {m for m in mods if m == "railsusp.pipeline" or m.startswith("railsusp.pipeline.")}
    assert not {m for m in mods if m.startswith(("railsusp.api", "railsusp.cli"))}, mods


def test_import_railsusp_stays_light_and_api_loads_on_first_use():
    code = (
        "import sys, railsusp; a = 'railsusp.api' in sys.modules; "
        "railsusp.open_run; print(a, 'railsusp.api' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "True"]


def test_the_modules_the_docs_name_are_attributes_after_a_plain_import():
    # docs/api.md: railsusp.api.OutdatedModelWarning, railsusp.vehicle.MODEL_REVISION raised
    # AttributeError after `import railsusp` (the docs audit of stop 72)
    code = (
        "import sys, railsusp; a = 'railsusp.vehicle' in sys.modules; "
        "print(a, railsusp.api.OutdatedModelWarning is railsusp.OutdatedModelWarning, "
        "railsusp.vehicle.MODEL_REVISION == __import__('railsusp.vehicle').vehicle.MODEL_REVISION)"
        "\ntry:\n    railsusp.no_such_module\nexcept AttributeError as e:\n    print(e)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.splitlines() == [
        "False True True",
        "module 'railsusp' has no attribute 'no_such_module'",
    ]


def test_only_a_plain_module_name_is_an_attribute():
    """The review of stop 72: ``hasattr(railsusp, "a.b")`` raised ModuleNotFoundError, and
    ``getattr(railsusp, "vehicle.model")`` gave the submodule; the package's own import of
    importlib was an attribute too."""
    code = (
        "import railsusp; print(hasattr(railsusp, 'zzz.y'), hasattr(railsusp, 'vehicle.model'), "
        "hasattr(railsusp, 'importlib'), hasattr(railsusp, 'vehicle'))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False", "False", "True"]
