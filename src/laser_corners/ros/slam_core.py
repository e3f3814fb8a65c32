"""The ROS-free core of the ROS 2 node's ``slam`` and ``localise`` modes.

Everything the node decides without touching a message class lives here, so it is tested
without ROS:

* :class:`MappingConfig`: the node's parameters in these modes, checked (one line naming the
  parameter when invalid);
* :class:`OdometryBook`: odometry (``odom -> base`` from ``/tf`` or ``nav_msgs/Odometry``) and
  the static transforms, kept per stamp (:class:`~laser_corners.io.poses.StreamingTrack`:
  linear interpolation at the scan stamp, the laser mount from the static tree), the last
  :data:`ODOMETRY_KEPT_S` seconds before the last processed scan, at most twice that before
  the newest sample (a node runs for days);
* :class:`MappingCore`: pairs each scan with the odometry at its stamp (a scan waits until
  odometry after its stamp is in, at most ``tf_wait`` seconds after it arrived), runs
  :class:`~laser_corners.slam.Slam` or the ``Localiser`` on it and computes ``map -> odom``
  (``pose ∘ odom⁻¹``); it says when the occupancy grid is due for republishing and builds it.

The rclpy adapter (:mod:`laser_corners.ros.ros2_mapping`) only turns messages into calls of
this module and its results into messages.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from laser_corners.errors import OutputError
from laser_corners.io.occupancy import OccupancyGrid, write_map
from laser_corners.io.poses import StreamingTrack, frame_name
from laser_corners.localise import Localiser
from laser_corners.localise.estimate import timing_record
from laser_corners.pose import compose_many, invert_many
from laser_corners.registration.mapfolder import SavedMap, load_map
from laser_corners.ros.mapping_config import MAPPING_OPTIONS, MappingConfig, check_output
from laser_corners.ros.mapping_watch import MappingWatch
from laser_corners.scan import LaserScan
from laser_corners.slam.grid import occupancy_grid
from laser_corners.slam.output import SlamRunInfo, peak_rss_mb, write_slam_map
from laser_corners.slam.slam import Slam

__all__ = [
    "CLOCK_JUMP_SAMPLES",
    "MAPPING_OPTIONS",
    "ODOMETRY_KEPT_S",
    "MapViews",
    "MappingConfig",
    "MappingCore",
    "OdometryBook",
    "Update",
    "check_output",
    "map_to_odom",
]

ODOMETRY_KEPT_S = 60.0
"""Seconds of odometry kept at least before the stamp of the last processed scan, and at
most twice this before the newest odometry sample, so the store stays bounded when the laser
stops while the odometry goes on (the book forgets in batches: it holds up to about twice
this, see ``StreamingTrack.forget_before``).
Far beyond ROS's default 10 s tf buffer: scans come out in arrival order, so a later scan
stamped a minute before the last processed one is a clock jump or a bag replayed again; a
scan older than the odometry kept is dropped and counted as without odometry, and odometry
older than that kept, :data:`CLOCK_JUMP_SAMPLES` samples in a row, starts the book anew."""

CLOCK_JUMP_SAMPLES = 10
"""Odometry samples in a row older than those kept after which the book starts anew (the
clock jumped back, as when a bag is played in a loop; tf2 clears its buffer then); fewer are
stray late samples, not taken."""


def map_to_odom(pose: NDArray[np.float64], odom: NDArray[np.float64]) -> NDArray[np.float64]:
    """The ``map -> odom`` transform that puts the base at ``pose`` (map) given its odometry
    pose ``odom``: ``pose ∘ odom⁻¹`` (so ``map_to_odom ∘ odom = pose``)."""
    return compose_many(
        np.asarray(pose, dtype=np.float64), invert_many(np.asarray(odom, dtype=np.float64))
    )


class OdometryBook:
    """Odometry and static transforms as they arrive; the base pose at any covered stamp.

    Parameters
    ----------
    odom_frame, base_frame : str
        The odometry frames ("" = those of the first ``nav_msgs/Odometry``, or the first
        ``/tf`` transform whose child has a static child, e.g. ``odom -> base_link``).

    Notes
    -----
    A sample costs about 270 bytes: 230 in the track, 40 in the set of stamps that drops
    republished samples (1.2 GB a day at 50 Hz): :meth:`forget_before` bounds both.
    """

    def __init__(self, odom_frame: str = "", base_frame: str = "") -> None:
        self.track = StreamingTrack()
        self.odom_frame = frame_name(odom_frame)
        self.base_frame = frame_name(base_frame)
        self._dynamic: list[tuple[str, str, float, tuple[float, float, float]]] = []
        self.n_odometry = 0
        """Odometry samples taken in total (a counter: forgetting does not lower it)."""
        self._stamps: set[float] = set()  # those of the samples kept
        self._stale = 0  # samples in a row older than those kept
        self.clock_jumps = 0
        """Times the store started anew: :data:`CLOCK_JUMP_SAMPLES` samples in a row older
        than those kept (the clock jumped back: a bag played in a loop)."""
        self.on_input: Callable[[str, str], None] = lambda parent, child: None
        """Called with the frames of every odometry-like input (the watch counts them)."""

    def add_odometry(
        self, odom_frame: str, base_frame: str, stamp: float, pose: tuple[float, float, float]
    ) -> None:
        """One odometry sample (``nav_msgs/Odometry`` or the ``odom -> base`` transform)."""
        odom, base = frame_name(odom_frame), frame_name(base_frame)
        self.on_input(odom, base)
        self.odom_frame = self.odom_frame or odom
        self.base_frame = self.base_frame or base
        if (odom, base) != (self.odom_frame, self.base_frame) or stamp in self._stamps:
            return  # another odometry, or a sample we have (a republished one)
        sample = (float(stamp), *map(float, pose))
        if not self.track.add_odometry(odom, base, sample):
            self._stale += 1  # older than the samples kept
            if self._stale < CLOCK_JUMP_SAMPLES:
                return  # a stray late sample: forgotten
            self.track.restart()  # the clock jumped back: start anew, as tf2 does
            self._stamps.clear()
            self.clock_jumps += 1
            self.track.add_odometry(odom, base, sample)
        self._stale = 0
        self._stamps.add(stamp)
        self.n_odometry += 1

    @property
    def span(self) -> tuple[float, float] | None:
        """First and last stamp of the odometry samples kept (the first moves on as
        :meth:`forget_before` drops old samples), None without samples."""
        first, last = self.track.first_stamp, self.track.last_stamp
        return None if first is None or last is None else (first, last)

    @property
    def n_kept(self) -> int:
        """The odometry samples held now (in the track; the set of stamps holds theirs)."""
        return len(self._stamps)

    def forget_before(self, stamp: float) -> int:
        """Forget the samples older than ``stamp`` but the newest at or before it (in the
        track, :meth:`~laser_corners.io.poses.StreamingTrack.forget_before`: only in batches,
        O(1) a sample, and their stamps); the pose at ``stamp`` and after stays, before the
        samples kept there is none. Returns how many were dropped."""
        dropped = self.track.forget_before(stamp)
        first = self.track.first_stamp
        if dropped and first is not None:
            self._stamps = {kept for kept in self._stamps if kept >= first}
        return dropped

    def add_transforms(
        self, transforms: list[tuple[str, str, float, tuple[float, float, float]]], static: bool
    ) -> None:
        """Transforms ``(parent, child, stamp, pose)`` of one ``TFMessage``; on ``/tf`` the
        ``odom -> base`` ones are odometry samples, the others join the tree."""
        if static:
            self.track.add_transforms([(p, c, pose) for p, c, _, pose in transforms], True)
            return
        tree = []
        for parent, child, stamp, pose in transforms:
            if self._is_odometry(frame_name(parent), frame_name(child)):
                self.add_odometry(parent, child, stamp, pose)
            else:
                self.on_input(frame_name(parent), frame_name(child))
                tree.append((parent, child, pose))
        if tree:
            self.track.add_transforms(tree, False)

    def _is_odometry(self, parent: str, child: str) -> bool:
        if self.odom_frame and self.base_frame:
            return (parent, child) == (self.odom_frame, self.base_frame)
        if self.odom_frame:
            return parent == self.odom_frame
        if self.base_frame:
            return child == self.base_frame
        return parent == "odom"  # REP 105's name, when nothing was configured

    def ready(self, stamp: float, laser_frame: str, need_mount: bool) -> bool:
        """Whether odometry after ``stamp`` is in (and the laser mount, if needed)."""
        if not self.n_odometry:
            return False
        if need_mount:
            return self.track.ready(round(stamp * 1e9), laser_frame)
        return self.track.ready(round(stamp * 1e9), self.base_frame)

    def base_pose(self, stamp: float) -> NDArray[np.float64] | None:
        """The base pose in the odometry frame at ``stamp`` (interpolated), or None."""
        pose = self.track.pose(stamp, self.base_frame) if self.n_odometry else None
        return None if pose is None else np.asarray(pose, dtype=np.float64)

    def mount(self, laser_frame: str) -> tuple[float, float, float] | None:
        """Base -> laser from the static tree, or None."""
        return self.track.mount_of(laser_frame) if self.base_frame else None


@dataclass
class Update:
    """What one scan produced: the base pose in the map frame and ``map -> odom``."""

    stamp: float
    pose: NDArray[np.float64]
    covariance: NDArray[np.float64]
    map_to_odom: NDArray[np.float64]
    status: str = "tracking"
    ms: float = 0.0


@dataclass
class Counts:
    """Scans arrived, processed, dropped (no odometry in time), malformed, and without an
    estimate (localise: no fix yet, or the scan disagreed with the map); the per-scan times
    (ms) of the last 10,000 processed (``localise.estimate.TIMINGS_KEPT``: a node runs for
    days). Every scan that arrived is in one of these or still waiting."""

    scans: int = 0
    processed: int = 0
    no_odometry: int = 0
    malformed: int = 0
    no_fix: int = 0
    ms: deque[float] = field(default_factory=timing_record)


class MapViews:
    """What :class:`MappingCore` makes of its map: the grid (published, saved as
    map_server's files), its landmarks and the map folder (slam)."""

    config: MappingConfig
    clock: Callable[[], float]
    estimator: Any
    saved: SavedMap | None
    saved_grid: OccupancyGrid | None
    _grid_at: float
    _grid_keyframes: int

    def write_map(self, folder: Path, wall_s: float) -> Path | None:
        """slam: write the map folder as ``laser-corners slam`` does (same writer); None when
        nothing was mapped.

        Raises
        ------
        OutputError
            When the folder cannot be written.
        """
        if self.config.mode != "slam" or self.estimator is None:
            return None
        result = self.estimator.result()
        info = SlamRunInfo(
            "laser-corners ros2 (live)", wall_s, peak_rss_mb(), resolution=self.config.resolution
        )
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputError(f"output {folder}: {exc}") from None
        write_slam_map(result, folder, info)  # no pictures: a node renders none
        return folder

    def save_grid(self, folder: Path) -> Path:
        """Write the current grid as map_server's ``map.yaml`` + ``map.pgm`` into ``folder``
        (slam: built from the keyframes now; localise: the map's); the YAML path.

        Raises
        ------
        OutputError
            Nothing mapped yet, or the files cannot be written.
        """
        grid = self.grid()
        if grid is None:
            raise OutputError("nothing mapped yet: no keyframe")
        folder.mkdir(parents=True, exist_ok=True)
        return write_map(grid, folder / "map.yaml")[0]

    def grid_due(self) -> bool:
        """slam: a new grid is due (``map_period`` passed and new keyframes since the last)."""
        if self.config.mode != "slam" or self.estimator is None:
            return False
        n = len(self.estimator.kf)
        return (
            n > 0
            and n != self._grid_keyframes
            and self.clock() - self._grid_at >= (self.config.map_period)
        )

    def grid(self) -> OccupancyGrid | None:
        """slam: the grid of the keyframes at their current estimates; localise: the saved
        map."""
        if self.config.mode == "localise":
            return self.saved_grid
        job = self.grid_job()
        return None if job is None else job()

    def grid_job(self) -> Callable[[], OccupancyGrid] | None:
        """slam: a snapshot of the keyframes (estimates copied) and the function that builds
        their grid, for a worker thread (the numba kernel releases the GIL, so scans go on
        meanwhile); the grid counts as built from now. None before the first keyframe."""
        if self.config.mode != "slam" or self.estimator is None or not len(self.estimator.kf):
            return None
        kf = self.estimator.kf
        n = min(len(kf.estimate), len(kf.scans))
        self._grid_at, self._grid_keyframes = self.clock(), len(kf)
        return partial(
            occupancy_grid,
            np.array(kf.estimate[:n], copy=True),
            list(kf.scans[:n]),
            self.estimator.mount.copy(),
            self.config.resolution,
        )

    def landmarks(self) -> NDArray[np.float64]:
        """Landmark positions ``(N, 2)`` in the map frame (empty when there are none)."""
        if self.config.mode == "slam" and self.estimator is not None:
            return self.estimator.backend.landmark_estimates().reshape(-1, 2)
        if self.saved is not None and self.saved.landmarks is not None:
            return np.asarray(self.saved.landmarks, dtype=np.float64).reshape(-1, 2)
        return np.zeros((0, 2))


class MappingCore(MapViews):
    """Scans + odometry in, poses and ``map -> odom`` out (slam or localise).

    Parameters
    ----------
    config : MappingConfig
        Validated parameters.
    clock : callable, optional
        Seconds (monotonic) for the grid republication period; ``time.monotonic``.
    """

    def __init__(self, config: MappingConfig, clock: Any = time.monotonic) -> None:
        self.config = config
        self.clock = clock
        self.book = OdometryBook(config.odom_frame, config.base_frame)
        self.options = (  # checked at start: InvalidParamsError, one line
            config.slam_options() if config.mode == "slam" else config.localise_options()
        )
        self.estimator: Any = None
        self.mount: NDArray[np.float64] | None = (
            np.asarray(config.mount, dtype=np.float64) if config.mount else None
        )
        self.pending: deque[tuple[LaserScan, float]] = deque()  # with the arrival time
        self.counts = Counts()
        self.watch = MappingWatch(
            config.odom_topic or "/tf",
            config.map_frame,
            config.odom_timeout,
            config.max_odom_jump,
            clock,
        )
        self.book.on_input = self.watch.saw
        self.last: Update | None = None
        self._grid_at = -math.inf
        self._grid_keyframes = -1
        self.saved_grid: OccupancyGrid | None = None
        self.saved: SavedMap | None = None
        self._initial: tuple[NDArray[np.float64], NDArray[np.float64] | None] | None = None
        if config.mode == "localise":  # read (and checked) at start: InputError, one line
            self.saved = load_map(config.map)
            self.saved_grid = self.saved.grid
            start = config.pose()
            if start is not None:  # AMCL's set_initial_pose + initial_pose
                self._initial = (np.asarray(start, dtype=np.float64), None)
        if config.output:  # checked now, not after the run: OutputError, one line
            check_output(Path(config.output))

    # ------------------------------------------------------------------ scans
    def add_scan(self, scan: LaserScan) -> list[Update]:
        """Queue a scan; process every queued scan whose odometry is in, in stamp order."""
        self.counts.scans += 1
        self.watch.scan_arrived()
        self.pending.append((scan, self.clock()))
        return self.release()

    def malformed_scan(self) -> None:
        """Count a scan message that could not be read (it arrived, too)."""
        self.counts.scans += 1
        self.counts.malformed += 1
        self.watch.scan_arrived()

    def release(self) -> list[Update]:
        """Process the queued scans that can be (call after new odometry too)."""
        out: list[Update] = []
        now = self.clock()
        while self.pending:
            scan, arrived = self.pending[0]
            assert scan.stamp is not None
            ready = self.book.ready(scan.stamp, scan.frame_id, self.mount is None)
            too_old = now - arrived > self.config.tf_wait
            if not ready and not too_old and len(self.pending) <= self.config.queue_size:
                break
            self.pending.popleft()
            if not ready and self.mount is None:  # odometry but no base -> laser transform
                ready = self.book.ready(scan.stamp, scan.frame_id, False)
            odom = self.book.base_pose(scan.stamp) if ready else None
            if odom is None:
                self.counts.no_odometry += 1
                self.watch.dropped(scan.stamp, self.counts.no_odometry, self.book)
                continue
            update = self._process(scan, odom)
            self.book.forget_before(scan.stamp - ODOMETRY_KEPT_S)  # slam and localise
            if update is not None:
                out.append(update)
        span = self.book.span
        if span is not None:  # the laser may have stopped while the odometry goes on
            self.book.forget_before(span[1] - 2 * ODOMETRY_KEPT_S)
        return out

    def _process(self, scan: LaserScan, odom: NDArray[np.float64]) -> Update | None:
        start = time.perf_counter()
        assert scan.stamp is not None
        if self.estimator is None:
            self._start(scan)
        if self.config.mode == "slam":
            self.watch.processed(scan.stamp, odom, self.book)
            pose, cov = self.estimator.add(scan, odom, scan.stamp)
            update = Update(scan.stamp, pose, cov, map_to_odom(pose, odom))
        else:
            est = self.estimator.add(scan, odom, scan.stamp)
            if est is None:
                self.counts.no_fix += 1
                return None
            update = Update(
                scan.stamp,
                np.asarray(est.pose, dtype=np.float64),
                np.asarray(est.covariance, dtype=np.float64),
                np.asarray(est.map_to_odom, dtype=np.float64),
                str(est.status),
            )
        update.ms = (time.perf_counter() - start) * 1e3
        self.counts.processed += 1
        self.counts.ms.append(update.ms)
        self.last = update
        return update

    def _start(self, scan: LaserScan) -> None:
        """Create the estimator at the first paired scan (the mount is known then)."""
        if self.mount is None:
            found = self.book.mount(scan.frame_id)
            if found is None and self.saved is not None:
                found = tuple(self.saved.mount)  # localise: the map's own mount
            self.mount = np.asarray(found if found is not None else (0.0, 0.0, 0.0))
        if self.config.mode == "slam":
            self.estimator = Slam(self.options, self.mount)
            return
        assert self.saved is not None
        self.estimator = Localiser(self.saved, options=self.options, mount=self.mount)
        if self._initial is not None:
            self.estimator.set_pose(*self._initial)

    def reinitialize(self, saved: SavedMap | None = None) -> bool:
        """localise: forget the pose and hypotheses; the next scans search the whole map
        (a new ``Localiser`` on the same map, or on ``saved``: a map loaded while running).
        False in slam mode."""
        if self.config.mode != "localise":
            return False
        self._initial = None
        if saved is not None:
            self.saved, self.saved_grid = saved, saved.grid
        if self.estimator is not None:
            assert self.saved is not None and self.mount is not None
            self.estimator = Localiser(self.saved, options=self.options, mount=self.mount)
        return True

    def set_pose(self, pose: NDArray[np.float64], covariance: NDArray[np.float64] | None) -> bool:
        """``/initialpose`` (localise): hand it to the localiser (kept until the first scan
        when it comes earlier); False in slam mode."""
        if self.config.mode != "localise":
            return False
        pose = np.asarray(pose, dtype=np.float64).reshape(3)
        if covariance is not None and not np.any(np.asarray(covariance)):
            covariance = None  # an all-zero covariance (some tools send one): the default
        if self.estimator is None:
            self._initial = (pose, covariance)
        else:
            self.estimator.set_pose(pose, covariance=covariance)
        return True

    def summary(self) -> str:
        """Counts and timing, for the log line at shutdown."""
        c = self.counts
        ms = np.asarray(c.ms)
        timing = (
            f", {ms.mean():.2f} ms/scan mean, p95 {np.percentile(ms, 95):.2f}, max {ms.max():.1f}"
            if ms.size
            else ""
        )
        if ms.size < c.processed:  # a long run: the times kept are the last ones
            timing += f" (last {ms.size} scans)"
        w = self.watch
        return (
            f"{c.scans} scans, {c.processed} processed, {c.no_odometry} without odometry, "
            f"{c.malformed} malformed, {len(self.pending)} still waiting, {c.no_fix} before a "
            f"fix; {self.book.n_odometry} odometry samples ({self.watch.pair(self.book)}), "
            f"{w.counts.odom_jumps} odometry jumps; seen on {w.source}: {w.seen_pairs()}{timing}"
        )
