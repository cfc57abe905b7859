"""The shape of core: no import cycles (counting imports inside functions), no private reach-ins.

Every ``import`` and ``from ... import`` anywhere in a core module counts,
including those inside functions and under ``TYPE_CHECKING``. Cycles are
checked between modules and between the packages of core (a package's
``__init__`` counts as the package).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

CORE = Path(__file__).resolve().parents[1] / "core"


def _module_name(path: Path) -> str:
    parts = path.relative_to(CORE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(p): p for p in CORE.rglob("*.py")}


def _imports(name: str, path: Path) -> list[tuple[str, list[str]]]:
    """``(module imported, names taken from it)`` for every import in a module."""
    tree = ast.parse(path.read_text())
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name.removeprefix("terratheme.") for a in node.names]
            out += [(n, []) for n in names if n.startswith("core")]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = (node.module or "").removeprefix("terratheme.")
            if not mod.startswith("core"):
                continue
            for a in node.names:
                sub = f"{mod}.{a.name}"
                # "from core.packing import seed_format" imports the submodule.
                out.append((sub, []) if sub in MODULES else (mod, [a.name]))
    return out


GRAPH = {name: _imports(name, path) for name, path in MODULES.items()}


def _package(name: str) -> str:
    parts = name.split(".")
    return ".".join(parts[:2]) if len(parts) > 1 else name


def _cycle(edges: dict[str, set[str]]) -> list[str] | None:
    """One cycle of a directed graph as a list of nodes, or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(edges.get(node, ())):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        state[node] = 2
        stack.pop()
        return None

    for node in sorted(edges):
        if node not in state and (found := visit(node)):
            return found
    return None


def _module_edges() -> dict[str, set[str]]:
    edges: dict[str, set[str]] = {}
    for name, imports in GRAPH.items():
        for mod, _ in imports:
            if mod in MODULES and mod != name:
                edges.setdefault(name, set()).add(mod)
    return edges


def test_every_import_resolves_to_a_core_module():
    missing = sorted({mod for imports in GRAPH.values() for mod, _ in imports
                      if mod not in MODULES})
    assert not missing


def test_no_cycle_between_modules():
    assert _cycle(_module_edges()) is None


def test_no_cycle_between_packages():
    edges: dict[str, set[str]] = {}
    for name, targets in _module_edges().items():
        for t in targets:
            if _package(t) != _package(name) and _package(name) != "core":
                edges.setdefault(_package(name), set()).add(_package(t))
    assert _cycle(edges) is None


def test_no_module_imports_another_modules_private_names():
    bad = [f"{name}: {mod}.{n}" for name, imports in GRAPH.items() for mod, names in imports
           for n in names if n.startswith("_") and mod != name]
    assert not bad


def test_every_part_is_a_package_with_a_public_api():
    top = sorted(p.name for p in CORE.glob("*.py"))
    assert top == ["__init__.py", "errors.py"]
    for pkg in sorted(p for p in CORE.iterdir() if p.is_dir() and p.name != "__pycache__"):
        init = pkg / "__init__.py"
        assert init.is_file(), pkg
        tree = ast.parse(init.read_text())
        assert ast.get_docstring(tree), f"{pkg.name}/__init__.py has no docstring"
        names = [n for n in tree.body if isinstance(n, ast.Assign)
                 and any(isinstance(t, ast.Name) and t.id == "__all__" for t in n.targets)]
        assert names, f"{pkg.name}/__init__.py lists no __all__"


@pytest.mark.parametrize("edges, want", [
    ({"a": {"b"}, "b": {"a"}}, True),
    ({"a": {"b"}, "b": {"c"}}, False),
    ({"a": {"b"}, "b": {"c"}, "c": {"a"}}, True),
])
def test_the_cycle_finder_finds_cycles(edges, want):
    assert (_cycle(edges) is not None) == want


def test_core_sets_no_signal_handlers():
    """Signal handling is process-wide policy: the CLI's (app/cli.py), never the library's."""
    users = sorted(name for name, path in MODULES.items()
                   if any(isinstance(node, ast.Import) and any(a.name == "signal"
                                                               for a in node.names)
                          or isinstance(node, ast.ImportFrom) and node.module == "signal"
                          for node in ast.walk(ast.parse(path.read_text()))))
    assert users == []


def test_each_package_imports_only_those_before_it_in_the_documented_order():
    import re

    doc = ast.get_docstring(ast.parse((CORE / "__init__.py").read_text()))
    listed = re.search(r"One package per part \(([^)]*)\)", " ".join(doc.split())).group(1)
    order = [f"core.{p.strip()}" for p in listed.split(",")]
    packages = {_package(n) for n in MODULES if n != "core"}
    assert sorted(order) == sorted(packages)  # every package listed, once
    rank = {p: i for i, p in enumerate(order)}
    late = sorted({(_package(src), _package(dst)) for src, deps in GRAPH.items()
                   for dst, _ in deps if src != "core" and dst != "core"
                   and rank[_package(dst)] > rank[_package(src)]})
    assert late == []
