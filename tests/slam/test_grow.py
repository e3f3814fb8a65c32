"""Maps that grow (:mod:`laser_corners.slam.grow`): a second session started in the map of a
first one, in a simulated building with known poses."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("gtsam")

from laser_corners.errors import InputError
from laser_corners.io.occupancy import OccupancyGrid, write_map
from laser_corners.pose import between_many, compose_many
from laser_corners.registration.mapfolder import GRAPH_FILE, load_map, save_map_data
from laser_corners.registration.points import scan_points
from laser_corners.sim import World
from laser_corners.slam import Slam, SlamOptions, run_slam
from laser_corners.slam.grow import (
    BEAM_STEP,
    join_warning,
    load_prior_map,
    prior_points,
    prior_scans,
)
from laser_corners.slam.result import LoopClosure
from sim_drives import drive_slam, legs, marked_building, noisy_odometry

RATE = 10.0
SESSION_1 = [[1.5, 1.5], [4.5, 1.5], [4.5, 6.5], [1.5, 6.5], [1.5, 1.5], [7.5, 4.0], [10.5, 2]]
SESSION_2 = [[10.5, 6.5], [10.5, 2.0], [7.5, 4.0], [3.0, 4.0], [1.5, 6.0]]
ELSEWHERE = (5.0, -3.0, 1.0)
"""The second session's odometry frame: unrelated to the map's."""


def _session(slam: Slam, world: World, truth: np.ndarray, seed: int, t0: float) -> None:
    odo = noisy_odometry(truth, np.random.default_rng(seed))
    odo = compose_many(np.array(ELSEWHERE), between_many(truth[0], odo))
    stamps = t0 + np.arange(len(truth)) / RATE
    drive_slam(slam, world, truth, odo, stamps, np.random.default_rng(seed + 1))


@pytest.fixture(scope="module")
def old(tmp_path_factory) -> tuple[Path, np.ndarray]:
    """The map folder of the first session (its frame: the truth's) and its truth."""
    truth = legs(SESSION_1)
    slam = Slam(SlamOptions())
    odo = noisy_odometry(truth, np.random.default_rng(1))  # starts at the true pose
    drive_slam(slam, marked_building(), truth, odo, np.arange(len(truth)) / RATE, rng(3))
    folder = tmp_path_factory.mktemp("grow") / "old"
    folder.mkdir()
    result = slam.result()
    save_map_data(result, folder)
    result.write_g2o(folder / GRAPH_FILE)
    return folder, truth


def rng(seed: int) -> np.random.Generator:
    return np.random.default_rng(seed)


def _keyframe_errors(result, truth: np.ndarray) -> np.ndarray:
    n = result.prior_keyframes
    poses, scans = result.keyframe_poses[n:], result.keyframes[n:]
    return np.hypot(*(poses[:, :2] - truth[scans, :2]).T)


def test_a_second_session_without_a_pose_is_fixed_into_the_old_frame(old, tmp_path) -> None:
    folder, truth_1 = old
    saved = load_prior_map(folder)
    truth = legs(SESSION_2)
    slam = Slam(SlamOptions(), prior_map=saved)
    _session(slam, marked_building(), truth, seed=2, t0=100.0)
    result = slam.result()
    n = len(saved)
    assert result.prior_keyframes == n == result.counts["prior_keyframes"]
    assert result.prior_map == str(folder)
    assert result.counts["relocalisations_accepted"] >= 1
    assert result.counts["grow_unjoined"] == 0 and result.warnings == []
    # the old keyframes stay near where they were, bent by the new closures towards the
    # truth (OLD's graph, not fixed priors); the new ones land on the truth
    assert np.abs(result.keyframe_poses[:n] - saved.poses).max() < 0.1
    before = np.hypot(*(saved.poses[:, :2] - truth_1[saved.scan_index, :2]).T)
    after = np.hypot(*(result.keyframe_poses[:n, :2] - truth_1[saved.scan_index, :2]).T)
    assert after.max() < before.max() and after.mean() < before.mean()
    assert np.all(result.keyframes[:n] == -1) and np.all(result.keyframes[n:] >= 0)
    assert _keyframe_errors(result, truth).max() < 0.15
    assert np.hypot(*(result.poses[:, :2] - truth[:, :2]).T).max() < 0.15
    # some closures join the sessions; the new map holds both and grows again
    assert any(c.accepted and c.match < n <= c.query for c in result.closures)
    save_map_data(result, tmp_path)
    grown = load_map(tmp_path)
    assert len(grown) == len(result.keyframe_poses) > n
    np.testing.assert_allclose(grown.points[: saved.offsets[-1]], saved.points)
    np.testing.assert_allclose(grown.stamps[:n], saved.stamps)
    assert grown.places is not None and grown.places.keyframe.max() >= n
    assert grown.places.keyframe.min() == saved.places.keyframe.min()
    assert len(load_prior_map(tmp_path)) == len(grown)


def test_an_initial_pose_starts_the_session_in_the_map(old) -> None:
    folder, _ = old
    truth = legs(SESSION_2)
    guess = truth[0] + np.array([0.2, -0.15, 0.05])
    slam = Slam(SlamOptions(), prior_map=load_prior_map(folder), initial_pose=guess)
    _session(slam, marked_building(), truth, seed=2, t0=100.0)
    result = slam.result()
    assert result.counts["relocalisations_attempted"] == 0  # never lost
    assert result.counts["grow_unjoined"] == 0
    assert _keyframe_errors(result, truth).max() < 0.15


def _unrelated_world() -> World:
    """A long hall with posts, nothing like the building."""
    world = World().add_polygon([[0, 0], [20, 0], [20, 3], [0, 3]])
    for x in (4.0, 9.0, 13.5):
        world.add_circle((x, 1.0), 0.25)
    world.add_polygon([[16, 2.2], [17.5, 2.2], [17.5, 3], [16, 3]])
    return world


def test_a_session_that_never_finds_itself_stays_its_own_segment(old) -> None:
    folder, _ = old
    saved = load_prior_map(folder)
    truth = legs([[1.5, 1.5], [18.5, 1.5], [18.5, 2.0], [1.5, 2.0]])
    slam = Slam(SlamOptions(), prior_map=saved)
    _session(slam, _unrelated_world(), truth, seed=5, t0=100.0)
    result = slam.result()
    assert result.counts["grow_unjoined"] == 1
    assert any("never found itself" in w for w in result.warnings)
    assert not any(c.accepted and c.match < len(saved) <= c.query for c in result.closures)
    assert len(result.keyframe_poses) > len(saved)
    assert np.abs(result.keyframe_poses[: len(saved)] - saved.poses).max() < 0.02
    # the new session is still mapped consistently in its own frame
    own = result.keyframe_poses[len(saved) :]
    rel = between_many(own[:-1], own[1:])
    true_rel = between_many(
        truth[result.keyframes[len(saved) : -1]], truth[result.keyframes[len(saved) + 1 :]]
    )
    assert np.abs(rel[:, :2] - true_rel[:, :2]).max() < 0.1


def test_prior_scans_give_back_the_keyframe_points(old) -> None:
    saved = load_map(old[0])
    points = prior_points(saved)
    assert len(points) == len(saved)
    mount = np.array([0.1, 0.0, 0.05])
    scans = prior_scans(points, mount, 30.0)
    for p, scan in list(zip(points, scans, strict=True))[::10]:
        again = scan_points(scan, mount, 0.0, 30.0, 0.0)
        # nearly one beam each, every one on a keyframe point turned by half a beam at most
        assert 0.95 * len(p.xy) <= len(again.xy) <= len(p.xy)
        d = np.hypot(*(again.xy[:, None, :] - p.xy[None, :, :]).transpose(2, 0, 1))
        rng = np.hypot(*(again.xy - mount[:2]).T)
        assert np.all(d.min(axis=1) <= 0.5 * BEAM_STEP * rng + 1e-9)
        assert not np.any(np.isnan(scan.ranges))  # gaps are zero ranges, not "no return"


def test_a_map_of_another_package_or_version_is_refused(old, tmp_path) -> None:
    grid = OccupancyGrid(np.zeros((40, 40), np.int8), 0.05, (0.0, 0.0, 0.0))
    yaml, _ = write_map(grid, tmp_path / "map.yaml")
    with pytest.raises(InputError, match="map_server map has no keyframe scans"):
        load_prior_map(yaml)
    folder = tmp_path / "v2"
    folder.mkdir()
    with np.load(old[0] / "keyframes.npz") as data:
        arrays = {k: data[k] for k in data.files}
    arrays["format_version"] = np.int64(2)
    np.savez(folder / "keyframes.npz", **arrays)
    with pytest.raises(InputError, match="format version 2"):
        load_prior_map(folder)


def test_an_initial_pose_needs_a_prior_map(tmp_path) -> None:
    with pytest.raises(InputError, match="initial_pose: only with a prior map"):
        run_slam(tmp_path / "none.bag", initial_pose=(0.0, 0.0, 0.0))


def test_join_warning_asks_for_a_closure_between_the_sessions() -> None:
    inside = LoopClosure(query=12, match=11, relative=(0, 0, 0), accepted=True, reason="ok")
    across = LoopClosure(query=12, match=3, relative=(0, 0, 0), accepted=False, reason="x")
    assert "never found itself" in join_warning([inside, across], 10, placed=False)
    assert join_warning([inside, across], 10, placed=True) is None
    across.accepted = True
    assert join_warning([inside, across], 10, placed=False) is None


def _copy(folder: Path, to: Path, without: tuple[str, ...] = ()) -> Path:
    to.mkdir()
    for p in folder.iterdir():
        if p.name not in without:
            (to / p.name).write_bytes(p.read_bytes())
    return to


def test_the_old_map_is_grown_with_its_own_pose_graph(old, tmp_path) -> None:
    folder, _ = old
    saved = load_prior_map(folder)
    assert saved.graph is not None
    n = len(saved)
    chain = saved.graph.chain()
    assert chain.sum() == n - 1 and (~chain).sum() >= 1  # the links and the old closures
    slam = Slam(SlamOptions(), prior_map=saved)
    # one prior (the gauge), every factor of the old graph, its closures robust
    kinds = [type(slam.backend.graph.at(i)).__name__ for i in range(slam.backend.graph.size())]
    assert kinds.count("PriorFactorPose2") == 1
    assert kinds.count("BetweenFactorPose2") == len(saved.graph.pairs)
    assert len(slam.backend.loops) == (~chain).sum()
    # without a graph (an older folder) the old keyframes are held by priors, as before
    bare = load_prior_map(_copy(folder, tmp_path / "bare", without=(GRAPH_FILE,)))
    assert bare.graph is None
    held = Slam(SlamOptions(), prior_map=bare)
    kinds = [type(held.backend.graph.at(i)).__name__ for i in range(held.backend.graph.size())]
    assert kinds.count("PriorFactorPose2") == n


def test_a_graph_of_another_map_is_refused_in_one_line(old, tmp_path) -> None:
    folder, _ = old
    other = _copy(folder, tmp_path / "other")
    lines = (other / GRAPH_FILE).read_text().splitlines()
    (other / GRAPH_FILE).write_text("\n".join(line for line in lines if " 3 " not in line[:13]))
    with pytest.raises(InputError, match=r"graph.g2o: \d+ vertices, the map has \d+ keyframes"):
        load_prior_map(other)
    moved = _copy(folder, tmp_path / "moved")
    text = (moved / GRAPH_FILE).read_text().replace("VERTEX_SE2 2 ", "VERTEX_SE2 2 5", 1)
    (moved / GRAPH_FILE).write_text(text)
    with pytest.raises(InputError, match="vertex 2 is not at its keyframe's pose"):
        load_prior_map(moved)
