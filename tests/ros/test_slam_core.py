"""The ROS-free core of the ROS 2 node's slam / localise modes, without ROS.

Scans of a simulated building with known poses; odometry arrives as ``/tf``-like transforms
(``odom -> base_link``) or ``nav_msgs/Odometry``-like samples, the mount on ``/tf_static``.
"""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("gtsam")

from laser_corners.errors import InputError, InvalidParamsError, InvalidScanError
from laser_corners.io.occupancy import OccupancyGrid
from laser_corners.io.poses import FORGET_BATCH
from laser_corners.localise import (
    EngineOptions,
    LocaliseOptions,
    Localiser,
    SmoothOptions,
    estimate,
)
from laser_corners.pose import compose_many, invert_many
from laser_corners.registration.mapfolder import load_map
from laser_corners.registration.odometry import OdometryNoise
from laser_corners.registration.place_index import PlaceOptions
from laser_corners.ros.nav_convert import (
    fill_occupancy_grid,
    fill_pose_with_covariance,
    fill_transform,
    landmark_marker_fields,
    odometry_of,
    pose_with_covariance_of,
    transform_of,
)
from laser_corners.ros.slam_core import (
    ODOMETRY_KEPT_S,
    MappingConfig,
    MappingCore,
    OdometryBook,
    map_to_odom,
)
from laser_corners.sim import SICK_LMS_1DEG, World

RATE = 10.0
MOUNT = (0.2, -0.05, 0.1)


def _world() -> World:
    world = World().add_polygon([[0, 0], [12, 0], [12, 8], [0, 8]])
    world.add_polygon([[2.5, 2.5], [3.3, 2.5], [3.3, 3.2], [2.5, 3.2]])
    world.add_polygon([[9, 5.5], [10, 5.5], [9.5, 6.4]])
    return world


def _drive(n: int = 60) -> tuple[np.ndarray, list]:
    """Base poses along x at 0.4 m/s and their scans (frame ``laser``)."""
    truth = np.array([(1.5 + 0.04 * i, 1.5 + 0.01 * i, 0.02 * i) for i in range(n)])
    world, rng = _world(), np.random.default_rng(1)
    laser = compose_many(truth, np.asarray(MOUNT))
    scans = [
        dataclasses.replace(
            world.scan(tuple(p), SICK_LMS_1DEG, noise_sigma=0.005, rng=rng, stamp=i / RATE),
            frame_id="laser",
        )
        for i, p in enumerate(laser)
    ]
    return truth, scans


def _tf(parent: str, child: str, stamp: float, pose) -> tuple:
    return (parent, child, stamp, tuple(float(v) for v in pose))


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_map_to_odom_puts_the_base_at_its_map_pose() -> None:
    rng = np.random.default_rng(0)
    for _ in range(20):
        pose = rng.uniform([-50, -50, -np.pi], [50, 50, np.pi])
        odom = rng.uniform([-50, -50, -np.pi], [50, 50, np.pi])
        np.testing.assert_allclose(compose_many(map_to_odom(pose, odom), odom), pose, atol=1e-9)


def test_odometry_book_interpolates_tf_and_chains_the_static_mount() -> None:
    book = OdometryBook()
    book.add_transforms(
        [_tf("base_link", "mast", 0, (0.1, 0, 0)), _tf("mast", "laser", 0, (0.1, -0.05, 0.1))],
        static=True,
    )
    book.add_transforms([_tf("odom", "base_link", 1.0, (1.0, 0.0, 0.0))], static=False)
    assert not book.ready(1.5, "laser", need_mount=True)  # no odometry after the stamp yet
    book.add_transforms([_tf("odom", "base_link", 2.0, (2.0, 1.0, 0.4))], static=False)
    assert book.ready(1.5, "laser", need_mount=True)
    assert not book.ready(1.5, "camera", need_mount=True)  # no chain base -> camera
    np.testing.assert_allclose(book.base_pose(1.5), [1.5, 0.5, 0.2])
    np.testing.assert_allclose(book.mount("laser"), MOUNT, atol=1e-12)
    assert (book.odom_frame, book.base_frame) == ("odom", "base_link")
    book.add_odometry("other_odom", "base_link", 3.0, (9, 9, 0))  # another odometry: ignored
    book.add_odometry("odom", "base_link", 1.0, (5, 5, 0))  # a repeated stamp: ignored
    np.testing.assert_allclose(book.base_pose(1.0), [1.0, 0.0, 0.0])
    np.testing.assert_allclose(book.base_pose(2.0), [2.0, 1.0, 0.4])


