"""The simulated world of the matching tests: a room with many corners.

(Not a conftest.py: test modules import it, and a second conftest would shadow
``tests/conftest.py`` in pytest's default import mode.)
"""

from __future__ import annotations

from laser_corners.sim import World


def corner_room() -> World:
    """An 8 x 6 m room with alcoves and five pillars (about 30 corners)."""
    w = World(name="corner room")
    w.add_polygon(
        [
            [-4, -3],
            [1, -3],
            [1, -2.4],
            [2, -2.4],
            [2, -3],
            [4, -3],
            [4, 0],
            [3.4, 0],
            [3.4, 1],
            [4, 1],
            [4, 3],
            [-1, 3],
            [-1, 2.2],
            [-2.5, 2.2],
            [-2.5, 3],
            [-4, 3],
        ]
    )
    w.add_polygon([[0.5, 0.5], [1.2, 0.5], [1.2, 1.0], [0.5, 1.0]])
    w.add_polygon([[-2.2, -1.0], [-1.6, -1.3], [-1.3, -0.7], [-1.9, -0.4]])
    w.add_polygon([[-0.5, -2.0], [0.0, -2.0], [0.0, -1.6], [-0.5, -1.6]])
    w.add_polygon([[2.2, 1.5], [2.8, 1.5], [2.8, 2.0], [2.2, 2.0]])
    w.add_polygon([[-3.2, 0.6], [-2.7, 0.9], [-2.9, 1.3]])
    return w
