"""Planning a batch (:mod:`laser_corners.batch.plan`): one job per LaserScan topic, unique output
names that stay with their job."""

from __future__ import annotations

from pathlib import Path

from conftest import real_file
from laser_corners.batch import (
    plan_jobs,
)


def test_plan_expands_topics_and_keeps_names_unique(tmp_path: Path) -> None:
    rooms = real_file("hokuyo270_rooms.bag")
    log = real_file("fr079-corrected.clf.gz")
    other = tmp_path / "robot2"
    other.mkdir()
    twin = other / log.name
    twin.write_bytes(log.read_bytes())

    jobs = plan_jobs([rooms, log, twin])
    topics = sorted(j.topic for j in jobs if j.input == str(rooms.resolve()))
    assert topics == ["/left_scan", "/rear_scan", "/right_scan"]
    names = [j.output for j in jobs]
    assert len(set(names)) == len(names) == 5
    assert "hokuyo270_rooms.left_scan.parquet" in names
    # the two logs of the same name get distinct names derived from their paths
    twins = [j.output for j in jobs if j.output.startswith("fr079-corrected")]
    assert len(twins) == 2 and "fr079-corrected.parquet" not in twins

    # a name used in the folder before stays with its job; another job never takes it
    reserved = {str(twin.resolve()): "fr079-corrected.parquet"}
    again = {j.key: j.output for j in plan_jobs([log, twin], reserved=reserved)}
    assert again[str(twin.resolve())] == "fr079-corrected.parquet"
    assert again[str(log.resolve())] != "fr079-corrected.parquet"

    only_left = plan_jobs([rooms], topic="/left_scan")
    assert [(j.topic, j.output) for j in only_left] == [
        ("/left_scan", "hokuyo270_rooms.left_scan.parquet")
    ]
