"""Kind detection and the choice of reader and writer: missing, empty and unknown files."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from conftest import real_file
from laser_corners import InputError
from laser_corners.errors import OutputError
from laser_corners.io import open_keypoint_writer, open_scans


def test_missing_and_empty_files(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such file"):
        open_scans(tmp_path / "absent.bag")
    for name in ("empty.bag", "empty.clf.gz", "empty.npz", "empty.csv"):
        (tmp_path / name).write_bytes(b"")
        with pytest.raises(InputError, match=re.escape(f"{tmp_path / name}: file is empty")):
            open_scans(tmp_path / name)


def test_unknown_kind_and_topic_on_a_log(tmp_path: Path) -> None:
    odd = tmp_path / "scan.xyz"
    odd.write_bytes(b"\x00\x01binary")
    with pytest.raises(InputError, match="unknown kind of recording"):
        open_scans(odd)
    with pytest.raises(InputError, match="a carmen file has no topics; a topic applies to bags"):
        open_scans(real_file("intel-corrected.clf.gz"), topic="/scan")


def test_unknown_output_suffix_and_bag_output_for_a_log(tmp_path: Path) -> None:
    source = open_scans(real_file("intel-corrected.clf.gz"))
    with pytest.raises(OutputError, match=r"unknown output kind '\.txt'"):
        open_keypoint_writer(tmp_path / "k.txt", source, with_map=True)
    with pytest.raises(InputError, match="a bag output needs a bag input"):
        open_keypoint_writer(tmp_path / "k.bag", source, with_map=True)


def test_a_ros1_bag_without_the_bag_suffix_is_one_clear_error(tmp_path: Path) -> None:
    renamed = tmp_path / "fr079.bag.orig"
    renamed.write_bytes(real_file("fr079.bag").read_bytes()[:100_000])
    with pytest.raises(InputError, match=r"fr079\.bag\.orig: a ROS 1 bag is read only under"):
        open_scans(renamed)
