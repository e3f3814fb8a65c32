"""Scan-to-scan registration from corner keypoints: matches, verification, weighted SE(2).

Pipeline (numba, :mod:`laser_corners.matching.core` and :mod:`~laser_corners.matching.solve`):

1. candidate matches: each keypoint of A with its ``k_nearest`` nearest keypoints of B in
   descriptor space (distance <= ``max_distance``; optional Lowe ratio test and mutual check);
2. geometric verification, either RANSAC over two-point SE(2) hypotheses (all pairs when there
   are at most ``iterations`` of them, else seeded random pairs) or the maximum clique of
   pairwise-consistent matches (FALKO's CCDA: two matches agree when the distance between
   their keypoints in A and in B differ by at most ``tolerance``);
   Hypotheses also come from one match alone (``single_point``): the rotation is the
   difference of the two keypoints' orientations (bisectors), the translation follows;
3. weighted least squares SE(2) (Gauss-Newton on the Mahalanobis residuals with the keypoint
   covariances ``C_a + R C_b Rᵀ``), the final inliers (residual <= ``tolerance``, one match
   per keypoint) and the pose covariance ``(JᵀWJ)⁻¹``;
4. optionally (``verify_scan``) the scans themselves: the refined pose must make the two
   scans agree (:mod:`laser_corners.matching.verify`); the best ``max_hypotheses``
   hypotheses are tried in turn.

The pose is that of B's sensor frame in A's frame, ``p_A = R(θ)·p_B + t`` (the convention of
:func:`laser_corners.eval.repeatability.pair_repeatability`).

For place recognition (one query against thousands of scans) see
:mod:`laser_corners.matching.batch` (:class:`KeypointBank`, :func:`register_many`,
:func:`register_pairs`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from laser_corners.detector import CornerDetector
from laser_corners.errors import InvalidScanError
from laser_corners.keypoints import Keypoints
from laser_corners.matching.core import VERIFY_CLIQUE, VERIFY_RANSAC
from laser_corners.matching.descriptors import DescriptorParams, Descriptors, describe
from laser_corners.matching.kernel_args import KernelOptions, Side
from laser_corners.matching.solve import register_pair
from laser_corners.matching.verify import ScanArrays, scan_arrays
from laser_corners.options import Options
from laser_corners.params import DetectorParams
from laser_corners.scan import LaserScan, Pose2D

__all__ = ["PLACE_RECOGNITION", "MatchOptions", "Registration", "register", "register_keypoints"]

DEFAULT_MAX_DISTANCE = {"csc": 0.75, "bsc": 0.3}
"""Default ``MatchOptions.max_distance`` per descriptor kind."""

_REASONS = {
    1: "too few keypoints",
    2: "too few candidate matches",
    3: "too few geometrically consistent matches",
    4: "the scans disagree with the pose",
}


class MatchOptions(Options):
    """Options of the matcher (defaults in brackets).

    Attributes
    ----------
    min_inliers : int
        Inliers needed to accept a registration [4] (at least 2 without ``verify_scan``, 1
        with it).
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
    max_opening_difference : float
        Largest difference of the opening angles of a candidate match, degrees [180: off].
    single_point : bool
        Also make a hypothesis from each match alone (rotation from the two keypoint
        orientations) [True].
    max_hypotheses : int
        Hypotheses refined and, with ``verify_scan``, checked against the scans, best
        first (distinct poses only) [3].
    verify_scan : bool
        Accept only a pose under which the two scans agree
        (:mod:`laser_corners.matching.verify`; needs the scans) [False].
    scan_tolerance : float
        Range agreement of a scan point, metres [0.2].
    min_scan_agreement : float
        Share of the tested points that must agree, both ways [0.5].
    max_scan_conflict : float
        Largest share of the tested points seen through, both ways [0.05].
    min_scan_points : int
        Fewest points tested, both ways [20].
    scan_points : int
        Points per scan used by the check, evenly spread [90].
    align_iterations : int
        Gauss-Newton iterations refining the pose on the scans before the check (0: none;
        the refined pose is the result) [3].
    """

    title: ClassVar[str] = "MatchOptions"
    what: ClassVar[str] = "match option"

    min_inliers: int = Field(4, ge=1)
    tolerance: float = Field(0.1, gt=0.0)
    k_nearest: int = Field(3, ge=1)
    ratio: float = Field(1.0, gt=0.0)
    mutual: bool = False
    max_distance: float | None = Field(None, gt=0.0)
    verification: Literal["ransac", "clique"] = "ransac"
    iterations: int = Field(200, ge=1)
    min_separation: float = Field(0.3, ge=0.0)
    seed: int = Field(0, ge=0)
    default_sigma: float = Field(0.03, gt=0.0)
    angle_tolerance: float = Field(0.5, gt=0.0)
    max_opening_difference: float = Field(180.0, ge=0.0)
    single_point: bool = True
    max_hypotheses: int = Field(3, ge=1)
    verify_scan: bool = False
    scan_tolerance: float = Field(0.1, gt=0.0)
    min_scan_agreement: float = Field(0.5, ge=0.0, le=1.0)
    max_scan_conflict: float = Field(0.05, ge=0.0, le=1.0)
    min_scan_points: int = Field(20, ge=0)
    scan_points: int = Field(90, ge=1)
    align_iterations: int = Field(3, ge=0)

    def kernel_options(self, kind: str) -> KernelOptions:
        """The one conversion of the options into the kernels' argument
        (:class:`~laser_corners.matching.kernel_args.KernelOptions`, the same names), for
        descriptors of ``kind`` (which sets the default ``max_distance``)."""
        max_distance = self.max_distance
        if max_distance is None:
            max_distance = DEFAULT_MAX_DISTANCE[kind]
        return KernelOptions(
            min_inliers=int(self.min_inliers),
            tolerance=float(self.tolerance),
            k_nearest=int(self.k_nearest),
            ratio=float(self.ratio),
            mutual=bool(self.mutual),
            max_distance=float(max_distance),
            verification=VERIFY_CLIQUE if self.verification == "clique" else VERIFY_RANSAC,
            iterations=int(self.iterations),
            min_separation=float(self.min_separation),
            seed=int(self.seed),
            default_sigma=float(self.default_sigma),
            angle_tolerance=float(self.angle_tolerance),
            max_opening_difference=float(self.max_opening_difference),
            single_point=bool(self.single_point),
            max_hypotheses=int(self.max_hypotheses),
            verify_scan=bool(self.verify_scan),
            scan_tolerance=float(self.scan_tolerance),
            min_scan_agreement=float(self.min_scan_agreement),
            max_scan_conflict=float(self.max_scan_conflict),
            min_scan_points=int(self.min_scan_points),
            align_iterations=int(self.align_iterations),
        )


PLACE_RECOGNITION = MatchOptions(
    min_inliers=1,
    k_nearest=2,
    max_distance=0.4,
    max_opening_difference=20.0,
    max_hypotheses=2,
    verify_scan=True,
)
"""Options for place recognition (one scan against a whole map, ``evaluate loops``): the
scan check decides, so one inlier is enough; tighter candidate matches (two nearest,
descriptor distance <= 0.4, opening angles within 20 degrees) keep the cost of the thousands
of pairs per query low. Descriptor gate for ``csc``; pass ``max_distance`` for ``bsc``."""


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
    agreement : float
        With ``verify_scan``: the share of tested scan points that agree (the smaller of the
        two directions); 1.0 without the check; 0.0 when not accepted.
    """

    accepted: bool
    reason: str
    n_inliers: int
    pose: Pose2D
    cov: NDArray[np.float64]
    inliers: NDArray[np.int64]
    n_candidates: int = 0
    agreement: float = 0.0