def _core(clock=None, **values) -> MappingCore:
    config = MappingConfig.from_mapping({"mode": "slam", **values})
    return MappingCore(config, clock=clock or Clock())


def test_scans_wait_for_odometry_and_come_out_in_order() -> None:
    truth, scans = _drive(40)
    core = _core()
    core.book.add_transforms([_tf("base_link", "laser", 0, MOUNT)], static=True)
    # the scans arrive before the odometry of their stamp (as over DDS: tf lags)
    out = []
    for i, scan in enumerate(scans):
        out += core.add_scan(scan)
        if i >= 3:
            j = i - 3
            core.book.add_transforms([_tf("odom", "base_link", j / RATE, truth[j])], False)
            out += core.release()
    assert [u.stamp for u in out] == sorted(u.stamp for u in out)
    assert len(out) == len(scans) - 4  # the last ones wait for odometry after their stamp
    assert core.counts.no_odometry == 0
    np.testing.assert_allclose(core.estimator.mount, MOUNT)  # the mount came from /tf_static
    # odometry is exact here: the map pose is the odometry pose, map -> odom is ~identity
    for update in out:
        i = round(update.stamp * RATE)
        np.testing.assert_allclose(update.pose, truth[i], atol=0.03)
        assert abs(update.map_to_odom[:2]).max() < 0.03
        assert update.covariance.shape == (3, 3)
        assert np.all(np.linalg.eigvalsh(update.covariance) > 0)


def test_map_to_odom_absorbs_odometry_drift() -> None:
    """Odometry rotated by 10 degrees about its start: map -> odom undoes it."""
    truth, scans = _drive(40)
    drift = np.array([0.5, -0.3, math.radians(10)])
    odom = compose_many(drift, truth)  # odometry frame offset from the map
    core = _core(mount=list(MOUNT))
    out = []
    for i, scan in enumerate(scans):
        core.book.add_odometry("odom", "base_link", i / RATE, odom[i])
        core.book.add_odometry("odom", "base_link", (i + 0.5) / RATE, odom[i])
        out += core.add_scan(scan)
    assert len(out) == len(scans)
    first = out[0]  # SLAM starts its map at the first odometry pose
    np.testing.assert_allclose(first.map_to_odom, [0, 0, 0], atol=1e-9)
    # every later map pose is map_to_odom ∘ odometry
    for update in out:
        i = round(update.stamp * RATE)
        np.testing.assert_allclose(
            compose_many(update.map_to_odom, odom[i]), update.pose, atol=1e-9
        )


def test_scans_without_odometry_are_dropped_and_counted() -> None:
    """A scan waits ``tf_wait`` seconds (wall clock) after it arrived, then is dropped."""
    _, scans = _drive(30)
    clock = Clock()
    core = _core(clock, mount=list(MOUNT), tf_wait=0.5)
    for scan in scans:
        clock.now += 0.1
        assert core.add_scan(scan) == []
    assert core.counts.no_odometry == len(scans) - 5  # kept: those that arrived < 0.5 s ago
    assert len(core.pending) == 5
    clock.now += 10.0
    assert core.release() == [] and core.counts.no_odometry == len(scans)


def test_a_full_queue_drops_its_oldest_scans() -> None:
    _, scans = _drive(30)
    core = _core(mount=list(MOUNT), tf_wait=60.0, queue_size=10)
    for scan in scans:
        core.add_scan(scan)
    assert len(core.pending) == 10
    assert core.counts.no_odometry == 20


def test_grid_is_due_after_the_period_and_new_keyframes() -> None:
    truth, scans = _drive(60)
    clock = Clock()
    core = _core(clock, mount=list(MOUNT), map_period=2.0)
    assert not core.grid_due() and core.grid() is None  # nothing mapped yet
    for i, scan in enumerate(scans[:30]):
        core.book.add_odometry("odom", "base_link", i / RATE, truth[i])
        core.book.add_odometry("odom", "base_link", (i + 0.5) / RATE, truth[i])
        core.add_scan(scan)
    assert core.grid_due()
    grid = core.grid()
    assert isinstance(grid, OccupancyGrid)
    rows, cols = grid.shape
    assert 6 < cols * grid.resolution < 16 and 4 < rows * grid.resolution < 12  # the room
    occ = grid.occupancy
    assert (occ >= 65).sum() > 100 and ((occ >= 0) & (occ < 50)).sum() > 1000
    assert not core.grid_due()  # just built
    clock.now = 5.0
    assert not core.grid_due()  # the period passed, but no new keyframe
    for i, scan in enumerate(scans[30:], start=30):
        core.book.add_odometry("odom", "base_link", i / RATE, truth[i])
        core.book.add_odometry("odom", "base_link", (i + 0.5) / RATE, truth[i])
        core.add_scan(scan)
    assert core.grid_due()


