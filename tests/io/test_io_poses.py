"""Pose tracks: the streaming track equals the whole-bag track."""

from __future__ import annotations

import numpy as np
import pytest

from laser_corners.io.poses import PoseTrack, StreamingTrack


def test_streaming_track_unwraps_yaw_exactly_as_np_unwrap() -> None:
    rng = np.random.default_rng(3)
    yaw = np.angle(np.exp(1j * np.cumsum(rng.uniform(-1.5, 1.5, 400))))  # many wraps
    samples = [(0.1 * i, float(np.cos(i)), float(np.sin(i)), float(y)) for i, y in enumerate(yaw)]
    late = samples.pop(200)  # one sample arrives out of order
    track = StreamingTrack()
    for sample in samples[:300]:
        track.add_odometry("odom", "base", sample)
    track.add_odometry("odom", "base", late)
    for sample in samples[300:]:
        track.add_odometry("odom", "base", sample)
    track.add_transforms([("base", "laser", (0.1, 0.0, 0.5))], is_static=True)
    ordered = np.array(sorted([*samples, late]))
    reference = PoseTrack(
        "odom", "base", ordered[:, 0], ordered[:, 1], ordered[:, 2], np.unwrap(ordered[:, 3]),
        {"laser": ("base", (0.1, 0.0, 0.5))},
    )  # fmt: skip
    for stamp in np.linspace(-0.2, 40.3, 97):
        expected = reference.pose(float(stamp), "laser")
        got = track.pose(float(stamp), "laser")
        assert got == pytest.approx(expected, abs=1e-12) if expected else got is None
    in_order = StreamingTrack()
    for sample in sorted([*samples, late]):
        in_order.add_odometry("odom", "base", sample)
    in_order.pose(0.0, "base")
    np.testing.assert_array_equal(in_order._current().yaw, np.unwrap(ordered[:, 3]))  # type: ignore[union-attr]
