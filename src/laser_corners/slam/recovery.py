"""Recovery of an iSAM2 update gtsam refused: :class:`Recovery`.

When iSAM2 finds the system indeterminate (gtsam's ``RuntimeError``: an under-constrained or
too poorly conditioned variable, e.g. a new segment after a 1 km odometry jump), iSAM2 is
rebuilt from every factor with the variable the error names re-anchored by a prior at its
current estimate (:data:`ANCHOR_SIGMAS`), up to :data:`RECOVER_ATTEMPTS` times; when that does
not help, the factors added since the last good update are dropped and the new variables
anchored where they were guessed. Each is counted and named in a warning line.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable

from laser_corners.registration.graph import X
from laser_corners.slam.counts import SlamCounts
from laser_corners.slam.factors import FactorLog

try:
    import gtsam
except ImportError:  # pragma: no cover - the "slam" extra is missing
    gtsam = None

__all__ = ["ANCHOR_SIGMAS", "RECOVER_ATTEMPTS", "Recovery", "first_line"]

ANCHOR_SIGMAS = (1.0, 1.0, 0.1)
"""Standard deviations (m, m, rad) of the prior that re-anchors a variable iSAM2 found
indeterminate (a landmark's: the first two)."""
RECOVER_ATTEMPTS = 3
"""Rebuilds of iSAM2, each with one more variable re-anchored, before the new factors are
dropped."""
_SYMBOL = re.compile(r"Symbol: ([a-z])(\d+)")


def first_line(exc: BaseException) -> str:
    """gtsam's message in one line (it spans a paragraph)."""
    text = " ".join(str(exc).split())
    head = text.split(".")[0] if text else type(exc).__name__
    return head[:200]


class Recovery:
    """Rebuilds iSAM2 after a refused update.

    Parameters
    ----------
    make_isam : callable
        ``make_isam() -> gtsam.ISAM2``, a new empty iSAM2.
    counts : SlamCounts
        Counts ``optimiser_recoveries``, ``optimiser_anchors``, ``optimiser_factors_dropped``.
    warnings : list of str
        Gets one line per recovery.
    """

    def __init__(
        self, make_isam: Callable[[], object], counts: SlamCounts, warnings: list[str]
    ) -> None:
        self.make_isam = make_isam
        self.counts = counts
        self.warnings = warnings

    def recover(
        self,
        exc: RuntimeError,
        factors: FactorLog,
        guess: object,
        new_keys: Iterable[int],
        good: int,
        newest: int,
    ) -> object:
        """A new iSAM2 over ``factors`` from ``guess`` (every variable's latest estimate),
        with the variable the error names re-anchored, else (when that fails) without the
        factors from index ``good`` on (those of the failed update) and with the update's
        new variables ``new_keys`` anchored. ``newest``: the newest keyframe, the culprit
        when the message names none.

        Raises
        ------
        RuntimeError
            Even the graph of the last good update with the new variables anchored is
            indeterminate (a caller keeps what was mapped, see ``slam.run``).
        """
        self.counts.optimiser_recoveries += 1
        what = first_line(exc)
        anchored: list[int] = []
        for _ in range(RECOVER_ATTEMPTS):
            key = _culprit(exc, newest)
            if key in anchored:
                break
            self._anchor(factors, key, guess)
            anchored.append(key)
            try:
                return self._rebuilt(factors, guess, anchored, what)
            except RuntimeError as again:
                exc = again
        failed = range(good, factors.graph.size())
        factors.drop(failed)
        for key in new_keys:
            self._anchor(factors, key, guess)
        isam = self._rebuild(factors, guess)
        n = len(failed) - len(anchored)
        self.counts.optimiser_factors_dropped += n
        self.warnings.append(
            f"optimiser: {what}; dropped the {n} factors of that update and went on"
        )
        return isam

    def _rebuilt(self, factors: FactorLog, guess: object, anchored: list[int], what: str):
        """:meth:`_rebuild`, and the warning naming the re-anchored variables."""
        isam = self._rebuild(factors, guess)
        names = ", ".join(gtsam.Symbol(k).string() for k in anchored)
        self.warnings.append(f"optimiser: {what}; re-anchored {names} and went on")
        return isam

    def _anchor(self, factors: FactorLog, key: int, guess: object) -> None:
        """A prior (:data:`ANCHOR_SIGMAS`) holding ``key`` at ``guess`` (counted)."""
        factors.anchor(key, guess, ANCHOR_SIGMAS)
        self.counts.optimiser_anchors += 1

    def _rebuild(self, factors: FactorLog, guess: object) -> object:
        """A new iSAM2 over every factor not dropped, from ``guess``."""
        isam = self.make_isam()
        isam.update(factors.active([], set()), guess)
        return isam


def _culprit(exc: RuntimeError, newest: int) -> int:
    """The variable gtsam's message names (``Symbol: x12``), else keyframe ``newest``."""
    found = _SYMBOL.search(str(exc))
    if found is not None and found.group(1) in "xl":
        return gtsam.symbol(found.group(1), int(found.group(2)))
    return X(max(newest, 0))