def _check_pair(kp: Keypoints, desc: Descriptors, name: str) -> None:
    if not isinstance(kp, Keypoints) or not isinstance(desc, Descriptors):
        raise InvalidScanError(f"register_keypoints: {name} needs Keypoints and Descriptors")
    if len(kp) != len(desc):
        raise InvalidScanError(
            f"register_keypoints: {name} has {len(kp)} keypoints but {len(desc)} descriptors"
        )


NO_SCAN = ScanArrays(np.zeros(0), np.zeros(4), np.zeros((0, 2)))
"""Scan arrays of a side without a scan (the scan check must be off)."""


def side_arrays(k: Keypoints, d: Descriptors, scan: ScanArrays = NO_SCAN) -> Side:
    """One scan as the kernels' :class:`~laser_corners.matching.kernel_args.Side`."""
    return Side(
        np.ascontiguousarray(k.xy, dtype=np.float64),
        np.ascontiguousarray(k.cov, dtype=np.float64),
        np.ascontiguousarray(k.orientation, dtype=np.float64),
        np.ascontiguousarray(k.opening_angle_deg, dtype=np.float64),
        np.ascontiguousarray(d.bits),
        np.ascontiguousarray(d.values),
        *scan,
    )


def _scans_to_verify(
    opt: MatchOptions, scan_a: LaserScan | None, scan_b: LaserScan | None
) -> tuple[ScanArrays, ScanArrays]:
    """The scans' kernel arrays for ``verify_scan`` (none without it)."""
    if not opt.verify_scan:
        return NO_SCAN, NO_SCAN
    if not (isinstance(scan_a, LaserScan) and isinstance(scan_b, LaserScan)):
        raise InvalidScanError("register_keypoints: verify_scan needs scan_a and scan_b")
    return scan_arrays(scan_a, opt.scan_points), scan_arrays(scan_b, opt.scan_points)


