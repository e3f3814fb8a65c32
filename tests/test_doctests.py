"""The examples in the core's docstrings run and print what they claim."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = [
    "laser_corners",
    "laser_corners.scan",
    "laser_corners.params",
    "laser_corners.kernel.linefit",
    "laser_corners.detector",
    "laser_corners.keypoints",
    "laser_corners.matching.descriptors",
    "laser_corners.matching.registration",
    "laser_corners.kernel.candidates",
    "laser_corners.kernel.merge",
    "laser_corners.noise",
    "laser_corners.presets",
    "laser_corners.registration.align",
    "laser_corners.registration.odometry",
    "laser_corners.slam.options",
    "laser_corners.localise.options",
]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name: str) -> None:
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0
