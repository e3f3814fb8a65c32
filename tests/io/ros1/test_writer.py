"""Our ``.bag`` outputs as the real ROS 1 tools see them (Debian's rosbag: reindex, info, read).

``make test`` installs ROS 1 from Debian (target ``ros1-deps``); the system ``python3`` with
``python3-rosbag`` runs the tools. Without them these tests skip with the reason (and fail in
CI, where they must be installed).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import struct
import subprocess
from pathlib import Path

import pytest
from rosbags.highlevel import AnyReader

from conftest import real_file
from laser_corners import CornerDetector
from laser_corners.io import open_keypoint_writer, open_scans
from laser_corners.pipeline import detect_recording

SYSTEM_PYTHON = "/usr/bin/python3"  # Debian's, with python3-rosbag
_READ_ALL = """
import json, sys
import rosbag
counts = {}
with rosbag.Bag(sys.argv[1]) as bag:
    compression = bag.get_compression_info().compression
    for topic, msg, _ in bag.read_messages():
        counts[topic] = counts.get(topic, 0) + 1
print(json.dumps({"counts": counts, "compression": compression}))
"""


def _skip_or_fail(reason: str) -> None:
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(f"expected in CI (make test installs it): {reason}")
    pytest.skip(reason)


def _rosbag_tools() -> str:
    """The ``rosbag`` command (Debian's ROS 1), or skip (fail in CI) with the reason."""
    rosbag = shutil.which("rosbag")
    found = Path(SYSTEM_PYTHON).is_file() and rosbag is not None
    if found:
        probe = subprocess.run([SYSTEM_PYTHON, "-c", "import rosbag"], capture_output=True)
        found = probe.returncode == 0
    if not found:
        _skip_or_fail(
            "ROS 1 rosbag not installed (rosbag, python3-rosbag): `make test` installs it with "
            "apt-get as root (target ros1-deps)"
        )
    assert rosbag is not None
    return rosbag


def _read_with_rosbag(bag: Path) -> dict[str, object]:
    done = subprocess.run(
        [SYSTEM_PYTHON, "-c", _READ_ALL, str(bag)], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, f"rosbag cannot read {bag.name}: {done.stderr[-800:]}"
    return dict(json.loads(done.stdout))


def _our_bag(tmp_path: Path, compression: str) -> tuple[Path, dict[str, int]]:
    """A keypoint bag of fr079.bag (200 scans detected, the rest of the input copied) and its
    message counts by topic, as rosbags reads them."""
    source = open_scans(real_file("fr079.bag"))
    out = tmp_path / f"fr079_{compression}.bag"
    writer = open_keypoint_writer(out, source, with_map=True, compression=compression)
    detect_recording(source, CornerDetector(), writer, max_scans=200)
    with AnyReader([out]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
    return out, counts


@pytest.mark.real
@pytest.mark.parametrize("compression", ["none", "lz4", "bz2"])
def test_rosbag_reindex_info_and_read_keep_every_message(tmp_path: Path, compression: str) -> None:
    """The bag header record is padded as rosbag pads it (first chunk at byte 4117), so
    ``rosbag reindex`` (what docs/ advise for a killed output) rebuilds the index without
    writing over the first chunk; ``rosbag info`` and ``rosbag.Bag`` then read every message,
    in each chunk compression rosbag offers."""
    rosbag = _rosbag_tools()
    out, counts = _our_bag(tmp_path, compression)
    assert counts["/scan_corners"] == 200 and sum(counts.values()) > 20_000
    head = out.read_bytes()[:8192]
    (fields,) = struct.unpack_from("<I", head, 13)
    (padding,) = struct.unpack_from("<I", head, 17 + fields)
    assert fields + padding == 4096  # rosbag's layout: the first record at 13 + 4104
    assert struct.unpack_from("<I", head, 4117)[0] > 0 and b"op=\x05" in head[4117:4200]

    before = _read_with_rosbag(out)
    assert before == {"counts": counts, "compression": compression}
    reindexed = tmp_path / "reindexed.bag"
    shutil.copy(out, reindexed)
    done = subprocess.run(
        [rosbag, "reindex", "-f", str(reindexed)], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr[-800:]
    info = subprocess.run(
        [rosbag, "info", str(reindexed)], capture_output=True, text=True, timeout=300
    )
    assert info.returncode == 0, info.stderr[-800:]
    assert re.search(rf"^messages:\s+{sum(counts.values())}$", info.stdout, re.MULTILINE)
    assert _read_with_rosbag(reindexed) == before
    with AnyReader([reindexed]) as reader:  # and rosbags reads the reindexed bag
        assert {c.topic: c.msgcount for c in reader.connections} == counts
