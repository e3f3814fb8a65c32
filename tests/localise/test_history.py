"""The search's past scans (``localise.history``): kept one per step, forgotten after
``keep``, replayed newest first by chaining back from a pose by odometry."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from laser_corners.localise.freespace import Support
from laser_corners.localise.history import SearchHistory
from laser_corners.pose import compose_many, invert_many
from laser_corners.registration.align import Alignment


def _fill(history: SearchHistory, odometry: np.ndarray, step: float) -> None:
    for i, odo in enumerate(odometry):
        history.remember(i * step, i, np.full((2, 2), float(i)), odo)


def test_keeps_one_scan_per_step_and_forgets_after_keep() -> None:
    history = SearchHistory(keep=1.0, step=0.25)
    _fill(history, np.zeros((40, 3)), 0.125)  # every second is kept
    kept = [p.scan.index for p in history.replay(_matcher(), np.zeros(3), np.zeros(3))]
    assert kept == [38, 36, 34, 32, 30]  # 4.75 m travelled; the last 1.0 m kept
    history.clear()
    assert len(history) == 0


def _matcher(agreement: float = 1.0, moved: np.ndarray | None = None) -> SimpleNamespace:
    """A stand-in for ``MapMatcher``: ICP returns ``moved`` (default: the guess) agreeing
    ``agreement``; no free-space conflict; hypotheses need 0.5."""

    def align(xy, guess, prior):
        pose = guess if moved is None else moved
        return Alignment(pose, agreement, 2, np.eye(3)), agreement

    return SimpleNamespace(
        align=align,
        prior=lambda delta, jump: np.eye(3),
        support=lambda pose, xy: Support(0.0, 0.0, 0.0),
        options=SimpleNamespace(hypothesis_agreement=0.5),
    )


def test_replay_chains_back_by_odometry_from_the_given_pose() -> None:
    rng = np.random.default_rng(3)
    odometry = np.cumsum(rng.normal(0.0, 0.3, (12, 3)), axis=0)
    truth_shift = np.array([5.0, -2.0, 0.7])  # map <- odometry frame
    history = SearchHistory(keep=100.0, step=0.0)
    _fill(history, odometry, 1.0)
    pose_now = compose_many(truth_shift, odometry[-1])
    replayed = list(history.replay(_matcher(), pose_now, odometry[-1], before=11))
    assert [p.scan.index for p in replayed] == list(range(10, -1, -1))  # the current left out
    for p in replayed:
        assert np.allclose(p.pose, compose_many(truth_shift, odometry[p.scan.index]))


def test_replay_keeps_the_guess_where_icp_disagrees() -> None:
    history = SearchHistory(keep=100.0, step=0.0)
    _fill(history, np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]), 1.0)
    # ICP would move it far, but agrees too little to be kept
    poor = _matcher(agreement=0.2, moved=np.array([9.0, 9.0, 0.0]))
    out = list(history.replay(poor, np.zeros(3), np.array([1.0, 0.0, 0.0])))
    assert out[1].agreement == pytest.approx(0.2)
    expected = compose_many(invert_many([1.0, 0.0, 0.0]), np.zeros(3))
    assert np.allclose(out[1].pose, expected)  # dead reckoning, not the poor alignment


def _fits(shares: list[tuple[float, float]]) -> bool:
    """``SearchHistory.fits`` over kept scans whose (outside, conflict) shares are
    ``shares``, oldest first, with the default thresholds (``max_outside`` 0.5,
    ``max_conflict`` 0.2, ``track_conflict`` 0.5 over ``conflict_scans`` 10)."""
    history = SearchHistory(keep=100.0, step=0.0)
    odometry = np.column_stack([np.arange(len(shares), dtype=float), np.zeros((len(shares), 2))])
    _fill(history, odometry, 1.0)
    matcher = _matcher()
    matcher.support = lambda pose, xy: Support(*shares[round(pose[0])], 1.0)
    matcher.options = SimpleNamespace(
        hypothesis_agreement=0.5,
        max_outside=0.5,
        max_conflict=0.2,
        track_conflict=0.5,
        conflict_scans=10,
    )
    return history.fits(matcher, odometry[-1], odometry[-1])


def test_fits_ends_at_a_scan_from_unknown_space() -> None:
    # the robot came from where the map saw nothing (outside, no contradiction): what the
    # chain says before it is dead reckoning, contradicting or not
    older = [(0.1, 0.9)] * 20 + [(0.8, 0.05)] * 3
    assert _fits(older + [(0.05, 0.1)] * 15)
    assert not _fits([(0.05, 0.9)] * 20 + [(0.05, 0.1)] * 15)  # contradicting in the map


def test_fits_counts_scans_both_outside_and_contradicting_the_map() -> None:
    # a look-alike that fits the last metres, chained back further, half outside the map
    # and seeing through its walls: evidence against it, not a way out of the check
    assert not _fits([(0.6, 0.65)] * 20 + [(0.05, 0.15)] * 15)
