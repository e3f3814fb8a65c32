"""The shape of ``laser_corners.io``: imports only go down, small modules and functions."""

from __future__ import annotations

import ast
from pathlib import Path

IO = Path(__file__).resolve().parents[2] / "src" / "laser_corners" / "io"
READERS = {"rosbag", "carmen", "arrays"}
WRITERS = {"writers", "bagwriter", "trajectory", "occupancy"}  # + TUM poses, map_server grids
HELPERS = {
    "poses",
    "ros1.decode",
    "ros1.chunks",
    "ros1.index",
    "ros1.lean",
    "ros1.runs",
    "bagfile",
    "messages",
    "ros1.writer",
    "ros1.legacy",
    "ros1",  # the package: a docstring, imports nothing
}
LAZY_OK = {"pyarrow", "pyarrow.parquet"}  # heavy: imported when a Parquet writer opens


def _io_imports(path: Path) -> tuple[set[str], list[str]]:
    """``laser_corners.io`` modules imported by ``path`` (top level), and imports in functions."""
    tree = ast.parse(path.read_text())
    top: set[str] = set()
    nested: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            names = [node.module]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        if node.col_offset > 0:
            nested.extend(names)
        for name in names:
            if name.startswith("laser_corners.io."):
                top.add(".".join(name.split(".")[2:]))
            elif name == "laser_corners.io":
                top.add("__init__")
    return top, nested


def _io_modules() -> dict[str, Path]:
    """``laser_corners.io`` modules by name below ``io`` (``base``, ``ros1.lean``, ``ros1``)."""
    names = {}
    for path in IO.rglob("*.py"):
        parts = path.relative_to(IO).with_suffix("").parts
        parts = parts[:-1] if parts[-1] == "__init__" and len(parts) > 1 else parts
        names[".".join(parts)] = path
    return names


def test_io_imports_only_go_down() -> None:
    graph = {name: _io_imports(path) for name, path in _io_modules().items()}
    layer = {"partial": -1, "base": 0, **dict.fromkeys(HELPERS, 1)}
    layer |= {**dict.fromkeys(READERS | WRITERS, 2), "registry": 3, "__init__": 4, "run": 5}
    assert set(graph) <= set(layer), f"unplaced modules: {set(graph) - set(layer)}"
    for module, (imports, nested) in graph.items():
        for target in imports:
            assert layer[target] < layer[module] or (
                layer[target] == layer[module] == 1  # bag helpers use each other, acyclically
            ), f"io.{module} imports io.{target}"
        assert set(nested) <= LAZY_OK, f"io.{module} imports inside a function: {nested}"
    assert graph["partial"][0] == set() and graph["base"][0] == {"partial"}
    importers = {m for m, (imports, _) in graph.items() if imports & (READERS | WRITERS)}
    assert importers <= {"registry", "__init__"}, importers

    # the helpers form no cycle
    def visit(module: str, stack: tuple[str, ...]) -> None:
        assert module not in stack, f"import cycle: {' -> '.join((*stack, module))}"
        for target in graph[module][0] & HELPERS:
            visit(target, (*stack, module))

    for helper in HELPERS:
        visit(helper, ())


def test_io_modules_and_functions_are_small() -> None:
    for path in _io_modules().values():
        source = path.read_text()
        # the package's module backstop (tests/test_layering.py); functions <= 80 lines
        assert len(source.splitlines()) <= 600, f"{path.name}: {len(source.splitlines())} lines"
        for node in ast.walk(ast.parse(source)):
            if isinstance(node, ast.FunctionDef):
                length = node.end_lineno - node.lineno + 1  # type: ignore[operator]
                assert length <= 80, f"{path.name}:{node.name} has {length} lines"