def test_write_map_writes_the_slam_folder(tmp_path) -> None:
    truth, scans = _drive(30)
    core = _core(mount=list(MOUNT), output=str(tmp_path / "out"))
    assert core.write_map(tmp_path / "none", 1.0) is None  # nothing mapped
    for i, scan in enumerate(scans):
        core.book.add_odometry("odom", "base_link", i / RATE, truth[i])
        core.book.add_odometry("odom", "base_link", (i + 0.5) / RATE, truth[i])
        core.add_scan(scan)
    folder = core.write_map(tmp_path / "out", 3.0)
    names = {p.name for p in folder.iterdir()}
    assert {"trajectory.tum", "map.pgm", "map.yaml", "summary.json", "graph.g2o"} <= names
    lines = (folder / "trajectory.tum").read_text().splitlines()
    assert len([line for line in lines if not line.startswith("#")]) == len(scans)


@pytest.mark.parametrize(
    ("values", "message"),
    [
        ({"mode": "slam", "mape": "x"}, "ROS 2 parameters: unknown parameter 'mape'"),
        ({"mode": "slam", "mount": [1.0, 2.0]}, "mount: expected [x, y, yaw]"),
        ({"mode": "localise"}, "map: mode localise needs -p map:=DIR (or a map_server .yaml)"),
        ({"mode": "slam", "map_period": 0.0}, "map_period"),
        ({"mode": "slam", "queue_size": "many"}, "queue_size"),
    ],
)
def test_invalid_parameters_give_one_line(values, message) -> None:
    with pytest.raises(InvalidParamsError) as err:
        MappingConfig.from_mapping(values)
    assert message in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize(("given", "kept"), [("tf", ""), ("/tf", ""), ("", ""), ("odom", "odom")])
def test_odom_topic_tf_means_the_odometry_on_tf(given: str, kept: str) -> None:
    config = MappingConfig.from_mapping({"mode": "slam", "odom_topic": given})
    assert config.odom_topic == kept


def test_missing_map_folder_is_one_line(tmp_path) -> None:
    config = MappingConfig.from_mapping({"mode": "localise", "map": str(tmp_path / "nope")})
    with pytest.raises(InputError, match="nope: no such map folder"):
        MappingCore(config)
    (tmp_path / "empty").mkdir()
    config = MappingConfig.from_mapping({"mode": "localise", "map": str(tmp_path / "empty")})
    with pytest.raises(InputError, match=r"keyframes\.npz missing"):
        MappingCore(config)


def test_slam_mode_landmarks_are_the_backend_estimates(tmp_path) -> None:
    # the node asks for the landmarks every map period (markers); they are the back end's
    # current estimates (none with landmarks off). It crashed the node before (exit 1).
    truth, scans = _drive(60)
    for on in (False, True):
        config = tmp_path / f"slam_{on}.yaml"
        config.write_text(f"landmarks: {str(on).lower()}\n")
        core = _core(mount=list(MOUNT), slam_config=str(config))
        assert core.landmarks().shape == (0, 2)  # nothing mapped yet
        _feed(core, truth, scans)
        xy = core.landmarks()
        assert xy.ndim == 2 and xy.shape[1] == 2 and np.isfinite(xy).all()
        assert np.array_equal(xy, core.estimator.backend.landmark_estimates().reshape(-1, 2))
        if not on:
            assert len(xy) == 0


def _feed(core: MappingCore, truth: np.ndarray, scans: list, start: int = 0) -> list:
    out = []
    for i, scan in enumerate(scans[start:], start=start):
        core.book.add_odometry("odom", "base_link", i / RATE, truth[i])
        core.book.add_odometry("odom", "base_link", (i + 0.5) / RATE, truth[i])
        out += core.add_scan(scan)
    return out


