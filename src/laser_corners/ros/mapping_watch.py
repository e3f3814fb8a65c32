"""What the ROS 2 node's ``slam`` / ``localise`` modes warn about, ROS-free: nothing silent.

A node that maps nothing because its odometry never comes, or comes in other frames, used to
say so only in the shutdown counts. :class:`MappingWatch` looks at the odometry book and the
scan counts of :class:`~laser_corners.ros.slam_core.MappingCore` and says, in a warning at most
every :data:`WARN_PERIOD` seconds per kind (the counts go on meanwhile):

* ``no odometry``: scans arrive but no odometry sample was accepted for ``odom_timeout``
  seconds, naming the odometry source and the frame pairs seen on it;
* ``frames``: odometry (``nav_msgs/Odometry`` or ``/tf`` transforms) arrives, but none in the
  configured ``odom_frame`` / ``base_frame``, naming the pairs seen;
* ``dropped``: scans dropped without odometry (after ``tf_wait``, or stamped before the
  odometry kept: the core forgets what is older than ``ODOMETRY_KEPT_S`` before its last
  processed scan), with the stamps of the last dropped scan and of the odometry the node has;
* ``jump`` (slam): the odometry moved more than ``max_odom_jump`` metres between consecutive
  processed scans.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

__all__ = ["WARN_PERIOD", "MappingWatch", "WatchCounts"]

WARN_PERIOD = 5.0
"""Seconds between two warnings of one kind."""


class OdometryBook(Protocol):
    """What the watch reads of :class:`laser_corners.ros.slam_core.OdometryBook`."""

    odom_frame: str
    base_frame: str
    n_odometry: int
    span: tuple[float, float] | None


@dataclass
class WatchCounts:
    """What the watch counted: odometry jumps; the odometry pairs seen (with counts)."""

    odom_jumps: int = 0
    seen: dict[tuple[str, str], int] = field(default_factory=dict)


class MappingWatch:
    """Throttled warnings of the mapping modes (see the module docstring).

    Parameters
    ----------
    source : str
        Where odometry comes from (``/tf`` or the ``nav_msgs/Odometry`` topic), for the text.
    map_frame : str
        The node's own frame: its ``map -> odom`` on ``/tf`` is not odometry seen.
    odom_timeout, max_odom_jump : float
        Seconds without odometry while scans arrive; metres between consecutive scans.
    clock : callable
        Seconds (monotonic), the core's.
    """

    def __init__(
        self,
        source: str,
        map_frame: str,
        odom_timeout: float,
        max_odom_jump: float,
        clock: Callable[[], float],
    ) -> None:
        self.source, self.map_frame = source, map_frame
        self.odom_timeout, self.max_odom_jump = odom_timeout, max_odom_jump
        self.clock = clock
        self.scan_topic = "scan"
        self.counts = WatchCounts()
        self._started = self._odom_at = clock()
        self._scan_at = -math.inf
        self._n_odometry = 0
        self._warned: dict[str, float] = {}
        self._pending: dict[str, str] = {}
        self._previous: tuple[float, NDArray[np.float64]] | None = None

    # ------------------------------------------------------------------ events
    def saw(self, parent: str, child: str) -> None:
        """An odometry-like input (an Odometry message, a dynamic transform) arrived."""
        if parent == self.map_frame:
            return  # our own map -> odom, back from /tf
        key = (parent, child)
        self.counts.seen[key] = self.counts.seen.get(key, 0) + 1

    def scan_arrived(self) -> None:
        self._scan_at = self.clock()

    def dropped(self, stamp: float, n_dropped: int, book: OdometryBook) -> None:
        """A scan was dropped without odometry (``book``: the core's odometry book)."""
        have = "none" if book.span is None else f"{book.span[0]:.3f} .. {book.span[1]:.3f} s"
        self._pending["dropped"] = (
            f"{n_dropped} scan(s) on {self.scan_topic} dropped so far without odometry: the "
            f"last at stamp {stamp:.3f} s; odometry in hand ({self.pair(book)} from "
            f"{self.source}): {have}"
        )

    def processed(self, stamp: float, odom: NDArray[np.float64], book: OdometryBook) -> None:
        """slam: compare the odometry of a processed scan with the previous one's."""
        previous, self._previous = self._previous, (stamp, np.asarray(odom, dtype=np.float64))
        if previous is None:
            return
        step = float(np.hypot(*(odom[:2] - previous[1][:2])))
        if step > self.max_odom_jump:
            self.counts.odom_jumps += 1
            self._pending["jump"] = (
                f"odometry jumped {step:.2f} m between the scans at {previous[0]:.3f} and "
                f"{stamp:.3f} s ({self.pair(book)} from {self.source}; max_odom_jump "
                f"{self.max_odom_jump:g} m); {self.counts.odom_jumps} jump(s) so far"
            )

    # ------------------------------------------------------------------ warnings
    def warnings(self, book: OdometryBook) -> list[str]:
        """The warnings due now (each kind at most every :data:`WARN_PERIOD` s)."""
        now = self.clock()
        if book.n_odometry != self._n_odometry:
            self._n_odometry, self._odom_at = book.n_odometry, now
        for kind in ("frames", "no odometry"):  # states: said while they hold
            self._pending.pop(kind, None)
        idle = now - max(self._odom_at, self._started)
        if not book.n_odometry and self.counts.seen and idle > self.odom_timeout:
            self._pending["frames"] = (
                f"no odometry in frames {self.pair(book)} on {self.source}; seen there: "
                f"{self.seen_pairs()} (set -p odom_frame:=... -p base_frame:=... to one of them)"
            )
        if idle > self.odom_timeout and now - self._scan_at <= self.odom_timeout:
            last = "none yet" if not book.n_odometry else f"the last {idle:.1f} s ago"
            self._pending["no odometry"] = (
                f"no odometry for {idle:.1f} s while scans arrive on {self.scan_topic}: "
                f"expecting {self.pair(book)} on {self.source} ({last}); seen there: "
                f"{self.seen_pairs()}"
            )
        out = []
        for kind, text in list(self._pending.items()):
            if now - self._warned.get(kind, -math.inf) >= WARN_PERIOD:
                self._warned[kind] = now
                out.append(text)
                del self._pending[kind]
        return out

    def pair(self, book: OdometryBook) -> str:
        """The odometry frames expected, ``odom -> base`` (as configured or found)."""
        return f"{book.odom_frame or 'odom'} -> {book.base_frame or '(any child)'}"

    def seen_pairs(self) -> str:
        """The odometry-like frame pairs seen, most frequent first, with counts."""
        if not self.counts.seen:
            return "nothing"
        pairs = sorted(self.counts.seen.items(), key=lambda kv: -kv[1])
        return ", ".join(f"{p} -> {c} ({n})" for (p, c), n in pairs[:6])
