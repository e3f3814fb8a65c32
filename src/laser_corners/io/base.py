"""The two interfaces of :mod:`laser_corners.io` and the helpers every reader and writer shares.

* :class:`ScanSource`: an iterable of :class:`~laser_corners.LaserScan` with counted skips and
  a reading position for messages;
* :class:`KeypointWriter`: ``write(scan_index, scan, keypoints)`` and ``close()`` (this base
  class writes nothing) plus :meth:`KeypointWriter.summary`, what the output keeps;
* :class:`~laser_corners.io.partial.PartialOutput` (from :mod:`laser_corners.io.partial`,
  re-exported here): an output written under a temporary name in its folder and renamed to its
  final name when complete, so a killed run never leaves a half-written file under the final
  name; :func:`~laser_corners.io.partial.refuse_input`: an output that is an input is refused;
* :func:`open_text`, :func:`read_head`: text lines (plain or gzip) and the first bytes of a file.

This module imports no reader and no writer: readers and writers import it, and only
:mod:`laser_corners.io.registry` imports the readers and writers (rosbags' ``rosbag2/reader.py``
and its storage plugins are laid out the same way).
"""

from __future__ import annotations

import gzip
import math
from abc import ABC, abstractmethod
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from itertools import islice
from pathlib import Path
from typing import Literal

from laser_corners.errors import InputError
from laser_corners.io.partial import ClosesOnExit, PartialOutput, file_mode, refuse_input
from laser_corners.keypoints import Keypoints
from laser_corners.pose import pose_problem
from laser_corners.scan import LaserScan

__all__ = [
    "BAD_POSE",
    "BAD_STAMP",
    "KINDS",
    "MAX_STAMP",
    "KeypointWriter",
    "PartialOutput",
    "ScanSource",
    "SourceKind",
    "TopicChoiceError",
    "WriterSummary",
    "file_mode",
    "open_text",
    "read_head",
    "refuse_input",
    "scan_problem",
    "skip_warning",
]

SourceKind = Literal["ros1", "ros2", "mcap", "carmen", "npz", "csv"]
KINDS: tuple[str, ...] = ("ros1", "ros2", "mcap", "carmen", "npz", "csv")
"""Every kind of recording :func:`~laser_corners.io.open_scans` reads."""
BAG_KINDS: frozenset[str] = frozenset({"ros1", "ros2", "mcap"})
"""The kinds read through rosbags (they have topics)."""

MAX_SKIP_EXAMPLES = 5
"""How many skipped records a source remembers the position of."""
MAX_STAMP = 1e11
"""Largest plausible |stamp|, seconds (year 5138 after 1970): beyond it, a broken record."""
BAD_STAMP = "scan with a non-finite or absurd stamp"
"""Skip reason: a scan whose stamp is NaN, infinite or beyond :data:`MAX_STAMP`."""
BAD_POSE = "scan with an absurd pose"
"""Skip reason: a scan whose pose is beyond :data:`~laser_corners.pose.MAX_COORDINATE`."""


def scan_problem(scan: LaserScan) -> tuple[str, str] | None:
    """``(skip reason, detail)`` when the stamp or the pose of ``scan`` is unusable (NaN,
    infinite, absurd), else None: a few float checks per scan."""
    stamp = scan.stamp
    if stamp is not None and not (math.isfinite(stamp) and abs(stamp) <= MAX_STAMP):
        return BAD_STAMP, f"stamp {stamp}"
    if scan.pose is not None:
        problem = pose_problem(scan.pose)
        if problem is not None:
            return BAD_POSE, problem
    return None


def skip_warning(path: str | Path, skipped: dict[str, int]) -> str | None:
    """One line saying what reading ``path`` skipped (``"fr079.bag: skipped while reading: 1
    damaged bag chunk, 246 scans in damaged chunks or records (not in the output)"``), None
    when nothing."""
    if not skipped:
        return None
    what = ", ".join(f"{count} {reason}" for reason, count in sorted(skipped.items()))
    return f"{path}: skipped while reading: {what} (not in the output)"


