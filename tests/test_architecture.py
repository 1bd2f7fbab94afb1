"""Imports between railsusp modules run one way: no import cycle.

Every module under src/railsusp is parsed with ``ast`` (nothing is imported or run), and
every import in it counts, at module level, inside functions and under ``TYPE_CHECKING``
alike: a deferred or typing-only import hides a circle, it does not remove it. A cycle is a
strongly connected component of more than one module (or a module importing itself).
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"

#: cycles known to exist and due to be removed (the test fails once one has gone, so an
#: entry cannot be forgotten). None now: estimate <-> refine <-> identifiability, the
#: command modules <-> railsusp.cli and pipeline <-> report_html were all removed.
KNOWN_CYCLES_TO_REMOVE: set[tuple[str, str]] = set()


def module_names(root: Path, package: str) -> dict[str, Path]:
    """Dotted name of every module of ``package`` under ``root`` (a package is its
    ``__init__``)."""
    out = {}
    for path in sorted((root / package).rglob("*.py")):
        parts = path.relative_to(root).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def import_graph(root: Path, package: str) -> dict[str, set[str]]:
    """Module -> the modules of ``package`` it imports (``from a import b`` counts ``a``,
    and ``a.b`` too where ``b`` is a module; relative imports resolved)."""
    modules = module_names(root, package)
    graph: dict[str, set[str]] = {name: set() for name in modules}
    for name, path in modules.items():
        here = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text("utf-8"), str(path))):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    anchor = here.split(".")
                    anchor = anchor[: len(anchor) - node.level + 1]
                    base = ".".join([*anchor, base] if base else anchor)
                # a package importing its own submodules (from pkg import sub in
                # pkg/__init__) imports those, not itself
                targets = [base] if base != name else []
                targets += [f"{base}.{alias.name}" for alias in node.names]
            for target in targets:
                # the longest prefix that is one of our modules (import a.b.c runs a.b.c)
                parts = target.split(".")
                for n in range(len(parts), 0, -1):
                    candidate = ".".join(parts[:n])
                    if candidate in modules:
                        graph[name].add(candidate)
                        break
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module, or with a self-import
    (Tarjan's algorithm), each sorted, in sorted order."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1 or v in graph[v]:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(found)


def test_no_import_cycle_among_railsusp_modules():
    found = cycles(import_graph(SRC, "railsusp"))
    known = {frozenset(c) for c in KNOWN_CYCLES_TO_REMOVE}
    unexpected = [c for c in found if frozenset(c) not in known]
    assert not unexpected, "import cycles: " + "; ".join(" <-> ".join(c) for c in unexpected)
    gone = known - {frozenset(c) for c in found}
    assert not gone, "no longer a cycle, remove from KNOWN_CYCLES_TO_REMOVE: " + "; ".join(
        " <-> ".join(sorted(c)) for c in gone
    )


def test_the_estimation_package_imports_one_way():
    """The estimation package's modules form a chain without cycles, none of them imports
    the package itself (whose ``__init__`` re-exports them all), and the old circle
    estimate -> identifiability -> estimate / estimate <-> refine is gone."""
    graph = import_graph(SRC, "railsusp")
    inside = {m for m in graph if m.startswith("railsusp.estimate.")}
    assert {"railsusp.estimate.problem", "railsusp.estimate.nsga", "railsusp.estimate.refine",
            "railsusp.estimate.identifiability", "railsusp.estimate.result"} <= inside  # fmt: skip
    for m in inside:
        assert "railsusp.estimate" not in graph[m], f"{m} imports its own package"
    sub = {m: graph[m] & inside for m in inside}
    assert cycles(sub) == []
    assert "railsusp.estimate.refine" not in graph["railsusp.estimate.result"] or (
        "railsusp.estimate.result" not in graph["railsusp.estimate.refine"]
    )


def test_the_cycle_finder_finds_cycles(tmp_path):
    """A package with a -> b -> c -> a (one deferred, one relative import), d -> d and an
    acyclic e -> a: two cycles, e in neither."""
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("from pkg import d\n")  # not a self-import
    (pkg / "a.py").write_text("from pkg.sub import b\n")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "sub" / "b.py").write_text("def f():\n    from .. import c\n")
    (pkg / "c.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                              "    import pkg.a\n")  # fmt: skip
    (pkg / "d.py").write_text("import pkg.d\n")
    (pkg / "e.py").write_text("from pkg.a import x\nimport numpy\n")
    graph = import_graph(tmp_path, "pkg")
    assert graph["pkg.e"] == {"pkg.a"} and graph["pkg"] == {"pkg.d"}
    assert cycles(graph) == [["pkg.a", "pkg.c", "pkg.sub.b"], ["pkg.d"]]