def test_a_long_run_keeps_the_newest_times_and_says_so(monkeypatch) -> None:
    """A node runs for days: the last ``TIMINGS_KEPT`` scans' times are kept (the newest), the
    processed scans counted, and the summary says its timing is of the last ones."""
    truth, scans = _drive(12)
    short = _core(mount=list(MOUNT))
    _feed(short, truth, scans[:4])
    assert len(short.counts.ms) == short.counts.processed == 4
    assert "ms/scan mean" in short.summary() and "last" not in short.summary()
    monkeypatch.setattr(estimate, "TIMINGS_KEPT", 5)
    core = _core(mount=list(MOUNT))
    kept = []
    for i in range(len(scans)):
        _feed(core, truth[: i + 1], scans[: i + 1], start=i)
        if len(kept) == 5:  # one scan more: the oldest time dropped, the newest appended
            assert list(core.counts.ms) == [*kept[1:], core.last.ms]
        kept = list(core.counts.ms)
    assert len(core.counts.ms) == 5 and core.counts.processed == len(scans)
    assert "ms/scan mean" in core.summary() and "(last 5 scans)" in core.summary()


ODOM_RATE = 50.0


def _standing(core: MappingCore, n: int, scan_every: float) -> list[int]:
    """``n`` odometry samples at :data:`ODOM_RATE` Hz of a robot standing still, a scan
    every ``scan_every`` seconds (stamped between two samples); the odometry samples the
    book holds after each scan."""
    truth, scans = _drive(1)
    held = []
    every = round(scan_every * ODOM_RATE)
    for i in range(n):
        core.book.add_odometry("odom", "base_link", i / ODOM_RATE, truth[0])
        if i and i % every == 0:
            scan = dataclasses.replace(scans[0], stamp=(i - 0.5) / ODOM_RATE)
            core.add_scan(scan)
            held.append(core.book.n_kept)
    return held


def test_a_long_run_keeps_a_bounded_odometry_store() -> None:
    """A node runs for days: 200,000 odometry samples (66 minutes at 50 Hz) and the book
    holds those of about ``ODOMETRY_KEPT_S`` before the last scan, not all of them."""
    core = _core(mount=list(MOUNT))
    held = _standing(core, 200_000, 20.0)
    assert core.counts.processed == len(held) and core.counts.no_odometry == 0
    assert core.book.n_odometry == 200_000  # a counter: everything taken
    assert core.book.n_kept == core.book.track.n_kept
    bound = 2 * (ODOMETRY_KEPT_S + 20.0) * ODOM_RATE + FORGET_BATCH  # forget_before's
    assert max(held) <= bound, max(held)
    assert core.book.span is not None and core.book.span[1] == (200_000 - 1) / ODOM_RATE


def test_the_odometry_store_stays_bounded_when_the_laser_stops() -> None:
    """The laser stops (a cable, a driver crash) while the odometry goes on for an hour,
    each sample followed by ``release`` as the node does: the book keeps about twice
    ``ODOMETRY_KEPT_S`` before the newest sample, not the hour."""
    core = _core(mount=list(MOUNT))
    _standing(core, 3_000, 20.0)  # 60 s with scans
    truth, _ = _drive(1)
    held = []
    for i in range(3_000, 3_000 + 180_000):  # 60 minutes without a scan
        core.book.add_odometry("odom", "base_link", i / ODOM_RATE, truth[0])
        core.release()
        held.append(core.book.n_kept)
    bound = 2 * 2 * ODOMETRY_KEPT_S * ODOM_RATE + FORGET_BATCH  # forget_before's
    assert max(held) <= bound, max(held)
    first, last = core.book.span
    assert last - first >= 2 * ODOMETRY_KEPT_S  # what a lagging scan needs is still there


def test_a_scan_older_than_the_odometry_kept_is_dropped() -> None:
    """A scan stamped before the odometry kept is dropped and counted as without odometry,
    and the watch's warning names its stamp and the odometry in hand."""
    clock = Clock()
    core = _core(clock, mount=list(MOUNT))
    _standing(core, 15_000, 20.0)  # 300 s
    processed, last = core.counts.processed, core.last.stamp
    first = core.book.span[0]
    assert 0.0 < first <= last - ODOMETRY_KEPT_S  # forgotten before, kept after the horizon
    _, scans = _drive(1)
    old = dataclasses.replace(scans[0], stamp=first - 0.1)
    assert core.add_scan(old) == []
    assert core.counts.no_odometry == 1 and core.counts.processed == processed
    clock.now += 100.0
    (text,) = [w for w in core.watch.warnings(core.book) if "dropped" in w]
    assert f"at stamp {old.stamp:.3f} s" in text and f"{first:.3f} .. " in text


