"""The tests mirror the source tree, and classes stay small (issue 31 item 7).

A module with logic (``src/laser_corners/**/*.py`` defining a function or a class at its top
level; not ``__init__.py`` re-exports, not ``__main__``) is mirrored when
``tests/<subpackage path>/test_<module>.py`` exists (a top-level module:
``tests/test_<module>.py``), so a reader finds a module's tests without a search.

The test folders are not packages (pytest's default ``prepend`` import mode): every file below
``tests`` is imported under its bare name, so two test files of one name
(``tests/cli/test_slam.py`` and ``tests/viz/test_slam.py``) cannot be collected in one run, and
a second ``conftest.py`` hides the helpers the tests import from ``tests/conftest.py``. A
module whose mirror would share its name with another file stays unmirrored.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "laser_corners"
TESTS = ROOT / "tests"
MIN_MIRRORED = 0.60
MAX_CLASS_LINES = 250


def modules_with_logic(src: Path = SRC) -> list[Path]:
    """Modules below ``src`` (relative paths) that define a function or a class."""
    found = []
    for path in sorted(src.rglob("*.py")):
        if path.name in ("__init__.py", "__main__.py"):
            continue
        body = ast.parse(path.read_text(), filename=str(path)).body
        defines = (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)
        if any(isinstance(node, defines) for node in body):
            found.append(path.relative_to(src))
    return found


def mirror_of(module: Path, tests: Path = TESTS) -> Path:
    """``tests/<subpackage path>/test_<module>.py`` of a module path relative to the package."""
    return tests.joinpath(*module.parts[:-1], f"test_{module.name}")


def unmirrored(src: Path = SRC, tests: Path = TESTS) -> tuple[list[Path], int]:
    """The modules with logic that have no mirrored test file, and how many have logic."""
    modules = modules_with_logic(src)
    return [m for m in modules if not mirror_of(m, tests).is_file()], len(modules)


def test_mirror_rules_on_a_small_tree(tmp_path: Path) -> None:
    src, tests = tmp_path / "src", tmp_path / "tests"
    files = {
        src / "__init__.py": "from .a import f\n",
        src / "__main__.py": "def main():\n    pass\n",
        src / "a.py": "def f():\n    return 1\n",
        src / "consts.py": "X = 1\n",
        src / "room" / "__init__.py": "",
        src / "room" / "b.py": "class B:\n    pass\n",
        src / "room" / "c.py": "async def c():\n    pass\n",
        tests / "test_a.py": "",
        tests / "room" / "test_b.py": "",
        tests / "test_c.py": "",  # not the mirror of room/c.py
    }
    for path, text in files.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    assert modules_with_logic(src) == [Path("a.py"), Path("room/b.py"), Path("room/c.py")]
    assert mirror_of(Path("room/b.py"), tests) == tests / "room" / "test_b.py"
    assert unmirrored(src, tests) == ([Path("room/c.py")], 3)


def same_names(tests: Path = TESTS) -> dict[str, list[str]]:
    """File names (test modules, helpers, ``conftest.py``) used more than once below
    ``tests``, with their folders."""
    found: dict[str, list[str]] = {}
    for path in sorted(tests.rglob("*.py")):
        found.setdefault(path.name, []).append(path.parent.relative_to(tests).as_posix())
    return {name: folders for name, folders in found.items() if len(folders) > 1}


def test_same_names_finds_two_files_of_one_name(tmp_path: Path) -> None:
    for folder in ("cli", "viz", "slam"):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / f"test_{'slam' if folder != 'slam' else 'grid'}.py").write_text("")
    (tmp_path / "conftest.py").write_text("")
    (tmp_path / "slam" / "conftest.py").write_text("")
    assert same_names(tmp_path) == {"conftest.py": [".", "slam"], "test_slam.py": ["cli", "viz"]}


def test_no_two_files_below_tests_share_a_name() -> None:
    assert same_names() == {}, "imported under one bare name: pytest cannot collect both"


def test_most_modules_with_logic_have_their_mirrored_test_file() -> None:
    missing, total = unmirrored()
    share = 1 - len(missing) / total
    listed = "\n".join(f"  {m} -> {mirror_of(m).relative_to(ROOT)}" for m in missing)
    assert share >= MIN_MIRRORED, (
        f"{share:.0%} of {total} modules with logic have a mirrored test file "
        f"(at least {MIN_MIRRORED:.0%} wanted); unmirrored:\n{listed}"
    )


def test_no_class_is_over_250_lines() -> None:
    large = {}
    for path in sorted(SRC.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.ClassDef):
                length = node.end_lineno - node.lineno + 1  # type: ignore[operator]
                if length > MAX_CLASS_LINES:
                    large[f"{path.relative_to(SRC).as_posix()}:{node.name}"] = length
    assert not large, f"classes over {MAX_CLASS_LINES} lines: {large}"
