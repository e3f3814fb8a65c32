"""Shared fixtures: the real-data folder beside the checkout, simulated scans."""

from __future__ import annotations

import ctypes
import math
import os
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import matplotlib
import numpy as np
import pytest

from laser_corners import Keypoints

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")

REPO_ROOT = Path(__file__).resolve().parents[1]
REAL_DATA = (REPO_ROOT / ".." / "shared" / "data" / "real").resolve()
PR_SET_PDEATHSIG = 1  # linux/prctl.h


@pytest.fixture(scope="session")
def real_data() -> Path:
    """``../shared/data/real`` beside the checkout; skips the test when it is absent."""
    if not REAL_DATA.is_dir():
        pytest.skip(f"real data folder not found: {REAL_DATA} (expected ../shared/data/real)")
    return REAL_DATA


def real_file(name: str) -> Path:
    """A file of the real-data folder; skips the calling test when it is absent."""
    path = REAL_DATA / name
    if not path.is_file():
        pytest.skip(f"real data file not found: {path}")
    return path


def damaged_copy(
    src: Path, dst: Path, *, keep: int | None = None, flip: slice | None = None
) -> Path:
    """Copy ``src`` to ``dst``, keeping only its first ``keep`` bytes and/or flipping the bits
    of the bytes in ``flip``; returns ``dst``."""
    data = bytearray(src.read_bytes())
    if keep is not None:
        data = data[:keep]
    if flip is not None:
        for i in range(*flip.indices(len(data))):
            data[i] ^= 0xA5
    dst.write_bytes(bytes(data))
    return dst


def random_keypoints(n: int, seed: int = 0) -> Keypoints:
    """``n`` keypoints with random fields (stamp 12.5, frame ``laser``)."""
    rng = np.random.default_rng(seed)
    return Keypoints(
        xy=rng.uniform(-5, 5, (n, 2)),
        beam_index=rng.integers(0, 100, n),
        opening_angle_deg=rng.uniform(45, 135, n),
        orientation=rng.uniform(-math.pi, math.pi, n),
        n_scales=rng.integers(3, 9, n),
        rmse=rng.uniform(0, 0.02, n),
        n_merged=rng.integers(1, 4, n),
        stamp=12.5,
        frame_id="laser",
    )


def default_sigint() -> None:
    """A ``preexec_fn`` giving the child SIGINT's default action: a child of a background parent
    (``cmd &``) inherits SIGINT ignored, and a test that sends Ctrl-C must reach it."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def die_with_parent() -> Callable[[], None]:
    """A ``preexec_fn`` that makes a child started by this thread get SIGTERM when it dies.

    Linux ``prctl(PR_SET_PDEATHSIG, SIGTERM)``: a test's processes (nodes, roscore, writers)
    end with the pytest process even when it is killed with SIGKILL (a CI timeout), when no
    teardown runs. Elsewhere it does nothing (the tests' teardowns still stop them).
    """
    parent = os.getpid()

    def preexec() -> None:
        if not sys.platform.startswith("linux"):
            return
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0) != 0:
            raise OSError(ctypes.get_errno(), "prctl(PR_SET_PDEATHSIG) failed")
        if os.getppid() != parent:  # the parent died before prctl: act as the signal would
            os.kill(os.getpid(), signal.SIGTERM)

    return preexec


def run_until_killed(script: str, *args: str) -> str:
    """Run ``script`` in a new Python, read its first output line, then SIGKILL it."""
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(REPO_ROOT / "src"), os.environ.get("PYTHONPATH", "")]),
    }
    process = subprocess.Popen(
        [sys.executable, "-c", script, *args],
        stdout=subprocess.PIPE,
        text=True,
        env=env,
        preexec_fn=die_with_parent(),
    )
    try:
        assert process.stdout is not None
        line = process.stdout.readline().strip()
    finally:
        process.send_signal(signal.SIGKILL)
        process.wait(timeout=30)
    assert process.returncode == -signal.SIGKILL and line, "the writer did not start"
    return line


def cache_answers(
    check: str, cold_cache: Path
) -> tuple[subprocess.CompletedProcess, subprocess.CompletedProcess]:
    """The Python one-liner ``check`` run in a fresh interpreter twice: with this process's
    numba cache (warm) and with the empty folder ``cold_cache`` as the cache (cold)."""

    def run(extra: dict[str, str]) -> subprocess.CompletedProcess:
        env = {**os.environ, **extra}
        return subprocess.run(
            [sys.executable, "-c", check], capture_output=True, text=True, env=env, timeout=300
        )

    return run({}), run({"NUMBA_CACHE_DIR": str(cold_cache)})