def test_odometry_from_a_clock_jumped_back_starts_the_store_anew() -> None:
    """A bag played in a loop: after 300 s the clock starts again at 0 with the same data.
    The scans of the second pass get odometry (the book starts anew once
    ``CLOCK_JUMP_SAMPLES`` samples in a row are older than those kept), not dropped."""
    core = _core(mount=list(MOUNT))
    _standing(core, 15_000, 20.0)
    first_pass = core.counts.processed
    assert core.book.span[0] > 0.0  # the first pass's oldest samples are forgotten
    _standing(core, 15_000, 20.0)
    assert core.book.clock_jumps == 1
    assert core.counts.processed >= 2 * first_pass - 1
    assert core.counts.no_odometry <= 1


def test_a_forgetting_book_gives_the_poses_after_its_horizon() -> None:
    """Two books take the same odometry (republished samples among it); one forgets the
    samples before 80 s: its poses from 80 s on are the other's, republished old samples
    are not taken again."""
    rng = np.random.default_rng(4)
    whole, kept = OdometryBook(), OdometryBook()
    n = 5_000
    yaw = np.angle(np.exp(1j * np.cumsum(rng.uniform(-1.0, 1.0, n))))
    poses = np.column_stack([rng.normal(0, 1, (n, 2)).cumsum(axis=0), yaw])
    for i, pose in enumerate(poses):
        for book in (whole, kept):
            book.add_odometry("odom", "base_link", i / ODOM_RATE, pose)
            if i % 7 == 0 and i > 3:  # a republished sample
                book.add_odometry("odom", "base_link", (i - 3) / ODOM_RATE, poses[i - 3])
    assert kept.forget_before(80.0) == 80.0 * ODOM_RATE
    assert kept.n_kept == n - 80.0 * ODOM_RATE and whole.n_kept == n
    assert kept.span == (80.0, (n - 1) / ODOM_RATE) and whole.span[0] == 0.0
    for stamp in rng.uniform(80.0, n / ODOM_RATE + 0.4, 300):
        np.testing.assert_array_equal(kept.base_pose(stamp), whole.base_pose(stamp))
    assert kept.base_pose(79.99) is None and whole.base_pose(79.99) is not None
    for book in (whole, kept):
        book.add_odometry("odom", "base_link", 10.0, (7.0, 7.0, 0.0))  # republished
    assert kept.n_odometry == whole.n_odometry == n and kept.n_kept == n - 4_000
    assert kept.span[0] == 80.0


@pytest.fixture(scope="module")
def saved_map(tmp_path_factory) -> tuple:
    """A map of the simulated drive, written by the slam mode's writer."""
    truth, scans = _drive(60)
    core = _core(mount=list(MOUNT))
    _feed(core, truth, scans)
    folder = core.write_map(tmp_path_factory.mktemp("map") / "map", 3.0)
    return folder, truth, scans


def test_localise_from_an_initial_pose_given_before_the_first_scan(saved_map) -> None:
    """/initialpose before any scan: kept, applied when the localiser starts; the poses then
    follow the map's trajectory and map -> odom absorbs the odometry's offset."""
    folder, truth, scans = saved_map
    config = {"mode": "localise", "map": str(folder), "mount": list(MOUNT)}
    core = MappingCore(MappingConfig.from_mapping(config))
    assert core.grid() is not None and core.grid().shape[0] > 50  # the saved map.pgm
    drift = np.array([1.0, -2.0, 0.3])  # this run's odometry frame differs from the map's
    odom = compose_many(drift, truth)
    assert core.set_pose(truth[10], np.diag([0.01, 0.01, 0.001]))
    out = _feed(core, odom, scans, start=10)
    assert len(out) >= 45, core.summary()
    for update in out:
        i = round(update.stamp * RATE)
        np.testing.assert_allclose(update.pose[:2], truth[i][:2], atol=0.1)
        np.testing.assert_allclose(
            compose_many(update.map_to_odom, odom[i]), update.pose, atol=1e-6
        )
    assert core.set_pose(truth[0], None)  # once running, handed over at once
    assert core.estimator.status == "tracking"


def test_localise_in_a_map_server_yaml(saved_map) -> None:
    """``-p map:=.../map.yaml``: a map_server map (here the slam folder's own map.yaml) is
    localised in through virtual keyframes (``registration.gridmap``); its grid is published."""
    folder, truth, scans = saved_map
    config = {"mode": "localise", "map": str(folder / "map.yaml"), "mount": list(MOUNT)}
    core = MappingCore(MappingConfig.from_mapping(config))
    assert core.saved is not None and core.saved.virtual_scans is not None
    assert core.grid() is core.saved.grid and core.grid().shape[0] > 50
    assert core.set_pose(truth[10], np.diag([0.01, 0.01, 0.001]))
    out = _feed(core, truth, scans, start=10)
    assert len(out) >= 45, core.summary()
    for update in out:
        np.testing.assert_allclose(update.pose[:2], truth[round(update.stamp * RATE)][:2], atol=0.1)
    bad = folder.parent / "bad.yaml"
    bad.write_text("image: map.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nmode: grey\n")
    config = MappingConfig.from_mapping({"mode": "localise", "map": str(bad)})
    with pytest.raises(InputError, match=r"bad.yaml: field 'mode'"):
        MappingCore(config)


