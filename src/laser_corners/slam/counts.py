"""The counters of a SLAM run in one record: :class:`SlamCounts`.

The parts of :class:`~laser_corners.slam.slam.Slam` (tracking, keyframes, loop closure,
relocalisation, the back end, the finishing passes) each increment their fields of one shared
record; :meth:`SlamCounts.as_dict` is :attr:`SlamResult.counts
<laser_corners.slam.result.SlamResult.counts>` (the ``counts`` of ``summary.json``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields

__all__ = ["COUNT_KEYS", "SlamCounts"]


@dataclass
class SlamCounts:
    """Every counter of a SLAM run, in the order reports list them.

    ``scans_without_returns`` and ``keyframes_one_direction`` are counted by
    :func:`~laser_corners.slam.run.run_slam` only: None (left out of :meth:`as_dict`) when
    nothing counted them, e.g. a ROS node's SLAM. ``prior_keyframes`` (the keyframes of the
    map a run grows) and ``grow_unjoined`` (1 when the new session never found itself in it,
    :mod:`.grow`) only in a run that grows a map.
    """

    scans: int = 0
    keyframes: int = 0
    skipped_no_odometry: int = 0
    time_jumps: int = 0
    alignment_failures: int = 0
    second_guesses: int = 0
    second_guesses_used: int = 0
    rescues: int = 0
    rescues_used: int = 0
    closures_proposed: int = 0
    closures_accepted: int = 0
    closures_rejected: int = 0
    closures_pruned: int = 0
    refine_tried: int = 0
    refine_links: int = 0
    refine_pruned: int = 0
    rescan_tried: int = 0
    rescan_kept: int = 0
    landmarks: int = 0
    landmark_observations: int = 0
    corner_registrations: int = 0
    corner_registrations_used: int = 0
    lost: int = 0
    relocalisations_attempted: int = 0
    relocalisations_accepted: int = 0
    relocalisations_exhaustive: int = 0
    scans_without_returns: int | None = None
    keyframes_one_direction: int | None = None
    prior_keyframes: int | None = None
    grow_unjoined: int | None = None
    optimiser_recoveries: int = 0
    optimiser_anchors: int = 0
    optimiser_factors_dropped: int = 0
    optimiser_covariance_failures: int = 0
    final_optimisation_failures: int = 0

    def as_dict(self) -> dict[str, int]:
        """The counters counted (None ones left out), in field order."""
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        return {k: int(v) for k, v in out.items() if v is not None}

    def update(self, counts: Mapping[str, int]) -> None:
        """Set the counters named in ``counts`` (a pass's own tally, e.g. :func:`.rescan.rescan`).

        Raises
        ------
        KeyError
            A name that is not a counter of this record.
        """
        for key, value in counts.items():
            if key not in COUNT_KEYS:
                raise KeyError(f"not a SLAM counter: {key!r}")
            setattr(self, key, int(value))


COUNT_KEYS = tuple(f.name for f in fields(SlamCounts))
"""Every counter name of :class:`SlamCounts`, in order."""
