"""``simulate``, ``demo`` and ``warmup`` (docs/simulation-and-accuracy.md)."""

from __future__ import annotations

import importlib.util
import time
from pathlib import Path
from typing import Annotated

import typer

from laser_corners.cli.app import app
from laser_corners.cli.common import check_number, image_file, new_folder
from laser_corners.cli.kernels import KernelCommand, warm_slam_kernels

__all__ = ["demo", "simulate", "warmup"]


@app.command(cls=KernelCommand)
def demo(
    output: Annotated[
        Path, typer.Option("--output", "-o", help="Image to write (.png, .pdf, .svg ...).")
    ] = Path("demo.png"),
    noise: Annotated[float, typer.Option(help="Range noise sigma, metres.")] = 0.005,
) -> None:
    """Simulate a UST-10LX scan of a room, detect corners, compare with the truth, plot."""
    check_number("--noise", noise, minimum=0.0)
    from laser_corners.demo import run_demo

    path, _ = image_file(output)
    missed = run_demo(path, noise_sigma=noise)
    if missed:
        raise typer.Exit(1)


@app.command()
def simulate(
    output: Annotated[
        Path, typer.Option("--output", "-o", help="Folder for scans.npz, truth.npz, scans.bag.")
    ] = Path("sim"),
    world: Annotated[
        str, typer.Option(help="World kind: room, l_room, corridor or random.")
    ] = "random",
    sensor: Annotated[
        str, typer.Option(help="Sensor: ust-10lx, sick-1deg, sick-0.5deg, hokuyo-0.352deg.")
    ] = "ust-10lx",
    noise: Annotated[
        float | None,
        typer.Option(help="Range noise sigma, metres (default: the sensor's spec)."),
    ] = None,
    scans: Annotated[int, typer.Option(min=1, help="Number of scans.")] = 200,
    speed: Annotated[float, typer.Option(help="Robot speed, m/s.")] = 0.5,
    seed: Annotated[int, typer.Option(help="Random seed (world, trajectory, noise).")] = 0,
    bag: Annotated[bool, typer.Option("--bag/--no-bag", help="Also write a ROS 1 bag.")] = True,
) -> None:
    """Simulate a drive through a random world: scans, ground-truth corners, a ROS bag."""
    check_number("--noise", noise, minimum=0.0)
    check_number("--speed", speed, minimum=0.0)
    import numpy as np

    from laser_corners.sim import get_sensor, random_world, trajectory
    from laser_corners.sim.export import simulate_sequence, write_sequence

    profile = get_sensor(sensor)
    new_folder(output)
    rng = np.random.default_rng(seed)
    the_world = random_world(rng, None if world == "random" else world)
    poses = trajectory(the_world, scans, rng, rate_hz=profile.rate_hz, speed=speed)
    sigma = profile.range_noise_sigma if noise is None else noise
    sequence = simulate_sequence(the_world, profile, poses, sigma, rng)
    paths = write_sequence(sequence, output, bag=bag)
    typer.echo(
        f"{the_world.name}: {len(the_world.corners)} corners, {scans} scans of {profile.name} "
        f"(noise sigma {sigma} m), {int(sequence.visible.sum())} visible corner sightings"
    )
    for path in paths.values():
        typer.echo(f"wrote {path}")


@app.command(cls=KernelCommand)
def warmup() -> None:
    """Compile (or load) the kernels of the detector, then of the SLAM, the localiser and the
    matching, now, so the first real run starts at once."""
    import numpy as np

    from laser_corners import CornerDetector, LaserScan

    start = time.perf_counter()
    angles = np.linspace(-np.pi / 2, np.pi / 2, 181)  # a 6 m x 4 m room, sensor in the middle
    along_x = 3.0 / np.maximum(np.abs(np.cos(angles)), 1e-9)
    along_y = 2.0 / np.maximum(np.abs(np.sin(angles)), 1e-9)
    scan = LaserScan(np.minimum(along_x, along_y), -np.pi / 2, np.pi / 180, 0.05, 30.0)
    detector = CornerDetector()
    keypoints = detector.detect(scan)
    _ = keypoints.cov  # the covariance kernels are lazy
    many = detector.detect_many([scan, scan])
    _ = [k.cov for k in many]
    typer.echo(f"detector kernels ready in {time.perf_counter() - start:.1f} s")
    if importlib.util.find_spec("gtsam") is None:  # the slam extra is optional
        typer.echo("SLAM, localiser and matching kernels: not compiled (no gtsam: the slam extra)")
        return
    start = time.perf_counter()
    warm_slam_kernels()
    typer.echo(f"SLAM, localiser and matching kernels ready in {time.perf_counter() - start:.1f} s")
