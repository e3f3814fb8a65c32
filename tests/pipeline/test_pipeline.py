"""The pipeline layer: open_recording, ParamsChoice, THE detect loop (chunks, reader thread)."""

from __future__ import annotations

import doctest
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from laser_corners import CornerDetector, InputError, InvalidParamsError, LaserScan
from laser_corners.demo import demo_world
from laser_corners.io import KeypointWriter
from laser_corners.pipeline import (
    ParamsChoice,
    RunSummary,
    detect_recording,
    open_recording,
    scan_at,
)
from laser_corners.presets import get_preset
from laser_corners.sim import UST_10LX, corner_scan, get_sensor


def _log(path: Path, n: int, step_deg: float = 1.0) -> Path:
    """A CARMEN log of ``n`` noisy scans of a rectangular room (FLASER, 180 deg)."""
    rng = np.random.default_rng(n)
    beams = round(180 / step_deg) + 1
    angles = np.linspace(-np.pi / 2, np.pi / 2, beams)
    base = np.minimum(
        3.0 / np.maximum(np.abs(np.cos(angles)), 1e-9),
        1.5 / np.maximum(np.abs(np.sin(angles)), 1e-9),
    )
    with path.open("w") as handle:
        for i in range(n):
            ranges = base + rng.normal(0.0, 0.003, beams)
            body = " ".join(f"{r:.4f}" for r in ranges)
            handle.write(f"FLASER {beams} {body} 0 0 0 0 0 0 {i * 0.1:.3f} host {i * 0.1:.3f}\n")
    return path


class _Recorder(KeypointWriter):
    """Remembers what it was given, and whether it was closed."""

    def __init__(self) -> None:
        super().__init__()
        self.rows: list[tuple[int, int]] = []  # scan index, keypoint count
        self.xy: list[np.ndarray] = []
        self.closed = False

    def write(self, scan_index: int, scan: LaserScan, keypoints) -> None:  # type: ignore[no-untyped-def]
        super().write(scan_index, scan, keypoints)
        self.rows.append((scan_index, len(keypoints)))
        self.xy.append(keypoints.xy)

    def close(self) -> None:
        self.closed = True


class _Source:
    """An iterable of scans that fails (or is interrupted) after ``stop_at`` scans."""

    def __init__(self, scans: list[LaserScan], stop_at: int, error: BaseException) -> None:
        self.scans, self.stop_at, self.error = scans, stop_at, error
        self.position = "start"
        self.skipped: dict[str, int] = {}
        self.skip_examples: list[str] = []

    def __iter__(self) -> Iterator[LaserScan]:
        for i, scan in enumerate(self.scans):
            if i == self.stop_at:
                raise self.error
            self.position = f"row {i}"
            yield scan


def _scans(n: int) -> list[LaserScan]:
    rng = np.random.default_rng(3)
    return [corner_scan(noise_sigma=0.005, rng=rng) for _ in range(n)]


