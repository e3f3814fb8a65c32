"""Pose tracks: the streaming track equals the whole-bag track."""

from __future__ import annotations

import bisect

import numpy as np
import pytest

from laser_corners.io.poses import PoseTrack, StreamingTrack, interp_at


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
        "odom",
        "base",
        ordered[:, 0],
        ordered[:, 1],
        ordered[:, 2],
        np.unwrap(ordered[:, 3]),
        {"laser": ("base", (0.1, 0.0, 0.5))},
    )
    for stamp in np.linspace(-0.2, 40.3, 97):
        expected = reference.pose(float(stamp), "laser")
        got = track.pose(float(stamp), "laser")
        assert got == pytest.approx(expected, abs=1e-12) if expected else got is None
    in_order = StreamingTrack()
    for sample in sorted([*samples, late]):
        in_order.add_odometry("odom", "base", sample)
    in_order.add_transforms([("base", "laser", (0.1, 0.0, 0.5))], is_static=True)
    in_order.pose(0.0, "base")
    np.testing.assert_array_equal(in_order._yaw, np.unwrap(ordered[:, 3]))
    # the list interpolation is np.interp's, bit for bit (samples, between them, outside)
    for stamp in [*np.linspace(-0.7, 40.6, 301).tolist(), *ordered[:, 0].tolist()]:
        assert in_order.pose(stamp, "laser") == reference.pose(stamp, "laser")


def test_interp_at_is_np_interp_bit_for_bit() -> None:
    rng = np.random.default_rng(5)
    times = np.sort(rng.uniform(0.0, 10.0, 50))
    values = rng.normal(0.0, 3.0, 50)
    for stamp in [*rng.uniform(-1.0, 11.0, 500).tolist(), *times.tolist(), -5.0, 99.0]:
        j = bisect.bisect_right(times.tolist(), stamp) - 1
        got = interp_at(stamp, times.tolist(), values.tolist(), j)
        assert got == float(np.interp(stamp, times, values))
