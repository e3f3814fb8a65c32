"""The whole-map search: the best distinct poses of a scan on a likelihood grid, by a
multi-resolution branch and bound (Hess et al. 2016) over a lattice of allowed positions.

A :class:`Pyramid` keeps, once per map, max-pooled copies of a
:class:`~laser_corners.registration.correlative.ScoreGrid`: level ``e`` holds, per cell, the
largest score of a sliding window of the cells a point moves over in a block of
``2^e x 2^e`` lattice positions. A :class:`Lattice` is the set of
positions a caller allows (near its keyframes, clear of walls, a window): ``origin + step *
(j, i)`` with ``step`` a whole number ``m`` of grid cells where ``allowed[i, j]``. Every pose
(position, heading) of the lattice is scored by the mean likelihood of the scan's points in
their cells, as an exhaustive search would; :func:`best_poses` returns the same answers
without scoring them all:

* a node of depth ``d`` is a block of ``2^d x 2^d`` lattice positions at one heading; its
  points' cells move over ``(2^d - 1) m + 1`` cells, so the sum of the pooled scores of the
  first level covering that window (level ``d`` when the pyramid was made for ``m``)
  bounds every pose of the block from above; a leaf (``d = 0``) is scored exactly;
* the nodes are kept in one max-heap by their bound, best first (from every heading's
  top-level blocks that hold an allowed position). A node popped is split into its allowed
  children; a leaf popped is the best pose not yet popped (every other node's bound, hence
  every pose under it, is no higher), so the leaves come out in decreasing score;
* the ``count`` best DISTINCT poses are taken greedily from that stream, as
  :func:`~laser_corners.pose.distinct_poses` does over the exhaustive scores sorted: a leaf
  is an answer when it is :func:`~laser_corners.pose.poses_apart` from every answer before
  it; a node whose every pose is too close to an answer is dropped unsplit. The answers are
  those of the exhaustive search (poses of equal score may swap).

Cost and memory: the pyramid has :data:`LEVELS` grids of about the map's grid size (one
byte a cell and level, plus a border of ``(2^e - 1) m`` cells each: 2.8 MB for aces' 592 x 592
cells), made once in ``O(LEVELS x cells x log w)``; both grow with the map's area. A search
costs the top level (headings x top blocks x points) plus the blocks whose bound beats the
``count``-th answer: the first answer a small share of the lattice; later distinct answers,
which score far below the first in a building of look-alikes, many more
(``docs/relocalisation.md``).

References
----------
W. Hess, D. Kohler, H. Rapp, D. Andor, "Real-time loop closure in 2D LIDAR SLAM", IEEE
International Conference on Robotics and Automation (ICRA), 2016.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numba
import numpy as np
from numpy.typing import NDArray

from laser_corners.pose import between_many, compose_many
from laser_corners.registration.correlative import ScoreGrid

__all__ = [
    "LEVELS",
    "QUANT",
    "SLICE_NODES",
    "Lattice",
    "Pyramid",
    "SlicedSearch",
    "best_poses",
    "carried",
]

LEVELS = 7
"""Pooled levels of a :class:`Pyramid` (blocks of 1 .. 64 lattice positions a side)."""
QUANT = 255
"""Steps of a pooled score (0 .. 1) in a :class:`Pyramid`'s bytes."""
SEED_BLOCKS = 4
"""Top-level blocks bounded per node of a :class:`SlicedSearch`'s budget (a bound reads each
point once, a node split reads it four times)."""
SLICE_NODES = 4000
"""Nodes of a :class:`SlicedSearch` spent per scan by its callers (localisation, SLAM
relocalisation): about 3 µs a node on average with 120 points on this project's shared 2-core
machine, some 12 ms a scan (``docs/relocalisation.md``). Fewer delay the answers: with 2,000,
fr079's right pose came 12 scans after the scan searched, too late for a fix before a
corridor (``tests/localise/test_places.py``)."""


