"""The later visit through the ROS 2 node's localise mode (``bench_localise.py --ros2``).

The node's ROS-free core (:class:`~laser_corners.ros.slam_core.MappingCore`) is given the
bag's messages as the node gets them, in the bag's log-time order (``ros2 bag play``):

* the configured :class:`~laser_corners.localise.LocaliseOptions` become the node's
  parameters (:func:`node_parameters`: every field that differs from its default, by its
  parameter name, ``places.min_votes``; the map folder as ``map``; the odometry topic the CLI
  reads as ``odom_topic``) and :meth:`MappingConfig.from_mapping` turns them into the config,
  as the rclpy adapter does;
* each message goes through the node's own conversion (``scan_from_msg``, ``odometry_of``,
  ``transform_of``) into the core's calls (``add_scan``, ``book.add_odometry`` +
  ``release``, ``book.add_transforms`` + ``release``); with ``odom_topic`` set the node does
  not subscribe ``/tf``, so ``/tf`` is left out (``/tf_static`` is read);
* the node starts one second (of stamps) before the visit's first scan: odometry stamped from
  then on, the scans of the visit (stamp from the half on);
* real-time semantics: the core's clock (``tf_wait``, the queue) is the log time of the
  message being given, and a scan is processed when the core releases it (the replay waits for
  it, so the worker's queue of a live node, which drops scans when processing lags behind,
  does not come in).

The online estimate of a scan is the pose the node publishes for it (``Update.pose`` on
``amcl_pose``); *held* poses (every scan from the first estimate on) are the last published
``map -> odom`` composed with the node's odometry at the scan's stamp.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from laser_corners.localise import LocaliseOptions
from laser_corners.pipeline.recording import open_recording
from laser_corners.pose import compose_many
from laser_corners.ros.convert import scan_from_msg
from laser_corners.ros.mapping_config import MappingConfig, estimator_parameters
from laser_corners.ros.nav_convert import odometry_of, transform_of
from laser_corners.ros.slam_core import MappingCore, Update
from laser_corners.scan import LaserScan

ODOMETRY = "nav_msgs/msg/Odometry"
START_BEFORE_S = 1.0
"""The node starts this long (stamps) before the visit's first scan."""


def _field(options: LocaliseOptions, name: str) -> Any:
    value: Any = options
    for part in name.split("."):
        value = getattr(value, part)
    return value


def node_parameters(folder: Path, options: LocaliseOptions, odom_topic: str | None) -> dict:
    """The node's parameters for localise mode in ``folder`` with ``options``: the options
    that differ from the defaults by their parameter names, the map, the odometry topic."""
    params: dict[str, Any] = {"mode": "localise", "map": str(folder)}
    if odom_topic and odom_topic != "tf":
        params["odom_topic"] = odom_topic
    default = LocaliseOptions()
    for name in estimator_parameters("localise"):
        value = _field(options, name)
        if value != _field(default, name):
            params[name] = list(value) if isinstance(value, tuple) else value
    if options.mount is not None:
        params["mount"] = [float(v) for v in options.mount]
    return params


@dataclass
class Processed:
    """One scan the core processed: its stamp, odometry, what the node published (None: no
    estimate), the lost track's dead-reckoned pose then (None: no window), CPU ms, and
    whether the localiser was tracking when it came."""

    stamp: float
    odom: np.ndarray
    update: Update | None
    window: np.ndarray | None
    cpu_ms: float
    tracking: bool


class ReplayCore(MappingCore):
    """The node's core, noting each scan it processes (in the order it processes them)."""

    def __init__(self, config: MappingConfig, clock: Any) -> None:
        super().__init__(config, clock=clock)
        self.processed_scans: list[Processed] = []

    def _process(self, scan: LaserScan, odom: np.ndarray) -> Update | None:
        tracking = self.estimator is not None and self.estimator.status == "tracking"
        cpu = time.process_time()
        update = super()._process(scan, odom)
        cpu_ms = (time.process_time() - cpu) * 1e3
        window = self.estimator.window
        dead = None if update is not None or window is None else np.array(window.pose)
        assert scan.stamp is not None
        done = Processed(float(scan.stamp), np.array(odom), update, dead, cpu_ms, tracking)
        self.processed_scans.append(done)
        return update


@dataclass
class Replay:
    """What the node's core did with the visit: the scans processed and its counts."""

    core: ReplayCore
    parameters: dict
    odometry_frame: Any = None
    scans_given: int = 0
    messages: dict[str, int] = field(default_factory=dict)


class _Clock:
    now = 0.0

    def __call__(self) -> float:
        return self.now


