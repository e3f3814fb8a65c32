"""Shared fixture of the localiser's parts' tests: the simulated building's map."""

from __future__ import annotations

import pytest
from test_localiser import BUILDING_PATH, building, loop_path, map_folder

from laser_corners.slam.mapfile import load_map


@pytest.fixture(scope="module")
def building_world(tmp_path_factory):
    """The simulated building's map (loaded) and the true poses of a loop through it."""
    truth = loop_path(BUILDING_PATH)
    return load_map(map_folder(tmp_path_factory.mktemp("map"), building(), truth)), truth
