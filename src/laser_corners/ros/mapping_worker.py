"""The worker thread of the ROS 2 node's ``slam`` and ``localise`` modes (ROS-free).

Every step of :class:`~laser_corners.ros.slam_core.MappingCore` (scans, odometry, initial
poses, services) runs on one worker thread, in arrival order, so that no ROS callback waits
for a global search, an optimisation or a map write: a callback converts its message and
hands the step over (:meth:`MappingWorker.post`); a scan is dropped and counted when
``queue_size`` scans still wait there (:meth:`MappingWorker.offer_scan`).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

from laser_corners.errors import LaserCornersError
from laser_corners.ros.slam_core import MappingCore, Update

__all__ = ["MappingWorker"]

BUSY = "scans dropped: the worker is busy (a global search or an optimisation)"


class MappingWorker:
    """One worker thread running the core's steps; counts of what it dropped or skipped.

    Parameters
    ----------
    core : MappingCore
        The core the steps work on.
    logger : callable
        Returns the logger (rclpy's: ``info``, ``warning`` and ``error`` with
        ``throttle_duration_sec``).
    publish : callable
        Called on the worker with every :class:`~laser_corners.ros.slam_core.Update` a step
        released.
    """

    def __init__(
        self, core: MappingCore, logger: Callable[[], Any], publish: Callable[[Update], None]
    ) -> None:
        self.core = core
        self.logger = logger
        self.publish = publish
        self.executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="mapping")
        self.lock = threading.Lock()
        self.pending = 0
        """Scans handed to the worker and not yet processed."""
        self.busy_drops = 0
        """Scans dropped because ``queue_size`` scans still waited on the worker."""
        self.callback_ms = 0.0
        """The longest callback (ms) measured with :meth:`timed`."""
        self.n_skipped = 0
        """Messages skipped (malformed, in a wrong frame) or failed on the worker."""
        self.lost = 0
        """Scans the middleware reported lost before they reached the node."""
        self.closed = False

    def submit(self, step: Callable[[], Any]) -> Future[Any]:
        """Run ``step`` on the worker (in arrival order); the caller reads its result."""
        return self.executor.submit(step)

    def drain(self) -> None:
        """Wait until the worker has run every step submitted so far (none once shut
        down)."""
        if not self.closed:
            self.submit(lambda: None).result()

    def post(self, step: Callable[[], Any], what: str) -> None:
        """Run ``step`` on the worker, nobody waiting: a known error skips ``what`` (logged,
        counted), any other is an error line; none is lost in an unread future."""

        def guarded() -> None:
            try:
                step()
            except LaserCornersError as exc:
                self.skip(f"skipped {what}: {exc}")
            except Exception as exc:  # a bug: keep the node alive, show the error
                self.n_skipped += 1
                self.logger().error(f"{what} failed: {exc!r}")

        self.submit(guarded)

    def offer_scan(self, scan: Any) -> bool:
        """Hand a scan to the worker unless ``queue_size`` scans wait there already (then it
        is dropped, counted and a throttled warning says so); whether it was taken."""
        with self.lock:
            full = self.pending >= self.core.config.queue_size
            self.pending += not full
            self.busy_drops += full
        if full:
            self.logger().warning(BUSY, throttle_duration_sec=5.0)
            return False
        self.post(lambda: self._scan_step(scan), "a scan")
        return True

    def _scan_step(self, scan: Any) -> None:
        try:
            self.run(lambda: self.core.add_scan(scan))
        finally:
            with self.lock:
                self.pending -= 1

    def timed(self, began: float) -> None:
        """Record a callback that began at ``began`` (``time.perf_counter``)."""
        self.callback_ms = max(self.callback_ms, (time.perf_counter() - began) * 1e3)

    def skip(self, text: str) -> None:
        """Count a skipped message; a throttled warning."""
        self.n_skipped += 1
        self.logger().warning(text, throttle_duration_sec=5.0)

    def run(self, step: Callable[[], list[Update]]) -> None:
        """Run a core step, publish what it released, log the watch's warnings due."""
        updates: list[Update] = []
        try:
            updates = step()
        except LaserCornersError as exc:
            self.skip(f"scan skipped: {exc}")
        except Exception as exc:  # a bug: keep the node alive, show the error
            self.n_skipped += 1
            self.logger().error(f"scan processing failed: {exc!r}")
        for update in updates:
            self.publish(update)
        for text in self.core.watch.warnings(self.core.book):
            self.logger().warning(text)

    def summary(self) -> str:
        """The worker's counts, after its queue and a last release (the scans whose
        ``tf_wait`` ran out count as dropped, not as waiting)."""
        self.submit(lambda: self.run(self.core.release)).result()
        return (
            f"{self.busy_drops} scans dropped while the worker was busy, {self.lost} scans "
            f"lost before the node (DDS), {self.n_skipped} messages skipped, longest callback "
            f"{self.callback_ms:.1f} ms"
        )

    def shutdown(self) -> None:
        """Finish the queue and stop the thread."""
        self.closed = True
        self.executor.shutdown(wait=True)
