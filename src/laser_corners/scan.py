"""2D laser scans: validation, gaps and polar -> Cartesian conversion (paper section III)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from laser_corners.errors import InvalidScanError
from laser_corners.pose import (  # the SE(2) helpers' home; re-exported for compatibility
    Pose2D,
    compose,
    invert,
    pose_error,
    relative_pose,
    rotation,
    transform_points,
)

__all__ = [
    "LaserScan",
    "Pose2D",
    "compose",
    "invert",
    "pose_error",
    "relative_pose",
    "rotation",
    "transform_points",
]

# largest (n_beams - 1) * |angle_increment|: a full turn, plus a tolerance for increments
# rounded to float32 by drivers
_MAX_FIELD_OF_VIEW = 2.0 * math.pi * (1.0 + 1e-4)


def _finite_float(name: str, value: object) -> float:
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InvalidScanError(f"LaserScan.{name} must be a number, got {value!r}") from None
    if not math.isfinite(number):
        raise InvalidScanError(f"LaserScan.{name} must be finite, got {number}")
    return number


@dataclass(frozen=True)
class LaserScan:
    """One 2D laser scan, in the layout of ``sensor_msgs/LaserScan``.

    Beam ``i`` points at ``angle_min + i * angle_increment`` (radians, counter-clockwise in
    the sensor frame). A negative ``angle_increment`` is allowed (legal in ROS: beams in
    clockwise order); the detector gives the same keypoints for either beam order. The beams
    may span at most one full turn. A beam is a *gap* (no valid return) when its range is
    NaN, infinite, ``<= range_min`` or ``>= range_max``; gaps are counted, never an error.

    Parameters
    ----------
    ranges : array_like, shape (N,)
        Measured ranges in metres.
    angle_min : float
        Angle of the first beam, radians.
    angle_increment : float
        Angle between consecutive beams, radians (non-zero; negative for clockwise scans).
    range_min, range_max : float
        Valid range interval (exclusive at both ends), metres.
    stamp : float, optional
        Acquisition time in seconds.
    frame_id : str, optional
        Sensor frame name.
    pose : tuple of float, optional
        Sensor pose ``(x, y, theta)`` in a map/odometry frame, when known.

    Raises
    ------
    InvalidScanError
        (a ``ValueError``) naming the field, for non-finite angle fields, a zero
        ``angle_increment``, beams spanning more than a full turn
        (``(len(ranges) - 1) * |angle_increment| > 2 pi``), a negative or infinite
        ``range_min``, ``range_min >= range_max`` or ``ranges`` that are not 1-D.

    Examples
    --------
    >>> scan = LaserScan(ranges=[1.0, 1.0, float("nan")], angle_min=0.0,
    ...                  angle_increment=0.01, range_min=0.06, range_max=10.0)
    >>> scan.n_gaps
    1
    """

    ranges: NDArray[np.float64]
    angle_min: float
    angle_increment: float
    range_min: float = 0.0
    range_max: float = math.inf
    stamp: float | None = None
    frame_id: str = ""
    pose: Pose2D | None = field(default=None)

    def __post_init__(self) -> None:
        try:
            ranges = np.array(self.ranges, dtype=np.float64, copy=True)
        except (TypeError, ValueError):
            raise InvalidScanError("LaserScan.ranges must be numeric") from None
        if ranges.ndim != 1:
            raise InvalidScanError(
                f"LaserScan.ranges must be 1-D, got an array of shape {ranges.shape}"
            )
        ranges.setflags(write=False)
        object.__setattr__(self, "ranges", ranges)
        angle_min = _finite_float("angle_min", self.angle_min)
        angle_increment = _finite_float("angle_increment", self.angle_increment)
        if angle_increment == 0.0:
            raise InvalidScanError("LaserScan.angle_increment must be non-zero")
        try:
            range_min = float(self.range_min)
            range_max = float(self.range_max)
        except (TypeError, ValueError):
            raise InvalidScanError("LaserScan.range_min/range_max must be numbers") from None
        if math.isnan(range_min) or math.isnan(range_max):
            raise InvalidScanError("LaserScan.range_min/range_max must not be NaN")
        if not (0.0 <= range_min < math.inf):
            raise InvalidScanError(
                f"LaserScan.range_min must be a finite number >= 0 (metres), got {range_min}"
            )
        field_of_view = (ranges.shape[0] - 1) * abs(angle_increment)
        if field_of_view > _MAX_FIELD_OF_VIEW:
            raise InvalidScanError(
                f"LaserScan.angle_increment ({angle_increment} rad) with {ranges.shape[0]} "
                f"beams spans {field_of_view:.4g} rad, more than a full turn (2 pi)"
            )
        if range_min >= range_max:
            raise InvalidScanError(
                f"LaserScan.range_min ({range_min}) must be < range_max ({range_max})"
            )
        object.__setattr__(self, "angle_min", angle_min)
        object.__setattr__(self, "angle_increment", angle_increment)
        object.__setattr__(self, "range_min", range_min)
        object.__setattr__(self, "range_max", range_max)
        if self.stamp is not None:
            object.__setattr__(self, "stamp", float(self.stamp))
        if self.pose is not None:
            pose = tuple(float(v) for v in self.pose)
            if len(pose) != 3 or not all(math.isfinite(v) for v in pose):
                raise InvalidScanError(f"LaserScan.pose must be 3 finite numbers, got {self.pose}")
            object.__setattr__(self, "pose", pose)

    # --- trusted constructor for readers (helper READER, issue 14) ---------------------------
    @classmethod
    def from_checked(
        cls,
        ranges: NDArray[np.float64],
        angle_min: float,
        angle_increment: float,
        range_min: float,
        range_max: float,
        stamp: float | None,
        frame_id: str,
        pose: Pose2D | None,
    ) -> LaserScan:
        """A scan from fields a reader has already checked, without validation or copy.

        The caller guarantees what ``__post_init__`` would establish: ``ranges`` a read-only
        1-D float64 array, Python floats with finite angles, a non-zero increment,
        ``range_min < range_max``, a float or None stamp, and a pose of 3 finite floats or
        None. Anything else must go through ``LaserScan(...)``.
        """
        scan = object.__new__(cls)
        for name, value in (
            ("ranges", ranges),
            ("angle_min", angle_min),
            ("angle_increment", angle_increment),
            ("range_min", range_min),
            ("range_max", range_max),
            ("stamp", stamp),
            ("frame_id", frame_id),
            ("pose", pose),
        ):
            object.__setattr__(scan, name, value)  # frozen dataclass, as __post_init__ does
        return scan

    # --- end of the trusted constructor -------------------------------------------------------

    @property
    def n_beams(self) -> int:
        """Number of beams, valid or not."""
        return int(self.ranges.shape[0])

    @property
    def geometry(self) -> tuple[int, float, float, float, float]:
        """``(n_beams, angle_min, angle_increment, range_min, range_max)``: scans with equal
        geometry share beam angles and validity limits (one ``detect_many`` call, one preset
        adaptation)."""
        return (self.n_beams, self.angle_min, self.angle_increment, self.range_min, self.range_max)

    @property
    def angles(self) -> NDArray[np.float64]:
        """Beam angles in radians, computed from ``len(ranges)`` (not from an ``angle_max``)."""
        return self.angle_min + self.angle_increment * np.arange(self.n_beams, dtype=np.float64)

    @property
    def valid(self) -> NDArray[np.bool_]:
        """Mask of beams with a valid return (finite, strictly inside the range interval)."""
        with np.errstate(invalid="ignore"):
            return (
                np.isfinite(self.ranges)
                & (self.ranges > self.range_min)
                & (self.ranges < self.range_max)
            )

    @property
    def n_gaps(self) -> int:
        """Number of invalid beams."""
        return self.n_beams - int(np.count_nonzero(self.valid))

    def to_cartesian(self) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Convert to Cartesian points in angular (beam) order.

        Returns
        -------
        xy : ndarray, shape (N, 2)
            Points in the sensor frame, metres; rows of invalid beams are NaN.
        valid : ndarray of bool, shape (N,)
            The :attr:`valid` mask.
        """
        valid = self.valid
        angles = self.angles
        r = np.where(valid, self.ranges, np.nan)
        xy = np.empty((self.n_beams, 2), dtype=np.float64)
        xy[:, 0] = r * np.cos(angles)
        xy[:, 1] = r * np.sin(angles)
        return xy, valid

    @property
    def resolution_deg(self) -> float:
        """Absolute angular resolution in degrees."""
        return abs(math.degrees(self.angle_increment))
