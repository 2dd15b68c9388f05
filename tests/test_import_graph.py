"""The packages' import graph: no circle among module-level imports, and no module imports the
``localpbo`` command (``localpbo_core.cli``) except its console script.

The graph is read from the source with :mod:`ast`, not by importing. An edge A -> B is an
``import``/``from ... import`` executed when A is imported: statements at module level,
including those inside module-level ``if``/``try``/``with`` blocks, but not the body of
``if TYPE_CHECKING:`` and not imports inside functions or classes' methods (those run when the
function is called: ``localpbo_core.cli`` adds the ROS verbs' parsers that way, and
``localpbo_ros.commands`` imports rclpy that way). ``from P import name`` is an edge to
``P.name`` when that is a module of the packages, else to ``P``.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import networkx as nx
import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {
    "localpbo_core": ROOT / "localpbo_core",
    "localpbo_msgs_py": ROOT / "localpbo_msgs_py",
    "localpbo_ros": ROOT / "ros_ws" / "src" / "localpbo_ros" / "localpbo_ros",
}
CLI = "localpbo_core.cli"
CLI_IMPORTERS = {"localpbo_core.console"}
"""The ``localpbo`` console script runs the CLI; nothing else may import it."""


def module_files() -> dict[str, Path]:
    """Every module of the packages by dotted name (a package by its own name)."""
    modules: dict[str, Path] = {}
    for package, folder in PACKAGES.items():
        for path in sorted(folder.rglob("*.py")):
            parts = [package, *path.relative_to(folder).with_suffix("").parts]
            if parts[-1] == "__init__":
                parts = parts[:-1]
            modules[".".join(parts)] = path
    return modules


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def import_nodes(
    tree: ast.Module, *, module_level: bool, type_checking: bool = True
) -> Iterator[ast.Import | ast.ImportFrom]:
    """The import statements of ``tree``: those run at import time if ``module_level``, else
    also those inside functions and classes; the body of ``if TYPE_CHECKING:`` only with
    ``type_checking`` and not ``module_level``."""
    if not module_level and type_checking:
        for node in ast.walk(tree):
            if isinstance(node, ast.Import | ast.ImportFrom):
                yield node
        return
    stack: list[ast.stmt] = list(tree.body)
    while stack:
        node = stack.pop()
        if isinstance(node, ast.Import | ast.ImportFrom):
            yield node
        elif isinstance(node, ast.If):
            if not _is_type_checking(node.test):
                stack.extend(node.body)
            stack.extend(node.orelse)
        elif isinstance(node, ast.Try):
            for block in (node.body, node.orelse, node.finalbody):
                stack.extend(block)
            for handler in node.handlers:
                stack.extend(handler.body)
        elif isinstance(node, ast.With):
            stack.extend(node.body)
        elif not module_level:
            stack.extend(n for n in ast.iter_child_nodes(node) if isinstance(n, ast.stmt))
            if isinstance(node, ast.Match):
                for case in node.cases:
                    stack.extend(case.body)


def imported_modules(
    name: str, path: Path, modules: dict[str, Path], *, module_level: bool, type_checking: bool
) -> set[str]:
    """The modules of the packages that ``name`` (at ``path``) imports."""
    is_package = path.name == "__init__.py"
    found: set[str] = set()
    tree = ast.parse(path.read_text(), str(path))
    for node in import_nodes(tree, module_level=module_level, type_checking=type_checking):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        else:
            if node.level:
                base = name.split(".") if is_package else name.split(".")[:-1]
                base = base[: len(base) - (node.level - 1)]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ""
            targets = [
                f"{source}.{alias.name}" if f"{source}.{alias.name}" in modules else source
                for alias in node.names
            ]
        found.update(t for t in targets if t in modules and t != name)
    return found


def import_graph(*, module_level: bool = True, type_checking: bool = True) -> nx.DiGraph:
    """Edges of the imports :func:`import_nodes` yields with these flags."""
    modules = module_files()
    graph = nx.DiGraph()
    graph.add_nodes_from(modules)
    for name, path in modules.items():
        found = imported_modules(
            name, path, modules, module_level=module_level, type_checking=type_checking
        )
        for target in found:
            graph.add_edge(name, target)
    return graph


def circles(graph: nx.DiGraph) -> str:
    """The circles of ``graph``, one ``a -> b -> a`` each, "; "-separated."""
    return "; ".join(" -> ".join([*c, c[0]]) for c in nx.simple_cycles(graph))


def test_the_graph_is_read() -> None:
    graph = import_graph()
    assert {CLI, "localpbo_core.sweep", "localpbo_ros.commands", "localpbo_msgs_py.bag"} <= set(
        graph
    )
    assert graph.has_edge("localpbo_core.cli", "localpbo_core.arguments")
    assert graph.has_edge("localpbo_ros.commands", "localpbo_core.arguments")
    assert not graph.has_edge("localpbo_core.cli", "localpbo_ros.commands")  # inside a function
    assert import_graph(module_level=False).has_edge(CLI, "localpbo_ros.commands")


def test_module_level_imports_have_no_circle() -> None:
    found = circles(import_graph())
    assert not found, "import circles: " + found


def test_imports_in_functions_close_no_circle() -> None:
    """Imports inside functions too (not ``if TYPE_CHECKING:`` bodies): a circle there is a
    pair of modules that need each other, only loaded late."""
    found = circles(import_graph(module_level=False, type_checking=False))
    assert not found, "import circles: " + found


def test_only_the_console_script_imports_the_cli() -> None:
    graph = import_graph(module_level=False)  # function-local imports count here
    assert set(graph.predecessors(CLI)) <= CLI_IMPORTERS


@pytest.mark.parametrize("package", ["localpbo_core", "localpbo_msgs_py"])
def test_lower_packages_do_not_import_the_nodes(package: str) -> None:
    """``localpbo_core`` and ``localpbo_msgs_py`` never import ``localpbo_ros`` at module
    level: the ROS verbs plug into the CLI from a function, when the package is installed."""
    graph = import_graph()
    edges = [
        (a, b)
        for a, b in graph.edges
        if a.startswith(package + ".") or a == package
        if b.split(".")[0] == "localpbo_ros"
    ]
    assert not edges


def test_a_circle_is_found() -> None:
    """The check itself: an edge back from ``localpbo_core.arguments`` to the CLI closes a
    circle that the cycle search reports."""
    graph = import_graph()
    graph.add_edge("localpbo_core.arguments", CLI)
    assert any(CLI in c for c in nx.simple_cycles(graph))