# non-default localiser options that shape the tracked poses (points, ICP, odometry noise,
# the engine off) and the search's; as ROS 2 parameters and as the CLI's LocaliseOptions
NODE_OPTIONS = {
    "fix_scans": 7,
    "places.min_votes": 3,
    "smooth.enabled": False,
    "point_spacing": 0.15,
    "icp.iterations": 9,
    "match_sigma": 0.05,
    "odometry.sigma_xy": 0.08,
    "engine.gate_xy": 0.4,
}
CLI_OPTIONS = LocaliseOptions(
    fix_scans=7,
    places=PlaceOptions(min_votes=3),
    smooth=SmoothOptions(enabled=False),
    point_spacing=0.15,
    icp=LocaliseOptions().icp.model_copy(update={"iterations": 9}),
    match_sigma=0.05,
    odometry=OdometryNoise(sigma_xy=0.08),
    engine=EngineOptions(gate_xy=0.4),
)


def _cli_estimates(folder, odom: np.ndarray, scans: list, start: int, initial) -> list:
    """What the CLI's localiser (``run_localise``'s ``Localiser``) estimates for the scans
    from ``start`` on: the map's folder, :data:`CLI_OPTIONS`, the mount, the initial pose."""
    loc = Localiser(load_map(folder), CLI_OPTIONS, mount=MOUNT)
    if initial is not None:
        loc.set_pose(initial)
    found = [loc.add(scan, odom[i], scan.stamp) for i, scan in enumerate(scans) if i >= start]
    return [e for e in found if e is not None]


def test_localise_options_reach_the_localiser(saved_map, tmp_path) -> None:
    """Every LocaliseOptions field is a parameter (issue 31 item 2): non-default values reach
    the Localiser, also the one a reinitialisation or a new map makes; AMCL's
    set_initial_pose + initial_pose start it tracking there; the node's estimates are the
    CLI's localiser's with the same options (pose, covariance, map -> odom to 1e-9)."""
    folder, truth, scans = saved_map
    config = MappingConfig.from_mapping(
        {
            "mode": "localise",
            "map": str(folder),
            "mount": list(MOUNT),
            **NODE_OPTIONS,
            "set_initial_pose": True,
            "initial_pose.x": float(truth[10][0]),
            "initial_pose.y": float(truth[10][1]),
            "initial_pose.yaw": float(truth[10][2]),
        }
    )
    core = MappingCore(config)
    out = _feed(core, truth, scans, start=10)
    options = core.estimator.options
    assert options == CLI_OPTIONS and options != LocaliseOptions()
    assert options.engine.gate_xy == 0.4 and core.estimator.engine is not None
    assert len(out) >= 45 and core.estimator.status == "tracking", core.summary()
    np.testing.assert_allclose(out[0].pose[:2], truth[10][:2], atol=0.1)  # from initial_pose
    cli = _cli_estimates(folder, truth, scans, 10, truth[10])
    assert [u.stamp for u in out] == [e.stamp for e in cli]
    for update, e in zip(out, cli, strict=True):
        np.testing.assert_allclose(update.pose, e.pose, rtol=0, atol=1e-9)
        np.testing.assert_allclose(update.covariance, e.covariance, rtol=0, atol=1e-9)
        np.testing.assert_allclose(update.map_to_odom, e.map_to_odom, rtol=0, atol=1e-9)
        assert update.status == str(e.status)
    other = load_map(folder)
    assert core.reinitialize(other) and core.saved is other and core.grid() is other.grid
    assert core.estimator.options.fix_scans == 7 and core.estimator.map is not None
    with pytest.raises(InvalidParamsError, match="fix_scans"):  # checked at start
        MappingCore(MappingConfig.from_mapping({**config_map(folder), "fix_scans": 0}))


def config_map(folder) -> dict:
    return {"mode": "localise", "map": str(folder), "mount": list(MOUNT)}


def test_initial_pose_is_refused_in_slam_mode() -> None:
    assert not _core().set_pose(np.zeros(3), None)