def parse_parameters(pairs: list[str]) -> dict[str, Any]:
    """``NAME=VALUE`` strings (``--ros2-param``) as node parameters, each value read as YAML
    (``tf_wait=5`` is a float, ``odom_topic=tf`` a string), as ``ros2 run -p`` reads them."""
    params = {}
    for pair in pairs:
        name, sep, value = pair.partition("=")
        if not sep or not name:
            raise SystemExit(f"--ros2-param {pair!r}: expected NAME=VALUE")
        params[name.strip()] = yaml.safe_load(value)
    return params


def replay(
    path: Path,
    folder: Path,
    options: LocaliseOptions,
    t_start: float,
    t_end: float | None = None,
    extra: dict[str, Any] | None = None,
    odometry_frame: Any = None,
) -> Replay:
    """Give the bag's messages to the node's core in localise mode in ``folder``: the scans
    stamped from ``t_start`` (to ``t_end``), odometry from ``START_BEFORE_S`` before;
    ``extra``: node parameters over those of :func:`node_parameters`; ``odometry_frame``
    (x, y, yaw): the odometry messages' poses moved by it (the localiser's odometry in a frame
    of its own, as :mod:`bench_localise` gives the CLI's; an odometry topic only)."""
    with open_recording(path, None) as rec:
        source = rec.source
        params = {**node_parameters(folder, options, source.odom_topic), **(extra or {})}
        clock = _Clock()
        core = ReplayCore(MappingConfig.from_mapping(params), clock)
        config = core.config
        topics = [source.topic, "/tf_static"]
        topics.append(config.odom_topic if config.odom_topic else "/tf")
        if odometry_frame is not None and not config.odom_topic:
            raise SystemExit("an odometry frame needs an odometry topic (the odometry on /tf)")
        run = Replay(core, params, odometry_frame)
        with source.reader() as reader:
            for connection, log_time, raw in source.messages(reader, topics):
                clock.now = log_time * 1e-9
                msg = reader.deserialize(raw, connection.msgtype)
                run.messages[connection.topic] = run.messages.get(connection.topic, 0) + 1
                _give(core, run, connection, msg, (t_start, t_end))
    return run


def _give(core: ReplayCore, run: Replay, connection: Any, msg: Any, span: tuple) -> None:
    """One message into the core, as the rclpy adapter's callbacks do."""
    t_start, t_end = span
    if connection.topic == "/tf_static":
        core.book.add_transforms([transform_of(ts) for ts in msg.transforms], True)
        core.release()
    elif connection.msgtype == ODOMETRY:
        sample = odometry_of(msg)
        if run.odometry_frame is not None:
            moved = compose_many(np.asarray(run.odometry_frame), np.asarray(sample[3]))
            sample = (*sample[:3], tuple(map(float, moved)))
        if sample[2] >= t_start - START_BEFORE_S:
            core.book.add_odometry(*sample)
            core.release()
    elif connection.topic == "/tf":
        transforms = [transform_of(ts) for ts in msg.transforms]
        moving = [t for t in transforms if t[2] >= t_start - START_BEFORE_S]
        if moving:
            core.book.add_transforms(moving, False)
            core.release()
    else:
        scan = scan_from_msg(msg)
        assert scan.stamp is not None
        if scan.stamp >= t_start - 1e-4 and (t_end is None or scan.stamp < t_end - 1e-4):
            run.scans_given += 1
            core.add_scan(scan)


def published(run: Replay, stamps: np.ndarray) -> dict:
    """The node's output per processed scan as the benchmark scores it: estimates (stamp,
    pose, scan index into ``stamps``, status), held poses, dead-reckoned poses, CPU ms of the
    scans given while tracking, and the scan index of each processed scan (``given``)."""
    out: dict[str, list] = {
        k: [] for k in ("est_t", "est_p", "est_i", "est_s", "held_t", "held_p", "dead_t")
    }
    out.update(dead_p=[], cpu_tracking=[], given=[])
    map_to_odom = None
    for p in run.core.processed_scans:
        i = int(np.clip(np.searchsorted(stamps, p.stamp - 1e-4), 0, len(stamps) - 1))
        out["given"].append(i)
        if p.tracking:
            out["cpu_tracking"].append(p.cpu_ms)
        if p.update is not None:
            out["est_t"].append(stamps[i])
            out["est_p"].append(p.update.pose)
            out["est_i"].append(i)
            out["est_s"].append(p.update.status)
            map_to_odom = p.update.map_to_odom
        elif p.window is not None:
            out["dead_t"].append(stamps[i])
            out["dead_p"].append(p.window)
        if map_to_odom is not None:
            out["held_t"].append(stamps[i])
            out["held_p"].append(compose_many(map_to_odom, p.odom))
    return out
