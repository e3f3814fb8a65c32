"""Readers of real recordings and writers of keypoints.

Read any supported recording with :func:`open_scans` (kind inferred from the path), write
keypoints with :func:`open_keypoint_writer` (CSV, Parquet, or a copy of the input bag with
keypoint topics). Formats and layouts: ``docs/io-and-cli.md``.
"""

from laser_corners.io.source import KINDS, ScanSource, detect_kind, open_scans
from laser_corners.io.writers import KeypointWriter, open_keypoint_writer

__all__ = [
    "KINDS",
    "KeypointWriter",
    "ScanSource",
    "detect_kind",
    "open_keypoint_writer",
    "open_scans",
]
