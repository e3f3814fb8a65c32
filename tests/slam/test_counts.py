"""One record of a SLAM run's counters (laser_corners.slam.counts)."""

from __future__ import annotations

import pytest

from laser_corners.slam.counts import COUNT_KEYS, SlamCounts


def test_as_dict_lists_every_counter_in_order_and_leaves_out_the_uncounted() -> None:
    counts = SlamCounts(scans=3)
    counts.time_jumps += 2
    out = counts.as_dict()
    uncounted = ("scans_without_returns", "keyframes_one_direction")
    grow_only = ("prior_keyframes", "grow_unjoined")  # a run that grows a map counts them
    assert list(out) == [k for k in COUNT_KEYS if k not in uncounted + grow_only]
    assert out["scans"] == 3 and out["time_jumps"] == 2 and out["keyframes"] == 0
    counts.keyframes_one_direction = 0  # counted (as zero): listed
    assert "keyframes_one_direction" in counts.as_dict()
    assert "scans_without_returns" not in counts.as_dict()


def test_the_summary_names_stay() -> None:
    # the names summary.json and the reports show, in the order they list them
    assert COUNT_KEYS[:4] == ("scans", "keyframes", "skipped_no_odometry", "time_jumps")
    assert (
        COUNT_KEYS.index("relocalisations_exhaustive")
        < COUNT_KEYS.index("scans_without_returns")
        < COUNT_KEYS.index("optimiser_recoveries")
    )
    assert COUNT_KEYS[-1] == "final_optimisation_failures" and len(set(COUNT_KEYS)) == 35


def test_update_sets_a_pass_tally_and_refuses_an_unknown_name() -> None:
    counts = SlamCounts()
    counts.update({"rescan_tried": 7, "rescan_kept": 5})
    assert (counts.rescan_tried, counts.rescan_kept) == (7, 5)
    with pytest.raises(KeyError, match="rescan_lost"):
        counts.update({"rescan_lost": 1})
    assert counts.as_dict()["rescan_tried"] == 7
