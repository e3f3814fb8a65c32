"""Shared fixtures: the real-data folder beside the checkout, simulated scans."""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")

REPO_ROOT = Path(__file__).resolve().parents[1]
REAL_DATA = (REPO_ROOT / ".." / "shared" / "data" / "real").resolve()


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
