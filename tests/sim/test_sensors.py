"""Sensor profiles (:mod:`laser_corners.sim.sensors`) match the recordings they are named after."""

from __future__ import annotations

import math

import pytest

from laser_corners.errors import InvalidParamsError
from laser_corners.sim import (
    HOKUYO_270_0352,
    SENSORS,
    SICK_LMS_05DEG,
    SICK_LMS_1DEG,
    UST_10LX,
    get_sensor,
)


def test_sensor_profiles_match_their_recordings() -> None:
    assert UST_10LX.n_beams == 1081
    assert SICK_LMS_1DEG.n_beams == 180
    assert SICK_LMS_05DEG.n_beams == 360
    assert HOKUYO_270_0352.n_beams == 768
    assert HOKUYO_270_0352.angle_min == pytest.approx(-3 * math.pi / 4)
    assert HOKUYO_270_0352.angle_increment == pytest.approx(2 * math.pi / 1024)
    assert set(SENSORS) >= {"ust-10lx", "sick-1deg", "sick-0.5deg", "hokuyo-0.352deg"}
    with pytest.raises(InvalidParamsError, match="unknown sensor 'lms'"):
        get_sensor("lms")