# ------------------------------------------------------------------ parameters
def test_params_choice_docstring_and_options() -> None:
    import laser_corners.choice as choice_module

    result = doctest.testmod(choice_module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0
    with pytest.raises(InvalidParamsError, match="not both"):
        ParamsChoice.from_options("auto", "p.yaml")
    with pytest.raises(InvalidParamsError, match="unknown preset 'nope'"):
        ParamsChoice.from_options("nope")
    with pytest.raises(InvalidParamsError, match="unknown parameter 'bogus'"):
        ParamsChoice.from_options(None, None, ["bogus=1"])
    choice = ParamsChoice.from_options("auto", None, ["min_points=6"])
    assert choice.label == "auto + overrides" and choice.overrides == ("min_points=6",)


def test_open_recording_resolves_the_preset_from_the_first_scan(tmp_path: Path) -> None:
    log = _log(tmp_path / "room.clf", 6, step_deg=0.5)
    recording = open_recording(log, params=ParamsChoice("auto"))
    assert recording.first.n_beams == 361
    assert recording.params == get_preset("auto", recording.first)
    assert recording.params != get_preset("paper")
    assert recording.description == "room.clf (carmen)" and recording.preset == "auto"
    assert len(list(recording.scans())) == 6  # the first scan once, then the rest
    assert len(list(recording.scans())) == 6  # and again from the start


def test_open_recording_without_a_readable_scan(tmp_path: Path) -> None:
    bad = tmp_path / "bad.clf"
    bad.write_text("ROBOTLASER1 0 -1.57 3.14 0.0174 50 0.1 0 180 1.0 2.0\n")
    with pytest.raises(InputError, match=r"bad\.clf: no readable scan \(line 1"):
        open_recording(bad)


def test_scan_at_says_how_many_scans_there_are(tmp_path: Path) -> None:
    log = _log(tmp_path / "room.clf", 4)
    source = open_recording(log).source
    assert scan_at(source, 3).stamp == pytest.approx(0.3)
    with pytest.raises(InputError, match=r"no scan 4; the recording has 4 scans \(0 to 3\)"):
        scan_at(source, 4)


# ------------------------------------------------------------------ the loop
def _room_scans(n: int) -> list[LaserScan]:
    """Simulated scans of the demo room; every 7th one by another sensor (another geometry)."""
    rng = np.random.default_rng(5)
    world = demo_world()
    return [
        world.scan(
            (0.4 + 0.02 * i, -0.3, 0.25),
            get_sensor("sick-1deg") if i % 7 == 3 else UST_10LX,
            noise_sigma=0.005,
            rng=rng,
        )
        for i in range(n)
    ]


@pytest.mark.parametrize("prefetch", [False, True])
@pytest.mark.parametrize("threads", [1, 2])
def test_the_loop_finds_what_detect_finds(prefetch: bool, threads: int) -> None:
    scans = _room_scans(40)
    detector = CornerDetector()
    found = [detector.detect(s) for s in scans]
    expected = [len(k) for k in found]
    source = _Source(scans, 99, RuntimeError("unused"))
    writer = _Recorder()
    summary = detect_recording(
        source, detector, writer, threads=threads, prefetch=prefetch, chunk_scans=16
    )
    assert writer.closed and not summary.interrupted
    assert writer.rows == list(enumerate(expected))
    np.testing.assert_array_equal(np.concatenate(writer.xy), np.concatenate([k.xy for k in found]))
    assert summary.n_scans == 40 and summary.n_keypoints == sum(expected) > 40
    assert summary.position == "row 39"
    assert summary.detect_seconds > 0 and summary.seconds >= summary.detect_seconds


def test_the_loop_over_a_recording(tmp_path: Path) -> None:
    log = _log(tmp_path / "room.clf", 12)
    recording = open_recording(log, params=ParamsChoice("auto"))
    summary = detect_recording(recording)
    assert summary.n_scans == 12 and summary.position == "line 12"


def test_the_loop_steps_and_stops(tmp_path: Path) -> None:
    scans = _scans(30)
    writer = _Recorder()
    summary = detect_recording(scans, CornerDetector(), writer, step=4, max_scans=5)
    assert [index for index, _ in writer.rows] == [0, 4, 8, 12, 16]
    assert summary.n_scans == 5


@pytest.mark.parametrize("prefetch", [False, True])
def test_a_read_error_keeps_the_scans_before_it(prefetch: bool) -> None:
    source = _Source(_scans(50), 37, InputError("x.log: truncated (at row 37)"))
    writer = _Recorder()
    with pytest.raises(InputError, match="truncated"):
        detect_recording(source, CornerDetector(), writer, prefetch=prefetch, chunk_scans=8)
    assert writer.closed and [index for index, _ in writer.rows] == list(range(37))


@pytest.mark.parametrize("prefetch", [False, True])
def test_ctrl_c_from_the_reader_stops_with_a_summary(prefetch: bool) -> None:
    source = _Source(_scans(60), 45, KeyboardInterrupt())
    writer = _Recorder()
    seen: list[RunSummary] = []
    summary = detect_recording(
        source,
        CornerDetector(),
        writer,
        progress=seen.append,
        every=10,
        prefetch=prefetch,
        chunk_scans=16,
    )
    assert summary.interrupted and writer.closed
    assert summary.n_scans == len(writer.rows) == 45 and summary.position == "row 44"
    assert seen[-1] is summary and len(seen) >= 3


def test_ctrl_c_in_the_detector_keeps_the_chunk_done_so_far(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    real = CornerDetector.detect
    calls = {"n": 0}

    def detect(self, scan, return_candidates=False):  # type: ignore[no-untyped-def]
        calls["n"] += 1
        if calls["n"] == 21:
            raise KeyboardInterrupt
        return real(self, scan, return_candidates)

    monkeypatch.setattr(CornerDetector, "detect", detect)
    writer = _Recorder()
    source = _Source(_scans(40), 99, RuntimeError("unused"))
    summary = detect_recording(source, CornerDetector(), writer, chunk_scans=256, prefetch=False)
    assert summary.interrupted and summary.n_scans == len(writer.rows) == 20
    assert summary.position == "row 19"


def test_ctrl_c_in_detect_many_keeps_the_blocks_done(monkeypatch: pytest.MonkeyPatch) -> None:
    real = CornerDetector.detect_many
    calls = {"n": 0}

    def detect_many(self, scans):  # type: ignore[no-untyped-def]
        calls["n"] += 1
        if calls["n"] == 2:  # the second block of 32
            raise KeyboardInterrupt
        return real(self, scans)

    monkeypatch.setattr(CornerDetector, "detect_many", detect_many)
    writer = _Recorder()
    source = _Source(_scans(100), 999, RuntimeError("unused"))
    summary = detect_recording(source, CornerDetector(), writer, prefetch=True)
    assert summary.interrupted and summary.n_scans == len(writer.rows) == 32
    assert summary.position == "row 31"
