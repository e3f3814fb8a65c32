"""The final refinement pass: every keyframe re-aligned to its spatial neighbours' map.

After the final batch optimisation the map is globally consistent but held together only by the
keyframe chain and the few loop closures the online search found (one search every
``loop.every`` keyframes). This pass adds what Cartographer's constraint search adds online:
constraints from many keyframes to every submap near them, whatever the time between.

Every ``loop.submap_keyframes``-th keyframe (n) anchors a submap: the keyframes within 1.5 n
of it, in its frame, at their final estimates. Each ``refine_every``-th keyframe is aligned by
point-to-line ICP, from its final estimate, to at most ``refine_candidates`` submaps (nearest
first) whose anchor lies within ``loop.radius`` of it and at least ``refine_min_travel`` of
travel before or after it, and which do not hold the keyframe itself. An alignment becomes a
relative-pose factor under the loop closures' robust model when, as for a loop closure, at
least ``loop.min_score`` of the keyframe's points lie on the submap and the alignment is not
degenerate, and, the map being consistent already, when it moves the keyframe by less than
``agree_xy`` / ``agree_yaw``: a larger move is a wrong match, not a correction.
No search: the estimate is the guess.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from laser_corners.pose import between_many
from laser_corners.registration.align import PointMap, icp
from laser_corners.registration.points import ScanPoints
from laser_corners.slam.backend import Backend
from laser_corners.slam.loops import submap_points
from laser_corners.slam.options import SlamOptions

__all__ = ["RefineLinks", "refine", "refine_links"]

REFINE_PRIOR = 1e-6
"""Information (per m², per rad²) pulling a refinement alignment towards the estimate: none to
speak of, the submap decides."""


@dataclass
class RefineLinks:
    """Relative-pose measurements of the refinement pass (:func:`refine_links`).

    Attributes
    ----------
    match, query : ndarray of int
        The submap anchor keyframe and the re-aligned keyframe of each link.
    relative : ndarray, shape (L, 3)
        Measured pose of ``query`` in ``match``'s frame.
    tried : int
        Alignments tried.
    """

    match: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    query: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    relative: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    tried: int = 0

    def __len__(self) -> int:
        return int(self.query.shape[0])


def _submap(
    anchor: int, block: int, points: list[ScanPoints], estimate: NDArray[np.float64]
) -> tuple[PointMap, PointMap]:
    """Line points (with normals) and every point of the keyframes within ``1.5 block`` of
    the anchor, in the anchor's frame."""
    lo = max(0, anchor - block - block // 2)
    hi = min(len(points), anchor + block + block // 2 + 1)
    every, line_xy, normals = submap_points(anchor, list(range(lo, hi)), points, estimate)
    return PointMap.build(line_xy, normals), PointMap.build(every, np.zeros_like(every))


def _pairs(
    estimate: NDArray[np.float64],
    travelled: NDArray[np.float64],
    anchors: NDArray[np.int64],
    options: SlamOptions,
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """(keyframe, anchor) pairs to align: each ``refine_every``-th keyframe with its nearest
    ``refine_candidates`` anchors within ``loop.radius``, travelled apart by at least
    ``refine_min_travel``."""
    keys = np.arange(0, estimate.shape[0], options.refine_every)
    query, match = [], []
    for chunk in np.array_split(keys, max(1, keys.shape[0] // 256)):
        d = np.hypot(
            estimate[chunk, None, 0] - estimate[None, anchors, 0],
            estimate[chunk, None, 1] - estimate[None, anchors, 1],
        )
        apart = np.abs(travelled[chunk, None] - travelled[None, anchors])
        d[(d >= options.loop.radius) | (apart < options.refine_min_travel)] = np.inf
        n = min(options.refine_candidates, anchors.shape[0])
        near = np.argsort(d, axis=1)[:, :n]
        ok = np.isfinite(np.take_along_axis(d, near, axis=1))
        query.append(np.repeat(chunk, n).reshape(-1, n)[ok])
        match.append(anchors[near][ok])
    if not query:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    return np.concatenate(query), np.concatenate(match)


def refine_links(
    points: list[ScanPoints],
    estimate: NDArray[np.float64],
    travelled: NDArray[np.float64],
    options: SlamOptions,
) -> RefineLinks:
    """The refinement pass's measurements (module docstring) for keyframes with ``points``
    at their final ``estimate`` (K, 3) and ``travelled`` distance (K,)."""
    estimate = np.asarray(estimate, dtype=np.float64)
    block = options.loop.submap_keyframes
    anchors = np.arange(block // 2, estimate.shape[0], block, dtype=np.int64)
    if anchors.shape[0] == 0:
        return RefineLinks()
    query, match = _pairs(estimate, np.asarray(travelled), anchors, options)
    guesses = between_many(estimate[match], estimate[query])
    maps: dict[int, tuple[PointMap, PointMap]] = {}
    keep, measured = [], []
    prior = np.eye(3) * REFINE_PRIOR
    for i, (k, j) in enumerate(zip(query.tolist(), match.tolist(), strict=True)):
        if abs(k - j) <= block + block // 2:  # k is in the submap
            continue
        if j not in maps:
            maps[j] = _submap(j, block, points, estimate)
        line, every = maps[j]
        xy = points[k].xy
        if xy.shape[0] < 20 or len(line) < 20:
            continue
        aligned = icp(
            xy,
            line,
            guesses[i],
            prior,
            options.icp,
            inlier_distance=options.inlier_distance,
            overlap_map=every,
        )
        agree = (options.agree_xy, options.agree_yaw)
        if aligned.confirms(guesses[i], options.loop.min_score, *agree):
            keep.append(i)
            measured.append(aligned.pose)
    idx = np.asarray(keep, dtype=np.int64)
    return RefineLinks(
        match=match[idx],
        query=query[idx],
        relative=np.asarray(measured, dtype=np.float64).reshape(-1, 3),
        tried=int(query.shape[0]),
    )


def refine(
    backend: Backend,
    values: object,
    points: list[ScanPoints],
    travelled: NDArray[np.float64],
    options: SlamOptions,
) -> tuple[object, object, dict[str, int]]:
    """The refinement pass after the final optimisation (``values``): the links of
    :func:`refine_links` at ``backend``'s estimate, solved once more with them
    (:meth:`Backend.optimise`, robust and pruned as the loop closures): (graph, values,
    counts ``refine_tried`` / ``refine_links`` / ``refine_pruned``)."""
    links = refine_links(points, backend.estimate, travelled, options)
    sig = (options.loop.sigma_xy, options.loop.sigma_xy, options.loop.sigma_yaw)
    extra = [
        (int(j), int(k), rel, sig)
        for j, k, rel in zip(links.match, links.query, links.relative, strict=True)
    ]
    graph, values = backend.optimise(extra, start=values)
    counts = {
        "refine_tried": links.tried,
        "refine_links": len(links) - backend.extra_pruned,
        "refine_pruned": backend.extra_pruned,
    }
    return graph, values, counts
