"""numba's cache of the package's kernels follows edits to any kernel file
(:mod:`laser_corners.kernel_cache`): a cached kernel that calls a kernel of another file
is not loaded with that file's old code."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import laser_corners

INNER = """import numba as nb


@nb.njit(cache=True)
def value():
    return {value}
"""

OUTER = """import numba as nb

from laser_corners.kernel._probe_inner import value


@nb.njit(cache=True)
def outer():
    return 10 * value()
"""


def _run_outer(src: Path, cache: Path) -> str:
    """``outer()`` in a fresh interpreter on the package copy in ``src``."""
    env = {**os.environ, "PYTHONPATH": str(src), "NUMBA_CACHE_DIR": str(cache)}
    code = "from laser_corners.kernel._probe_outer import outer; print(outer())"
    run = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300
    )
    assert run.returncode == 0, run.stderr
    return run.stdout.strip()


def test_an_edit_to_a_called_kernel_file_is_seen_by_its_cached_callers(tmp_path: Path) -> None:
    """A copy of the package with two kernel files, ``_probe_outer.outer`` (cached) calling
    ``_probe_inner.value`` (cached): after ``value`` is edited, ``outer`` returns the new
    value. With numba's own keying (each kernel by its own file) the second run loaded
    ``outer`` from the cache with the old ``value`` linked in (10, not 220). Each run is a
    subprocess of a few seconds (numba's import and two tiny compilations)."""
    src = tmp_path / "src"
    package = Path(laser_corners.__file__).resolve().parent
    shutil.copytree(package, src / "laser_corners", ignore=shutil.ignore_patterns("__pycache__"))
    kernel = src / "laser_corners" / "kernel"
    (kernel / "_probe_inner.py").write_text(INNER.format(value=1))
    (kernel / "_probe_outer.py").write_text(OUTER)
    cache = tmp_path / "cache"
    assert _run_outer(src, cache) == "10"
    assert list(cache.rglob("_probe_outer.outer-*.nbi")), "outer was not cached"
    assert _run_outer(src, cache) == "10"  # from the cache
    (kernel / "_probe_inner.py").write_text(INNER.format(value=22))
    assert _run_outer(src, cache) == "220"


def test_the_key_follows_kernel_sources_only(tmp_path: Path) -> None:
    """The key changes with any file that imports numba (a kernel, the walk of
    ``kernel/neighbourhood.py``), not with others, even those that name numba in a help
    text (``cli/batch.py``'s ``--threads``)."""
    from laser_corners.kernel_cache import kernel_key

    package = tmp_path / "laser_corners"
    source = Path(laser_corners.__file__).resolve().parent
    shutil.copytree(source, package, ignore=shutil.ignore_patterns("__pycache__"))
    key = kernel_key(package)
    assert len(key) == 16 and key == kernel_key(package)
    plain = package / "params.py"
    assert b"numba" not in plain.read_bytes()
    plain.write_text(plain.read_text() + "\n# a comment\n")
    assert kernel_key(package) == key
    helped = package / "cli" / "batch.py"
    assert b"numba" in helped.read_bytes() and b"import numba" not in helped.read_bytes()
    helped.write_text(helped.read_text() + "\n# a comment\n")
    assert kernel_key(package) == key
    walk = package / "kernel" / "neighbourhood.py"
    walk.write_text(walk.read_text() + "\n# a comment\n")
    assert kernel_key(package) != key


def test_an_unwritable_cache_falls_back_to_a_temporary_folder(tmp_path: Path) -> None:
    """The package's folder and the user's cache not writable (installed by another user,
    HOME unset) and NUMBA_CACHE_DIR under a regular file (root ignores permissions, not
    that): numba would stop every import of a kernel with "cannot cache function ... no
    locator available". numba is told to use NUMBA_CACHE_DIR only (its other locators, the
    package's __pycache__ and the user's cache, are what is unwritable); the command works,
    with at most one warning line and the kernels cached in the temporary folder."""
    trajectory = tmp_path / "t.tum"
    trajectory.write_text("".join(f"{t}.0 {0.5 * t} 0 0 0 0 0 1\n" for t in range(10)))
    relations = tmp_path / "r.relations"
    relations.write_text("".join(f"{t}.0 {t + 1}.0 0.5 0 0 0 0 0\n" for t in range(9)))
    src = Path(laser_corners.__file__).resolve().parents[1]
    env = {k: v for k, v in os.environ.items() if k not in ("HOME", "XDG_CACHE_HOME")}
    env |= {
        "PYTHONPATH": str(src),
        "NUMBA_CACHE_DIR": "/etc/passwd/numba",
        "NUMBA_CACHE_LOCATOR_CLASSES": "UserProvidedCacheLocator",
        "TMPDIR": str(tmp_path / "tmp"),
    }
    (tmp_path / "tmp").mkdir()
    code = "from laser_corners.cli import main; main()"
    run = subprocess.run(
        [sys.executable, "-c", code, "evaluate", "slam", str(trajectory), str(relations)],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr
    assert "Traceback" not in run.stderr and "9 / 9" in run.stdout, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("laser-corners: warning:"), run.stderr
    assert "/etc/passwd/numba" in lines[0] and str(tmp_path / "tmp") in lines[0], lines
    assert list((tmp_path / "tmp").rglob("*.nbi")), "nothing was cached in the fallback"
