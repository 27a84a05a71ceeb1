"""The package's structure: imports point one way, shared helpers have public names.

Built from the source with ``ast`` (imports inside functions count too), so a
cycle hidden behind a function-level import still fails here.
"""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "skdelay"


def _module_name(path):
    parts = path.relative_to(ROOT).with_suffix("").parts
    name = ".".join(parts)
    return name.removesuffix(".__init__")


def _imports(path, name, modules):
    """Modules of ``modules`` that ``path`` imports, and the underscore names it imports."""
    pkg = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    found, private = set(), []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = pkg.split(".")[: len(pkg.split(".")) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            for alias in node.names:
                full = f"{base}.{alias.name}"
                if full in modules:
                    found.add(full)
                elif base in modules:
                    found.add(base)
                    if alias.name.startswith("_") and not alias.name.startswith("__"):
                        private.append(f"{name}: from {base} import {alias.name}")
        elif isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name in modules}
    found.discard(name)
    return found, private


def _graph():
    paths = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph, private = {}, []
    for name, path in paths.items():
        graph[name], priv = _imports(path, name, paths)
        private += priv
    return graph, private


def _find_cycle(graph):
    state, stack = {}, []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            # a package's __init__ re-exports its submodules: importing the package
            # from a submodule is the submodule's own business, not a cycle
            if nxt == node.rsplit(".", 1)[0] or node == nxt.rsplit(".", 1)[0]:
                continue
            if state.get(nxt) == "open":
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state:
                cycle = visit(nxt)
                if cycle:
                    return cycle
        stack.pop()
        state[node] = "done"
        return None

    for node in sorted(graph):
        if node not in state:
            cycle = visit(node)
            if cycle:
                return cycle
    return None


def test_no_import_cycle_inside_the_package():
    graph, _ = _graph()
    assert len(graph) > 40  # the walk found the package
    cycle = _find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_the_cycle_finder_finds_cycles():
    assert _find_cycle({"p.a": {"p.b"}, "p.b": {"p.c"}, "p.c": {"p.a"}}) == [
        "p.a", "p.b", "p.c", "p.a"]
    assert _find_cycle({"p.a": {"p.b"}, "p.b": set()}) is None


def test_no_private_names_imported_across_modules():
    _, private = _graph()
    assert private == []


@pytest.mark.parametrize("folder", ["benchmarks", "docs"])
def test_benchmarks_and_docs_scripts_use_public_names(folder):
    bad = []
    for path in (ROOT / folder).rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("skdelay"):
                if "._" in node.module:
                    bad.append(f"{path.name}: {node.module}")
                bad += [f"{path.name}: {node.module}.{a.name}" for a in node.names
                        if a.name.startswith("_")]
    assert bad == []
