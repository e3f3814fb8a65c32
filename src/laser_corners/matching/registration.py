"""Scan-to-scan registration from corner keypoints: matches, verification, weighted SE(2).

Pipeline (numba, :mod:`laser_corners.matching.core` and :mod:`~laser_corners.matching.solve`):

1. candidate matches: each keypoint of A with its ``k_nearest`` nearest keypoints of B in
   descriptor space (distance <= ``max_distance``; optional Lowe ratio test and mutual check);
2. geometric verification, either RANSAC over two-point SE(2) hypotheses (all pairs when there
   are at most ``iterations`` of them, else seeded random pairs) or the maximum clique of
   pairwise-consistent matches (FALKO's CCDA: two matches agree when the distance between
   their keypoints in A and in B differ by at most ``tolerance``);
3. weighted least squares SE(2) (Gauss-Newton on the Mahalanobis residuals with the keypoint
   covariances ``C_a + R C_b Rᵀ``), the final inliers (residual <= ``tolerance``, one match
   per keypoint) and the pose covariance ``(JᵀWJ)⁻¹``.

The pose is that of B's sensor frame in A's frame, ``p_A = R(θ)·p_B + t`` (the convention of
:func:`laser_corners.eval.repeatability.pair_repeatability`).

For place recognition (one query against thousands of scans) detect and describe every scan
once, put them in a :class:`KeypointBank` and call :func:`register_many`: one numba call,
parallel over candidates, with cheap rejects (too few keypoints, too few candidate matches)
before any geometry.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from laser_corners.detector import CornerDetector
from laser_corners.errors import InvalidParamsError, InvalidScanError
from laser_corners.keypoints import Keypoints
from laser_corners.matching.core import VERIFY_CLIQUE, VERIFY_RANSAC
from laser_corners.matching.descriptors import DescriptorParams, Descriptors, describe
from laser_corners.matching.solve import register_batch, register_pair
from laser_corners.params import DetectorParams
from laser_corners.scan import LaserScan, Pose2D

__all__ = [
    "BatchResult",
    "KeypointBank",
    "MatchOptions",
    "Registration",
    "register",
    "register_keypoints",
    "register_many",
]

DEFAULT_MAX_DISTANCE = {"csc": 0.75, "bsc": 0.3}
"""Default ``MatchOptions.max_distance`` per descriptor kind."""

_REASONS = {
    1: "too few keypoints",
    2: "too few candidate matches",
    3: "too few geometrically consistent matches",
}


@dataclass(frozen=True)
class MatchOptions:
    """Options of the matcher (defaults in brackets).

    Attributes
    ----------
    min_inliers : int
        Inliers needed to accept a registration [4] (at least 2 are always needed).
    tolerance : float
        Inlier tolerance, metres: largest residual of an inlier and largest disagreement of
        pairwise distances in the clique test [0.1].
    k_nearest : int
        Candidate matches per keypoint of A [3].
    ratio : float
        Lowe's ratio test on the two nearest distances; 1.0 turns it off (then k_nearest
        applies), below 1 only the nearest is kept [1.0].
    mutual : bool
        Keep a match only when it is also the nearest from B's side [False].
    max_distance : float or None
        Largest normalised descriptor distance of a candidate match [None: 0.75 for csc,
        0.3 for bsc]. The main speed/recall knob: on fr079.bag's relations, csc at 0.5
        halves the time per pair and accepts 21 % instead of 26 % of the pairs.
    verification : {"ransac", "clique"}
        Geometric verification ["ransac"].
    iterations : int
        RANSAC hypotheses (all pairs when fewer) [200].
    min_separation : float
        Smallest distance between the two keypoints of a RANSAC hypothesis, metres [0.3].
    seed : int
        RANSAC seed (results are deterministic for a seed) [0].
    default_sigma : float
        Standard deviation used for keypoints without a covariance (NaN ``cov``) [0.03].
    angle_tolerance : float
        Largest disagreement, radians, between the rotation of a hypothesis and the rotation
        a match implies by its two keypoint orientations (bisectors); also in the pairwise
        test of the clique. ``math.pi`` or more turns it off [0.5].
    """

    min_inliers: int = 4
    tolerance: float = 0.1
    k_nearest: int = 3
    ratio: float = 1.0
    mutual: bool = False
    max_distance: float | None = None
    verification: Literal["ransac", "clique"] = "ransac"
    iterations: int = 200
    min_separation: float = 0.3
    seed: int = 0
    default_sigma: float = 0.03
    angle_tolerance: float = 0.5

    def __post_init__(self) -> None:
        if self.verification not in ("ransac", "clique"):
            raise InvalidParamsError(
                f"verification must be 'ransac' or 'clique', got {self.verification!r}"
            )
        if self.k_nearest < 1 or self.iterations < 1 or self.tolerance <= 0:
            raise InvalidParamsError(f"invalid match options: {self}")

    def _args(self, kind: str) -> tuple:
        verify = VERIFY_CLIQUE if self.verification == "clique" else VERIFY_RANSAC
        max_distance = self.max_distance
        if max_distance is None:
            max_distance = DEFAULT_MAX_DISTANCE[kind]
        return (
            self.k_nearest, float(self.ratio), bool(self.mutual), float(max_distance),
            verify, float(self.tolerance), float(self.min_separation), int(self.iterations),
            int(self.seed), int(self.min_inliers), float(self.default_sigma) ** 2,
            float(self.angle_tolerance),
        )  # fmt: skip


@dataclass(frozen=True)
class Registration:
    """Result of a registration.

    Attributes
    ----------
    accepted : bool
        At least ``min_inliers`` inliers.
    reason : str
        Why not accepted ("" when accepted).
    n_inliers : int
        Inlier matches.
    pose : Pose2D
        Pose (x, y, θ) of B's sensor frame in A's frame (identity when not accepted).
    cov : ndarray, shape (3, 3)
        Covariance of ``pose`` (x, y, θ) from the weighted least squares (NaN if not accepted).
    inliers : ndarray, shape (n_inliers, 2), int64
        Inlier pairs (index in A's keypoints, index in B's keypoints).
    n_candidates : int
        Candidate matches before the geometric verification.
    """

    accepted: bool
    reason: str
    n_inliers: int
    pose: Pose2D
    cov: NDArray[np.float64]
    inliers: NDArray[np.int64]
    n_candidates: int = 0


def _check_pair(kp: Keypoints, desc: Descriptors, name: str) -> None:
    if not isinstance(kp, Keypoints) or not isinstance(desc, Descriptors):
        raise InvalidScanError(f"register_keypoints: {name} needs Keypoints and Descriptors")
    if len(kp) != len(desc):
        raise InvalidScanError(
            f"register_keypoints: {name} has {len(kp)} keypoints but {len(desc)} descriptors"
        )


def _kp_args(k: Keypoints) -> tuple:
    return (
        np.ascontiguousarray(k.xy),
        np.ascontiguousarray(k.cov),
        np.ascontiguousarray(k.orientation, dtype=np.float64),
    )


def _desc_args(d: Descriptors) -> tuple:
    return (np.ascontiguousarray(d.bits), np.ascontiguousarray(d.values))


def register_keypoints(
    kp_a: Keypoints,
    desc_a: Descriptors,
    kp_b: Keypoints,
    desc_b: Descriptors,
    options: MatchOptions | None = None,
) -> Registration:
    """Register keypoints B to keypoints A (each in its own sensor frame).

    Parameters
    ----------
    kp_a, kp_b : Keypoints
        Keypoints with covariances (NaN covariances use ``options.default_sigma``).
    desc_a, desc_b : Descriptors
        Their descriptors, of the same kind and size.
    options : MatchOptions, optional
        Matcher options.

    Returns
    -------
    Registration
        Unaccepted (with a reason) when there are too few keypoints, matches or inliers.
    """
    opt = options or MatchOptions()
    _check_pair(kp_a, desc_a, "A")
    _check_pair(kp_b, desc_b, "B")
    if (
        desc_a.kind != desc_b.kind
        or desc_a.bits.shape[1] != desc_b.bits.shape[1]
        or (desc_a.values.shape[1] != desc_b.values.shape[1])
    ):
        raise InvalidScanError("register_keypoints: descriptors of A and B differ in kind or size")
    pose = np.zeros(3)
    pose_cov = np.full((3, 3), np.nan)
    inl = np.empty((max(min(len(kp_a), len(kp_b)), 1), 2), dtype=np.int64)
    inv_bits = 1.0 / desc_a.n_bits if desc_a.n_bits else 0.0
    status, n_inl, n_cand = register_pair(
        desc_a.kind_code, inv_bits,
        *_kp_args(kp_a), *_desc_args(desc_a), *_kp_args(kp_b), *_desc_args(desc_b),
        *opt._args(desc_a.kind), pose, pose_cov, inl,
    )  # fmt: skip
    if status != 0:
        return Registration(
            False, _REASONS[status], int(n_inl), (0.0, 0.0, 0.0), np.full((3, 3), np.nan),
            np.zeros((0, 2), np.int64), int(n_cand),
        )  # fmt: skip
    return Registration(
        True, "", int(n_inl), (float(pose[0]), float(pose[1]), float(pose[2])), pose_cov,
        inl[:n_inl].copy(), int(n_cand),
    )  # fmt: skip


def register(
    scan_a: LaserScan,
    scan_b: LaserScan,
    detector: CornerDetector | None = None,
    params: DetectorParams | None = None,
    descriptor: str | DescriptorParams = "csc",
    options: MatchOptions | None = None,
) -> Registration:
    """Detect, describe and register scan B to scan A.

    Parameters
    ----------
    scan_a, scan_b : LaserScan
        The scans (any geometry each).
    detector : CornerDetector, optional
        Detector to use; else one built from ``params`` (default: the paper's parameters).
    params : DetectorParams, optional
        Detector parameters when no ``detector`` is given.
    descriptor : {"csc", "bsc"} or DescriptorParams
        Descriptor (see :mod:`laser_corners.matching.descriptors`).
    options : MatchOptions, optional
        Matcher options.

    Returns
    -------
    Registration
        ``reg.pose`` is the pose of B's sensor frame in A's frame.

    Examples
    --------
    >>> import numpy as np
    >>> from laser_corners.sim import World
    >>> room = World().add_polygon([[-4, -3], [1, -3], [1, -2.4], [2, -2.4], [2, -3], [4, -3],
    ...                             [4, 3], [-1, 3], [-1, 2.2], [-2.5, 2.2], [-2.5, 3], [-4, 3]])
    >>> room = room.add_polygon([[0.5, 0.5], [1.2, 0.5], [1.2, 1.0], [0.5, 1.0]])
    >>> reg = register(room.scan((0.0, 0.0, 0.0)), room.scan((0.5, -0.3, 0.4)))
    >>> reg.accepted, np.round(reg.pose, 2).tolist()
    (True, [0.5, -0.3, 0.4])
    """
    for name, scan in (("A", scan_a), ("B", scan_b)):
        if not isinstance(scan, LaserScan):
            raise InvalidScanError(f"register: scan {name} is a {type(scan).__name__}")
    det = detector if detector is not None else CornerDetector(params)
    kp_a = det.detect(scan_a)
    kp_b = det.detect(scan_b)
    d_a = describe(scan_a, kp_a, descriptor)
    d_b = describe(scan_b, kp_b, descriptor)
    return register_keypoints(kp_a, d_a, kp_b, d_b, options)


@dataclass
class KeypointBank:
    """Keypoints and descriptors of many scans in flat arrays, for :func:`register_many`.

    Build it once per log with :meth:`from_lists`; candidate ``c`` owns rows
    ``offsets[c]:offsets[c+1]``.
    """

    kind: str
    n_bits: int
    xy: NDArray[np.float64]
    cov: NDArray[np.float64]
    orientation: NDArray[np.float64]
    bits: NDArray[np.uint64]
    values: NDArray[np.float64]
    offsets: NDArray[np.int64] = field(default_factory=lambda: np.zeros(1, np.int64))

    def __len__(self) -> int:
        return int(self.offsets.shape[0] - 1)

    @classmethod
    def from_lists(
        cls, keypoints: Sequence[Keypoints], descriptors: Sequence[Descriptors]
    ) -> KeypointBank:
        """Concatenate per-scan keypoints and descriptors (all of one descriptor kind)."""
        if len(keypoints) != len(descriptors) or not descriptors:
            raise InvalidScanError("KeypointBank: need as many descriptor sets as keypoint sets")
        kinds = {d.kind for d in descriptors}
        if len(kinds) != 1:
            raise InvalidScanError(f"KeypointBank: mixed descriptor kinds {sorted(kinds)}")
        for i, (k, d) in enumerate(zip(keypoints, descriptors, strict=True)):
            if len(k) != len(d):
                raise InvalidScanError(
                    f"KeypointBank: scan {i} has {len(k)} keypoints, {len(d)} descriptors"
                )
        counts = np.array([len(k) for k in keypoints], dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        return cls(
            descriptors[0].kind,
            descriptors[0].n_bits,
            np.ascontiguousarray(np.concatenate([k.xy for k in keypoints])),
            np.ascontiguousarray(np.concatenate([k.cov for k in keypoints])),
            np.ascontiguousarray(
                np.concatenate([k.orientation for k in keypoints]), dtype=np.float64
            ),
            np.ascontiguousarray(np.concatenate([d.bits for d in descriptors])),
            np.ascontiguousarray(np.concatenate([d.values for d in descriptors])),
            offsets,
        )


@dataclass(frozen=True)
class BatchResult:
    """Results of :func:`register_many`, one entry per candidate asked for.

    Attributes
    ----------
    candidates : ndarray, int64
        Candidate indices into the bank.
    accepted : ndarray of bool
    n_inliers : ndarray, int64
    poses : ndarray, shape (C, 3)
        Pose of the candidate's sensor frame in the query's frame (zeros if not accepted).
    covs : ndarray, shape (C, 3, 3)
    """

    candidates: NDArray[np.int64]
    accepted: NDArray[np.bool_]
    n_inliers: NDArray[np.int64]
    poses: NDArray[np.float64]
    covs: NDArray[np.float64]


def register_many(
    kp_a: Keypoints,
    desc_a: Descriptors,
    bank: KeypointBank,
    candidates: NDArray[np.int64] | Sequence[int] | None = None,
    options: MatchOptions | None = None,
) -> BatchResult:
    """Register every candidate scan of ``bank`` to the query (A) in one numba call.

    Parallel over candidates (all cores numba is allowed). The common reject (too few
    candidate matches) costs the descriptor distance matrix only, M_a x M_b distances.
    ``poses[c]`` is the pose of candidate c's sensor frame in the query's frame; use
    ``n_inliers`` as the score (place recognition: the candidate with the most inliers).
    """
    opt = options or MatchOptions()
    _check_pair(kp_a, desc_a, "the query")
    if desc_a.kind != bank.kind:
        raise InvalidScanError(
            f"register_many: query descriptors are {desc_a.kind}, bank {bank.kind}"
        )
    which = (np.arange(len(bank), dtype=np.int64) if candidates is None
             else np.ascontiguousarray(candidates, dtype=np.int64))  # fmt: skip
    if which.size and (which.min() < 0 or which.max() >= len(bank)):
        raise InvalidScanError(f"register_many: candidate index out of range 0..{len(bank) - 1}")
    c = which.shape[0]
    status = np.zeros(c, dtype=np.int64)
    n_inl = np.zeros(c, dtype=np.int64)
    poses = np.zeros((c, 3))
    covs = np.full((c, 3, 3), np.nan)
    inv_bits = 1.0 / bank.n_bits if bank.n_bits else 0.0
    register_batch(
        1 if bank.kind == "csc" else 0, inv_bits,
        *_kp_args(kp_a), *_desc_args(desc_a),
        bank.xy, bank.cov, bank.orientation, bank.bits, bank.values, bank.offsets, which,
        *opt._args(bank.kind), status, n_inl, poses, covs,
    )  # fmt: skip
    accepted = status == 0
    poses[~accepted] = 0.0
    return BatchResult(which, accepted, n_inl, poses, covs)