def test_bad_slam_config_is_one_line(tmp_path) -> None:
    path = tmp_path / "slam.yaml"
    path.write_text("keyframe_distance: -1\n")
    config = MappingConfig.from_mapping({"slam_config": str(path)})
    with pytest.raises(InvalidParamsError, match="keyframe_distance"):
        config.slam_options()


# ---------------------------------------------------------------------- message conversions
def _vec(**kw) -> SimpleNamespace:
    return SimpleNamespace(**{k: kw.get(k, 0.0) for k in ("x", "y", "z")})


def _quat() -> SimpleNamespace:
    return SimpleNamespace(x=0.0, y=0.0, z=0.0, w=1.0)


def _stamp(sec: int, nanosec: int) -> SimpleNamespace:
    return SimpleNamespace(sec=sec, nanosec=nanosec)


def _transform_msg() -> SimpleNamespace:
    return SimpleNamespace(
        header=SimpleNamespace(stamp=_stamp(0, 0), frame_id=""),
        child_frame_id="",
        transform=SimpleNamespace(translation=_vec(), rotation=_quat()),
    )


def _pose_cov_msg() -> SimpleNamespace:
    return SimpleNamespace(
        header=SimpleNamespace(stamp=_stamp(0, 0), frame_id="map"),
        pose=SimpleNamespace(
            pose=SimpleNamespace(position=_vec(), orientation=_quat()), covariance=[0.0] * 36
        ),
    )


def test_transform_round_trip() -> None:
    ts = fill_transform(_transform_msg(), "map", "odom", (1.0, -2.0, 3.0))
    ts.header.stamp = _stamp(12, 500_000_000)
    parent, child, stamp, pose = transform_of(ts)
    assert (parent, child, stamp) == ("map", "odom", 12.5)
    np.testing.assert_allclose(pose, (1.0, -2.0, 3.0), atol=1e-12)
    ts.transform.translation.x = float("nan")
    with pytest.raises(InvalidScanError, match="map -> odom"):
        transform_of(ts)
    with pytest.raises(InvalidScanError, match="TransformStamped"):
        transform_of(SimpleNamespace())


def test_pose_with_covariance_round_trip() -> None:
    cov = np.array([[0.04, 0.01, 0.002], [0.01, 0.09, -0.003], [0.002, -0.003, 0.01]])
    msg = fill_pose_with_covariance(_pose_cov_msg(), (3.0, 4.0, -2.5), cov)
    full = np.asarray(msg.pose.covariance).reshape(6, 6)
    assert full[5, 5] == 0.01 and full[0, 5] == 0.002 and full[2, 2] == 0.0
    frame, pose, back = pose_with_covariance_of(msg)
    assert frame == "map"
    np.testing.assert_allclose(pose, (3.0, 4.0, -2.5), atol=1e-12)
    np.testing.assert_allclose(back, cov)
    msg.pose.covariance = [0.0] * 35
    with pytest.raises(InvalidScanError, match="35 values"):
        pose_with_covariance_of(msg)


def test_odometry_of() -> None:
    msg = SimpleNamespace(
        header=SimpleNamespace(stamp=_stamp(3, 0), frame_id="odom"),
        child_frame_id="base_link",
        pose=SimpleNamespace(pose=SimpleNamespace(position=_vec(x=1.0), orientation=_quat())),
    )
    msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = math.sin(0.3), math.cos(0.3)
    frame, child, stamp, pose = odometry_of(msg)
    assert (frame, child, stamp) == ("odom", "base_link", 3.0)
    np.testing.assert_allclose(pose, (1.0, 0.0, 0.6), atol=1e-12)


def test_occupancy_grid_message_keeps_rows_bottom_up() -> None:
    occupancy = np.array([[0, 100, -1], [0, 0, 0]], dtype=np.int8)
    grid = OccupancyGrid(occupancy, 0.1, (-1.0, 2.0, 0.0))
    info = SimpleNamespace(
        resolution=0.0,
        width=0,
        height=0,
        origin=SimpleNamespace(position=_vec(), orientation=_quat()),
    )
    msg = fill_occupancy_grid(SimpleNamespace(info=info, data=None), grid)
    assert (msg.info.width, msg.info.height) == (3, 2)
    assert msg.info.resolution == pytest.approx(0.1)
    assert (msg.info.origin.position.x, msg.info.origin.position.y) == (-1.0, 2.0)
    assert list(msg.data) == [0, 100, -1, 0, 0, 0]  # row 0 (bottom) first, as ROS


