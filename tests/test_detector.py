"""Properties of the detector (hypothesis) and its behaviour on known scenes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from laser_corners import CornerDetector, DetectorParams, Keypoints, LaserScan
from laser_corners.errors import InvalidParamsError
from laser_corners.presets import get_preset
from laser_corners.sim import UST_10LX, World, cast_ranges, corner_scan, rectangular_room

DETECTOR = CornerDetector(DetectorParams())
FAST = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def match(a: Keypoints | np.ndarray, b: Keypoints | np.ndarray) -> float:
    """Largest distance from a point of ``a`` to its nearest point of ``b`` (same counts)."""
    xa = a.xy if isinstance(a, Keypoints) else a
    xb = b.xy if isinstance(b, Keypoints) else b
    assert len(xa) == len(xb)
    if len(xa) == 0:
        return 0.0
    d = np.hypot(xa[:, None, 0] - xb[None, :, 0], xa[:, None, 1] - xb[None, :, 1])
    return float(d.min(axis=1).max())


def test_clean_right_angle_corner_gives_exactly_one_keypoint() -> None:
    scan = corner_scan(corner=(2.0, 1.0))
    keypoints, candidates = DETECTOR.detect(scan, return_candidates=True)
    assert len(candidates) > 1  # several scan points see the corner...
    assert len(keypoints) == 1  # ...and they become one keypoint
    assert keypoints.n_merged[0] == len(candidates)
    assert np.hypot(*(keypoints.xy[0] - [2.0, 1.0])) < 0.002
    assert keypoints.opening_angle_deg[0] == pytest.approx(90.0, abs=1.0)
    # the bisector of a concave corner seen from the origin points back into the room
    assert math.cos(keypoints.orientation[0] - math.atan2(-1.0, -1.0)) > 0.99


@pytest.mark.parametrize("corner", [(1.0, 0.5), (3.0, -2.0), (-1.5, 4.0), (0.7, 0.7)])
def test_right_angle_corners_anywhere_in_view_give_one_keypoint(corner) -> None:
    for seed in range(3):
        scan = corner_scan(corner=corner, noise_sigma=0.003, rng=np.random.default_rng(seed))
        keypoints = DETECTOR.detect(scan)
        assert len(keypoints) == 1, (corner, seed, keypoints.xy)
        assert np.hypot(*(keypoints.xy[0] - corner)) < 0.01


def test_room_corners_found_without_false_keypoints() -> None:
    world = rectangular_room()
    pose = (0.3, -0.2, 0.1)
    scan = world.scan(pose, UST_10LX, noise_sigma=0.005, rng=np.random.default_rng(0))
    truth = world.visible_corners(pose, UST_10LX)
    keypoints = DETECTOR.detect(scan)
    assert len(truth) >= 2
    assert match(keypoints, truth) < 0.01


@FAST
@given(
    delta=st.floats(-math.pi, math.pi),
    distance=st.floats(1.0, 4.0),
    bearing_deg=st.floats(25.0, 65.0),
)
def test_rotating_the_scan_rotates_the_keypoints(delta: float, distance, bearing_deg) -> None:
    """Noise-free corner: keypoints rotate with the scan, up to the sampling error of the apex,
    less than one beam spacing at the corner. Not to 1e-9: the apex lies between two beams, so
    the points beside it have one neighbourhood holding a point of the other wall; ordinary
    least squares in y|x or x|y is not rotation-equivariant on such a neighbourhood, and which
    of the two apex points has the lower RMSE (and becomes the keypoint) can flip with the
    orientation. Both walls are seen at 25-65 deg from the beam: on a grazing wall (points
    7 cm apart) only large, corner-straddling neighbourhoods pass."""
    bearing = math.radians(bearing_deg)
    scan = corner_scan(corner=(distance * math.cos(bearing), distance * math.sin(bearing)))
    rotated = LaserScan(
        scan.ranges, scan.angle_min + delta, scan.angle_increment, scan.range_min, scan.range_max
    )
    a = DETECTOR.detect(scan)
    b = DETECTOR.detect(rotated)
    c, s = math.cos(delta), math.sin(delta)
    expected = a.xy @ np.array([[c, s], [-s, c]])
    assert len(a) == 1
    assert match(b.xy, expected) < distance * scan.angle_increment


@FAST
@given(
    shift=st.tuples(st.floats(-50, 50), st.floats(-50, 50)),
    theta=st.floats(-math.pi, math.pi),
    seed=st.integers(0, 1000),
)
def test_rigid_motion_of_the_points_moves_keypoints_rigidly(shift, theta, seed) -> None:
    """Translate (any noise) and rotate (noise-free) the Cartesian points: keypoints follow."""
    rng = np.random.default_rng(seed)
    scan = rectangular_room().scan((0.2, 0.1, 0.3), UST_10LX, noise_sigma=0.004, rng=rng)
    xy, _ = scan.to_cartesian()
    base = DETECTOR.detect_points(xy)
    moved = DETECTOR.detect_points(xy + np.array(shift))
    assert match(moved.xy, base.xy + np.array(shift)) < 1e-9 * max(1.0, abs(max(shift, key=abs)))
    # rotations: least squares is not rotation-equivariant (see the test above), so
    # noise-free points, and keypoints rigid up to one beam spacing at the farthest corner
    clean = rectangular_room().scan((0.2, 0.1, 0.3), UST_10LX).to_cartesian()[0]
    c, s = math.cos(theta), math.sin(theta)
    rot = np.array([[c, -s], [s, c]])
    base = DETECTOR.detect_points(clean)
    turned = DETECTOR.detect_points(clean @ rot.T)
    spacing = np.hypot(*base.xy.T).max() * UST_10LX.angle_increment
    assert match(turned.xy, base.xy @ rot.T) < spacing


@FAST
@given(seed=st.integers(0, 10_000), noise=st.sampled_from([0.0, 0.005, 0.01]))
def test_reversing_beam_order_gives_the_same_keypoints(seed: int, noise: float) -> None:
    rng = np.random.default_rng(seed)
    pose = (rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(-3, 3))
    scan = rectangular_room().scan(pose, UST_10LX, noise_sigma=noise, rng=rng)
    n = scan.n_beams
    reversed_scan = LaserScan(
        scan.ranges[::-1],
        scan.angle_min + (n - 1) * scan.angle_increment,
        -scan.angle_increment,
        scan.range_min,
        scan.range_max,
    )
    a = DETECTOR.detect(scan)
    b = DETECTOR.detect(reversed_scan)
    assert match(a, b) < 1e-9
    assert sorted(a.beam_index.tolist()) == sorted((n - 1 - b.beam_index).tolist())


@settings(max_examples=60, deadline=None)
@given(
    distance=st.floats(0.5, 8.0),
    heading=st.floats(-1.2, 1.2),
    noise=st.floats(0.0, 0.002),
    seed=st.integers(0, 10_000),
)
def test_straight_wall_with_small_noise_gives_no_keypoint(distance, heading, noise, seed) -> None:
    # an infinite-looking straight wall at `distance`, turned by `heading`
    c, s = math.cos(heading), math.sin(heading)
    p = np.array([distance * c, distance * s])
    t = np.array([-s, c]) * 40.0
    wall = np.r_[p - t, p + t][None, :]
    ranges = cast_ranges(wall, (0.0, 0.0, 0.0), UST_10LX.angles)
    rng = np.random.default_rng(seed)
    finite = np.isfinite(ranges)
    ranges[finite] += rng.normal(0, noise, int(finite.sum())) if noise > 0 else 0.0
    scan = LaserScan(
        ranges, UST_10LX.angle_min, UST_10LX.angle_increment, UST_10LX.range_min, UST_10LX.range_max
    )
    assert len(DETECTOR.detect(scan)) == 0


special = st.sampled_from([np.nan, np.inf, -np.inf, 0.0, -1.0, 1e300, 0.06, 10.0])


@settings(max_examples=80, deadline=None)
@given(
    ranges=hnp.arrays(
        np.float64,
        st.integers(0, 300),
        elements=st.one_of(st.floats(0.0, 12.0), special),
    )
)
def test_any_ranges_never_raise(ranges: np.ndarray) -> None:
    scan = LaserScan(ranges, -2.0, 0.01, 0.06, 10.0)
    keypoints = DETECTOR.detect(scan)
    assert keypoints.xy.shape == (len(keypoints), 2)
    assert np.isfinite(keypoints.xy).all()
    batch = DETECTOR.detect_many([scan, scan])
    assert match(batch[0], keypoints) == 0.0


def test_detect_many_equals_detect() -> None:
    rng = np.random.default_rng(5)
    world = rectangular_room()
    scans = [
        world.scan(
            (rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-3, 3)),
            UST_10LX,
            noise_sigma=0.005,
            rng=rng,
            stamp=float(i),
        )
        for i in range(12)
    ]
    batch = DETECTOR.detect_many(scans)
    assert len(batch) == len(scans)
    total = 0
    for scan, got in zip(scans, batch, strict=True):
        one = DETECTOR.detect(scan)
        assert got.stamp == scan.stamp
        assert np.array_equal(got.xy, one.xy)
        assert np.array_equal(got.beam_index, one.beam_index)
        total += len(one)
    assert total > 0


def test_detect_many_rejects_mixed_geometry() -> None:
    a = corner_scan()
    b = LaserScan(a.ranges[:-1], a.angle_min, a.angle_increment, a.range_min, a.range_max)
    with pytest.raises(ValueError, match="scan 1 has a different geometry"):
        DETECTOR.detect_many([a, b])


def test_all_gaps_and_tiny_scans() -> None:
    for ranges in ([], [1.0], [np.nan] * 50, [0.0] * 50, [np.inf] * 5):
        assert len(DETECTOR.detect(LaserScan(ranges, 0.0, 0.01, 0.06, 10.0))) == 0


def test_scale_table_exposes_per_scale_results() -> None:
    scan = corner_scan()
    keypoints = DETECTOR.detect(scan)
    table = DETECTOR.scale_table(scan)
    j = int(keypoints.beam_index[0])
    assert table.passed.shape == (scan.n_beams, len(DETECTOR.params.scales))
    assert table.passed[j].sum() == keypoints.n_scales[0]
    assert not table.passed[:5].any()  # too few points at the scan's start
    passed = table.intersections[j][table.passed[j]]
    assert np.allclose(passed.mean(axis=0), keypoints.xy[0], atol=1e-9)


def test_keypoints_records_and_transform() -> None:
    keypoints = DETECTOR.detect(corner_scan(corner=(2.0, 1.0)))
    rec = keypoints.to_records()
    assert rec.x[0] == keypoints.xy[0, 0] and rec.n_merged[0] == keypoints.n_merged[0]
    rows = keypoints.to_dicts()
    assert set(rows[0]) >= {
        "x",
        "y",
        "beam_index",
        "opening_angle_deg",
        "orientation",
        "n_scales",
        "rmse",
        "n_merged",
    }
    moved = keypoints.transformed((1.0, 2.0, math.pi / 2), frame_id="map")
    assert np.allclose(moved.xy[0], [1.0 - keypoints.xy[0, 1], 2.0 + keypoints.xy[0, 0]])
    assert moved.frame_id == "map"
    assert math.cos(moved.orientation[0] - keypoints.orientation[0] - math.pi / 2) > 1 - 1e-12


def test_world_visible_corners_drop_hidden_ones() -> None:
    world = World().add_polygon([[1.0, -0.5], [2.0, -0.5], [2.0, 0.5], [1.0, 0.5]])
    seen = world.visible_corners((0.0, 0.0, 0.0), UST_10LX)
    # from the origin only the face x=1 is seen: its corners are silhouettes, none is seen
    assert len(seen) == 0
    seen = world.visible_corners((0.0, -2.0, 0.0), UST_10LX)
    assert np.allclose(seen, [[1.0, 1.5]])  # the corner (1, -0.5): both its walls are seen


def test_scale_index_is_the_first_scale_of_the_winning_run() -> None:
    scan = corner_scan(corner=(2.0, 1.0))
    keypoints, candidates = DETECTOR.detect(scan, return_candidates=True)
    table = DETECTOR.scale_table(scan)
    for kps in (keypoints, candidates):
        assert kps.scale_index.dtype == np.int64 and kps.scale_index.shape == (len(kps),)
        for j, k0, n in zip(kps.beam_index, kps.scale_index, kps.n_scales, strict=True):
            assert table.passed[j, k0 : k0 + n].all()
            assert k0 == 0 or not table.passed[j, k0 - 1]
    assert keypoints.to_dicts()[0]["scale_index"] == keypoints.scale_index[0]
    assert (Keypoints.empty().scale_index == np.zeros(0)).all()


def test_detector_from_preset_and_by_name() -> None:
    scan = corner_scan()
    assert CornerDetector("paper").params == DetectorParams()
    assert CornerDetector.from_preset("auto", scan).params == get_preset("auto", scan)
    assert len(CornerDetector.from_preset("robust", scan).detect(scan)) == 1
    for name in ("auto", "robust"):
        with pytest.raises(InvalidParamsError, match=f"preset '{name}' needs a scan.*from_preset"):
            CornerDetector.from_preset(name)
        with pytest.raises(InvalidParamsError, match=f"preset '{name}' needs a scan"):
            CornerDetector(name)
    with pytest.raises(InvalidParamsError, match="unknown preset 'nope'"):
        CornerDetector.from_preset("nope")
    with pytest.raises(InvalidParamsError, match="takes DetectorParams or a preset name"):
        CornerDetector(3)  # type: ignore[arg-type]
