"""The reader interface: :class:`ScanSource` and :func:`open_scans`.

``open_scans(path)`` guesses the kind of recording from the path and its first bytes (ROS 1 bag,
ROS 2 bag with sqlite3 or MCAP storage, CARMEN log plain or gzip, NPZ or CSV arrays) and returns
a :class:`ScanSource`: an iterable of :class:`~laser_corners.LaserScan` with stamp, frame and,
when the file has it, the sensor pose. Problems that make the whole file unusable raise
:class:`~laser_corners.errors.InputError` (one line naming the file and position); a bad
record inside a good file is skipped and counted in :attr:`ScanSource.skipped`.
"""

from __future__ import annotations

import gzip
from abc import ABC, abstractmethod
from collections.abc import Iterator
from itertools import islice
from pathlib import Path
from typing import Literal

from laser_corners.errors import InputError
from laser_corners.scan import LaserScan

__all__ = ["KINDS", "ScanSource", "detect_kind", "open_scans"]

SourceKind = Literal["ros1", "ros2", "mcap", "carmen", "npz", "csv"]
KINDS: tuple[str, ...] = ("ros1", "ros2", "mcap", "carmen", "npz", "csv")
"""Every kind of recording :func:`open_scans` reads."""

_MAX_SKIP_EXAMPLES = 5
_CARMEN_SUFFIXES = {".clf", ".log", ".carmen", ".txt", ".gfs"}
_CARMEN_WORDS = (b"FLASER", b"ROBOTLASER1", b"RAWLASER", b"VERTEX2", b"ODOM", b"PARAM", b"#")


class ScanSource(ABC):
    """An iterable of the scans of one recording.

    Attributes
    ----------
    path : Path
        The recording.
    kind : str
        One of :data:`KINDS`.
    topic : str or None
        The LaserScan topic read (bags only).
    skipped : dict of str to int
        Bad records skipped so far in the current (or last) iteration, by reason.
    skip_examples : list of str
        Where the first few skips happened (``"line 12: not a number"``).
    position : str
        Where the current iteration is (``"message 1200"``, ``"line 345"``), for messages
        about interruptions and errors.
    """

    kind: SourceKind

    def __init__(self, path: Path, topic: str | None = None) -> None:
        self.path = path
        self.topic = topic
        self.skipped: dict[str, int] = {}
        self.skip_examples: list[str] = []
        self.position = "start"

    @property
    @abstractmethod
    def n_scans(self) -> int | None:
        """Number of scans, or ``None`` when it is unknown without reading the whole file."""

    @abstractmethod
    def _scans(self) -> Iterator[LaserScan]:
        """Yield the scans, calling :meth:`_skip` for bad records."""

    def __iter__(self) -> Iterator[LaserScan]:
        self.skipped = {}
        self.skip_examples = []
        self.position = "start"
        return self._scans()

    def _skip(self, reason: str, where: str, detail: str = "") -> None:
        """Count a skipped record of kind ``reason`` found at ``where``."""
        self.skipped[reason] = self.skipped.get(reason, 0) + 1
        if len(self.skip_examples) < _MAX_SKIP_EXAMPLES:
            self.skip_examples.append(f"{where}: {reason}" + (f" ({detail})" if detail else ""))

    def error(self, message: str) -> InputError:
        """An :class:`InputError` naming the file and the current position."""
        return InputError(f"{self.path}: {message} (at {self.position})")

    def first_scan(self) -> LaserScan | None:
        """The first scan of the recording (reads only as far as needed), or ``None``."""
        return next(iter(self), None)

    def scan_at(self, index: int) -> LaserScan:
        """The scan of index ``index`` (0-based) in reading order.

        Raises
        ------
        InputError
            When the recording has fewer scans.
        """
        if index < 0:
            raise InputError(f"{self.path}: scan index must be >= 0, got {index}")
        scan = next(islice(iter(self), index, None), None)
        if scan is None:
            raise InputError(
                f"{self.path}: scan {index} requested but the recording has fewer scans"
            )
        return scan

    def describe(self) -> dict[str, object]:
        """Facts for ``laser-corners info`` (kind, counts, topics), without the scan geometry."""
        return {"path": str(self.path), "kind": self.kind, "scans": self.n_scans}

    def __repr__(self) -> str:
        topic = f", topic={self.topic!r}" if self.topic else ""
        return f"{type(self).__name__}({str(self.path)!r}, kind={self.kind!r}{topic})"