def register_keypoints(
    kp_a: Keypoints,
    desc_a: Descriptors,
    kp_b: Keypoints,
    desc_b: Descriptors,
    options: MatchOptions | None = None,
    scan_a: LaserScan | None = None,
    scan_b: LaserScan | None = None,
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
    scan_a, scan_b : LaserScan, optional
        The scans of the keypoints; needed by ``options.verify_scan``.

    Returns
    -------
    Registration
        Unaccepted (with a reason) when there are too few keypoints, matches or inliers, or
        when the scans disagree with every hypothesis.

    Raises
    ------
    InvalidScanError
        Mismatched keypoints and descriptors, or ``verify_scan`` without both scans.
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
    scans = _scans_to_verify(opt, scan_a, scan_b)
    pose = np.zeros(3)
    pose_cov = np.full((3, 3), np.nan)
    inl = np.empty((max(min(len(kp_a), len(kp_b)), 1), 2), dtype=np.int64)
    inv_bits = 1.0 / desc_a.n_bits if desc_a.n_bits else 0.0
    status, n_inl, n_cand, agreement = register_pair(
        desc_a.kind_code,
        inv_bits,
        side_arrays(kp_a, desc_a, scans[0]),
        side_arrays(kp_b, desc_b, scans[1]),
        opt.kernel_options(desc_a.kind),
        pose,
        pose_cov,
        inl,
    )
    if status != 0:
        return Registration(
            False,
            _REASONS[status],
            int(n_inl),
            (0.0, 0.0, 0.0),
            np.full((3, 3), np.nan),
            np.zeros((0, 2), np.int64),
            int(n_cand),
        )
    return Registration(
        True,
        "",
        int(n_inl),
        (float(pose[0]), float(pose[1]), float(pose[2])),
        pose_cov,
        inl[:n_inl].copy(),
        int(n_cand),
        float(agreement),
    )


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
        Matcher options (``MatchOptions(verify_scan=True)`` adds the scan check).

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
    return register_keypoints(kp_a, d_a, kp_b, d_b, options, scan_a, scan_b)
