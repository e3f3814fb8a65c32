"""The package's shape: no import cycles, imports only go down, no hidden imports, small modules.

The import graph is read from the source with :mod:`ast` (every ``import`` statement, at module
level or inside a function), so an import hidden inside a function still counts.

Layers, lowest first (a module may import its own layer and the layers below):

0. the core: ``errors scan pose params keypoints detector presets ...`` and ``kernel/`` (numba)
1. ``io``
2. ``pipeline``
3. ``sim``, ``matching``
4. ``registration`` (what SLAM and localisation share: scan points, ICP, correlative and
   keypoint global search)
5. ``slam``, ``localise``
6. ``eval``
7. ``viz``
8. ``ros``, ``batch``, ``cli``, ``demo``
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = "laser_corners"
SRC = Path(__file__).resolve().parents[1] / "src" / PACKAGE

ROOM_LAYERS = {
    "io": 1,
    "pipeline": 2,
    "sim": 3,
    "matching": 3,
    "registration": 4,
    "slam": 5,
    "localise": 5,
    "eval": 6,
    "viz": 7,
    "ros": 8,
    "batch": 8,
    "cli": 8,
    "demo": 8,
}
MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 80


def _module_name(path: Path) -> str:
    parts = [PACKAGE, *path.relative_to(SRC).with_suffix("").parts]
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(SRC.rglob("*.py"))}


def _resolve(target: str, known: dict[str, Path]) -> str | None:
    """The longest known module that ``target`` names (``a.b.C`` -> ``a.b``)."""
    parts = target.split(".")
    while parts:
        name = ".".join(parts)
        if name in known:
            return name
        parts.pop()
    return None


def _imports(module: str, path: Path, known: dict[str, Path]) -> list[tuple[str, int, bool]]:
    """(imported module, line, inside a function) for every import of this package."""
    tree = ast.parse(path.read_text(), filename=str(path))
    is_package = path.name == "__init__.py"
    found: list[tuple[str, int, bool]] = []

    def visit(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            nested = in_function or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef)
            names: list[str] = []
            if isinstance(child, ast.Import):
                names = [alias.name for alias in child.names]
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    base = module.split(".")
                    base = base[: len(base) - child.level + (1 if is_package else 0)]
                    stem = ".".join([*base, child.module] if child.module else base)
                else:
                    stem = child.module or ""
                names = [f"{stem}.{alias.name}" for alias in child.names] or [stem]
            for name in names:
                if name.split(".")[0] != PACKAGE:
                    continue
                target = _resolve(name, known)
                if target is not None and target != module:
                    found.append((target, child.lineno, in_function))
            visit(child, nested)

    visit(tree, False)
    return found


def _layer(module: str) -> int:
    parts = module.split(".")
    return ROOM_LAYERS.get(parts[1], 0) if len(parts) > 1 else 0


def _graph() -> dict[str, list[tuple[str, int, bool]]]:
    known = _modules()
    return {name: _imports(name, path, known) for name, path in known.items()}


def _is_ancestor_package(package: str, module: str) -> bool:
    return module.startswith(package + ".")


def test_no_import_cycle() -> None:
    graph = {
        module: sorted(
            {t for t, _, _ in edges if not _is_ancestor_package(module, t)}
            # a package's __init__ re-exporting its own submodules is not a cycle with them
        )
        for module, edges in _graph().items()
    }
    state: dict[str, int] = {}
    stack: list[str] = []
    cycles: list[str] = []

    def dfs(node: str) -> None:
        state[node] = 1
        stack.append(node)
        for nxt in graph.get(node, []):
            if state.get(nxt, 0) == 0:
                dfs(nxt)
            elif state.get(nxt) == 1:
                cycles.append(" -> ".join([*stack[stack.index(nxt) :], nxt]))
        stack.pop()
        state[node] = 2

    for node in sorted(graph):
        if state.get(node, 0) == 0:
            dfs(node)
    assert not cycles, "import cycles:\n" + "\n".join(cycles)


def test_imports_only_go_down() -> None:
    upward = [
        f"{module}:{line} imports {target} (layer {_layer(target)} > {_layer(module)})"
        for module, edges in _graph().items()
        for target, line, _ in edges
        if _layer(target) > _layer(module)
    ]
    assert not upward, "upward imports:\n" + "\n".join(upward)


def test_no_package_import_inside_functions() -> None:
    # the command line (entry points) imports the library after parsing, so --help is instant
    hidden = [
        f"{module}:{line} imports {target} inside a function"
        for module, edges in _graph().items()
        for target, line, inside in edges
        if inside and not module.startswith(f"{PACKAGE}.cli")
    ]
    assert not hidden, "imports of this package inside functions:\n" + "\n".join(hidden)


@pytest.mark.parametrize("path", sorted(SRC.rglob("*.py")), ids=lambda p: str(p.relative_to(SRC)))
def test_module_and_function_size(path: Path) -> None:
    lines = path.read_text().splitlines()
    assert len(lines) <= MAX_MODULE_LINES, f"{path.name}: {len(lines)} lines"
    long = [
        f"{node.name}: {node.end_lineno - node.lineno + 1} lines"
        for node in ast.walk(ast.parse("\n".join(lines)))
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
        and node.end_lineno is not None
        and node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES
    ]
    assert not long, f"{path.name}: functions over {MAX_FUNCTION_LINES} lines: {long}"