def _head(path: Path, size: int = 64) -> bytes:
    try:
        with path.open("rb") as handle:
            return handle.read(size)
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror})") from None


def detect_kind(path: str | Path) -> SourceKind:
    """The kind of recording at ``path`` (from the suffix, else from the first bytes).

    Raises
    ------
    InputError
        When ``path`` is missing, empty or of no known kind.
    """
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such file or directory")
    if path.is_dir():
        if (path / "metadata.yaml").is_file():
            if any(path.glob("*.mcap")):
                return "mcap"
            return "ros2"
        raise InputError(
            f"{path}: a directory without metadata.yaml is not a ROS 2 bag; give a bag file, "
            "a ROS 2 bag directory, a CARMEN log, an .npz or a .csv"
        )
    if path.stat().st_size == 0:
        raise InputError(f"{path}: file is empty")
    head = _head(path)
    suffixes = [s.lower() for s in path.suffixes]
    suffix = suffixes[-1] if suffixes else ""
    if suffix == ".bag" or head.startswith(b"#ROSBAG"):
        return "ros1"
    if suffix == ".mcap" or head.startswith(b"\x89MCAP"):
        return "mcap"
    if suffix == ".db3" or head.startswith(b"SQLite format 3"):
        return "ros2"
    if suffix == ".npz" or head.startswith(b"PK\x03\x04"):
        return "npz"
    if suffix == ".csv":
        return "csv"
    if suffix == ".gz" or set(suffixes) & _CARMEN_SUFFIXES or head.startswith(b"\x1f\x8b"):
        return "carmen"
    if head.lstrip().startswith(_CARMEN_WORDS):
        return "carmen"
    raise InputError(
        f"{path}: unknown kind of recording; expected a ROS 1 .bag, a ROS 2 bag (directory, "
        ".db3 or .mcap), a CARMEN log (.clf, .log, .gz), an .npz or a .csv"
    )


def open_scans(path: str | Path, topic: str | None = None) -> ScanSource:
    """Open a recording of 2D laser scans; the kind is inferred from the path and content.

    Parameters
    ----------
    path : str or Path
        A ROS 1 ``.bag``, a ROS 2 bag (directory with ``metadata.yaml``, a ``.db3`` or an
        ``.mcap`` file), a CARMEN log (plain or ``.gz``), an ``.npz`` or a ``.csv`` of scans
        (layout in ``docs/io-and-cli.md``).
    topic : str, optional
        The ``sensor_msgs/LaserScan`` topic of a bag. Default: the only LaserScan topic.

    Returns
    -------
    ScanSource
        Iterate it for :class:`~laser_corners.LaserScan` objects.

    Raises
    ------
    InputError
        Missing, empty, unreadable or corrupt file, unknown kind, a topic that is not a
        LaserScan, several LaserScan topics and no ``topic``, or ``topic`` given for a file
        without topics.

    Examples
    --------
    >>> source = open_scans("../shared/data/real/fr079.bag")  # doctest: +SKIP
    >>> for scan in source:  # doctest: +SKIP
    ...     print(scan.stamp, scan.pose)
    """
    path = Path(path)
    kind = detect_kind(path)
    if kind in ("ros1", "ros2", "mcap"):
        from laser_corners.io.rosbag import BagSource

        return BagSource(path, kind, topic)
    if topic is not None:
        raise InputError(f"{path}: --topic applies to bags only; a {kind} file has no topics")
    if kind == "carmen":
        from laser_corners.io.carmen import CarmenSource

        return CarmenSource(path)
    from laser_corners.io.arrays import CsvSource, NpzSource

    return NpzSource(path) if kind == "npz" else CsvSource(path)


def open_text(path: Path) -> Iterator[str]:
    """Lines of a text file, gunzipped when it starts with the gzip magic number."""
    if _head(path, 2) == b"\x1f\x8b":
        return gzip.open(path, "rt", encoding="utf-8", errors="replace")  # type: ignore[return-value]
    return path.open("r", encoding="utf-8", errors="replace")
