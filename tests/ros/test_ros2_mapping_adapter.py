"""The rclpy adapter of the slam mode on its ``/tf`` path, without DDS.

The end-to-end test over DDS (``test_ros2_slam_node.py``) runs this path with the
``tf2_msgs`` that ``ros2/build_tf2_msgs.sh`` builds; here the adapter runs on a recording
stand-in for the node, with rclpy's real message classes and a stand-in ``TFMessage``, so it
runs without that build too: odometry and the mount come in as ``/tf`` and ``/tf_static``
transforms, ``map -> odom`` goes out on ``/tf``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from ros_helpers import isolated_message_packages, skip_or_fail

pytest.importorskip("gtsam")

from laser_corners.pose import compose_many
from laser_corners.sim import SICK_LMS_1DEG, World

pytestmark = [
    pytest.mark.ros2,
    pytest.mark.filterwarnings("ignore:module 'sre_:DeprecationWarning"),
]

MOUNT = (0.2, 0.0, 0.05)


@pytest.fixture(scope="module")
def ros2_messages() -> Iterator[None]:
    with isolated_message_packages():
        try:
            import nav_msgs.msg  # noqa: F401
            import rclpy  # noqa: F401
        except ImportError as exc:
            skip_or_fail(f"rclpy / nav_msgs not importable ({exc}): pip install -e '.[ros2]'")
        yield


class FakeTF:
    """Stands in for ``tf2_msgs/TFMessage``."""

    def __init__(self, transforms: list[Any] | None = None) -> None:
        self.transforms = list(transforms or [])


class Publisher:
    def __init__(self, topic: str) -> None:
        self.topic_name, self.published = topic, []

    def publish(self, msg: Any) -> None:
        self.published.append(msg)


class Node:
    """Records what the adapter creates and logs."""

    def __init__(self) -> None:
        self.pubs: dict[str, Publisher] = {}
        self.subs: dict[str, Any] = {}
        self.services: dict[str, Any] = {}
        self.logs: list[str] = []
        logger = SimpleNamespace(
            info=self.logs.append,
            debug=lambda text: None,
            warning=lambda text, **kw: self.logs.append(text),
            error=lambda text, **kw: self.logs.append(text),
        )
        self.get_logger = lambda: logger

    def create_publisher(self, cls: Any, topic: str, qos: Any) -> Publisher:
        self.pubs[topic] = Publisher(topic)
        return self.pubs[topic]

    def create_subscription(
        self, cls: Any, topic: str, callback: Any, qos: Any, **kwargs: Any
    ) -> Any:
        self.subs[topic] = callback
        return SimpleNamespace(topic_name=topic)

    def create_timer(self, period: float, callback: Any) -> None:
        self.timer = callback

    def create_service(self, cls: Any, name: str, callback: Any, **kwargs: Any) -> None:
        self.services[name] = callback


def _transform(parent: str, child: str, stamp: float, pose: Any) -> Any:
    from geometry_msgs.msg import TransformStamped

    from laser_corners.ros.convert import seconds_to_sec_nanosec
    from laser_corners.ros.nav_convert import fill_transform

    ts = fill_transform(TransformStamped(), parent, child, pose)
    ts.header.stamp.sec, ts.header.stamp.nanosec = seconds_to_sec_nanosec(stamp)
    return ts


def _slam_adapter(monkeypatch: pytest.MonkeyPatch) -> tuple[Node, Any]:
    """A slam-mode ``MappingAdapter`` on a recording :class:`Node`, with :class:`FakeTF` as
    the ``TFMessage`` class, activated (it subscribes at activate, as a managed node)."""
    from laser_corners.ros import ros2_mapping

    real = ros2_mapping.messages

    def with_tf() -> SimpleNamespace:
        m = real()
        m.tf = FakeTF
        return m

    monkeypatch.setattr(ros2_mapping, "messages", with_tf)
    node = Node()
    adapter = ros2_mapping.MappingAdapter(node, {"mode": "slam"})
    adapter.activate()
    return node, adapter


def test_slam_mode_reads_and_writes_tf(ros2_messages: None, monkeypatch) -> None:
    from ros2_replay import to_msg

    from laser_corners.ros.nav_convert import transform_of

    node, adapter = _slam_adapter(monkeypatch)
    assert {"/tf", "/tf_static", "scan"} <= set(node.subs) and "/tf" in node.pubs
    assert "map_to_odom" not in node.pubs

    world = World().add_polygon([[0, 0], [12, 0], [12, 8], [0, 8]])
    world.add_polygon([[2.5, 2.5], [3.3, 2.5], [3.3, 3.2], [2.5, 3.2]])
    truth = np.array([(1.5 + 0.05 * i, 1.5, 0.02 * i) for i in range(30)])
    odom = compose_many(np.array([0.3, -0.2, 0.1]), truth)  # the odometry frame is not the map
    laser = compose_many(truth, np.asarray(MOUNT))
    rng = np.random.default_rng(0)
    node.subs["/tf_static"](FakeTF([_transform("base_link", "laser", 0.0, MOUNT)]))
    for i, pose in enumerate(laser):
        t = i / 10.0
        scan = world.scan(tuple(pose), SICK_LMS_1DEG, noise_sigma=0.005, rng=rng, stamp=t)
        node.subs["/tf"](FakeTF([_transform("odom", "base_link", t, odom[i])]))
        node.subs["/tf"](FakeTF([_transform("odom", "base_link", t + 0.05, odom[i])]))
        node.subs["scan"](to_msg(dataclasses.replace(scan, frame_id="laser")))

    adapter.drain()  # the core runs on the adapter's worker thread
    sent = [ts for msg in node.pubs["/tf"].published for ts in msg.transforms]
    poses = node.pubs["pose"].published
    assert len(sent) == len(poses) == len(truth), node.logs
    np.testing.assert_allclose(adapter.core.estimator.mount, MOUNT)  # from /tf_static
    for i, (ts, pose_msg) in enumerate(zip(sent, poses, strict=True)):
        parent, child, stamp, map_to_odom = transform_of(ts)
        # future-dated by transform_tolerance (default 0.1 s), as AMCL does
        assert (parent, child) == ("map", "odom") and stamp == pytest.approx(i / 10.0 + 0.1)
        o = pose_msg.pose.pose
        pose = (o.position.x, o.position.y, 2 * np.arctan2(o.orientation.z, o.orientation.w))
        np.testing.assert_allclose(
            compose_many(np.array(map_to_odom), odom[i])[:2], pose[:2], atol=1e-6
        )
    node.subs["scan"](SimpleNamespace(header=None))  # malformed: logged, counted, no raise
    adapter.drain()
    assert adapter.core.counts.malformed == 1  # counted with the scans that arrived
    assert any("malformed scan" in line for line in node.logs)


def test_an_error_on_the_worker_is_logged_not_lost(ros2_messages: None, monkeypatch) -> None:
    """The callbacks hand their work to the adapter's worker thread: an error there is a
    skipped message (known errors) or an error line (others), counted, never a silent loss
    in an unread future, and the worker goes on."""
    from laser_corners.errors import InputError

    node, adapter = _slam_adapter(monkeypatch)
    calls = []

    def refuse(transforms, static):
        calls.append(static)
        if len(calls) == 1:
            raise InputError("a bad transform")
        raise RuntimeError("a bug")

    monkeypatch.setattr(adapter.core.book, "add_transforms", refuse)
    node.subs["/tf"](FakeTF([_transform("odom", "base_link", 0.0, (0.0, 0.0, 0.0))]))
    node.subs["/tf"](FakeTF([_transform("odom", "base_link", 0.1, (0.0, 0.0, 0.0))]))
    adapter.drain()
    assert calls == [False, False]  # both ran, the worker went on after the first error
    assert any(line == "skipped a tf message: a bad transform" for line in node.logs)
    assert any("a tf message failed: RuntimeError('a bug')" in line for line in node.logs)
    assert "2 messages skipped" in adapter.summary()


def test_no_class_of_the_ros_room_is_over_250_lines() -> None:
    """Issue 33: no class over 250 lines (MappingAdapter had 375): split by concern."""
    import ast
    from pathlib import Path

    import laser_corners.ros

    room = Path(laser_corners.ros.__file__).parent
    sizes = {
        f"{path.name}:{node.name}": node.end_lineno - node.lineno + 1
        for path in room.rglob("*.py")
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.ClassDef)
    }
    assert "ros2_mapping.py:MappingAdapter" in sizes
    assert {name: n for name, n in sizes.items() if n > 250} == {}
