"""``view``: stream a recording's scans and keypoints to rerun (docs/batch-and-viewer.md)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from laser_corners.cli.app import app, fail
from laser_corners.cli.common import (
    InputArg,
    OdomTopicOption,
    TopicOption,
    with_params_choice,
)
from laser_corners.cli.kernels import KernelCommand

if TYPE_CHECKING:
    from laser_corners.pipeline import ParamsChoice

__all__ = ["view"]


@app.command(cls=KernelCommand)
@with_params_choice
def view(
    input_path: InputArg,
    save: Annotated[
        Path | None,
        typer.Option(
            "--save", help="Write a rerun .rrd file instead of opening a viewer (works headless)."
        ),
    ] = None,
    connect: Annotated[
        str | None,
        typer.Option(
            "--connect",
            help="Send to a running rerun viewer at this gRPC address "
            "(rerun+http://127.0.0.1:9876/proxy).",
        ),
    ] = None,
    every: Annotated[int, typer.Option("--every", min=1, help="Log every N-th scan.")] = 1,
    max_scans: Annotated[
        int | None, typer.Option("--max-scans", min=1, help="Stop after this many scans.")
    ] = None,
    topic: TopicOption = None,
    odom_topic: OdomTopicOption = None,
    *,
    choice: ParamsChoice,
) -> None:
    """Stream scans and keypoints (and map-frame keypoints when poses exist) to rerun."""
    from laser_corners.viz.viewer import ViewerUnavailableError, view_recording

    if save is not None and save.is_dir():
        raise fail(f"{save}: is a folder; --save needs a file name")
    try:
        summary = view_recording(
            input_path,
            topic=topic,
            params=choice,
            save=save,
            connect=connect,
            every=every,
            max_scans=max_scans,
            odom_topic=odom_topic,
        )
    except ViewerUnavailableError as exc:
        hint = "" if save is not None else "; use --save FILE.rrd (no display needed)"
        raise fail(f"{exc}{hint}") from None
    where = f"wrote {save}" if save is not None else "sent to the viewer"
    typer.echo(
        f"{where}: {summary.n_scans} scans, {summary.n_keypoints} keypoints"
        f" ({summary.n_with_pose} scans with a pose)"
    )
