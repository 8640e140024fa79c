# SPDX-License-Identifier: GPL-3.0-or-later
"""No import cycle inside vsgl_addon/: the package's import graph, read from the source (ast).

Every relative import is an edge, whether it runs at module level or inside a function (a
function-level import in a cycle only hides the cycle until that function runs). An import of a
package's submodule is an edge to that submodule, not to the package's __init__: Python runs
the parent's __init__ first, but that is containment, not a dependency of either on the other.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "vsgl_addon"


def module_name(path: Path, package: Path = PACKAGE) -> str:
    parts = list(path.relative_to(package.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph(package: Path = PACKAGE) -> dict[str, dict[str, dict[str, int]]]:
    """{module: {imported module: {"module" or "function": line}}} of the relative imports in `package`."""
    paths = {module_name(path, package): path for path in sorted(package.rglob("*.py"))}
    graph: dict[str, dict[str, dict[str, int]]] = {name: {} for name in paths}
    for name, path in paths.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        module_level = {id(node) for node in tree.body}
        parts = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        for node in ast.walk(tree):
            if not isinstance(node, ast.ImportFrom) or node.level == 0:
                continue  # absolute imports are outside the package (test_registration forbids vsgl_addon.*)
            base = ".".join(parts[:len(parts) - (node.level - 1)] + ([node.module] if node.module else []))
            level = "module" if id(node) in module_level else "function"
            for alias in node.names:
                target = f"{base}.{alias.name}" if f"{base}.{alias.name}" in paths else base
                assert target in paths, f"{path}:{node.lineno}: {target} is not a module of the package"
                if target != name:
                    graph[name].setdefault(target, {}).setdefault(level, node.lineno)
    return graph


def find_cycle(graph, levels=("module", "function")) -> list[str] | None:
    """One cycle (modules, first repeated at the end) using edges of `levels`, or None."""
    edges = {name: sorted(target for target, found in targets.items() if set(found) & set(levels))
             for name, targets in graph.items()}
    state: dict[str, str] = {}
    stack: list[str] = []

    def visit(name):
        state[name] = "open"
        stack.append(name)
        for target in edges[name]:
            if state.get(target) == "open":
                return stack[stack.index(target):] + [target]
            if target not in state:
                cycle = visit(target)
                if cycle:
                    return cycle
        stack.pop()
        state[name] = "done"
        return None

    for name in sorted(edges):
        if name not in state:
            cycle = visit(name)
            if cycle:
                return cycle
    return None


def describe_cycle(graph, cycle) -> str:
    steps = []
    for source, target in zip(cycle, cycle[1:]):
        found = graph[source][target]
        where = ", ".join(f"{level} level, line {line}" for level, line in sorted(found.items()))
        steps.append(f"{source} -> {target} ({where})")
    return "; ".join(steps)


def test_the_graph_sees_the_package_imports():
    """The graph is not empty by mistake: known edges of both kinds are in it."""
    graph = import_graph()
    assert "module" in graph["vsgl_addon.renderer"]["vsgl_addon.pipeline"]
    assert "function" in graph["vsgl_addon"]["vsgl_addon.overlay"]  # register() imports the Blender modules
    assert "vsgl_addon.settings" in graph["vsgl_addon.reference.vsgl"]


@pytest.mark.parametrize("levels", [("module",), ("module", "function")], ids=["module-level", "all"])
def test_no_import_cycle_in_the_package(levels):
    graph = import_graph()
    cycle = find_cycle(graph, levels)
    assert cycle is None, "import cycle: " + describe_cycle(graph, cycle)


def test_a_cycle_is_found_and_named(tmp_path):
    """The checker itself: a function-level cycle across a subpackage is reported with its lines."""
    package = tmp_path / "pkg"
    (package / "sub").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "sub" / "__init__.py").write_text("")
    (package / "a.py").write_text("from .sub import b\n")
    (package / "sub" / "b.py").write_text("def f():\n    from ..a import thing\n")
    graph = import_graph(package)
    assert find_cycle(graph, ("module",)) is None
    cycle = find_cycle(graph)
    assert cycle == ["pkg.a", "pkg.sub.b", "pkg.a"]
    assert describe_cycle(graph, cycle) == ("pkg.a -> pkg.sub.b (module level, line 1); "
                                            "pkg.sub.b -> pkg.a (function level, line 2)")
