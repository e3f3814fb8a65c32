"""Regular grids of square cells over the map frame (the observability maps' cells)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["Grid", "bounded_grid"]


@dataclass(frozen=True)
class Grid:
    """A regular grid of square cells over the map frame.

    Cell ``(row, col)`` covers ``x in [x0 + col*res, x0 + (col+1)*res)`` and
    ``y in [y0 + row*res, y0 + (row+1)*res)``: row 0 is the bottom (``origin="lower"``).

    Attributes
    ----------
    x0, y0 : float
        Lower-left corner of the grid, metres.
    resolution : float
        Cell side, metres.
    shape : tuple of int
        ``(rows, cols)``.
    """

    x0: float
    y0: float
    resolution: float
    shape: tuple[int, int]

    @classmethod
    def covering(cls, points: ArrayLike, resolution: float = 0.03, margin: float = 1.0) -> Grid:
        """The smallest grid holding ``points`` (shape (M, 2)) with ``margin`` around them."""
        xy = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        xy = xy[np.all(np.isfinite(xy), axis=1)]
        if xy.shape[0] == 0:
            xy = np.zeros((1, 2))
        lo = xy.min(axis=0) - margin
        hi = xy.max(axis=0) + margin
        cols = math.ceil((hi[0] - lo[0]) / resolution)
        rows = math.ceil((hi[1] - lo[1]) / resolution)
        return cls(float(lo[0]), float(lo[1]), float(resolution), (max(rows, 1), max(cols, 1)))

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """``(left, right, bottom, top)`` for ``imshow(..., origin="lower", extent=...)``."""
        rows, cols = self.shape
        return (
            self.x0,
            self.x0 + cols * self.resolution,
            self.y0,
            self.y0 + rows * self.resolution,
        )

    def cell_of(self, points: ArrayLike) -> NDArray[np.int64]:
        """``(row, col)`` of each point, shape (M, 2); may lie outside the grid."""
        xy = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        col = np.floor((xy[:, 0] - self.x0) / self.resolution).astype(np.int64)
        row = np.floor((xy[:, 1] - self.y0) / self.resolution).astype(np.int64)
        return np.stack([row, col], axis=1)

    def center_of(self, cells: ArrayLike) -> NDArray[np.float64]:
        """Map-frame centres of ``(row, col)`` cells, shape (M, 2)."""
        rc = np.asarray(cells, dtype=np.float64).reshape(-1, 2)
        return np.stack(
            [
                self.x0 + (rc[:, 1] + 0.5) * self.resolution,
                self.y0 + (rc[:, 0] + 0.5) * self.resolution,
            ],
            axis=1,
        )


def bounded_grid(
    keypoints_xy: ArrayLike,
    trajectory_xy: ArrayLike,
    reach: float,
    resolution: float = 0.03,
    max_cells: int = 2_000_000,
    margin: float = 1.0,
) -> tuple[Grid, list[str]]:
    """A grid over the keypoints that the sensor path can explain, with a bounded cell count.

    The grid covers the keypoints within ``reach`` of the bounding box of the sensor path
    (``trajectory_xy``), plus the path itself, with ``margin`` around them; keypoints farther
    away (e.g. from "no return" readings taken for echoes) do not widen it. When that would take
    more than ``max_cells`` cells, the cell side grows until it fits.

    Returns
    -------
    grid : Grid
    notes : list of str
        What was clipped or coarsened, in plain words (empty when nothing was).
    """
    kps = np.asarray(keypoints_xy, dtype=np.float64).reshape(-1, 2)
    path = np.asarray(trajectory_xy, dtype=np.float64).reshape(-1, 2)
    path = path[np.all(np.isfinite(path), axis=1)]
    notes: list[str] = []
    if len(path):
        lo = path.min(axis=0) - reach
        hi = path.max(axis=0) + reach
        inside = np.all((kps >= lo) & (kps <= hi), axis=1)
        if not np.all(inside):
            notes.append(
                f"{np.count_nonzero(~inside)} of {len(kps)} map-frame keypoints lie more than "
                f"{reach:.1f} m beyond the sensor path; left out of the maps"
            )
        kps = kps[inside]
    grid = Grid.covering(np.concatenate([kps, path]), resolution, margin)
    cells = grid.shape[0] * grid.shape[1]
    if cells > max_cells:
        coarse = resolution * math.sqrt(cells / max_cells) * 1.01
        grid = Grid.covering(np.concatenate([kps, path]), coarse, margin)
        notes.append(
            f"map of {cells} cells of {resolution:g} m over the limit of {max_cells}: cells "
            f"coarsened to {coarse:.3f} m ({grid.shape[1]} x {grid.shape[0]})"
        )
    return grid, notes
