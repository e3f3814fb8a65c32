"""The corner-like keypoint detector of Sousa et al. (ICARA 2024), section III.

R. B. Sousa, H. M. Sobreira, M. F. Silva, A. P. Moreira, "Line Fitting-Based Corner-Like
Detector for 2D Laser Scanners Data", 2024 10th International Conference on Automation,
Robotics and Applications (ICARA), Athens, Greece, pp. 210-216,
doi:10.1109/ICARA60736.2024.10553006.

For every valid scan point p_j and every scale R_k the arrival neighbourhood (the run of
consecutive valid points before p_j, up to the first point farther than R_k from p_j or a gap)
and the departure neighbourhood (the same after p_j) are fitted with both closed-form line
models; the lower-RMSE model of each is kept (eqs. 2-9) and the two lines are intersected
(eqs. 10-13). Scale k *passes* when both neighbourhoods hold at least ``min_points`` points,
both RMSEs are at most ``max_fit_rmse``, the opening angle lies in
[``min_angle_deg``, ``max_angle_deg``] and the intersection lies within ``max_point_distance``
of p_j. A point is a corner-like feature when at least ``min_consecutive_scales`` consecutive
scales pass and all their intersections lie within ``max_centroid_distance`` of their
centroid, which is the point's keypoint.

Decisions the paper leaves open (see ``docs/method.md``):

* several runs of passing scales at one point: the longest run that also meets the centroid
  test wins; ties go to the run of smaller scales;
* several scan points that see one corner: per-point candidates whose keypoints lie within
  ``merge_radius`` of each other are merged by single linkage; the merged keypoint is the
  keypoint of the cluster's best candidate, the one with the lowest worst-fit RMSE (ties: more
  passing scales). Points beside the apex have a neighbourhood that straddles the corner, fit
  worse and intersect off the corner, so averaging them would bias the keypoint.

Options beyond the paper, off by default (the ``robust`` preset turns them on; see
``docs/simulation-and-accuracy.md`` and ``docs/method.md``): ``min_extent_ratio`` (a scale
passes only if both neighbourhoods reach at least that fraction of R_k from p_j),
``refine_radius`` (each keypoint re-estimated from lines fitted to longer runs of each wall)
and ``max_gap_beams`` (neighbourhoods step over short runs of dropouts).

The numba kernel lives in :mod:`laser_corners.kernel`: :mod:`~laser_corners.kernel.candidates`
(points -> per-point candidates, with :mod:`~laser_corners.kernel.neighbourhood` and
:mod:`~laser_corners.kernel.scale_tests`) and :mod:`~laser_corners.kernel.merge` (merging,
refinement, the per-scan and batch drivers); this module is the public API around it.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from functools import partial
from typing import Literal, overload

import numba
import numpy as np
from numpy.typing import NDArray

from laser_corners.choice import ParamsChoice
from laser_corners.errors import InvalidParamsError, InvalidScanError
from laser_corners.kernel.candidates import NC, candidates, kernel_config, polar_to_xy
from laser_corners.kernel.covariance import DeferredCovariances, DeferredScanCovariances
from laser_corners.kernel.merge import (
    M_BEAM,
    M_K0,
    M_NMERGED,
    M_NSC,
    M_OPEN,
    M_ORIENT,
    M_RMSE,
    M_X,
    M_Y,
    NM,
    OUT_PER_BEAM,
    detect_batch,
    detect_scan,
    finish,
    raw_rows,
)
from laser_corners.keypoints import Keypoints
from laser_corners.params import DetectorParams
from laser_corners.scan import LaserScan

__all__ = ["CornerDetector", "ScaleTable"]


_KEEP_WORK = 1 << 21  # largest work buffer (floats) a detector keeps between calls: 16 MB
_INT_COLUMNS = np.array([M_BEAM, M_NSC, M_NMERGED, M_K0])  # integer fields of the rows
_FIELDS = ("xy", "beam_index", "opening_angle_deg", "orientation", "rmse", "n_scales")
_FIELDS += ("n_merged", "scale_index")  # the order of _arrays_from_rows


def _arrays_from_rows(
    rows: NDArray[np.float64], cov_class: type, cov_lead: tuple, cov_args: tuple
) -> tuple[dict[str, NDArray[np.generic]], DeferredCovariances]:
    """The arrays of :class:`Keypoints` from kernel rows, and the deferred covariance of each
    (:mod:`laser_corners.kernel.covariance`): ``cov_class(*cov_lead, xy, beam_index, scale_index,
    n_scales, *cov_args)``, with ``cov_lead`` the scan's x, y (NaN for gaps, not modified
    afterwards) for :class:`DeferredCovariances` and ``cov_args`` the beam spacing in
    radians and the parameters from :func:`~laser_corners.kernel.candidates.kernel_config`.
    """
    columns = rows.T.copy()  # one row per field, each contiguous: views below
    xy = rows[:, M_X : M_Y + 1].copy()
    ints = columns.take(_INT_COLUMNS, axis=0).astype(np.int64)
    beam, n_scales, n_merged, k0 = ints
    cov = cov_class(*cov_lead, xy, beam, k0, n_scales, *cov_args)
    floats = columns[M_OPEN], columns[M_ORIENT], columns[M_RMSE]
    arrays = dict(zip(_FIELDS, (xy, beam, *floats, n_scales, n_merged, k0), strict=True))
    return arrays, cov


def _arrays_from_scan(
    rows: NDArray[np.float64],
    ranges: NDArray[np.float64],
    geometry: NDArray[np.float64],
    *cov_args: object,
) -> tuple[dict[str, NDArray[np.generic]], DeferredCovariances]:
    """:func:`_arrays_from_rows` of ``detect``'s rows of a scan (its ranges and the detector's
    geometry array, shared, are all the covariances need): called on first read."""
    return _arrays_from_rows(rows, DeferredScanCovariances, (ranges, geometry), cov_args)


_NO_COVARIANCES = partial(np.zeros, (0, 2, 2))
_NO_ARRAYS = _arrays_from_rows(np.empty((0, NM)), DeferredCovariances, (), ())[0]


def _no_keypoints() -> tuple[dict[str, NDArray[np.generic]], object]:
    """The arrays of a scan without keypoints (no buffer kept for them; zero-length arrays
    shared by all such keypoints: nothing can be written into them)."""
    return dict(_NO_ARRAYS), _NO_COVARIANCES


def _beam_spacing(x: NDArray[np.float64], y: NDArray[np.float64]) -> float:
    """Median angle between consecutive valid points seen from the origin (for covariances
    of points given without a scan geometry)."""
    ok = np.isfinite(x) & np.isfinite(y)
    ang = np.unwrap(np.arctan2(y[ok], x[ok]))
    return float(np.median(np.abs(np.diff(ang)))) if ang.shape[0] > 1 else 0.0


class ScaleTable:
    """Per-point, per-scale intermediate results of one scan, for analysis and figures.

    Attributes
    ----------
    intersections : ndarray, shape (N, K, 2)
        Line intersection at each point and scale (NaN where none was computed).
    passed : ndarray of bool, shape (N, K)
        Whether the scale passed all per-scale tests.
    scales : ndarray, shape (K,)
        The radii R_k.
    """

    def __init__(self, table: NDArray[np.float64], scales: NDArray[np.float64]) -> None:
        self.intersections = table[:, :, :2]
        self.passed = table[:, :, 2] > 0.5
        self.scales = scales


class CornerDetector:
    """Corner-like keypoint detector for 2D laser scans (Sousa et al., ICARA 2024).

    Parameters
    ----------
    params : DetectorParams or str, optional
        Detector parameters; the paper's defaults when omitted. A preset name is accepted
        for presets that need no scan (``"paper"``); presets that adapt to the sensor
        (``"auto"``, ``"robust"``) need one: use :meth:`from_preset` with a scan.

    References
    ----------
    .. [1] R. B. Sousa, H. M. Sobreira, M. F. Silva, A. P. Moreira, "Line Fitting-Based
       Corner-Like Detector for 2D Laser Scanners Data", 2024 10th International
       Conference on Automation, Robotics and Applications (ICARA), Athens, Greece,
       pp. 210-216, doi:10.1109/ICARA60736.2024.10553006.

    Examples
    --------
    >>> import numpy as np
    >>> from laser_corners import CornerDetector, LaserScan
    >>> from laser_corners.sim import corner_scan
    >>> scan = corner_scan()   # a clean right-angle corner at (2, 1) seen by a UST-10LX
    >>> kps = CornerDetector().detect(scan)
    >>> len(kps), np.round(kps.xy, 2).tolist()
    (1, [[2.0, 1.0]])
    >>> len(CornerDetector.from_preset("auto", scan).detect(scan))
    1
    """

    def __init__(self, params: DetectorParams | str | ParamsChoice | None = None) -> None:
        if params is None or isinstance(params, str | ParamsChoice):
            params = ParamsChoice.of(params).resolve(None)
        elif not isinstance(params, DetectorParams):
            raise InvalidParamsError(
                f"CornerDetector takes DetectorParams or a preset name, got {type(params).__name__}"
            )
        self.params = params
        self._config = kernel_config(params)
        self._scales = np.asarray(params.scales, dtype=np.float64)
        # (n_beams, angle_min, angle_increment, range_min, range_max) and the kernel's
        # geometry array of the last scan (cosines, sines, range limits): one attribute, so
        # that threads sharing the detector always read a matching pair
        self._geometry: tuple[tuple, NDArray[np.float64]] = ((-1,), np.empty(0))
        self._work: NDArray[np.float64] | None = None  # see _checkout

    @classmethod
    def from_preset(cls, name: str, scan: LaserScan | None = None) -> CornerDetector:
        """A detector with the parameters of preset ``name`` (``paper``, ``auto``, ``robust``).

        ``auto`` (scales from the angular resolution) and ``robust`` (thresholds from the
        range noise) adapt to the sensor and need ``scan``, any scan of the recording; they
        raise :class:`~laser_corners.InvalidParamsError` without one.
        """
        return cls(ParamsChoice(preset=name).resolve(scan))

    def __repr__(self) -> str:
        return f"CornerDetector({self.params!r})"

    # ----------------------------------------------------------------- helpers
    def _geometry_of(self, scan: LaserScan) -> NDArray[np.float64]:
        """The kernel's geometry array of ``scan`` (cached for the last geometry)."""
        if not isinstance(scan, LaserScan):
            raise InvalidScanError(f"expected a LaserScan, got {type(scan).__name__}")
        key = scan.geometry
        cached = self._geometry
        if key != cached[0]:
            angles = scan.angles
            limits = (scan.range_min, scan.range_max)
            geometry = np.concatenate((np.cos(angles), np.sin(angles), limits))
            cached = self._geometry = (key, geometry)
        return cached[1]

    def _checkout(self, size: int) -> NDArray[np.float64]:
        """A work buffer of >= ``size`` floats, the detector's own (taken while in use: a thread
        finding none makes one): reuse spares fresh memory's page faults (slow on a batch)."""
        work, self._work = self._work, None
        return work if work is not None and work.shape[0] >= size else np.empty(size)

    def _scan_xy(self, scan: LaserScan) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        geometry = self._geometry_of(scan)
        n = scan.n_beams
        x, y = np.empty(n), np.empty(n)
        polar_to_xy(scan.ranges, geometry[:n], geometry[n : 2 * n], *geometry[2 * n :], x, y)
        return x, y

    def _detect_xy(
        self,
        x: NDArray[np.float64],
        y: NDArray[np.float64],
        stamp: float | None,
        frame_id: str,
        with_raw: bool,
        spacing: float,
    ) -> Keypoints | tuple[Keypoints, Keypoints]:
        n = x.shape[0]
        cand = np.empty((n, NC))
        candidates(x, y, self._config, cand, np.empty((0, 0, 3)))
        rows = np.empty((n, NM))
        n_out = finish(x, y, cand, self._config, rows)
        cov_args = (spacing, self._config)
        arrays, cov = _arrays_from_rows(rows[:n_out], DeferredCovariances, (x, y), cov_args)
        keypoints = Keypoints._from_valid_arrays(stamp, frame_id, cov, **arrays)
        if not with_raw:
            return keypoints
        raw = np.empty((n, NM))
        n_raw = raw_rows(cand, raw)
        unrefined = self.params.model_copy(update={"refine_radius": 0.0})  # raw: not refined
        raw_args = (spacing, kernel_config(unrefined))
        arrays, cov = _arrays_from_rows(raw[:n_raw], DeferredCovariances, (x, y), raw_args)
        raw_kp = Keypoints._from_valid_arrays(stamp, frame_id, cov, **arrays)
        return keypoints, raw_kp

    # ----------------------------------------------------------------- public API
    @overload
    def detect(self, scan: LaserScan, return_candidates: Literal[False] = ...) -> Keypoints: ...

    @overload
    def detect(
        self, scan: LaserScan, return_candidates: Literal[True]
    ) -> tuple[Keypoints, Keypoints]: ...

    def detect(
        self, scan: LaserScan, return_candidates: bool = False
    ) -> Keypoints | tuple[Keypoints, Keypoints]:
        """Detect corner-like keypoints in one scan.

        Parameters
        ----------
        scan : LaserScan
            The scan.
        return_candidates : bool
            Also return the raw per-point candidates (before duplicate merging).

        Returns
        -------
        keypoints : Keypoints
            One keypoint per physical corner, sensor frame.
        candidates : Keypoints
            Only with ``return_candidates``: every scan point that passed, with its own
            keypoint (``n_merged`` is 1).
        """
        if return_candidates:
            x, y = self._scan_xy(scan)
            return self._detect_xy(x, y, scan.stamp, scan.frame_id, True, scan.angle_increment)
        cached = self._geometry  # the fast path of _geometry_of, inline
        key = None
        if type(scan) is LaserScan:
            key = (scan.ranges.shape[0], scan.angle_min, scan.angle_increment)
            key += (scan.range_min, scan.range_max)
        geometry = cached[1] if key == cached[0] else self._geometry_of(scan)
        work = self._checkout(scan.ranges.shape[0] * OUT_PER_BEAM)
        keypoints = self._detect_on(scan, geometry, work)
        self._work = work if work.shape[0] <= _KEEP_WORK else None  # _checkout
        return keypoints

    def _detect_on(
        self, scan: LaserScan, geometry: NDArray[np.float64], work: NDArray[np.float64]
    ) -> Keypoints:
        """:meth:`detect` of a scan whose kernel geometry array is known, in a work buffer
        of >= N · OUT_PER_BEAM floats (the scan's points, then its keypoint rows)."""
        ranges = scan.ranges
        n = ranges.shape[0]
        count = detect_scan(ranges, geometry, self._config, work)
        rows = work[2 * n : 2 * n + count * NM].reshape(count, NM).copy() if count else None
        if rows is None:
            return Keypoints._deferred(scan.stamp, scan.frame_id, 0, _no_keypoints)
        cov_args = (abs(scan.angle_increment), self._config)
        source = partial(_arrays_from_scan, rows, ranges, geometry, *cov_args)
        return Keypoints._deferred(scan.stamp, scan.frame_id, count, source)

    def detect_points(
        self, xy: NDArray[np.float64], return_candidates: bool = False
    ) -> Keypoints | tuple[Keypoints, Keypoints]:
        """Detect keypoints in Cartesian points given in angular (beam) order.

        Parameters
        ----------
        xy : ndarray, shape (N, 2)
            Scan points in beam order; rows with a NaN are gaps.
        return_candidates : bool
            As in :meth:`detect`.
        """
        pts = np.asarray(xy, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2:
            raise InvalidScanError(f"points must have shape (N, 2), got {pts.shape}")
        x = pts[:, 0].copy()  # copies: the gaps are set below, the covariances read them later
        y = pts[:, 1].copy()
        # a point with a NaN or inf in either coordinate is a gap
        bad = ~(np.isfinite(x) & np.isfinite(y))
        x[bad] = np.nan
        y[bad] = np.nan
        return self._detect_xy(x, y, None, "", return_candidates, _beam_spacing(x, y))

    def scale_table(self, scan: LaserScan) -> ScaleTable:
        """Per-point, per-scale intersections and pass flags (for analysis and figures)."""
        table = np.empty((scan.n_beams, self._scales.shape[0], 3))
        x, y = self._scan_xy(scan)
        candidates(x, y, self._config, np.empty((scan.n_beams, NC)), table)
        return ScaleTable(table, self._scales.copy())

    def detect_many(self, scans: Sequence[LaserScan] | Iterable[LaserScan]) -> list[Keypoints]:
        """Detect keypoints in a batch of scans of the same geometry, in parallel over scans.

        All scans must share ``len(ranges)``, ``angle_min``, ``angle_increment``,
        ``range_min`` and ``range_max``; use :meth:`detect` otherwise.
        """
        scans = list(scans)
        if not scans:
            return []
        first = None
        for i, scan in enumerate(scans):  # as cheap per scan as detect's own geometry check
            if type(scan) is LaserScan:
                key = (scan.ranges.shape[0], scan.angle_min, scan.angle_increment)
                key += (scan.range_min, scan.range_max)
            elif isinstance(scan, LaserScan):
                key = scan.geometry
            else:
                raise InvalidScanError(f"detect_many: item {i} is a {type(scan).__name__}")
            if first is None:
                first = key
            elif key != first:
                raise InvalidScanError(
                    f"detect_many: scan {i} has a different geometry from scan 0; "
                    "call detect() per scan instead"
                )
        first = scans[0]
        geometry = self._geometry_of(first)
        n, size = first.n_beams, len(scans)
        if numba.get_num_threads() == 1:  # nothing to run in parallel: detect's path
            work = self._checkout(n * OUT_PER_BEAM)  # one checkout for the batch
            out_kp = [self._detect_on(scan, geometry, work) for scan in scans]
            self._work = work if work.shape[0] <= _KEEP_WORK else None  # _checkout
            return out_kp
        work = self._checkout(size * n * (1 + OUT_PER_BEAM))  # the ranges, then the outputs
        ranges = np.stack([scan.ranges for scan in scans], out=work[: size * n].reshape(size, n))
        out = work[size * n : size * n * (1 + OUT_PER_BEAM)].reshape(size, n * OUT_PER_BEAM)
        counts = np.zeros(size, dtype=np.int64)
        detect_batch(ranges, geometry, self._config, out, counts)
        cov_args = (abs(first.angle_increment), self._config)
        out_kp = []
        for scan, row, count in zip(scans, out, counts.tolist(), strict=True):
            source = _no_keypoints
            if count:  # the rows, copied out of the work buffer
                rows = row[2 * n : 2 * n + count * NM].reshape(count, NM).copy()
                source = partial(_arrays_from_scan, rows, scan.ranges, geometry, *cov_args)
            out_kp.append(Keypoints._deferred(scan.stamp, scan.frame_id, count, source))
        self._work = work if work.shape[0] <= _KEEP_WORK else None  # _checkout
        return out_kp
