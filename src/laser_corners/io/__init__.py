"""Readers of real recordings and writers of keypoints.

Read any supported recording with :func:`open_scans` (kind inferred from the path), write
keypoints with :func:`open_keypoint_writer` (CSV, Parquet, or a copy of the input bag with
keypoint topics). Formats and layouts: ``docs/io-and-cli.md``.

Layout (imports only go down): :mod:`~laser_corners.io.base` (the two interfaces and shared
helpers; imports no reader or writer) < bag helpers (:mod:`~laser_corners.io.poses`, the ROS 1
fast path :mod:`laser_corners.io.ros1`, :mod:`~laser_corners.io.bagfile`,
:mod:`~laser_corners.io.messages`) < readers (:mod:`~laser_corners.io.rosbag`,
:mod:`~laser_corners.io.carmen`, :mod:`~laser_corners.io.arrays`) and writers
(:mod:`~laser_corners.io.writers`, :mod:`~laser_corners.io.bagwriter`) <
:mod:`~laser_corners.io.registry`, the only module that imports them all.
"""

from laser_corners.io.arrays import write_scans_csv, write_scans_npz
from laser_corners.io.base import (
    KINDS,
    KeypointWriter,
    ScanSource,
    TopicChoiceError,
    WriterSummary,
)
from laser_corners.io.registry import detect_kind, open_keypoint_writer, open_scans
from laser_corners.io.rosbag import BagSource
from laser_corners.io.writers import TABLE_COLUMNS, ParquetKeypointWriter

__all__ = [
    "KINDS",
    "TABLE_COLUMNS",
    "BagSource",
    "KeypointWriter",
    "ParquetKeypointWriter",
    "ScanSource",
    "TopicChoiceError",
    "WriterSummary",
    "detect_kind",
    "open_keypoint_writer",
    "open_scans",
    "write_scans_csv",
    "write_scans_npz",
]
