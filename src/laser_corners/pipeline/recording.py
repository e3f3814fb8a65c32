"""Open a recording and resolve its detector parameters (what every front end does first).

``open_recording(path, topic, choice, odom_topic=...)`` opens the file (any kind
:func:`laser_corners.io.open_scans` reads, with the odometry ``odom_topic`` of a bag), reads
its first scan (an :class:`~laser_corners.errors.InputError` "FILE: no readable scan" when
there is none), resolves the :class:`ParamsChoice` against that scan (the ``auto`` and
``robust`` presets adapt to it) and builds the detector. ``detect``, ``plot``, ``view``,
``batch``, ``slam`` and ``localise`` all start here.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from itertools import chain
from pathlib import Path

from laser_corners.choice import ParamsChoice
from laser_corners.detector import CornerDetector
from laser_corners.errors import InputError
from laser_corners.io import BagSource, ScanSource, detect_kind, open_scans
from laser_corners.params import DetectorParams
from laser_corners.scan import LaserScan

__all__ = [
    "ParamsChoice",
    "Recording",
    "as_choice",
    "laser_topic_sources",
    "laser_topics",
    "no_scan_error",
    "open_recording",
    "scan_at",
]


def as_choice(params: ParamsChoice | DetectorParams | None) -> ParamsChoice:
    """``params`` as a :class:`~laser_corners.choice.ParamsChoice` (fixed parameters become
    its ``base``); :meth:`ParamsChoice.of <laser_corners.choice.ParamsChoice.of>`."""
    return ParamsChoice.of(params)


@dataclass
class Recording:
    """An opened recording with its resolved parameters (what :func:`open_recording` returns).

    Attributes
    ----------
    source : ScanSource
        The reader (iterate it for the scans, the first one included).
    first : LaserScan
        The first readable scan.
    params : DetectorParams
        The resolved parameters.
    detector : CornerDetector
        A detector with ``params``.
    preset : str
        What the parameters are: the preset name or the parameter file (:attr:`ParamsChoice.label`).
    description : str
        ``"fr079.bag (ros1 /scan)"``: file name, kind and topic, for titles.
    """

    source: ScanSource
    first: LaserScan
    params: DetectorParams
    detector: CornerDetector
    preset: str
    description: str
    _rest: Iterator[LaserScan] | None = field(default=None, repr=False)

    def close(self) -> None:
        """Close the reading started by :func:`open_recording` if :meth:`scans` never took it."""
        rest, self._rest = self._rest, None
        close = getattr(rest, "close", None)
        if close is not None:
            close()

    def __enter__(self) -> Recording:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def scans(self) -> Iterator[LaserScan]:
        """The scans, first one included; the first call goes on from the read of ``first``."""
        rest, self._rest = self._rest, None
        return iter(self.source) if rest is None else chain((self.first,), rest)

    @property
    def path(self) -> Path:
        """The recording's path."""
        return Path(self.source.path)

    @property
    def has_poses(self) -> bool:
        """Whether scans carry sensor poses (the first one does, or the bag has odometry)."""
        return self.first.pose is not None or getattr(self.source, "odom_topic", None) is not None


def no_scan_error(source: ScanSource) -> InputError:
    """The error for a recording without a readable scan (with the first skips, if any)."""
    detail = f" ({'; '.join(source.skip_examples)})" if source.skip_examples else ""
    return InputError(f"{source.path}: no readable scan{detail}")


def open_recording(
    path: str | Path,
    topic: str | None = None,
    params: ParamsChoice | DetectorParams | None = None,
    *,
    odom_topic: str | None = None,
) -> Recording:
    """Open a recording, read its first scan and resolve the parameters against it.

    Parameters
    ----------
    path : str or Path
        Any recording :func:`laser_corners.io.open_scans` reads.
    topic : str, optional
        The LaserScan topic of a bag (default: the only one).
    params : ParamsChoice or DetectorParams, optional
        The parameter choice (default: the ``paper`` preset).
    odom_topic : str, optional
        The odometry of a bag: a ``nav_msgs/Odometry`` topic or ``"tf"`` (default: the only
        Odometry topic, else ``/tf``; several: a ``TopicChoiceError``).

    Returns
    -------
    Recording

    Raises
    ------
    InputError
        The file cannot be read, or it holds no readable scan ("FILE: no readable scan").
    InvalidParamsError
        The parameters are invalid for this recording.
    """
    source = open_scans(path, topic, odom_topic=odom_topic)
    scans = iter(source)
    first = next(scans, None)
    if first is None:
        raise no_scan_error(source)
    choice = as_choice(params)
    resolved = choice.resolve(first)
    topic_part = f" {source.topic}" if source.topic else ""
    return Recording(
        source=source,
        first=first,
        params=resolved,
        detector=CornerDetector(resolved),
        preset=choice.label,
        description=f"{Path(path).name} ({source.kind}{topic_part})",
        _rest=scans,
    )


def scan_at(source: ScanSource, index: int) -> LaserScan:
    """The scan of index ``index`` (0-based, reading order) of ``source``.

    Raises
    ------
    InputError
        A negative index, or a recording with fewer scans (the message says how many it has).
    """
    if index < 0:
        raise InputError(f"{source.path}: scan index must be >= 0, got {index}")
    count = 0
    for count, scan in enumerate(source, start=1):
        if count - 1 == index:
            return scan
    if count == 0:
        raise no_scan_error(source)
    raise InputError(
        f"{source.path}: no scan {index}; the recording has {count} scans (0 to {count - 1})"
    )


def _bag_listing(path: Path, kind: str, topic: str | None = None) -> ScanSource:
    """A bag source that picks the first of several LaserScan topics instead of failing (and
    reads no odometry when there are several Odometry topics)."""
    return BagSource(path, kind, topic, strict=False)  # type: ignore[arg-type]


def laser_topics(path: str | Path) -> list[str]:
    """The LaserScan topics of a bag (empty for recordings without topics).

    Raises
    ------
    InputError
        The file cannot be read.
    """
    path = Path(path)
    kind = detect_kind(path)
    if kind not in ("ros1", "ros2", "mcap"):
        return []
    return list(getattr(_bag_listing(path, kind), "laser_topics", []))


def laser_topic_sources(path: str | Path, topic: str | None = None) -> list[ScanSource]:
    """One source per LaserScan topic of ``path`` (``topic`` only, when given), for listings.

    A recording without topics gives its one source.
    """
    path = Path(path)
    kind = detect_kind(path)
    if kind not in ("ros1", "ros2", "mcap"):
        return [open_scans(path, topic)]
    listing = _bag_listing(path, kind, topic)
    topics = list(getattr(listing, "laser_topics", []))
    if topic is not None or len(topics) <= 1:
        return [listing]
    return [_bag_listing(path, kind, t) for t in topics]
