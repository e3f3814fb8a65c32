"""Registration: accuracy on simulated scans, determinism, bad inputs, batch scoring."""

from __future__ import annotations

import math

import numpy as np
import pytest
from matching_world import corner_room

from laser_corners import CornerDetector, InvalidScanError, Keypoints, LaserScan
from laser_corners.errors import InvalidParamsError
from laser_corners.matching import (
    KeypointBank,
    MatchOptions,
    describe,
    register,
    register_keypoints,
    register_many,
)
from laser_corners.sim import World


@pytest.fixture(scope="module")
def room() -> World:
    return corner_room()


def _relative(pa: tuple[float, float, float], pb: tuple[float, float, float]) -> np.ndarray:
    """Pose of B in A's frame from both map poses."""
    c, s = math.cos(pa[2]), math.sin(pa[2])
    dx, dy = pb[0] - pa[0], pb[1] - pa[1]
    return np.array([c * dx + s * dy, -s * dx + c * dy, math.remainder(pb[2] - pa[2], 2 * math.pi)])


POSES = [
    ((0.0, 0.0, 0.0), (0.5, -0.3, 0.4)),
    ((-1.0, 0.5, 1.0), (-0.2, -0.4, 0.5)),
    ((1.5, -1.0, 2.5), (2.0, 0.2, 2.0)),
]


@pytest.mark.parametrize("descriptor", ["csc", "bsc"])
@pytest.mark.parametrize("verification", ["ransac", "clique"])
def test_register_recovers_the_relative_pose(
    room: World, descriptor: str, verification: str
) -> None:
    rng = np.random.default_rng(11)
    opts = MatchOptions(verification=verification)  # type: ignore[arg-type]
    for pa, pb in POSES:
        a = room.scan(pa, noise_sigma=0.01, rng=rng)
        b = room.scan(pb, noise_sigma=0.01, rng=rng)
        reg = register(a, b, descriptor=descriptor, options=opts)
        assert reg.accepted, reg.reason
        truth = _relative(pa, pb)
        err = np.hypot(reg.pose[0] - truth[0], reg.pose[1] - truth[1])
        assert err < 0.01, (pa, pb, reg.pose, truth)
        assert abs(math.remainder(reg.pose[2] - truth[2], 2 * math.pi)) < math.radians(0.5)
        assert reg.n_inliers >= 4 and reg.inliers.shape == (reg.n_inliers, 2)
        assert np.all(np.linalg.eigvalsh(reg.cov) > 0)
        # the inliers really are close after the transform
        kd = CornerDetector()
        ka, kb = kd.detect(a).xy, kd.detect(b).xy
        c, s = math.cos(reg.pose[2]), math.sin(reg.pose[2])
        moved = kb[reg.inliers[:, 1]] @ np.array([[c, s], [-s, c]]) + reg.pose[:2]
        assert np.all(np.hypot(*(moved - ka[reg.inliers[:, 0]]).T) <= opts.tolerance)


def test_register_is_deterministic(room: World) -> None:
    rng = np.random.default_rng(2)
    a = room.scan((0.0, 0.0, 0.0), noise_sigma=0.02, rng=rng)
    b = room.scan((0.6, 0.3, -0.3), noise_sigma=0.02, rng=rng)
    opts = MatchOptions(iterations=5, k_nearest=3, seed=4)  # random draws, not all pairs
    r1 = register(a, b, options=opts)
    r2 = register(a, b, options=opts)
    assert r1.pose == r2.pose and r1.n_inliers == r2.n_inliers
    assert np.array_equal(r1.inliers, r2.inliers)


def test_bad_inputs_give_unaccepted_registrations_or_clear_errors(room: World) -> None:
    a = room.scan((0.0, 0.0, 0.0))
    det = CornerDetector()
    ka = det.detect(a)
    da = describe(a, ka)
    empty = Keypoints.empty()
    reg = register_keypoints(ka, da, empty, describe(a, empty))
    assert not reg.accepted and reg.reason == "too few keypoints" and reg.inliers.shape == (0, 2)
    one = Keypoints(
        ka.xy[:1],
        ka.beam_index[:1],
        ka.opening_angle_deg[:1],
        ka.orientation[:1],
        ka.n_scales[:1],
        ka.rmse[:1],
        ka.n_merged[:1],
        cov=ka.cov[:1],
    )
    reg = register_keypoints(ka, da, one, describe(a, one))
    assert not reg.accepted and reg.n_inliers == 0
    # a blank scan (no returns) and a scan of another geometry: no crash
    blank = LaserScan(np.full(500, np.inf), -2.0, 0.008, 0.05, 30.0)
    assert not register(a, blank).accepted
    other = World().add_polygon([[-5, -5], [5, -5], [5, 5], [-5, 5]])
    far = LaserScan(other.cast((0, 0, 0), np.linspace(-1.5, 1.5, 181)), -1.5, 3.0 / 180, 0.1, 30.0)
    assert isinstance(register(a, far).accepted, bool)
    with pytest.raises(InvalidScanError):
        register(a, "not a scan")  # type: ignore[arg-type]
    with pytest.raises(InvalidScanError):
        register_keypoints(ka, describe(a, ka, "bsc"), ka, da)
    with pytest.raises(InvalidParamsError):
        MatchOptions(verification="magic")  # type: ignore[arg-type]


