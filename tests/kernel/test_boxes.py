"""Block boxes of the neighbourhood walk (:mod:`laser_corners.kernel.boxes`): bridged gaps stay
out, oriented boxes are tight."""

from __future__ import annotations

import numpy as np

from laser_corners.kernel.boxes import box_d2
from laser_corners.kernel.neighbourhood import (
    block_boxes,
)


def test_block_boxes_leave_out_bridged_gaps() -> None:
    """A block's box bounds its valid beams; a gap the walk bridges (at most ``max_gap``
    beams) stays out of it, a longer run (here across a block boundary) or, with ``max_gap``
    0, any gap makes the box infinite; a block of bridged gaps only is empty. (Points on the
    x axis: the wall direction is (1, 0), oriented or not.)"""
    x = np.arange(64, dtype=np.float64)
    y = np.zeros(64)
    x[3] = np.nan  # one dropout in block 0
    x[14:18] = np.nan  # a run of 4 across blocks 1 and 2
    x[40:42] = np.nan  # a run of 2 at the start of block 5
    x[48:56] = np.nan  # block 6: gaps only (a run of 8)
    y[np.isnan(x)] = np.nan
    valid = np.isfinite(x)
    inf = np.inf
    for oriented in (True, False):
        box = block_boxes(x, y, valid, 2, oriented)[0]
        assert box[:, :2].tolist() == [[1.0, 0.0]] * 8
        assert box[0, 2:].tolist() == [0.0, 7.0, 0.0, 0.0]
        assert box[5, 2:].tolist() == [42.0, 47.0, 0.0, 0.0]
        for b in (1, 2, 6):  # run of 4 > 2, run of 8 > 2: infinite
            assert box[b, 2:].tolist() == [-inf, inf, -inf, inf], b
        box8 = block_boxes(x, y, valid, 8, oriented)[0]
        assert box8[1, 2:].tolist() == [8.0, 13.0, 0.0, 0.0]
        assert box8[6, 2:].tolist() == [inf, -inf, inf, -inf]  # empty: never within
        box0 = block_boxes(x, y, valid, 0, oriented)[0]
        assert np.isinf(box0[[0, 1, 2, 5, 6], 2:]).all()
        assert box0[3, 2:].tolist() == [24.0, 31.0, 0.0, 0.0]


def test_oriented_boxes_are_tight_on_an_oblique_noisy_wall() -> None:
    """On a dense noisy wall at 30 degrees, seen from one of its points, a block's oriented
    box bounds the distance of its farthest point (:func:`box_d2`, with its rounding margin)
    to within 0.1 mm (the noise is 1 mm; an axis-aligned box is looser by about the noise),
    and never below it."""
    rng = np.random.default_rng(3)
    t = np.arange(40_000) * 1e-5
    noise = rng.normal(0.0, 0.001, t.size)  # range noise, along the beams from (1.5, -1)
    wall = np.stack([t * np.cos(0.5), t * np.sin(0.5)])
    beam = wall - np.array([[1.5], [-1.0]])
    beam /= np.linalg.norm(beam, axis=0)
    x, y = wall + beam * noise
    valid = np.ones(t.size, dtype=bool)
    tight = block_boxes(x, y, valid, 0, True)
    loose = block_boxes(x, y, valid, 0, False)
    j = 1000
    excess = {"tight": [], "loose": []}
    for b in range(1500, 2500):
        far = np.max((x[8 * b : 8 * b + 8] - x[j]) ** 2 + (y[8 * b : 8 * b + 8] - y[j]) ** 2)
        for name, box in (("tight", tight), ("loose", loose)):
            bound = box_d2(box, 0, b, x[j], y[j])
            assert bound >= far, (name, b)
            excess[name].append(np.sqrt(bound) - np.sqrt(far))
    assert max(excess["tight"]) < 1e-4
    assert np.median(excess["loose"]) > 2 * np.median(excess["tight"])
