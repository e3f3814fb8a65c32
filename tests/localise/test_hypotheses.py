"""Hypotheses of the pose search (:mod:`laser_corners.localise.hypotheses`): the recent window,
merging, the fix rule (enough travel and scans, agreement, no conflict, a clear lead) and the
global search's agreement of a pose partly outside the map (``seen_share``)."""

from __future__ import annotations

import numpy as np
import pytest

from laser_corners.localise.freespace import Support
from laser_corners.localise.hypotheses import Hypothesis, choose_winner, merged, seen_share
from laser_corners.localise.options import LocaliseOptions

OPTIONS = LocaliseOptions(fix_travel=2.0, fix_scans=5, fix_agreement=0.7, fix_margin=0.05)


def scored(
    pose,
    agreements,
    born: int = 0,
    travel: float = 3.0,
    conflict: float = 0.0,
    outside: float = 0.0,
) -> Hypothesis:
    """A hypothesis that has seen ``agreements``, one per scan, with a constant support."""
    h = Hypothesis(np.asarray(pose, dtype=np.float64), born, travel=travel)
    h.followed = travel  # followed since proposed (main's fix_followed_travel), all of it here
    for agreement in agreements:
        h.remember(agreement, Support(outside=outside, conflict=conflict), window=10)
        h.scans += 1
    return h


def test_remember_keeps_the_last_window_of_every_queue() -> None:
    h = Hypothesis(np.zeros(3), 0)
    assert h.score() == 0.0
    for i in range(5):
        h.remember(i / 10, Support(outside=i, conflict=-i, loose=2 * i), window=3)
    assert list(h.recent) == [0.2, 0.3, 0.4] and h.score() == pytest.approx(0.3)
    assert list(h.outside) == [2, 3, 4] and list(h.conflict) == [-2, -3, -4]
    assert list(h.loose) == [4, 6, 8]


def test_merged_drops_the_younger_twin_and_keeps_the_best() -> None:
    old = scored((0.0, 0.0, 0.0), [0.5], born=1)
    twin = scored((0.3, 0.0, 0.1), [0.9], born=2)  # within 0.5 m and 0.2 rad: one place
    turned = scored((0.3, 0.0, 0.5), [0.8], born=3)  # same place, other heading
    far = scored((5.0, 0.0, 0.0), [0.6], born=0)
    kept = merged([twin, old, turned, far], OPTIONS)
    assert kept == [turned, far, old]  # best recent agreement first
    options = LocaliseOptions(max_hypotheses=2)
    assert merged([twin, old, turned, far], options) == [turned, far]


def test_a_clear_leader_with_enough_travel_and_scans_wins() -> None:
    best = scored((0.0, 0.0, 0.0), [0.9] * 6)
    rival = scored((4.0, 0.0, 0.0), [0.8] * 6)
    assert choose_winner([best, rival], OPTIONS, travel=2.0) is best
    assert choose_winner([], OPTIONS, travel=2.0) is None


@pytest.mark.parametrize(
    ("change", "why"),
    [
        ({"travel": 1.0}, "too little travel"),
        ({"agreements": [0.9] * 4}, "too few scans"),
        ({"agreements": [0.69] * 6}, "agreement under fix_agreement"),
        ({"conflict": 0.3}, "contradicts the free space"),
        ({"outside": 0.5}, "partly outside: needs outside_travel x the travel"),
    ],
)
def test_no_fix_without_every_condition(change: dict, why: str) -> None:
    fields = {"pose": (0.0, 0.0, 0.0), "agreements": [0.9] * 6, **change}
    assert choose_winner([scored(**fields)], OPTIONS, travel=2.0) is None, why


def test_no_fix_while_a_rival_is_close_or_barely_scored() -> None:
    best = scored((0.0, 0.0, 0.0), [0.9] * 6)
    close = scored((4.0, 0.0, 0.0), [0.87] * 6)  # lead 0.03 < fix_margin
    assert choose_winner([best, close], OPTIONS, travel=2.0) is None
    young = scored((4.0, 0.0, 0.0), [0.1, 0.1])  # two scans: not beaten yet
    assert choose_winner([best, young], OPTIONS, travel=2.0) is None
    young.remember(0.1, Support(0.0, 0.0), window=10)
    assert choose_winner([best, young], OPTIONS, travel=2.0) is best


def test_a_rival_seeing_through_the_maps_walls_is_beaten_sooner() -> None:
    # aces from scan 681: the right pose agrees 0.99 contradicting the free space on 0.08
    # of its beams; a look-alike 1.6 m along the corridor agrees 0.97 but sees through the
    # map's walls on 0.17: the agreement alone (0.02) stayed under the margin for 2 m more
    best = scored((0.0, 0.0, 0.0), [0.99] * 6, conflict=0.08)
    slid = scored((1.6, 0.0, 0.0), [0.97] * 6, conflict=0.17)
    assert choose_winner([best, slid], OPTIONS, travel=2.0) is best


def test_an_alias_as_good_on_both_counts_still_blocks_the_fix() -> None:
    # a symmetric room or a corridor alias: as many points explained, as many beams
    # contradicting the free space, so no lead on either
    best = scored((0.0, 0.0, 0.0), [0.95] * 6, conflict=0.1)
    twin = scored((0.0, 8.0, np.pi), [0.94] * 6, conflict=0.1)
    assert choose_winner([best, twin], OPTIONS, travel=2.0) is None


def test_a_lead_in_agreement_lost_in_free_space_conflict_is_no_lead() -> None:
    # the best by agreement contradicts the map's free space more than the rival by as
    # much as it explains more points: the evidence does not tell them apart
    best = scored((0.0, 0.0, 0.0), [0.95] * 6, conflict=0.15)
    rival = scored((4.0, 0.0, 0.0), [0.89] * 6, conflict=0.05)
    assert choose_winner([best, rival], OPTIONS, travel=2.0) is None


def test_seen_share_judges_a_pose_partly_outside_the_map_on_what_the_map_saw() -> None:
    opt = LocaliseOptions(partly_outside=0.15, max_outside=0.5)
    # in the band: the share of the beams the map could have seen, conflict not excused
    partly = Support(outside=0.4, conflict=0.05)
    assert seen_share(0.5, partly, opt) == pytest.approx((0.5 - 0.05) / (1.0 - 0.4))
    assert seen_share(0.5, Support(outside=0.4, conflict=0.2), opt) < seen_share(0.5, partly, opt)
    assert seen_share(0.5, Support(outside=0.5, conflict=0.0), opt) == pytest.approx(1.0)
    assert seen_share(0.9, Support(outside=0.3, conflict=0.0), opt) == 1.0  # at most 1
    # never below the plain share (conflict larger than what the outside beams excuse)
    assert seen_share(0.6, Support(outside=0.2, conflict=0.3), opt) == 0.6
    # out of the band: the plain share (hardly outside, or mostly outside the map)
    for outside in (0.0, 0.15, 0.51, 1.0):
        assert seen_share(0.5, Support(outside=outside, conflict=0.0), opt) == 0.5
    # the band is the options'
    wider = LocaliseOptions(partly_outside=0.05, max_outside=0.7)
    assert seen_share(0.5, Support(outside=0.1, conflict=0.0), wider) > 0.5
    assert seen_share(0.3, Support(outside=0.6, conflict=0.0), wider) == pytest.approx(0.75)
