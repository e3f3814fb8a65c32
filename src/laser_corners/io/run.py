"""Detect keypoints in a whole recording, writing as it goes (what ``laser-corners detect`` runs).

The loop is the same whatever the output: read a scan, detect, hand the keypoints to the
writer, report progress. An interruption (Ctrl-C) or a read error stops it; the writer is
closed either way, so what was written stays readable, and the :class:`RunSummary` says how
far it got.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

from laser_corners.detector import CornerDetector
from laser_corners.io import KeypointWriter, ScanSource

__all__ = ["RunSummary", "detect_recording"]


@dataclass
class RunSummary:
    """What a run did.

    Attributes
    ----------
    n_scans, n_keypoints : int
        Scans processed and keypoints found (and written).
    seconds : float
        Wall time of the loop.
    skipped : dict of str to int
        Bad records skipped, by reason.
    skip_examples : list of str
        Where the first skips happened.
    interrupted : bool
        Stopped by Ctrl-C.
    position : str
        Where reading stopped (``"message 1200 of /scan"``, ``"line 345"``).
    """

    n_scans: int = 0
    n_keypoints: int = 0
    seconds: float = 0.0
    skipped: dict[str, int] = field(default_factory=dict)
    skip_examples: list[str] = field(default_factory=list)
    interrupted: bool = False
    position: str = "start"

    @property
    def keypoints_per_scan(self) -> float:
        """Mean keypoints per scan (0 without scans)."""
        return self.n_keypoints / self.n_scans if self.n_scans else 0.0

    @property
    def scans_per_second(self) -> float:
        """Processing rate."""
        return self.n_scans / self.seconds if self.seconds > 0 else 0.0


def detect_recording(
    source: ScanSource,
    detector: CornerDetector,
    writer: KeypointWriter,
    progress: Callable[[RunSummary], None] | None = None,
    every: int = 25,
) -> RunSummary:
    """Detect keypoints in every scan of ``source`` and hand them to ``writer``.

    Parameters
    ----------
    source : ScanSource
        The recording.
    detector : CornerDetector
        The detector.
    writer : KeypointWriter
        Where keypoints go; closed before returning (also on errors and Ctrl-C).
    progress : callable, optional
        Called with the running summary every ``every`` scans and at the end.
    every : int
        Progress period in scans.

    Returns
    -------
    RunSummary
        ``interrupted`` is True after Ctrl-C (the exception is not re-raised).

    Raises
    ------
    InputError
        A read error in the middle of the recording (after closing the writer).
    """
    summary = RunSummary()
    report = progress or (lambda _: None)
    start = time.perf_counter()
    try:
        for index, scan in enumerate(source):
            keypoints = detector.detect(scan)
            writer.write(index, scan, keypoints)
            summary.n_scans += 1
            summary.n_keypoints += len(keypoints)
            if summary.n_scans % every == 0:
                summary.seconds = time.perf_counter() - start
                summary.skipped = dict(source.skipped)
                report(summary)
    except KeyboardInterrupt:
        summary.interrupted = True
    finally:
        writer.close()
        summary.seconds = time.perf_counter() - start
        summary.skipped = dict(source.skipped)
        summary.skip_examples = list(source.skip_examples)
        summary.position = source.position
    report(summary)
    return summary
