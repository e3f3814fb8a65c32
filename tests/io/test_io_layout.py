"""The shape of ``laser_corners.io``: imports only go down, small modules and functions."""

from __future__ import annotations

import ast
from pathlib import Path

IO = Path(__file__).resolve().parents[2] / "src" / "laser_corners" / "io"
READERS = {"rosbag", "carmen", "arrays"}
WRITERS = {"writers", "bagwriter", "trajectory", "occupancy"}  # + TUM poses, map_server grids
HELPERS = {
    "poses",
    "ros1_decode",
    "ros1_chunks",
    "ros1_index",
    "ros1_lean",
    "ros1_runs",
    "bagfile",
    "messages",
    "ros1_writer",
    "ros1_legacy",
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
                top.add(name.split(".")[2])
            elif name == "laser_corners.io":
                top.add("__init__")
    return top, nested


def test_io_imports_only_go_down() -> None:
    graph = {p.stem: _io_imports(p) for p in IO.glob("*.py")}
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
    for path in IO.glob("*.py"):
        source = path.read_text()
        assert len(source.splitlines()) < 400, f"{path.name}: {len(source.splitlines())} lines"
        for node in ast.walk(ast.parse(source)):
            if isinstance(node, ast.FunctionDef):
                length = node.end_lineno - node.lineno + 1  # type: ignore[operator]
                assert length <= 80, f"{path.name}:{node.name} has {length} lines"
