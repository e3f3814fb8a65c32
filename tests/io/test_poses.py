"""Pose tracks: the streaming track equals the whole-bag track."""

from __future__ import annotations

import bisect
import math
from types import SimpleNamespace

import numpy as np
import pytest

from laser_corners.io.poses import FORGET_BATCH, PoseTrack, StreamingTrack, interp_at


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
    # the list interpolation is np.interp's, bit for bit (samples, between them, outside);
    # between two samples across a wrap-around the yaw is the unwrapped one's or not at all
    for stamp in [*np.linspace(-0.7, 40.6, 301).tolist(), *ordered[:, 0].tolist()]:
        assert in_order.pose(stamp, "laser") == reference.pose(stamp, "laser")


def _walk(n: int, seed: int) -> list[tuple[float, float, float, float]]:
    """Odometry at 50 Hz in arrival order: a seeded random walk whose yaw wraps around
    often (and now and then jumps by more than pi), one sample in 20 arriving up to 5
    samples late."""
    rng = np.random.default_rng(seed)
    steps = rng.uniform(-0.8, 0.8, n)
    steps[rng.random(n) < 0.01] += 3.5
    yaw = np.angle(np.exp(1j * np.cumsum(steps)))
    xy = np.cumsum(rng.normal(0.0, 0.01, (n, 2)), axis=0)
    stamps = 1.2e9 + 0.02 * np.arange(n)
    rows = zip(stamps.tolist(), xy.tolist(), yaw.tolist(), strict=True)
    samples = [(t, x, y, a) for t, (x, y), a in rows]
    order = np.arange(n, dtype=np.float64)
    late = rng.random(n) < 0.05
    order[late] += rng.uniform(1.0, 5.0, late.sum())
    return [samples[i] for i in np.argsort(order, kind="stable")]


def _tracks() -> tuple[StreamingTrack, StreamingTrack]:
    tracks = StreamingTrack(), StreamingTrack()
    for track in tracks:
        track.add_transforms([("base", "laser", (0.1, 0.0, 0.5))], is_static=True)
    return tracks


def test_forgetting_keeps_the_poses_after_the_horizon_bit_for_bit() -> None:
    """A track that forgets the samples 20 s before the newest gives the poses of one that
    keeps them all (yaw wraps, late samples, a pending rebuild when forgetting or not), and
    holds a bounded number of samples."""
    whole, kept = _tracks()
    rng = np.random.default_rng(12)
    newest, dropped, held = -math.inf, [], []
    for i, sample in enumerate(_walk(20_000, seed=11)):
        assert whole.add_odometry("odom", "base", sample)
        assert kept.add_odometry("odom", "base", sample)
        newest = max(newest, sample[0])
        if i % 25:
            continue
        horizon = newest - 20.0
        dropped.append(kept.forget_before(horizon))
        held.append(kept.n_kept)
        if rng.random() < 0.5:  # else the next forget_before finds a rebuild pending
            for stamp in [horizon, *rng.uniform(horizon, newest + 0.6, 8).tolist()]:
                assert kept.pose(stamp, "laser") == whole.pose(stamp, "laser")
    assert sum(dropped) == whole.n_kept - kept.n_kept > 0
    assert sum(1 for n in dropped if n) >= 10  # forgotten in batches, not once
    assert min(n for n in dropped if n) >= FORGET_BATCH
    assert max(held) <= 2 * (20.0 * 50 + 25) + FORGET_BATCH  # see forget_before
    first = kept.first_stamp
    assert first is not None and first <= horizon
    for stamp in np.linspace(first, newest + 0.6, 500).tolist():
        assert kept.pose(stamp, "laser") == whole.pose(stamp, "laser")
    assert kept.pose(first - 0.01, "laser") is None  # forgotten
    assert whole.pose(first - 0.01, "laser") is not None


