"""The mapping modes' warnings (``laser_corners.ros.mapping_watch``), without ROS.

The core runs on a hand-driven clock with simulated scans; the warnings are what the node
logs, the summary what it prints at shutdown.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

pytest.importorskip("gtsam")

from test_slam_core import MOUNT, Clock, _core, _drive, _tf

from laser_corners.ros.mapping_watch import WARN_PERIOD


def _counts(summary: str) -> dict[str, int]:
    """The scan counts of a summary line."""
    names = ("scans", "processed", "without odometry", "malformed", "still waiting")
    found = {n: re.search(rf"(\d+) {n}\b", summary) for n in names}
    assert all(found.values()), summary
    return {n: int(m.group(1)) for n, m in found.items()}


def test_a_wrong_base_frame_is_named_with_the_frames_seen() -> None:
    truth, scans = _drive(30)
    clock = Clock()
    core = _core(clock, base_frame="base_footprint", tf_wait=0.5)
    core.book.add_transforms([_tf("base_link", "laser", 0, MOUNT)], static=True)
    warnings: list[str] = []
    for i, scan in enumerate(scans):
        clock.now = i * 0.1
        core.book.add_transforms([_tf("odom", "base_link", i * 0.1 + 0.05, truth[i])], False)
        assert core.add_scan(scan) == []
        warnings += core.watch.warnings(core.book)
    core.malformed_scan()
    text = "\n".join(warnings)
    assert "no odometry in frames odom -> base_footprint on /tf" in text, text
    assert re.search(r"seen there: odom -> base_link \(\d+\)", text), text
    assert "no odometry for" in text and "dropped so far without odometry" in text, text
    # throttled: 3 s of scans, one warning of each kind per 5 s
    assert len(warnings) == 3, warnings
    counts = _counts(core.summary())
    assert counts["scans"] == 31 and counts["processed"] == 0 and counts["malformed"] == 1
    assert counts["without odometry"] + counts["still waiting"] == 30, core.summary()
    assert counts["without odometry"] >= 20


def test_no_odometry_at_all_warns_after_odom_timeout_and_repeats_throttled() -> None:
    _, scans = _drive(80)
    clock = Clock()
    core = _core(clock, odom_timeout=2.0)
    warnings: list[tuple[float, str]] = []
    for i, scan in enumerate(scans):
        clock.now = i * 0.1
        core.add_scan(scan)
        warnings += [(clock.now, w) for w in core.watch.warnings(core.book)]
    lost = [t for t, w in warnings if w.startswith("no odometry for")]
    assert lost and lost[0] == pytest.approx(2.1), warnings
    assert np.all(np.diff(lost) >= WARN_PERIOD), lost
    first = next(w for _, w in warnings if w.startswith("no odometry for"))
    assert "expecting odom -> (any child) on /tf (none yet); seen there: nothing" in first
    assert not any("no odometry in frames" in w for _, w in warnings)  # nothing was seen


def test_an_odometry_jump_is_counted_and_named() -> None:
    truth, scans = _drive(30)
    clock = Clock()
    core = _core(clock, max_odom_jump=0.5)
    core.book.add_transforms([_tf("base_link", "laser", 0, MOUNT)], static=True)
    odom = truth.copy()
    odom[15:, 0] += 3.0  # the odometry teleports by 3 m between scans 14 and 15
    warnings: list[str] = []
    for i, scan in enumerate(scans):
        core.book.add_transforms([_tf("odom", "base_link", i / 10.0, odom[i])], False)
        core.book.add_transforms([_tf("odom", "base_link", (i + 0.5) / 10.0, odom[i])], False)
        core.add_scan(scan)
        warnings += core.watch.warnings(core.book)
    jumps = [w for w in warnings if w.startswith("odometry jumped")]
    assert len(jumps) == 1 and "jumped 3.0" in jumps[0] and "max_odom_jump 0.5 m" in jumps[0]
    assert "between the scans at 1.400 and 1.500 s" in jumps[0], jumps
    assert core.watch.counts.odom_jumps == 1
    assert "1 odometry jumps" in core.summary()


def test_good_odometry_says_nothing() -> None:
    truth, scans = _drive(40)
    clock = Clock()
    core = _core(clock)
    core.book.add_transforms([_tf("base_link", "laser", 0, MOUNT)], static=True)
    for i, scan in enumerate(scans):
        clock.now = i * 0.1
        core.book.add_transforms([_tf("odom", "base_link", i / 10.0, truth[i])], False)
        core.book.add_transforms([_tf("odom", "base_link", (i + 0.5) / 10.0, truth[i])], False)
        core.add_scan(scan)
        assert core.watch.warnings(core.book) == []
    counts = _counts(core.summary())
    assert counts["processed"] == 40 and counts["scans"] == 40