def _message_cells(occupancy: np.ndarray) -> list[int]:
    info = SimpleNamespace(
        resolution=0.0,
        width=0,
        height=0,
        origin=SimpleNamespace(position=_vec(), orientation=_quat()),
    )
    grid = OccupancyGrid(np.asarray(occupancy, dtype=np.int8), 0.05, (0.0, 0.0, 0.0))
    return list(fill_occupancy_grid(SimpleNamespace(info=info, data=None), grid).data)


def test_occupancy_grid_message_is_trinary_as_map_server() -> None:
    """Probabilities become -1/0/100 with map_server's rule: occupied above occupied_thresh
    (0.65), free below free_thresh (0.196), unknown between; unknown stays unknown."""
    cells = [-1, 0, 1, 19, 20, 50, 65, 66, 99, 100]
    assert _message_cells(np.array([cells])) == [-1, 0, 0, 0, -1, -1, -1, 100, 100, 100]


def test_saved_map_cells_go_over_unchanged(tmp_path) -> None:
    """The localise mode's map (read from map.pgm with map_server's rule) is already trinary:
    the same function leaves it as it is, so both modes publish one convention."""
    from laser_corners.io.occupancy import read_map, write_map

    rng = np.random.default_rng(1)
    grid = OccupancyGrid(rng.integers(-1, 101, (6, 7)).astype(np.int8), 0.05, (0.0, 0.0, 0.0))
    write_map(grid, tmp_path / "map.yaml")
    saved = read_map(tmp_path / "map.yaml").occupancy
    assert set(np.unique(saved)) <= {-1, 0, 100}
    assert _message_cells(saved) == saved.reshape(-1).tolist()


def test_landmark_markers() -> None:
    assert landmark_marker_fields(np.zeros((0, 2))) == []
    delete, spheres = landmark_marker_fields([[1.0, 2.0], [3.0, 4.0]])
    assert delete["action"] == 3
    assert spheres["type"] == 7 and spheres["points"] == [(1.0, 2.0, 0.0), (3.0, 4.0, 0.0)]


def test_inverse_helpers_agree() -> None:
    pose = np.array([1.0, 2.0, 0.5])
    np.testing.assert_allclose(compose_many(pose, invert_many(pose)), [0, 0, 0], atol=1e-12)


def test_without_a_mount_the_first_scan_waits_tf_wait_then_uses_identity() -> None:
    truth, scans = _drive(10)
    clock = Clock()
    core = _core(clock, tf_wait=1.0)
    for i, scan in enumerate(scans):
        core.book.add_odometry("odom", "base_link", i / RATE, truth[i])
        core.book.add_odometry("odom", "base_link", (i + 0.5) / RATE, truth[i])
        assert core.add_scan(scan) == []  # waiting for /tf_static
    clock.now = 1.5
    out = core.release()
    assert len(out) == len(scans) and core.counts.no_odometry == 0
    np.testing.assert_allclose(core.estimator.mount, [0.0, 0.0, 0.0])


def test_an_unwritable_output_is_refused_at_start(tmp_path) -> None:
    from laser_corners.errors import OutputError

    blocker = tmp_path / "a_file"
    blocker.write_text("")
    with pytest.raises(OutputError, match=f"output {blocker / 'map'}: not writable"):
        _core(output=str(blocker / "map"))
    _core(output=str(tmp_path / "new" / "map"))  # created, writable
    assert (tmp_path / "new" / "map").is_dir() and not any((tmp_path / "new" / "map").iterdir())


def test_save_grid_writes_map_server_files_and_slam_has_nothing_to_reinitialize(
    tmp_path,
) -> None:
    from laser_corners.errors import OutputError
    from laser_corners.io.occupancy import read_map

    truth, scans = _drive(20)
    core = _core()
    with pytest.raises(OutputError, match="nothing mapped yet"):
        core.save_grid(tmp_path)
    core.book.add_transforms([_tf("base_link", "laser", 0, MOUNT)], static=True)
    for i, scan in enumerate(scans):
        core.book.add_odometry("odom", "base_link", i / RATE, truth[i])
        core.book.add_odometry("odom", "base_link", (i + 0.5) / RATE, truth[i])
        core.add_scan(scan)
    path = core.save_grid(tmp_path / "live")
    assert path == tmp_path / "live" / "map.yaml" and path.with_suffix(".pgm").is_file()
    grid = read_map(path)
    assert (grid.occupancy == 100).sum() > 50 and (grid.occupancy == 0).sum() > 500
    assert core.reinitialize() is False
