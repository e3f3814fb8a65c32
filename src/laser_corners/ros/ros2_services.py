"""The services of the ROS 2 node's ``slam`` and ``localise`` modes (rclpy).

``std_srvs/Trigger`` services, each answered after the worker ran its step (so after the
scans that came before the request). They are served by the node's service node on a
thread of its own (``ros2_node._service_node``): while one waits for the worker (a map write
takes seconds), the scan, odometry, parameter and lifecycle callbacks go on.

* ``save_map``: map_server's ``map.yaml`` + ``map.pgm`` of the current grid into ``output``;
* ``serialize_map`` (slam): the whole map folder (what ``localise`` reads) into ``output``;
* ``deserialize_map`` (localise): load the map folder or map_server ``map.yaml`` named by the
  ``map`` parameter now (set it first: ``ros2 param set /laser_corners map /maps/b``) and
  search it globally;
* ``reinitialize_global_localization`` (localise): search the whole map again.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from laser_corners.errors import LaserCornersError, first_line
from laser_corners.registration.mapfolder import load_map
from laser_corners.ros.mapping_worker import MappingWorker
from laser_corners.ros.ros2_outputs import MappingOutputs

__all__ = ["NO_OUTPUT", "MappingServices"]

NO_OUTPUT = "no output folder: start the node with -p output:=DIR"
NAMES = ("save_map", "serialize_map", "deserialize_map", "reinitialize_global_localization")


class MappingServices:
    """The ``std_srvs/Trigger`` services of the mapping modes on ``node``.

    Parameters
    ----------
    node : rclpy.node.Node
        The node.
    m : SimpleNamespace
        The message classes (``m.Trigger`` None without ``std_srvs``: no services, one
        warning).
    worker : MappingWorker
        Runs each service's step after the steps before it.
    outputs : MappingOutputs
        Republishes the map a ``deserialize_map`` loaded.
    map_path : callable
        The ``map`` parameter's current value.
    """

    def __init__(
        self,
        node: Any,
        m: SimpleNamespace,
        worker: MappingWorker,
        outputs: MappingOutputs,
        map_path: Callable[[], str],
    ) -> None:
        self.node, self.worker, self.outputs, self.map_path = node, worker, outputs, map_path
        self.core = worker.core
        self.config = self.core.config
        self.started = time.monotonic()
        self.services: list[Any] = []
        if m.Trigger is None:
            node.get_logger().warning(
                f"std_srvs is not importable: no {', '.join(NAMES)} services "
                "(pip install 'laser-corners[ros2]')"
            )
            return
        callbacks = (self.on_save_map, self.on_serialize_map, self.on_deserialize_map)
        callbacks += (self.on_reinitialize,)
        # on the node's service node when it has one (its own thread): a wait for the worker
        # holds none of the node's callbacks; the names as the node resolves them
        self.host = getattr(node, "service_node", None) or node
        for name, callback in zip(NAMES, callbacks, strict=True):
            full = name if self.host is node else node.resolve_service_name(name)
            self.services.append(self.host.create_service(m.Trigger, full, callback))

    def close(self) -> None:
        """Remove the services."""
        for service in self.services:
            self.host.destroy_service(service)
        self.services = []

    def _answer(self, response: Any, service: str, step: Callable[[], tuple[bool, str]]) -> Any:
        """Fill a Trigger response from ``step() -> (success, message)``, run on the worker
        (after the scans before it); log it."""
        try:
            ok, text = self.worker.submit(step).result()
        except LaserCornersError as exc:
            ok, text = False, first_line(exc)
        response.success, response.message = bool(ok), text
        if ok:  # two call sites: rclpy refuses one site logging at two severities
            self.node.get_logger().info(f"{service}: {text}")
        else:
            self.node.get_logger().warning(f"{service}: {text}")
        return response

    def on_save_map(self, request: Any, response: Any) -> Any:
        """``save_map``: map_server's map.yaml + map.pgm of the current grid into ``output``."""

        def step() -> tuple[bool, str]:
            if not self.config.output:
                return False, NO_OUTPUT
            path = self.core.save_grid(Path(self.config.output))
            return True, f"wrote {path}, {path.with_suffix('.pgm')}"

        return self._answer(response, "save_map", step)

    def on_serialize_map(self, request: Any, response: Any) -> Any:
        """``serialize_map`` (slam): the whole map folder (what ``localise`` reads) into
        ``output``, as at shutdown."""

        def step() -> tuple[bool, str]:
            if self.config.mode != "slam":
                return False, "mode localise: the map is the input here (needs mode slam)"
            if not self.config.output:
                return False, NO_OUTPUT
            wall = time.monotonic() - self.started
            folder = self.core.write_map(Path(self.config.output), wall)
            if folder is None:
                return False, "nothing mapped yet"
            return True, f"wrote the map folder {folder}"

        return self._answer(response, "serialize_map", step)

    def on_deserialize_map(self, request: Any, response: Any) -> Any:
        """``deserialize_map`` (localise): load the map the ``map`` parameter names now (a
        map folder or a map_server ``map.yaml``), republish it and search it globally; a map
        that cannot be read leaves the current one in place."""

        def step() -> tuple[bool, str]:
            if self.config.mode != "localise":
                return False, "mode slam: a map is loaded in mode localise only"
            path = self.map_path()
            saved = load_map(path)  # InputError: one line, the current map stays
            self.core.reinitialize(saved)
            self.outputs.publish_map()
            return True, f"loaded {path} ({len(saved)} keyframes); global search from the next scan"

        return self._answer(response, "deserialize_map", step)

    def on_reinitialize(self, request: Any, response: Any) -> Any:
        """``reinitialize_global_localization`` (localise): search the whole map again."""

        def step() -> tuple[bool, str]:
            if self.core.reinitialize():
                return True, "global search from the next scan"
            return False, "nothing to reinitialize in mode slam (mode localise only)"

        return self._answer(response, "reinitialize_global_localization", step)