def _window_max(a: NDArray[np.float32], w: int, axis: int) -> NDArray[np.float32]:
    """``out[i] = max(a[i - w + 1 .. i])`` along ``axis`` for ``i`` in ``0 .. n + w - 2``
    (zeros outside ``a``), by doubling windows (a sparse table)."""
    pad = [(0, 0), (0, 0)]
    pad[axis] = (w - 1, w - 1)
    z = np.pad(a, pad)
    length = a.shape[axis] + w - 1
    span = 1
    while 2 * span <= w:
        head = np.take(z, np.arange(z.shape[axis] - span), axis=axis)
        tail = np.take(z, np.arange(span, z.shape[axis]), axis=axis)
        z = np.maximum(head, tail)
        span *= 2
    first = np.take(z, np.arange(length), axis=axis)
    second = np.take(z, np.arange(w - span, w - span + length), axis=axis)
    return np.maximum(first, second)


@dataclass
class Pyramid:
    """Max-pooled levels of a likelihood grid, flat: level ``e`` is the ``shapes[e]`` block at
    ``offsets[e]`` of ``data``; its cell ``(r, c)`` holds the largest score of the grid's cells
    ``r - w + 1 .. r`` x ``c - w + 1 .. c``, ``w = (2^e - 1) cells + 1``: the cells a point
    moves over in a block of ``2^e x 2^e`` positions of a lattice of ``cells`` cells. Stored
    in :data:`QUANT` steps rounded up (one byte a cell and level: bounds stay bounds); the
    leaves are scored on the grid itself."""

    grid: ScoreGrid
    cells: int
    data: NDArray[np.uint8]
    offsets: NDArray[np.int64]
    shapes: NDArray[np.int64]

    @classmethod
    def build(cls, grid: ScoreGrid, cells: int = 1, levels: int = LEVELS) -> Pyramid:
        """The pyramid of ``grid`` for lattices of ``cells`` cells (level 0 is the grid)."""
        parts = []
        for e in range(levels):
            w = (2**e - 1) * cells + 1
            parts.append(_window_max(_window_max(grid.score, w, 0), w, 1))
        shapes = np.array([p.shape for p in parts], dtype=np.int64)
        sizes = np.array([p.size for p in parts], dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
        flat = np.concatenate([p.ravel() for p in parts]).astype(np.float64)
        data = np.minimum(np.ceil(flat * QUANT), QUANT).astype(np.uint8)  # float32 x 255: exact
        return cls(grid, cells, data, offsets, shapes)

    def width(self, e: int) -> int:
        """The window (cells) of level ``e``."""
        return (2**e - 1) * self.cells + 1

    @property
    def nbytes(self) -> int:
        """Memory of the pooled levels (bytes)."""
        return int(self.data.nbytes)


@dataclass
class Lattice:
    """The positions a search may take: ``origin + step * (j, i)`` where ``allowed[i, j]``,
    ``step`` being ``cells`` cells of the grid searched."""

    origin: NDArray[np.float64]
    cells: int
    allowed: NDArray[np.bool_]

    @cached_property
    def blocks(self) -> tuple[NDArray[np.bool_], NDArray[np.int64], NDArray[np.int64]]:
        """The allowed blocks of every depth up to one block covering the lattice
        (:func:`_masks`), made at the first search (``allowed`` must not change after)."""
        side = max(self.allowed.shape)
        return _masks(self.allowed, max(math.ceil(math.log2(max(side, 1))), 0))

    def positions(self, resolution: float) -> NDArray[np.float64]:
        """The allowed positions (K, 2) on a grid of ``resolution``, row by row."""
        i, j = np.nonzero(self.allowed)
        step = self.cells * resolution
        return np.column_stack([self.origin[0] + step * j, self.origin[1] + step * i])


def _levels(lattice: Lattice, pyramid: Pyramid) -> NDArray[np.int64]:
    """The pooled level bounding a node of each depth ``d`` (the last is the top one): the
    first whose window covers the ``(2^d - 1) m + 1`` cells a point moves over in the node,
    the top depth the deepest the pyramid bounds and no deeper than one block covering the
    lattice."""
    side = max(lattice.allowed.shape)
    n_levels = len(pyramid.offsets)
    level = [0]
    while 2 ** (len(level) - 1) < side:
        need = (2 ** len(level) - 1) * lattice.cells + 1
        e = next((e for e in range(n_levels) if pyramid.width(e) >= need), None)
        if e is None:
            break
        level.append(e)
    return np.array(level, dtype=np.int64)


def _masks(allowed: NDArray[np.bool_], depth: int) -> tuple[NDArray, NDArray, NDArray]:
    """The allowed blocks per depth, flat like :class:`Pyramid`: block ``(a, b)`` of depth
    ``d`` holds an allowed position of ``2^d a .. 2^d a + 2^d - 1`` (rows) x the same (cols)."""
    parts = [allowed.astype(np.bool_)]
    for _ in range(depth):
        a = parts[-1]
        a = np.pad(a, ((0, a.shape[0] % 2), (0, a.shape[1] % 2)))
        parts.append(a.reshape(a.shape[0] // 2, 2, a.shape[1] // 2, 2).any(axis=(1, 3)))
    shapes = np.array([p.shape for p in parts], dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum([p.size for p in parts])[:-1]]).astype(np.int64)
    return np.concatenate([p.ravel() for p in parts]), offsets, shapes


@numba.njit(cache=True, nogil=True)
def _bound(
    data: NDArray,
    offset: int,
    rows: int,
    cols: int,
    w: int,
    cy: NDArray[np.int64],
    cx: NDArray[np.int64],
    dy: int,
    dx: int,
) -> float:
    """Sum over the points of the pooled level (window ``w``) at the block whose cells start at
    ``cy + dy``, ``cx + dx``: an upper bound of the block's poses (exact for ``w = 1``)."""
    acc = 0.0
    for k in range(cy.shape[0]):
        r = cy[k] + dy + w - 1
        c = cx[k] + dx + w - 1
        if 0 <= r < rows and 0 <= c < cols:
            acc += data[offset + r * cols + c]
    return acc


@numba.njit(cache=True, nogil=True)
def _push(
    keys: NDArray[np.float64],
    nodes: NDArray[np.int64],
    size: int,
    key: float,
    d: int,
    h: int,
    a: int,
    b: int,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Push ``(key, node)`` on the max-heap ``keys[:size]``; the arrays, grown when full."""
    if size == keys.shape[0]:
        keys = np.concatenate((keys, np.empty_like(keys)))
        nodes = np.concatenate((nodes, np.empty_like(nodes)))
    i = size
    while i > 0 and keys[(i - 1) // 2] < key:
        parent = (i - 1) // 2
        keys[i] = keys[parent]
        nodes[i] = nodes[parent]
        i = parent
    keys[i] = key
    nodes[i, 0], nodes[i, 1], nodes[i, 2], nodes[i, 3] = d, h, a, b
    return keys, nodes


@numba.njit(cache=True, nogil=True)
def _pop(keys: NDArray[np.float64], nodes: NDArray[np.int64], size: int) -> None:
    """Move the last of ``keys[:size]`` to the root and sift it down (the root was taken)."""
    size -= 1
    key = keys[size]
    node = nodes[size].copy()
    i = 0
    while True:
        child = 2 * i + 1
        if child >= size:
            break
        if child + 1 < size and keys[child + 1] > keys[child]:
            child += 1
        if keys[child] <= key:
            break
        keys[i] = keys[child]
        nodes[i] = nodes[child]
        i = child
    if size > 0:
        keys[i] = key
        nodes[i] = node


@numba.njit(cache=True, nogil=True)
def _near(
    chosen: NDArray[np.float64], n_chosen: int, box: NDArray[np.float64], apart: NDArray
) -> bool:
    """Whether every pose of ``box`` (x0, y0, x1, y1, yaw) is too close to one answer:
    within ``apart[0]`` (m) of it and ``apart[1]`` (rad) of its heading (not apart)."""
    for q in range(n_chosen):
        dyaw = abs((box[4] - chosen[q, 2] + math.pi) % (2 * math.pi) - math.pi)
        if dyaw >= apart[1]:
            continue
        fx = max(abs(box[0] - chosen[q, 0]), abs(box[2] - chosen[q, 0]))
        fy = max(abs(box[1] - chosen[q, 1]), abs(box[3] - chosen[q, 1]))
        if math.hypot(fx, fy) < apart[0]:
            return True
    return False


@numba.njit(cache=True, nogil=True)
def _cells(
    pts: NDArray[np.float64], yaws: NDArray[np.float64], shift: NDArray[np.float64], res: float
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """The grid cell (row, col) of every point at every heading, at the lattice's origin
    (``shift``: lattice origin minus grid origin), per heading in row order (the lookups of
    a block then run through memory in order)."""
    cy = np.empty((yaws.shape[0], pts.shape[0]), dtype=np.int64)
    cx = np.empty_like(cy)
    for h in range(yaws.shape[0]):
        c = math.cos(yaws[h])
        s = math.sin(yaws[h])
        for k in range(pts.shape[0]):
            cx[h, k] = math.floor((c * pts[k, 0] - s * pts[k, 1] + shift[0]) / res)
            cy[h, k] = math.floor((s * pts[k, 0] + c * pts[k, 1] + shift[1]) / res)
        order = np.argsort(cy[h] * (1 << 32) + cx[h])
        cy[h] = cy[h][order]
        cx[h] = cx[h][order]
    return cy, cx


@numba.njit(cache=True, nogil=True)
def _seed(
    pyramid: tuple,
    masks: tuple,
    level: NDArray[np.int64],
    cy: NDArray[np.int64],
    cx: NDArray[np.int64],
    m: int,
    heap: tuple,
    state: NDArray[np.int64],
    budget: int,
) -> tuple[NDArray[np.float64], NDArray[np.int64], int]:
    """Push the top-level blocks ``state[2] ..`` (flat over headings, then rows, then columns)
    that hold an allowed position, at most ``budget`` of them looked at; the heap, its size in
    ``state[0]``, the next block in ``state[2]``; returns the heap and the blocks looked at."""
    score, data, offsets, shapes = pyramid
    allowed, m_offsets, m_shapes = masks
    keys, nodes = heap
    top = level.shape[0] - 1
    n_top = m_shapes[top, 0] * m_shapes[top, 1]
    total = cy.shape[0] * n_top
    spent = 0
    while state[2] < total and spent < budget:
        h, rest = state[2] // n_top, state[2] % n_top
        a, b = rest // m_shapes[top, 1], rest % m_shapes[top, 1]
        if allowed[m_offsets[top] + rest]:
            key = _node_bound(score, data, offsets, shapes, level, cy[h], cx[h], m, top, a, b)
            if key > 0.0:
                keys, nodes = _push(keys, nodes, state[0], key, top, h, a, b)
                state[0] += 1
        state[2] += 1
        spent += 1
    return keys, nodes, spent


@numba.njit(cache=True, nogil=True)
def _advance(
    pyramid: tuple,
    masks: tuple,
    level: NDArray[np.int64],
    cy: NDArray[np.int64],
    cx: NDArray[np.int64],
    geometry: NDArray[np.float64],
    yaws: NDArray[np.float64],
    apart: NDArray[np.float64],
    heap: tuple,
    state: NDArray[np.int64],
    chosen: NDArray[np.float64],
    scores: NDArray[np.float64],
    budget: int,
) -> tuple[NDArray[np.float64], NDArray[np.int64], int]:
    """The branch and bound (module notes), resumed: at most ``budget`` nodes (a node
    popped, or :data:`SEED_BLOCKS` top-level blocks bounded) from ``state`` (heap size,
    answers, next top-level block), whose arrays it updates in place: the answers so far in
    ``chosen`` / ``scores`` (pose, score sum). ``geometry``: lattice origin x, y, step (m),
    cells per step. Returns the heap (grown) and the nodes spent; the same sequence of nodes
    in one call or many."""
    score, data, offsets, shapes = pyramid
    allowed, m_offsets, m_shapes = masks
    m = int(geometry[3])
    # a top-level bound reads each point once, a node split four times: four to a node
    blocks = SEED_BLOCKS * budget if budget < 2**60 else budget
    keys, nodes, blocks = _seed(pyramid, masks, level, cy, cx, m, heap, state, blocks)
    spent = (blocks + SEED_BLOCKS - 1) // SEED_BLOCKS
    top = level.shape[0] - 1
    seeded = state[2] >= cy.shape[0] * m_shapes[top, 0] * m_shapes[top, 1]
    size, n_chosen = state[0], state[1]
    box = np.empty(5)
    four = np.empty(4)
    while seeded and size > 0 and n_chosen < chosen.shape[0] and spent < budget:
        spent += 1
        key = keys[0]
        d, h, a, b = nodes[0, 0], nodes[0, 1], nodes[0, 2], nodes[0, 3]
        _pop(keys, nodes, size)
        size -= 1
        span = 2**d
        box[0] = geometry[0] + geometry[2] * b * span
        box[1] = geometry[1] + geometry[2] * a * span
        box[2] = box[0] + geometry[2] * (span - 1)
        box[3] = box[1] + geometry[2] * (span - 1)
        box[4] = yaws[h]
        if _near(chosen, n_chosen, box, apart):
            continue
        if d == 0:
            chosen[n_chosen, 0], chosen[n_chosen, 1], chosen[n_chosen, 2] = box[0], box[1], box[4]
            scores[n_chosen] = key
            n_chosen += 1
            continue
        span = m * 2 ** (d - 1)
        _children(score, data, offsets, shapes, level[d - 1], cy[h], cx[h], span, a, b, four)
        rows, cols = m_shapes[d - 1, 0], m_shapes[d - 1, 1]
        for u in range(2):
            for v in range(2):
                ca, cb = 2 * a + u, 2 * b + v
                bound = four[2 * u + v]
                if bound > 0.0 and ca < rows and cb < cols:
                    if allowed[m_offsets[d - 1] + ca * cols + cb]:
                        keys, nodes = _push(keys, nodes, size, bound, d - 1, h, ca, cb)
                        size += 1
    state[0], state[1] = size, n_chosen
    return keys, nodes, spent


@numba.njit(cache=True, nogil=True)
def _children(
    score: NDArray[np.float32],
    data: NDArray[np.uint8],
    offsets: NDArray[np.int64],
    shapes: NDArray[np.int64],
    e: int,
    cy: NDArray[np.int64],
    cx: NDArray[np.int64],
    span: int,
    a: int,
    b: int,
    out: NDArray[np.float64],
) -> None:
    """The bounds (:func:`_bound`, level ``e``; the exact scores on ``score`` for ``e = 0``)
    of the four children ``(2a + u, 2b + v)`` of a node, ``span`` cells wide each, in one pass
    over the points: ``out[2u + v]``."""
    rows, cols = shapes[e, 0], shapes[e, 1]
    w = rows - shapes[0, 0] + 1
    out[:] = 0.0
    base = offsets[e]
    for k in range(cy.shape[0]):
        r0 = cy[k] + span * 2 * a + w - 1
        c0 = cx[k] + span * 2 * b + w - 1
        for u in range(2):
            r = r0 + u * span
            if 0 <= r < rows:
                for v in range(2):
                    c = c0 + v * span
                    if 0 <= c < cols:
                        if e == 0:
                            out[2 * u + v] += score[r * cols + c]
                        else:
                            out[2 * u + v] += data[base + r * cols + c]
    if e > 0:
        out /= QUANT


@numba.njit(cache=True, nogil=True)
def _node_bound(
    score: NDArray[np.float32],
    data: NDArray[np.uint8],
    offsets: NDArray[np.int64],
    shapes: NDArray[np.int64],
    level: NDArray[np.int64],
    cy: NDArray[np.int64],
    cx: NDArray[np.int64],
    m: int,
    d: int,
    a: int,
    b: int,
) -> float:
    """The bound of block ``(a, b)`` of depth ``d`` on its pooled level (:func:`_bound`;
    the exact score on ``score`` for ``d = 0``)."""
    e = level[d]
    span = m * 2**d
    if e == 0:
        return _bound(score, 0, shapes[0, 0], shapes[0, 1], 1, cy, cx, span * a, span * b)
    w = shapes[e, 0] - shapes[0, 0] + 1
    top = _bound(data, offsets[e], shapes[e, 0], shapes[e, 1], w, cy, cx, span * a, span * b)
    return top / QUANT


class SlicedSearch:
    """:func:`best_poses` in slices: a branch and bound that keeps its heap between calls of
    :meth:`advance`, each spending at most a budget of nodes, and gives the answers of the
    one-shot search (the same nodes in the same order, however sliced) once :attr:`done`.

    A node is a node taken from the heap (split into its four children, or a leaf scored:
    four lookups a point) or :data:`SEED_BLOCKS` top-level blocks bounded (one each), so a
    budget of nodes bounds the time of a slice whatever the map, while the answer does not
    depend on the load.

    Parameters
    ----------
    pyramid, lattice, points, yaws, count, apart
        As :func:`best_poses`; the query is frozen at construction.
    """

    def __init__(
        self,
        pyramid: Pyramid,
        lattice: Lattice,
        points: NDArray[np.float64],
        yaws: NDArray[np.float64],
        count: int,
        apart: tuple[float, float],
    ) -> None:
        grid = pyramid.grid
        points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
        yaws = np.ascontiguousarray(yaws, dtype=np.float64).ravel()
        self.n_points = len(points)
        self.nodes = 0
        """Nodes spent so far."""
        self.state = np.zeros(3, dtype=np.int64)  # heap size, answers, next top-level block
        self.chosen = np.zeros((max(int(count), 0), 3))
        self.scores = np.zeros(max(int(count), 0))
        self._done = len(points) == 0 or len(yaws) == 0 or count < 1
        if self._done or not lattice.allowed.any():
            self._done = True
            return
        shift = np.asarray(lattice.origin, dtype=np.float64) - grid.origin
        cy, cx = _cells(points, yaws, shift, grid.resolution)
        step = lattice.cells * grid.resolution
        geometry = np.array([lattice.origin[0], lattice.origin[1], step, lattice.cells], float)
        self._kernel = (
            (grid.score.ravel(), pyramid.data, pyramid.offsets, pyramid.shapes),
            lattice.blocks,
            _levels(lattice, pyramid),
            cy,
            cx,
            geometry,
            yaws,
            np.array(apart, dtype=np.float64),
        )
        self._heap = (np.empty(1024), np.empty((1024, 4), dtype=np.int64))
        shapes = lattice.blocks[2]
        self._top_blocks = len(yaws) * int(np.prod(shapes[len(self._kernel[2]) - 1]))

    @property
    def done(self) -> bool:
        """Whether the answers are final (:meth:`result`)."""
        return self._done

    def advance(self, budget: int) -> int:
        """Go on for at most ``budget`` (>= 1) nodes; the nodes spent (0 once :attr:`done`)."""
        if self._done:
            return 0
        keys, nodes, spent = _advance(
            *self._kernel, self._heap, self.state, self.chosen, self.scores, int(budget)
        )
        self._heap = (keys, nodes)
        self.nodes += spent
        size, n_chosen = self.state[0], self.state[1]
        seeded = self.state[2] >= self._top_blocks
        self._done = bool(seeded and (size == 0 or n_chosen >= len(self.scores)))
        return int(spent)

    def finish(self) -> list[tuple[NDArray[np.float64], float]]:
        """Go on to the end (no budget): the answers (:meth:`result`)."""
        self.advance(np.iinfo(np.int64).max)
        return self.result()

    def result(self) -> list[tuple[NDArray[np.float64], float]]:
        """The answers found so far (all of them once :attr:`done`): :func:`best_poses`'s."""
        n = int(self.state[1])
        return [(self.chosen[i].copy(), float(self.scores[i]) / self.n_points) for i in range(n)]


def best_poses(
    pyramid: Pyramid,
    lattice: Lattice,
    points: NDArray[np.float64],
    yaws: NDArray[np.float64],
    count: int,
    apart: tuple[float, float],
) -> list[tuple[NDArray[np.float64], float]]:
    """The ``count`` best poses of ``points`` (base frame) on ``lattice`` x ``yaws``, at least
    ``apart`` apart, best first: those of scoring every pose (module notes).

    Parameters
    ----------
    pyramid : Pyramid
        The pooled levels of the likelihood grid searched (made once per map).
    lattice : Lattice
        The positions allowed.
    points : ndarray, shape (N, 2)
        The scan's points in its base frame.
    yaws : ndarray, shape (Y,)
        The headings searched (rad).
    count : int
        Answers wanted at most.
    apart : tuple of float
        (m, rad): two answers are :func:`~laser_corners.pose.poses_apart` by this.

    Returns
    -------
    list of (ndarray (3,), float)
        Each answer's pose (x, y, yaw) and mean likelihood of its points, best first. Poses
        where no point scores are not answers: an empty scan or lattice, or a scan off the
        map, gives ``[]``.
    """
    return SlicedSearch(pyramid, lattice, points, yaws, count, apart).finish()


def carried(
    poses: list[NDArray[np.float64]], then: NDArray[np.float64], now: NDArray[np.float64]
) -> list[NDArray[np.float64]]:
    """Answers of a search of the scan at odometry ``then`` (map-frame poses of that scan)
    carried to the scan at odometry ``now``: each composed with the motion between them
    (``then`` and ``now`` in any one frame: the odometry's, or a segment's dead-reckoned
    estimate)."""
    motion = between_many(then, now)
    return [compose_many(p, motion) for p in poses]
