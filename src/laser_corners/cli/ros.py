"""ROS commands: ``ros1`` and ``ros2``, the live nodes (docs/ros.md)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from laser_corners.cli.app import app

__all__ = ["ros1", "ros2"]


@app.command(
    context_settings={"allow_extra_args": True, "ignore_unknown_options": True},
)
def ros1(
    ctx: typer.Context,
    debug: Annotated[bool, typer.Option("--debug", help="Log per-scan latency.")] = False,
    package_path: Annotated[
        bool,
        typer.Option(
            "--package-path", help="Print the folder to add to ROS_PACKAGE_PATH, then exit."
        ),
    ] = False,
) -> None:
    """Run the ROS 1 node: scan -> corners (PoseArray) and corner_markers (MarkerArray).

    Extra arguments go to rospy: remappings (scan:=/base_scan) and private parameters
    (_preset:=paper, _min_points:=6). See docs/ros.md.
    """
    if package_path:
        from laser_corners import ros

        typer.echo(Path(ros.__file__).resolve().parent)
        return
    from laser_corners.ros.ros1_node import main as run_ros1_node

    raise typer.Exit(run_ros1_node(list(ctx.args), debug=debug))


@app.command(
    context_settings={"allow_extra_args": True, "ignore_unknown_options": True},
)
def ros2(ctx: typer.Context) -> None:
    """Run the ROS 2 node: scan -> corners (PoseArray) and corner_markers (MarkerArray).

    Arguments after --ros-args go to rclpy: remappings (-r scan:=/front/scan), parameters
    (-p preset:=auto, --params-file corners.yaml), --log-level. See docs/ros.md.
    """
    from laser_corners.ros.ros2_node import main as run_ros2_node

    raise typer.Exit(run_ros2_node(list(ctx.args)))
