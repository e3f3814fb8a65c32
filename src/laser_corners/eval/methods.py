"""The one registry of evaluation methods (``evaluate sim``, ``evaluate real``).

A *method* is a name and a factory: given one sample scan of a batch (presets that adapt to
the sensor or its noise read it), the factory returns an object with
``detect_many(scans) -> list[Keypoints]``.

=================  ======================================================================
name               detector
=================  ======================================================================
``paper``          :class:`~laser_corners.CornerDetector`, preset ``paper`` (the ICARA 2024
                   method of Sousa, Sobreira, Silva, Moreira)
``auto``           the same detector, preset ``auto`` (scales adapted to the scanner)
``robust``         the same detector, preset ``robust`` (adapted to the range noise)
``split-and-merge`` :class:`~laser_corners.eval.baselines.SplitAndMergeDetector`, the
                   line-intersection baseline
``falko-like``     :class:`~laser_corners.eval.falko_like.FalkoLikeDetector`: our reading of
                   the FALKO paper's score, *not* falkolib
=================  ======================================================================

Older names stay accepted: ``baseline`` for ``split-and-merge``, ``falko`` for
``falko-like``. Unknown names raise :class:`~laser_corners.errors.InvalidParamsError` listing
the known ones.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from typing import Protocol

from laser_corners.choice import ParamsChoice
from laser_corners.detector import CornerDetector
from laser_corners.errors import InvalidParamsError
from laser_corners.eval.baselines import SplitAndMergeDetector
from laser_corners.eval.falko_like import FalkoLikeDetector
from laser_corners.io import KeypointWriter
from laser_corners.keypoints import Keypoints
from laser_corners.pipeline import detect_recording
from laser_corners.presets import PRESETS
from laser_corners.scan import LaserScan

__all__ = [
    "ALIASES",
    "DEFAULT_METHODS",
    "DetectLoop",
    "Detects",
    "MethodFactory",
    "canonical_name",
    "detect_all",
    "method_factories",
    "method_names",
]


class Detects(Protocol):
    """Anything with ``detect(scan)`` and ``detect_many(scans) -> list[Keypoints]``."""

    def detect(self, scan: LaserScan) -> Keypoints: ...

    def detect_many(self, scans: list[LaserScan]) -> list[Keypoints]: ...


MethodFactory = Callable[[LaserScan], Detects]
"""Builds a detector for a batch of scans from one sample scan of the batch."""

DetectLoop = Callable[
    [Detects, Sequence[LaserScan], Callable[[int, int], None] | None], list[Keypoints]
]
"""Runs a detector over scans with a ``(done, total)`` progress callback (:func:`detect_all`)."""

_OTHERS: dict[str, MethodFactory] = {
    "split-and-merge": lambda scan: SplitAndMergeDetector(),
    "falko-like": lambda scan: FalkoLikeDetector(),
}

ALIASES: dict[str, str] = {"baseline": "split-and-merge", "falko": "falko-like"}
"""Older method names, still accepted."""

DEFAULT_METHODS: tuple[str, ...] = ("paper", "auto", "split-and-merge", "falko-like")
"""The methods an evaluation compares by default (``evaluate real``, ``evaluate loops``):
``paper`` is our detector with the paper's parameters; ``falko-like`` is our reading of the
FALKO paper, not falkolib."""


def _preset_factory(name: str) -> MethodFactory:
    choice = ParamsChoice(preset=name)
    return lambda scan: CornerDetector(choice.resolve(scan))


def method_names() -> list[str]:
    """The registered method names: detector presets, then the comparison detectors."""
    return [*PRESETS, *_OTHERS]


def canonical_name(name: str) -> str:
    """The registry name of ``name`` (aliases resolved).

    Raises
    ------
    InvalidParamsError
        ``name`` is not a method; the message lists the known ones.
    """
    name = ALIASES.get(name, name)
    if name not in PRESETS and name not in _OTHERS:
        raise InvalidParamsError(
            f"unknown method {name!r}; choose from: {', '.join(method_names())}"
        )
    return name


def method_factories(names: Iterable[str]) -> dict[str, MethodFactory]:
    """Factories by canonical method name, in the given order (duplicates dropped).

    Examples
    --------
    >>> list(method_factories(["paper", "baseline", "falko-like"]))
    ['paper', 'split-and-merge', 'falko-like']
    """
    out: dict[str, MethodFactory] = {}
    for raw in names:
        name = canonical_name(raw.strip())
        out.setdefault(name, _preset_factory(name) if name in PRESETS else _OTHERS[name])
    return out


class _Collected(KeypointWriter):
    """A writer that keeps every scan's keypoints in memory, in scan order."""

    def __init__(self) -> None:
        super().__init__()
        self.found: list[Keypoints] = []

    def write(self, scan_index: int, scan: LaserScan, keypoints: Keypoints) -> None:
        super().write(scan_index, scan, keypoints)
        self.found.append(keypoints)


def detect_all(
    detector: Detects,
    scans: Sequence[LaserScan],
    step: Callable[[int, int], None] | None = None,
    chunk: int = 500,
) -> list[Keypoints]:
    """Run ``detector`` on every scan through the pipeline's detect loop, in order.

    :func:`laser_corners.pipeline.detect_recording` cuts the scans into chunks of one geometry
    (``detect_many`` for each) and reports ``step(done, total)`` after each chunk.

    Raises
    ------
    KeyboardInterrupt
        Ctrl-C during the loop (an evaluation has no partial result to keep).
    """
    scans = list(scans)
    collected = _Collected()
    report = None if step is None else (lambda run: step(run.n_scans, len(scans)))
    summary = detect_recording(
        scans,
        detector,
        collected,
        report,
        every=chunk,  # type: ignore[arg-type]
        threads=None,
        chunk_scans=chunk,
        prefetch=False,
    )
    if summary.interrupted:
        raise KeyboardInterrupt
    return collected.found
