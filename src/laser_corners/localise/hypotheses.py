"""Hypotheses of the search for a pose in the map: :class:`Hypothesis`, :func:`merged` and
:func:`choose_winner` (the fix rule of :class:`~laser_corners.localise.Localiser`).

A hypothesis is a candidate pose chained by odometry, with its recent agreements and
free-space shares. The fix is declared only when one hypothesis has survived enough travel and
scans, agrees at least ``fix_agreement`` without contradicting the map's free space, and leads
every other surviving hypothesis by ``fix_margin`` on average over the scans both were scored
on: in a symmetric or ambiguous map several hypotheses keep agreeing and no fix is given.

The lead counts both kinds of evidence against a pose, each a share of the scan: the points
it leaves unexplained (one minus the agreement) and the beams that contradict the map's sure
free space (``Support.conflict``: ending where the map saw free space, or seeing through its
walls). A look-alike slid along a corridor explains nearly as many points as the right pose,
but its beams run through the map's walls and doors; counted on agreement alone it stayed
within the margin for metres (aces from scan 681: 0.97 against 0.99, conflict 0.17 against
0.08). An alias that is as good on both counts (a symmetric room, a corridor's repeated
stretch) still leads by nothing, and a best pose whose extra agreement is paid for in
conflict leads by nothing either.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from laser_corners.localise.freespace import Support
from laser_corners.localise.options import LocaliseOptions
from laser_corners.pose import poses_apart

__all__ = ["Hypothesis", "choose_winner", "merged", "seen_share"]


def seen_share(mapped: float, support: Support, options: LocaliseOptions) -> float:
    """The global search's agreement of a pose: the share of the scan the map could have seen.

    A robot at the map's frontier sees much space the map never saw: at its right pose many
    beams end outside the map (``support.outside``) and its plain share ``mapped`` of points
    near a map point is low, while a look-alike that puts the whole scan inside the map
    scores higher and can win a wrong fix (a hall alike every 5 m, mapped from one end:
    ``tests/localise/test_search.py``). A pose whose beams end partly outside the map
    (``partly_outside < outside <= max_outside``) is therefore judged on the part the map
    saw: ``(mapped - conflict) / (1 - outside)``, at most 1 and never below ``mapped``.
    The beams contradicting the map's free space (``support.conflict``) are subtracted, so
    that seeing through the map's walls is not excused: excusing only the outside beams
    gave a new wrong fix at aces' split 0.6 (5.84 m off). Elsewhere it is ``mapped``. The
    lost track's window has its own rule (``local.explained_share``).

    Parameters
    ----------
    mapped : float
        Share of the scan's points near a map point.
    support : Support
        The scan's free-space shares at the pose.
    options : LocaliseOptions
        ``partly_outside`` and ``max_outside`` bound the band.

    Returns
    -------
    float
        The agreement: at least ``mapped``, at most 1 (or ``mapped`` if more).

    Examples
    --------
    >>> from laser_corners.localise import LocaliseOptions
    >>> seen_share(0.5, Support(outside=0.4, conflict=0.05), LocaliseOptions())
    0.75
    >>> seen_share(0.5, Support(outside=0.1, conflict=0.0), LocaliseOptions())
    0.5
    """
    outside = support.outside
    if not options.partly_outside < outside <= options.max_outside:
        return mapped
    return max(mapped, min(1.0, (mapped - support.conflict) / max(1.0 - outside, 0.05)))


@dataclass
class Hypothesis:
    """A candidate pose chained by odometry, with its recent agreements."""

    pose: NDArray[np.float64]
    born: int
    recent: deque = field(default_factory=deque)
    travel: float = 0.0
    """Odometry travel (m, turns 0.5 m per radian) survived, the credited past scans'
    included (``localise.history``)."""
    scans: int = 0
    """Scans survived, the credited past scans' included."""
    followed: float = 0.0
    """Odometry travel (m, turns 0.5 m per radian) followed since it was proposed."""
    conflict: deque = field(default_factory=deque)
    """Recent shares of beams contradicting the map's free space (``freespace``)."""
    outside: deque = field(default_factory=deque)
    """Recent shares of beams ending where the map saw nothing."""
    loose: deque = field(default_factory=deque)
    """Recent shares of beams contradicting any evidence of the map (``Support.loose``)."""

    def score(self) -> float:
        """Mean recent agreement."""
        return float(np.mean(self.recent)) if self.recent else 0.0

    def remember(self, agreement: float, support: Support, window: int) -> None:
        """Append one scan's agreement and free-space support, keep the last ``window``."""
        for queue, value in (
            (self.recent, agreement),
            (self.conflict, support.conflict),
            (self.outside, support.outside),
            (self.loose, support.loose),
        ):
            queue.append(value)
            while len(queue) > window:
                queue.popleft()


def merged(hypotheses: list[Hypothesis], options: LocaliseOptions) -> list[Hypothesis]:
    """Oldest first; a hypothesis meeting an older one (``distinct_xy`` and ``distinct_yaw``)
    is dropped; at most ``max_hypotheses`` (best recent agreement) are kept."""
    kept: list[Hypothesis] = []
    for h in sorted(hypotheses, key=lambda h: h.born):
        apart = (options.distinct_xy, options.distinct_yaw)
        if all(poses_apart(h.pose, k.pose, *apart) for k in kept):
            kept.append(h)
    kept.sort(key=lambda h: -h.score())
    return kept[: options.max_hypotheses]


def choose_winner(
    hypotheses: list[Hypothesis], options: LocaliseOptions, travel: float
) -> Hypothesis | None:
    """The hypothesis that wins clearly, or None.

    Parameters
    ----------
    hypotheses : list of Hypothesis
        The surviving hypotheses (every one a rival of the best).
    options : LocaliseOptions
    travel : float
        Odometry travel (m) the winner must have survived: ``fix_travel`` for the global
        search, ``reacquire_travel`` inside a lost track's window; times ``outside_travel``
        when its recent scans end partly outside the map (the lead must hold longer).

    Returns
    -------
    Hypothesis or None
    """
    opt = options
    if not hypotheses:
        return None
    best = max(hypotheses, key=lambda h: h.score())
    outside = float(np.mean(best.outside))
    travel *= opt.outside_travel if outside > opt.partly_outside else 1.0
    if (
        best.travel < travel
        or best.followed < min(travel, opt.fix_followed_travel)
        or float(np.mean(best.conflict)) > opt.max_conflict
        or best.conflict[-1] > opt.max_conflict
        or float(np.mean(best.loose)) > opt.max_loose_conflict
        or best.scans < opt.fix_scans
        or best.score() < opt.fix_agreement
    ):
        return None
    for rival in hypotheses:
        if rival is not best and _lead(best, rival) < opt.fix_margin:
            return None
    return best


def _lead(best: Hypothesis, rival: Hypothesis) -> float:
    """Mean lead of ``best`` over ``rival`` on the scans both have scored (the last ones): how
    much more of each scan's points it explains plus how much less of its beams contradict
    the map's free space (see the module notes); a rival scored on fewer than 3 scans is not
    beaten yet."""
    k = min(len(best.recent), len(rival.recent))
    if k < 3:
        return -1.0
    agreement = np.subtract(list(best.recent)[-k:], list(rival.recent)[-k:])
    conflict = np.subtract(list(rival.conflict)[-k:], list(best.conflict)[-k:])
    return float(np.mean(agreement + conflict))