def test_ratio_and_mutual_options_still_register(room: World) -> None:
    a = room.scan((0.0, 0.0, 0.0))
    b = room.scan((0.4, 0.1, 0.3))
    for opts in (MatchOptions(ratio=0.9, min_inliers=3), MatchOptions(mutual=True, min_inliers=3)):
        reg = register(a, b, options=opts)
        assert reg.accepted, (opts, reg.reason)
        assert np.allclose(reg.pose, _relative((0, 0, 0), (0.4, 0.1, 0.3)), atol=0.01)


def test_register_many_matches_pairwise_results(room: World) -> None:
    rng = np.random.default_rng(5)
    det = CornerDetector()
    poses = [(0.0, 0.0, 0.0), (0.5, -0.3, 0.4), (0.3, 0.4, -0.3), (0.8, 0.1, 0.2)]
    scans = [room.scan(p, noise_sigma=0.01, rng=rng) for p in poses]
    kps = [det.detect(s) for s in scans]
    descs = [describe(s, k) for s, k in zip(scans, kps, strict=True)]
    blank = LaserScan(np.full(100, np.inf), -1.0, 0.02, 0.05, 30.0)
    kps.append(det.detect(blank))
    descs.append(describe(blank, kps[-1]))
    bank = KeypointBank.from_lists(kps, descs)
    out = register_many(kps[0], descs[0], bank)
    assert out.accepted.tolist()[:3] == [True] * 3 and not out.accepted[4]
    for c in range(1, 5):
        single = register_keypoints(kps[0], descs[0], kps[c], descs[c])
        assert out.n_inliers[c] == single.n_inliers and out.accepted[c] == single.accepted
        if not single.accepted:
            continue
        assert np.allclose(out.poses[c], single.pose)
        assert np.allclose(out.poses[c], _relative(poses[0], poses[c]), atol=0.01)
    sub = register_many(kps[0], descs[0], bank, candidates=[2])
    assert sub.n_inliers[0] == out.n_inliers[2]


def test_keypoints_without_covariance_or_orientation(room: World) -> None:
    """Keypoints of other detectors (no covariance, maybe no orientation) still register."""
    rng = np.random.default_rng(3)
    a = room.scan((0.0, 0.0, 0.0), noise_sigma=0.01, rng=rng)
    b = room.scan((0.5, -0.3, 0.4), noise_sigma=0.01, rng=rng)
    det = CornerDetector()

    def bare(k: Keypoints, orientation: np.ndarray) -> Keypoints:
        return Keypoints(
            k.xy, k.beam_index, k.opening_angle_deg, orientation, k.n_scales, k.rmse, k.n_merged
        )

    ka, kb = det.detect(a), det.detect(b)
    na, nb = bare(ka, ka.orientation), bare(kb, kb.orientation)
    assert np.isnan(na.cov).all()
    reg = register_keypoints(na, describe(a, na), nb, describe(b, nb))
    assert reg.accepted
    assert np.allclose(reg.pose, _relative((0, 0, 0), (0.5, -0.3, 0.4)), atol=0.02)
    # NaN orientations: empty descriptors, no crash, and no match through the angle test
    nan_o = np.full(len(kb), np.nan)
    nb2 = bare(kb, nan_o)
    for kind in ("csc", "bsc"):
        reg = register_keypoints(na, describe(a, na, kind), nb2, describe(b, nb2, kind))
        assert isinstance(reg.accepted, bool)
        reg = register_keypoints(
            na,
            describe(a, na, kind),
            nb2,
            describe(b, nb2, kind),
            MatchOptions(angle_tolerance=4.0),
        )
        assert isinstance(reg.accepted, bool)