class TopicChoiceError(InputError):
    """A bag has several LaserScan (or Odometry) topics and none was chosen.

    Attributes
    ----------
    path : Path
        The bag.
    topics : list of str
        Its LaserScan (Odometry) topics, one per line of the message.
    option : str
        The option that chooses: ``--topic`` (``--odom-topic`` for the odometry); the CLI
        prints one ``OPTION TOPIC`` line per topic.
    """

    def __init__(
        self,
        path: Path,
        topics: list[str],
        what: str = "LaserScan",
        option: str = "--topic",
        also: str = "",
    ) -> None:
        self.path = path
        self.topics = list(topics)
        self.option = option
        self.what = what
        lines = "".join(f"\n  {t}" for t in self.topics)
        head = f"{path}: {len(self.topics)} {what} topics; choose one of{also}:"
        super().__init__(head + lines)

    def one_line(self) -> str:
        """The message on one line (a batch manifest's record), the topics listed in it."""
        names = ", ".join(self.topics)
        count = f"{len(self.topics)} {self.what} topics"
        return f"{self.path}: {count} ({names}); choose with {self.option}"


def read_head(path: Path, size: int = 64) -> bytes:
    """The first ``size`` bytes of ``path``; :class:`InputError` when it cannot be read."""
    try:
        with path.open("rb") as handle:
            return handle.read(size)
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror})") from None


def open_text(path: Path) -> Iterator[str]:
    """Lines of a text file, gunzipped when it starts with the gzip magic number."""
    if read_head(path, 2) == b"\x1f\x8b":
        return gzip.open(path, "rt", encoding="utf-8", errors="replace")  # type: ignore[return-value]
    return path.open("r", encoding="utf-8", errors="replace")


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
        return self._usable(self._scans())

    def _usable(self, scans: Iterator[LaserScan]) -> Iterator[LaserScan]:
        """The scans of ``scans`` whose stamp and pose are usable; the others are counted
        skips (:func:`scan_problem`). Closing this closes ``scans``."""
        try:
            for scan in scans:
                problem = scan_problem(scan)
                if problem is None:
                    yield scan
                else:
                    self._skip(problem[0], self.position, problem[1])
        finally:
            close = getattr(scans, "close", None)
            if close is not None:
                close()

    def _skip(self, reason: str, where: str, detail: str = "") -> None:
        """Count a skipped record of kind ``reason`` found at ``where``."""
        self.skipped[reason] = self.skipped.get(reason, 0) + 1
        if len(self.skip_examples) < MAX_SKIP_EXAMPLES:
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


# ----------------------------------------------------------------------------- writers
@dataclass(frozen=True)
class WriterSummary:
    """What a keypoint writer has kept.

    Attributes
    ----------
    path : Path or None
        The output: its final name once closed, the temporary file while it is written,
        ``None`` for the writer that writes nothing.
    n_scans, n_keypoints : int
        Scans and keypoints written.
    complete : bool
        The output is closed and under its final name.
    """

    path: Path | None
    n_scans: int
    n_keypoints: int
    complete: bool


class KeypointWriter(ClosesOnExit):
    """Writes nothing: the writer used when no output is asked for (and the base class).

    Every writer has the same calls, :meth:`write` (or :meth:`write_many`) and :meth:`close`,
    so a detection loop never asks which one it has. Use it as a context manager: ``close()``
    also runs on Ctrl-C, and what was written is kept.

    Attributes
    ----------
    path : Path or None
        The output (its final name).
    n_scans, n_keypoints : int
        Scans and keypoints handed to :meth:`write` so far.
    """

    path: Path | None = None
    _partial: PartialOutput | None = None

    def __init__(self) -> None:
        self.n_scans = 0
        self.n_keypoints = 0
        self.closed = False

    def write(self, scan_index: int, scan: LaserScan, keypoints: Keypoints) -> None:
        """Record the keypoints of the scan of index ``scan_index``."""
        self.n_scans += 1
        self.n_keypoints += len(keypoints)

    def write_many(
        self, first_index: int, scans: Sequence[LaserScan], keypoints: Sequence[Keypoints]
    ) -> None:
        """Record consecutive scans at once: scan ``first_index + i`` found ``keypoints[i]``.

        Same result as calling :meth:`write` for each; table writers do it in one block.
        """
        for offset, (scan, found) in enumerate(zip(scans, keypoints, strict=True)):
            self.write(first_index + offset, scan, found)

    def close(self) -> None:
        """Flush and close the output, then give it its final name (idempotent)."""
        self.closed = True

    def summary(self) -> WriterSummary:
        """What the output keeps so far (path, scans, keypoints, whether complete)."""
        partial = self._partial
        path = self.path if self.closed or partial is None else partial.temporary
        return WriterSummary(path, self.n_scans, self.n_keypoints, self.closed)
