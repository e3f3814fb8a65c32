"""Many registrations in one numba call: place recognition over a whole log.

Detect and describe every scan once, put keypoints, descriptors and (for the scan check) the
scans in a :class:`KeypointBank`, then

* :func:`register_many`: one query (keypoints from anywhere) against candidate scans of the
  bank;
* :func:`register_pairs`: any list of (query, candidate) pairs of scans of the bank, e.g.
  several queries against their candidates in one call (fewer thread start-ups).

Both run :func:`laser_corners.matching.solve.register_pair` in parallel over the pairs
(``numba.prange``), bit-identical to :func:`~laser_corners.matching.register_keypoints`
pair by pair. The cheap rejects (too few keypoints, too few candidate matches, no shared
rotation) cost a fraction of a microsecond to a few microseconds, so a query against
thousands of scans is dominated by the pairs that reach the geometry and the scan check.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from laser_corners.errors import InvalidScanError
from laser_corners.keypoints import Keypoints
from laser_corners.matching.descriptors import Descriptors
from laser_corners.matching.kernel_args import Bank, Offsets, Side
from laser_corners.matching.registration import MatchOptions, _check_pair
from laser_corners.matching.solve import register_batch
from laser_corners.matching.verify import scan_arrays
from laser_corners.scan import LaserScan

__all__ = ["BatchResult", "KeypointBank", "register_many", "register_pairs"]


def _flat(parts: Sequence[NDArray], empty_shape: tuple[int, ...], dtype: type) -> NDArray:
    if not parts:
        return np.zeros(empty_shape, dtype=dtype)
    return np.ascontiguousarray(np.concatenate(parts), dtype=dtype)


def _offsets(counts: Sequence[int]) -> NDArray[np.int64]:
    return np.concatenate([[0], np.cumsum(np.asarray(counts, dtype=np.int64))]).astype(np.int64)


@dataclass
class KeypointBank:
    """Keypoints, descriptors and (optionally) scans of many scans in flat arrays.

    Build it once per log with :meth:`from_lists`; ``data`` holds the arrays as the kernels
    read them (:class:`~laser_corners.matching.kernel_args.Bank`: the rows of every scan and
    where each scan's rows start).
    """

    kind: str
    n_bits: int
    data: Bank
    has_scans: bool = False

    def __len__(self) -> int:
        return int(self.data.offsets.keypoints.shape[0] - 1)

    def counts(self) -> NDArray[np.int64]:
        """Keypoints per scan."""
        return np.diff(self.data.offsets.keypoints)

    def arrays(self) -> Bank:
        """The bank as the kernels' :class:`~laser_corners.matching.kernel_args.Bank`."""
        return self.data

    @classmethod
    def from_lists(
        cls,
        keypoints: Sequence[Keypoints],
        descriptors: Sequence[Descriptors],
        scans: Sequence[LaserScan] | None = None,
        scan_points: int = 90,
    ) -> KeypointBank:
        """Concatenate per-scan keypoints and descriptors (all of one descriptor kind), and
        the scans when given (needed by ``MatchOptions.verify_scan``; ``scan_points`` as
        ``MatchOptions.scan_points``)."""
        if len(keypoints) != len(descriptors) or not descriptors:
            raise InvalidScanError("KeypointBank: need as many descriptor sets as keypoint sets")
        if scans is not None and len(scans) != len(keypoints):
            raise InvalidScanError(
                f"KeypointBank: {len(scans)} scans, {len(keypoints)} keypoint sets"
            )
        kinds = {d.kind for d in descriptors}
        if len(kinds) != 1:
            raise InvalidScanError(f"KeypointBank: mixed descriptor kinds {sorted(kinds)}")
        for i, (k, d) in enumerate(zip(keypoints, descriptors, strict=True)):
            if len(k) != len(d):
                raise InvalidScanError(
                    f"KeypointBank: scan {i} has {len(k)} keypoints, {len(d)} descriptors"
                )
        n = len(keypoints)
        arr = [scan_arrays(s, scan_points) for s in scans] if scans is not None else []
        rows = Side(
            _flat([k.xy for k in keypoints], (0, 2), np.float64),
            _flat([k.cov for k in keypoints], (0, 2, 2), np.float64),
            _flat([k.orientation for k in keypoints], (0,), np.float64),
            _flat([k.opening_angle_deg for k in keypoints], (0,), np.float64),
            _flat([d.bits for d in descriptors], (0, 0), np.uint64),
            _flat([d.values for d in descriptors], (0, 0), np.float64),
            _flat([a.ranges for a in arr], (0,), np.float64),
            _flat([a.geometry[None, :] for a in arr], (n, 4), np.float64),
            _flat([a.points for a in arr], (0, 2), np.float64),
        )
        offsets = Offsets(
            _offsets([len(k) for k in keypoints]),
            _offsets([len(a.ranges) for a in arr] if arr else [0] * n),
            _offsets([len(a.points) for a in arr] if arr else [0] * n),
        )
        data = Bank(rows, offsets)
        return cls(descriptors[0].kind, descriptors[0].n_bits, data, scans is not None)


@dataclass(frozen=True)
class BatchResult:
    """Results of :func:`register_many` / :func:`register_pairs`, one entry per pair.

    Attributes
    ----------
    candidates : ndarray, int64
        Candidate indices into the bank.
    accepted : ndarray of bool
    n_inliers : ndarray, int64
    poses : ndarray, shape (C, 3)
        Pose of the candidate's sensor frame in the query's frame (zeros if not accepted).
    covs : ndarray, shape (C, 3, 3)
    agreement : ndarray, shape (C,)
        Scan agreement of accepted registrations (1.0 without the scan check, 0 otherwise).
    status : ndarray, int64
        0 accepted, 1 too few keypoints, 2 too few candidate matches, 3 too few consistent
        matches, 4 the scans disagree.
    """

    candidates: NDArray[np.int64]
    accepted: NDArray[np.bool_]
    n_inliers: NDArray[np.int64]
    poses: NDArray[np.float64]
    covs: NDArray[np.float64]
    agreement: NDArray[np.float64]
    status: NDArray[np.int64]


def _run(
    bank_a: KeypointBank,
    bank_b: KeypointBank,
    qa: NDArray[np.int64],
    cb: NDArray[np.int64],
    options: MatchOptions,
) -> BatchResult:
    if options.verify_scan and not (bank_a.has_scans and bank_b.has_scans):
        raise InvalidScanError("verify_scan needs the scans: KeypointBank.from_lists(..., scans)")
    for name, idx, bank in (("query", qa, bank_a), ("candidate", cb, bank_b)):
        if idx.size and (idx.min() < 0 or idx.max() >= len(bank)):
            raise InvalidScanError(f"{name} index out of range 0..{len(bank) - 1}")
    c = cb.shape[0]
    status = np.zeros(c, dtype=np.int64)
    n_inl = np.zeros(c, dtype=np.int64)
    poses = np.zeros((c, 3))
    covs = np.full((c, 3, 3), np.nan)
    agreement = np.zeros(c)
    inv_bits = 1.0 / bank_b.n_bits if bank_b.n_bits else 0.0
    register_batch(
        1 if bank_b.kind == "csc" else 0,
        inv_bits,
        *bank_a.data,
        *bank_b.data,
        qa,
        cb,
        options.kernel_options(bank_b.kind),
        status,
        n_inl,
        poses,
        covs,
        agreement,
    )
    accepted = status == 0
    poses[~accepted] = 0.0
    return BatchResult(cb, accepted, n_inl, poses, covs, agreement, status)


def register_many(
    kp_a: Keypoints,
    desc_a: Descriptors,
    bank: KeypointBank,
    candidates: NDArray[np.int64] | Sequence[int] | None = None,
    options: MatchOptions | None = None,
    scan_a: LaserScan | None = None,
) -> BatchResult:
    """Register every candidate scan of ``bank`` to the query (A) in one numba call.

    Parallel over candidates (all cores numba is allowed). ``poses[c]`` is the pose of
    candidate c's sensor frame in the query's frame; use ``n_inliers`` as the score (place
    recognition: the candidate with the most inliers). ``scan_a`` (the query's scan) is
    needed by ``options.verify_scan``, and then the bank must hold the scans too.
    """
    opt = options or MatchOptions()
    _check_pair(kp_a, desc_a, "the query")
    if desc_a.kind != bank.kind:
        raise InvalidScanError(
            f"register_many: query descriptors are {desc_a.kind}, bank {bank.kind}"
        )
    if opt.verify_scan and not isinstance(scan_a, LaserScan):
        raise InvalidScanError("register_many: verify_scan needs the query's scan (scan_a)")
    scans = [scan_a] if opt.verify_scan else None
    query = KeypointBank.from_lists([kp_a], [desc_a], scans, opt.scan_points)  # type: ignore[arg-type]
    which = (
        np.arange(len(bank), dtype=np.int64)
        if candidates is None
        else np.ascontiguousarray(candidates, dtype=np.int64)
    )
    return _run(query, bank, np.zeros(which.shape[0], dtype=np.int64), which, opt)


def register_pairs(
    bank: KeypointBank,
    queries: NDArray[np.int64] | Sequence[int],
    candidates: NDArray[np.int64] | Sequence[int],
    options: MatchOptions | None = None,
) -> BatchResult:
    """Register scan ``candidates[t]`` to scan ``queries[t]`` of ``bank`` for every t, in
    one numba call (``poses[t]``: the candidate's sensor frame in the query's frame).

    Raises
    ------
    InvalidScanError
        Index out of range, different lengths, or ``verify_scan`` on a bank without scans.
    """
    q = np.ascontiguousarray(queries, dtype=np.int64).reshape(-1)
    c = np.ascontiguousarray(candidates, dtype=np.int64).reshape(-1)
    if q.shape != c.shape:
        raise InvalidScanError(f"register_pairs: {q.shape[0]} queries, {c.shape[0]} candidates")
    return _run(bank, bank, q, c, options or MatchOptions())
