"""Keypoints: the detector's output, as plain numpy arrays."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray

from laser_corners.pose import Pose2D, rotation, transform_points, wrap_angle

__all__ = ["KEYPOINT_DTYPE", "Keypoints"]

KEYPOINT_DTYPE = np.dtype(
    [
        ("x", np.float64),
        ("y", np.float64),
        ("beam_index", np.int64),
        ("opening_angle_deg", np.float64),
        ("orientation", np.float64),
        ("n_scales", np.int64),
        ("rmse", np.float64),
        ("n_merged", np.int64),
        ("scale_index", np.int64),
        ("cov_xx", np.float64),
        ("cov_xy", np.float64),
        ("cov_yy", np.float64),
    ]
)
"""Record layout of :meth:`Keypoints.to_records` (one row per keypoint)."""
_PER_KEYPOINT = KEYPOINT_DTYPE.names[2:-3]


@dataclass(frozen=True)
class Keypoints:
    """Corner-like keypoints of one scan (sensor frame unless transformed).

    Attributes
    ----------
    xy : ndarray, shape (M, 2), float64
        Keypoint positions in metres.
    beam_index : ndarray, shape (M,), int64
        Index of the supporting scan point p_j (for merged keypoints: the representative
        candidate's point, see ``docs/method.md``).
    opening_angle_deg : ndarray, shape (M,)
        Corner opening angle between the two fitted lines, degrees, measured between the
        directions pointing from the corner into the arrival and departure neighbourhoods.
    orientation : ndarray, shape (M,)
        Direction of the opening's bisector, radians, in the same frame as ``xy``.
    n_scales : ndarray, shape (M,), int64
        Number of consecutive passing scales that support the keypoint.
    rmse : ndarray, shape (M,)
        Worst line-fit RMSE among the supporting fits, metres.
    n_merged : ndarray, shape (M,), int64
        Number of per-point candidates merged into the keypoint (1 for raw candidates).
    scale_index : ndarray, shape (M,), int64
        Index k0 of the first scale of the winning run of consecutive scales (of the
        representative candidate for merged keypoints); the run is scales k0 ..
        k0 + n_scales - 1. -1 when unknown (keypoints not made by the detector).
    cov : ndarray, shape (M, 2, 2)
        Covariance of ``xy``, m² (:mod:`laser_corners.kernel.covariance`; NaN when unknown). For
        keypoints from the detector it is computed on first access and then kept, so a
        ``detect`` whose covariances are never read does not pay for them.
    stamp : float or None
        Stamp of the scan.
    frame_id : str
        Frame of ``xy``.
    """

    xy: NDArray[np.float64]
    beam_index: NDArray[np.int64]
    opening_angle_deg: NDArray[np.float64]
    orientation: NDArray[np.float64]
    n_scales: NDArray[np.int64]
    rmse: NDArray[np.float64]
    n_merged: NDArray[np.int64]
    stamp: float | None = None
    frame_id: str = ""
    scale_index: NDArray[np.int64] | None = None
    cov: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        xy = np.asarray(self.xy, dtype=np.float64).reshape(-1, 2)
        object.__setattr__(self, "xy", xy)
        m = xy.shape[0]
        if self.scale_index is None:
            object.__setattr__(self, "scale_index", np.full(m, -1, dtype=np.int64))
        cov = np.full((m, 2, 2), np.nan) if self.cov is None else self.cov
        cov = np.asarray(cov, dtype=np.float64)
        if cov.shape != (m, 2, 2):
            raise ValueError(f"Keypoints.cov has shape {cov.shape}, expected ({m}, 2, 2)")
        object.__setattr__(self, "cov", cov)
        for name in _PER_KEYPOINT:  # the record fields between xy and the covariance
            arr = np.asarray(getattr(self, name), dtype=KEYPOINT_DTYPE[name]).reshape(-1)
            if arr.shape[0] != m:
                raise ValueError(f"Keypoints.{name} has {arr.shape[0]} entries, xy has {m}")
            object.__setattr__(self, name, arr)

    @classmethod
    def _from_valid_arrays(
        cls,
        stamp: float | None,
        frame_id: str,
        cov_source: Callable[[], NDArray[np.float64]] | None = None,
        **arrays: NDArray[np.generic],
    ) -> Keypoints:
        """Wrap arrays that already have the right dtypes and lengths, skipping the checks
        (the detector's per-scan fast path, where the checks cost more than the wrapping).

        ``cov_source``, when given and ``cov`` is not, is a picklable callable that returns
        the (M, 2, 2) covariances; it is called on the first access of :attr:`cov`.
        """
        keypoints = object.__new__(cls)
        if "scale_index" not in arrays:
            arrays["scale_index"] = np.full(arrays["xy"].shape[0], -1, dtype=np.int64)
        if "cov" not in arrays and cov_source is None:
            arrays["cov"] = np.full((arrays["xy"].shape[0], 2, 2), np.nan)
        state = keypoints.__dict__  # frozen: fill the instance's dict directly (one call)
        state.update(arrays)
        if "cov" not in arrays:
            state["_cov_source"] = cov_source
            state["_cov_rotations"] = ()
        state["stamp"] = stamp
        state["frame_id"] = frame_id
        return keypoints

    @classmethod
    def _deferred(
        cls,
        stamp: float | None,
        frame_id: str,
        count: int,
        source: Callable[[], tuple[dict[str, NDArray[np.generic]], Callable[[], Any]]],
    ) -> Keypoints:
        """Keypoints whose arrays are made on the first access of any of them (the detector's
        per-scan fast path: ``detect`` only wraps its output buffer).

        ``source()`` returns the arrays of every field but ``cov`` (right dtypes and lengths,
        ``count`` keypoints) and the ``cov_source`` of :meth:`_from_valid_arrays`.
        """
        keypoints = object.__new__(cls)
        keypoints.__dict__.update(stamp=stamp, frame_id=frame_id, _count=count, _source=source)
        return keypoints

    def _materialise(self) -> None:
        """Make the arrays of keypoints from :meth:`_deferred` (once)."""
        state = self.__dict__
        source = state.pop("_source", None)
        if source is None:
            return
        arrays, cov_source = source()
        state.update(arrays)
        if "cov" not in state:
            state["_cov_source"] = cov_source
            state.setdefault("_cov_rotations", ())

    def __getstate__(self) -> dict[str, Any]:
        self._materialise()  # pickles hold the arrays, not the detector's buffers
        return self.__dict__

    def __getattr__(self, name: str) -> Any:
        # only reached for attributes not in the instance: the arrays of deferred keypoints,
        # ``cov`` of lazy keypoints
        if name in _DEFERRED and "_source" in self.__dict__:
            self._materialise()
            return getattr(self, name)
        if name != "cov":
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        compute = self.__dict__.get("_cov_source")
        if compute is None:  # not made by the constructors (e.g. object.__new__)
            cov = np.full((len(self), 2, 2), np.nan)
        else:
            cov = compute()
            for rot in self.__dict__.get("_cov_rotations", ()):  # as transformed() does
                cov = rot @ cov @ rot.T
            self.__dict__.pop("_cov_source")  # frees the scan the source holds
        object.__setattr__(self, "cov", cov)
        return cov

    def _cov_is_lazy(self) -> bool:
        """Whether :attr:`cov` is still to be computed (for tests and benchmarks)."""
        return "cov" not in self.__dict__

    @classmethod
    def empty(cls, stamp: float | None = None, frame_id: str = "") -> Keypoints:
        """No keypoints."""
        z = np.zeros(0)
        zi = np.zeros(0, dtype=np.int64)
        return cls(
            np.zeros((0, 2)), zi, z, z, zi, z, zi, stamp=stamp, frame_id=frame_id, scale_index=zi
        )

    def __len__(self) -> int:
        xy = self.__dict__.get("xy")
        return int(self.__dict__["_count"] if xy is None else xy.shape[0])

    def to_records(self) -> np.recarray:
        """One record per keypoint with the fields of :data:`KEYPOINT_DTYPE`."""
        out = np.empty(len(self), dtype=KEYPOINT_DTYPE)
        out["x"] = self.xy[:, 0]
        out["y"] = self.xy[:, 1]
        for name in _PER_KEYPOINT:
            out[name] = getattr(self, name)
        out["cov_xx"] = self.cov[:, 0, 0]
        out["cov_xy"] = self.cov[:, 0, 1]
        out["cov_yy"] = self.cov[:, 1, 1]
        return out.view(np.recarray)

    def to_dicts(self) -> list[dict[str, Any]]:
        """One plain ``dict`` per keypoint (JSON-friendly Python scalars)."""
        rec = self.to_records()
        return [{name: row[name].item() for name in KEYPOINT_DTYPE.names} for row in rec]

    def transformed(self, pose: Pose2D, frame_id: str = "map") -> Keypoints:
        """The keypoints moved by the rigid transform ``pose = (x, y, theta)``.

        Use the sensor pose in a map frame to get map-frame keypoints.
        """
        theta = pose[2]
        rot = rotation(theta)
        xy = transform_points(self.xy, pose)
        orientation = wrap_angle(self.orientation + theta)
        values = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "cov"}
        values.update(xy=xy, orientation=orientation, frame_id=frame_id)
        if self._cov_is_lazy():  # stays lazy: turned when computed
            stamp = values.pop("stamp")
            values.pop("frame_id")
            compute = self.__dict__.get("_cov_source")
            moved = Keypoints._from_valid_arrays(stamp, frame_id, compute, **values)
            if compute is not None:
                rotations = (*self.__dict__.get("_cov_rotations", ()), rot)
                object.__setattr__(moved, "_cov_rotations", rotations)
            return moved
        cov = rot @ self.cov @ rot.T  # the covariance turns with the points
        return Keypoints(**values, cov=cov)

    def __repr__(self) -> str:
        return f"Keypoints(n={len(self)}, stamp={self.stamp}, frame_id={self.frame_id!r})"


# ``cov`` and ``scale_index`` are dataclass fields (constructor arguments, ``fields()``), but
# without a class attribute, so that an instance without one reaches ``__getattr__`` (lazy
# covariance, deferred arrays)
del Keypoints.cov
del Keypoints.scale_index
_DEFERRED = frozenset(f.name for f in fields(Keypoints)) - {"stamp", "frame_id"}