def test_a_sample_older_than_those_kept_is_not_taken() -> None:
    track = _tracks()[0]
    samples = [(0.02 * i, 0.0, 0.0, 0.0) for i in range(3 * FORGET_BATCH)]
    for sample in samples:
        track.add_odometry("odom", "base", sample)
    assert track.forget_before(samples[FORGET_BATCH // 2][0]) == 0  # too few: kept for now
    assert track.n_kept == len(samples)
    assert track.forget_before(samples[2 * FORGET_BATCH][0]) == 2 * FORGET_BATCH
    assert track.first_stamp == samples[2 * FORGET_BATCH][0]
    assert not track.add_odometry("odom", "base", (0.5, 1.0, 1.0, 1.0))
    assert track.n_kept == FORGET_BATCH
    assert track.add_odometry("odom", "base", (0.02 * 2500 + 0.01, 1.0, 1.0, 1.0))  # late
    assert track.n_kept == FORGET_BATCH + 1


def test_interp_at_is_np_interp_bit_for_bit() -> None:
    rng = np.random.default_rng(5)
    times = np.sort(rng.uniform(0.0, 10.0, 50))
    values = rng.normal(0.0, 3.0, 50)
    for stamp in [*rng.uniform(-1.0, 11.0, 500).tolist(), *times.tolist(), -5.0, 99.0]:
        j = bisect.bisect_right(times.tolist(), stamp) - 1
        got = interp_at(stamp, times.tolist(), values.tolist(), j)
        assert got == float(np.interp(stamp, times, values))


def _pairs_bag(path, epoch_s: int, n: int):
    """A ROS 1 bag stamped from ``epoch_s``: per scan, odometry at the scan's own header stamp
    and a second sample 1 ms later 0.5 m further (intel's odometry comes in such pairs); the
    scans, odometry x = 0.1 k at scan k; stamps (sec, nanosec) of the scans."""
    from rosbags.rosbag1 import Writer

    from laser_corners.sim import SICK_LMS_1DEG, rectangular_room
    from sim_drives import ODOM_TYPE, SCAN_TYPE, TF_TYPE, BagMessages

    bag = BagMessages(False)
    scan = rectangular_room().scan((0.0, 0.0, 0.0), SICK_LMS_1DEG)
    time = bag.t["builtin_interfaces/msg/Time"]
    stamps = []
    with Writer(path) as writer:
        static = writer.add_connection("/tf_static", TF_TYPE, typestore=bag.store)
        odom = writer.add_connection("/odom", ODOM_TYPE, typestore=bag.store)
        scans = writer.add_connection("/scan", SCAN_TYPE, typestore=bag.store)
        mount = bag.t[TF_TYPE](transforms=[bag.tf(0.0, "base_link", "laser", (0, 0, 0))])
        writer.write(static, epoch_s * 10**9, bag.ser(mount, TF_TYPE))
        for k in range(n):
            ns = epoch_s * 10**9 + k * 100_000_000 + 7_919 * k * k
            for dt, x in ((0, 0.1 * k), (1_000_000, 0.1 * k + 0.5)):
                msg = bag.odometry(0.0, (x, 0.0, 0.0))
                msg.header.stamp = time(*divmod(ns + dt, 10**9))
                writer.write(odom, ns + dt, bag.ser(msg, ODOM_TYPE))
                if dt == 0:
                    msg = bag.scan(0.0, scan)
                    msg.header.stamp = time(*divmod(ns, 10**9))
                    writer.write(scans, ns, bag.ser(msg, SCAN_TYPE))
                    stamps.append(divmod(ns, 10**9))
    return stamps


@pytest.mark.parametrize("epoch_s", [1211, 976054571])  # fr079's stamps, intel's (year 2000)
def test_a_scan_stamped_as_an_odometry_sample_gets_its_pose(tmp_path, epoch_s: int) -> None:
    """A scan's stamp is read as every odometry and tf stamp is (``sec + 1e-9 * nsec``, as the
    ROS 2 node reads them too), so a scan stamped as an odometry sample gets that sample's
    pose: at intel's epoch a float second steps by 1.2e-7 s, and a stamp one step off was
    interpolated towards the sample 1 ms later (0.5 m on: 6e-5 m off)."""
    from laser_corners.io import open_scans
    from laser_corners.ros.convert import stamp_to_sec

    bag = tmp_path / "pairs.bag"
    stamps = _pairs_bag(bag, epoch_s, 40)
    scans = list(open_scans(bag))
    assert len(scans) == 40
    for k, (scan, (sec, nsec)) in enumerate(zip(scans, stamps, strict=True)):
        assert scan.stamp == sec + 1e-9 * nsec
        assert scan.stamp == stamp_to_sec(SimpleNamespace(sec=sec, nanosec=nsec))  # the node's
        assert scan.pose == pytest.approx((0.1 * k, 0.0, 0.0), abs=1e-9)
