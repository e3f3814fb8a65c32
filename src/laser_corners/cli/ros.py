"""ROS commands: ``ros1`` (docs/ros.md); the ``ros2`` command belongs here too."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from laser_corners.cli.app import app

__all__ = ["ros1"]


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

    run_ros1_node(list(ctx.args), debug=debug)
