"""Localisation on the Freiburg logs, in the two protocols of issue 20.

Usage::

    PYTHONPATH=src python benchmarks/bench_localise.py [LOG ...] [--cache DIR] [--starts 5]
        [--scans 1200] [--kidnap 300] [--json FILE] [--protocols same later]
        [--ros2 [--ros2-param NAME=VALUE ...]]

LOG defaults to ``fr079``, ``aces`` and ``intel`` (``../shared/data/real/LOG.bag`` with
``LOG.relations``). Maps are made with :func:`laser_corners.slam.run_slam` (default options)
and cached as ``slam`` output folders under ``--cache`` (default
``$TMPDIR/laser-corners-localise``), never in the repository.

**Same log**: the whole log is mapped; the localiser (no initial pose) starts at ``--starts``
scans spread over the log and runs ``--scans`` scans from each. Reported: travel (odometry,
m) to the first fix and whether it was within 0.5 m / 5° of the map's own trajectory
(``trajectory.tum``); the share of the scans after the first fix with an estimate within
0.3 m / 3° of it; *wrong* = estimates more than 0.5 m off (any, not only fixes); tracking ms
per scan (scans tracked, mean and p95) and ms per scan over all scans. **Kidnap**: from each
start the localiser runs 300 scans, then the input jumps ``--kidnap`` scans ahead with the
odometry made continuous across the jump (a robot carried away: the odometry does not see
it); reported: lost detected, relocalised, travel to the relocalisation, wrong estimates.

**Later visit**: the first half of the scans is mapped (``stop_scan``; ``--split`` another
share), the second half is localised in it with no initial pose; the map's trajectory (first
half) and the localiser's estimates (second half) are joined and scored with the relation
metric on every relation with a stamp in the second half, beside the full-log SLAM's
trajectory on the same relations;
*wrong* = second-half estimates more than 0.5 m from the full-log SLAM's pose of the scan
moved into the half map's frame through its nearest first-half pose (:func:`anchored_truth`:
the two SLAM maps agree locally but can bend differently, aces by metres). The relation
metric interpolates the joined trajectory across the scans without an estimate, so a gap
(the robot outside the half map, or not found yet) counts as error; ``posed`` scores only
the relations whose two stamps have a pose (within 0.1 s), with ``posed``/``relations``
their share; ``held`` fills every scan from the first fix on with the last estimate's
map -> odom applied to the odometry (the pose a robot would use, as the ROS node's ``/tf``
gives it) and leaves out the relations with a stamp before the first fix. *Gaps
dead-reckoned in the window*: the interpolated score again, with the scans that have no
estimate while a lost track's search window is open (``Localiser.window``, issue 20) given the
window's dead-reckoned pose; the localiser does not report these poses (no estimate there).
*First fix travel*: the search's travel (odometry, a turn counted as 0.5 m per radian, as
``fix_travel`` counts it), and in brackets the metres driven (turns not counted).

**Yardstick** (``--yardstick``): the full-log SLAM's own online estimates (each scan's pose as
:meth:`~laser_corners.slam.Slam.add` returns it, before later loop closures correct it), scored
on the later visit's relations: the best a causal estimator of this SLAM front end does on them
with the whole log to map, beside the localiser's online ratio; and both again on the
relations within the second half whose stamps are at most :data:`SHORT` s apart, where drift
cannot matter: what giving an estimate at each scan, before the later scans are seen, costs
against the final trajectory.

**ROS 2 node** (``--ros2``): the later visit's second half again through the ROS 2 node's
core in localise mode (:mod:`localise_ros2`: the bag's messages in log-time order through the
node's conversions, the options as node parameters, ``--ros2-param NAME=VALUE`` more of them),
scored by the same code; the table's *ROS 2 core online ratio* beside the CLI's ratio, and a
table of the node's counts and its largest pose difference from the CLI's estimates.

**Odometry frame** (``--odometry-frame x,y,yaw``, default :data:`ODOMETRY_FRAME`): the
localiser's odometry is the log's moved by this rigid transform, in every protocol (and the
node's odometry messages with ``--ros2``). A robot's odometry on a later visit starts in a
frame of its own; the log's odometry frame is the map's (the SLAM starts at its first
odometry pose), which a scan before the first fix could exploit by accident: with the
identity, fr079's later visit scored 1.07 where every other frame gives 1.65 (the engine,
then fed while unplaced, tracked in the odometry's frame). ``0,0,0`` gives the log's own.

``--table FILE`` writes the tables (markdown, with the command, date and machine).

Timings are of this machine under whatever else runs on it (2 cores shared).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from laser_corners.eval.relations import read_relations, relation_metrics
from laser_corners.io.trajectory import read_tum
from laser_corners.kernel_cache import source_key
from laser_corners.localise import LocaliseOptions, Localiser
from laser_corners.localise.run import smoothing_slam
from laser_corners.localise.smooth import smooth
from laser_corners.pipeline.recording import open_recording
from laser_corners.pose import between_many, compose_many, invert_many
from laser_corners.registration.mapfolder import load_map
from laser_corners.slam import Slam, SlamOptions, run_slam
from laser_corners.slam.output import SlamRunInfo
from laser_corners.viz.slam_report import write_slam_outputs

sys.path.insert(0, str(Path(__file__).resolve().parent))
from localise_ros2 import parse_parameters, published, replay
from report import write_table

REAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
ODOMETRY_FRAME = (50.0, -30.0, 1.0)
"""The localiser's odometry frame in the log's (x m, y m, yaw rad): see the module notes."""


def read_log(path: Path) -> tuple[list, np.ndarray, np.ndarray]:
    """Every scan with odometry: scans, base odometry (N, 3), stamps (N,)."""
    scans, odo, stamps = [], [], []
    with open_recording(path, None) as rec:
        mounts = getattr(rec.source, "mounts", {})
        for scan in rec.scans():
            if scan.pose is None or scan.stamp is None:
                continue
            undo = invert_many(mounts.get(scan.frame_id) or (0.0, 0.0, 0.0))
            scans.append(scan)
            odo.append(compose_many(np.asarray(scan.pose), undo))
            stamps.append(float(scan.stamp))
    return scans, np.array(odo), np.array(stamps)


def cached_map(path: Path, folder: Path, stop_scan: int | None) -> Path:
    """A ``slam`` output folder for ``path``, made once per version of the sources: a map
    cached by other code is made again: the figures must come from the code that reports
    them (until 2026-12-08 a cached map was kept whatever made it; intel's later visit scored
    1.44 on maps cached by earlier code, 1.55 on maps made by the code of that day)."""
    stamp = folder / "made-by.txt"
    made_by = source_key()  # the package imported, all its sources
    if (folder / "keyframes.npz").is_file() and stamp.is_file():
        if stamp.read_text().strip() == made_by:
            return folder
    if folder.exists():
        print(f"{folder}: made by other code, mapping again", file=sys.stderr)
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    start = time.perf_counter()
    result = run_slam(path, stop_scan=stop_scan)
    info = SlamRunInfo(str(path), time.perf_counter() - start, 0.0)
    write_slam_outputs(result, folder, info)
    stamp.write_text(made_by + "\n")
    return folder


def pose_error(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    d = between_many(b, a)
    return math.hypot(d[0], d[1]), abs(math.degrees(d[2]))


def drive(loc, saved, scans, odo, stamps, order, ref) -> dict:
    """Feed the scans ``order``; score against ``ref`` (N, 3) poses by scan index."""
    rows = []
    travel = 0.0
    slam = smoothing_slam(saved, loc.mount) if loc.options.smooth.enabled else None
    estimates = []
    for n, i in enumerate(order):
        if n:
            d = between_many(odo[order[n - 1]], odo[i])
            travel += math.hypot(d[0], d[1])
        status = loc.status
        cpu = time.process_time()
        e = loc.add(scans[i], odo[i], stamps[i])
        cpu = (time.process_time() - cpu) * 1e3
        if slam is not None:
            slam.add(scans[i], odo[i], stamps[i])
        if e is not None:
            estimates.append(e)
        err = pose_error(e.pose, ref[i]) if e is not None else (math.inf, math.inf)
        rows.append((i, travel, e is not None, *err, status, loc.ms_per_scan[-1], cpu))
    if slam is None:
        return {"rows": rows, "smoothed": None}
    positions = np.array([e.scan_index for e in estimates], dtype=np.int64)
    sm = smooth(estimates, positions, slam.result(), loc.options)
    errors = [pose_error(p, ref[order[k]]) for k, p in zip(sm.index, sm.poses, strict=True)]
    return {"rows": rows, "smoothed": (sm.index, np.array(errors).reshape(-1, 2))}


def smoothed_score(smoothed, first: int | None, n_scans: int) -> dict | None:
    """Of the smoothed poses (``drive``): the share of the scans from ``first`` on within
    0.3 m / 3° of the reference, and the poses more than 0.5 m off."""
    if smoothed is None:
        return None
    index, err = smoothed
    good = (index >= (first or 0)) & (err[:, 0] <= 0.3) & (err[:, 1] <= 3.0)
    after = n_scans - first if first is not None else 0
    return {
        "share_within": float(good.sum() / after) if after else 0.0,
        "wrong": int((err[:, 0] > 0.5).sum()),
        "placed": len(index),
    }


def same_log(saved, scans, odo, stamps, ref, starts, n_scans, options) -> list[dict]:
    out = []
    for s in starts:
        loc = Localiser(saved, options)
        order = np.arange(s, min(s + n_scans, len(scans)))
        driven = drive(loc, saved, scans, odo, stamps, order, ref)
        rows = driven["rows"]
        got = [k for k, r in enumerate(rows) if r[2]]
        first = got[0] if got else None
        after = rows[first:] if first is not None else []
        good = sum(r[2] and r[3] <= 0.3 and r[4] <= 3.0 for r in after)
        tracked = [r[6] for r in rows if r[5] == "tracking"]
        cpu = [r[7] for r in rows if r[5] == "tracking"]
        out.append(
            {
                "start": int(s),
                "fix_travel": rows[first][1] if first is not None else None,
                "fix_correct": bool(
                    first is not None and rows[first][3] <= 0.5 and rows[first][4] <= 5
                ),
                "share_within": good / len(after) if after else 0.0,
                "wrong": sum(r[2] and r[3] > 0.5 for r in rows),
                "lost": loc.counts["lost"],
                "ms_tracking_mean": float(np.mean(tracked)) if tracked else None,
                "ms_tracking_p95": float(np.percentile(tracked, 95)) if tracked else None,
                "ms_tracking_median": float(np.median(tracked)) if tracked else None,
                "cpu_ms_tracking_mean": float(np.mean(cpu)) if cpu else None,
                "ms_all_mean": float(np.mean([r[6] for r in rows])),
                "smoothed": smoothed_score(driven["smoothed"], first, len(rows)),
            }
        )
    return out


def carried(odo: np.ndarray, last: int, after: np.ndarray) -> np.ndarray:
    """The odometry of a robot carried from scan ``last`` to scan ``after[0]``: continuous
    (the scans ``after`` keep their motion, not their place; the odometry does not see it)."""
    shift = compose_many(odo[last], invert_many(odo[after[0]]))
    out = odo.copy()
    out[after] = compose_many(shift, odo[after])
    return out


def kidnap(saved, scans, odo, stamps, ref, starts, skip, options) -> list[dict]:
    """300 scans, then a jump of ``skip`` scans the odometry does not see, then 600 scans."""
    out = []
    for s in starts:
        before = np.arange(s, s + 300)
        after = np.arange(s + 300 + skip, s + 900 + skip)
        if after[-1] >= len(scans):
            continue
        odo2 = carried(odo, before[-1], after)
        loc = Localiser(saved, options)
        driven = drive(loc, saved, scans, odo2, stamps, np.r_[before, after], ref)
        rows = driven["rows"]
        later = rows[300:]
        lost_at = next((k for k, r in enumerate(later) if r[5] != "tracking"), None)
        fixes = [f for f in loc.fixes if f.scan_index >= 300]
        out.append(
            {
                "start": int(s),
                "tracking_before": rows[299][5] == "tracking" or rows[299][2],
                "lost_after_scans": lost_at,
                "relocalised": bool(fixes),
                "reloc_travel": fixes[0].travel if fixes else None,
                "wrong": sum(r[2] and r[3] > 0.5 for r in rows),
                "smoothed": smoothed_score(driven["smoothed"], None, len(rows)),
            }
        )
    return out


def anchored_truth(half_t, half_p, full_t, full_p, stamps) -> tuple[np.ndarray, np.ndarray]:
    """The full-log SLAM's pose of each scan at ``stamps``, moved into the half map's frame.

    The two SLAM runs agree locally (the same relation error on the first half) but not
    globally (aces: 1.1 m median after the best rigid alignment: a pose graph bends
    differently), so a second-half pose is compared in the half map's frame through its
    nearest first-half pose (nearest in the full-log frame): truth = H_j ∘ (F_j⁻¹ ∘ F_i).
    Returns the poses (S, 3) and the anchor distances (S,) in metres.
    """
    k = np.clip(np.searchsorted(full_t, half_t - 1e-4), 0, len(full_t) - 1)
    anchors_full = full_p[k]
    i = np.clip(np.searchsorted(full_t, stamps - 1e-4), 0, len(full_t) - 1)
    target = full_p[i]
    if len(target) == 0:
        return np.zeros((0, 3)), np.zeros(0)
    dist, j = cKDTree(anchors_full[:, :2]).query(target[:, :2])
    truth = compose_many(half_p[j], between_many(anchors_full[j], target))
    return truth, dist


def visit_cli(saved, options, scans, odo, stamps, half) -> dict:
    """The second half through the ``Localiser`` (the CLI's): per scan its estimate (stamp,
    pose, scan index, status), held and dead-reckoned poses, CPU ms while tracking; the
    smoothing SLAM (with ``options.smooth``) fed alongside."""
    loc = Localiser(saved, options)
    slam = smoothing_slam(saved, loc.mount) if options.smooth.enabled else None
    out: dict = {k: [] for k in ("est_t", "est_p", "est_i", "est_s", "held_t", "held_p", "dead_t")}
    out.update(dead_p=[], cpu_tracking=[], estimates=[], loc=loc, slam=slam, slam_cpu=0.0)
    out["given"] = list(range(half, len(scans)))
    map_to_odom = None  # the last map -> odom, applied to the odometry (what a robot uses)
    for i in range(half, len(scans)):
        tracking = loc.status == "tracking"
        cpu = time.process_time()
        e = loc.add(scans[i], odo[i], stamps[i])
        if tracking:  # CPU ms of the scans given while tracking (anchored or local)
            out["cpu_tracking"].append((time.process_time() - cpu) * 1e3)
        if slam is not None:
            cpu = time.process_time()
            slam.add(scans[i], odo[i], stamps[i])
            out["slam_cpu"] += time.process_time() - cpu
        if e is not None:
            out["estimates"].append(e)
            out["est_t"].append(stamps[i])
            out["est_p"].append(e.pose)
            out["est_i"].append(i)
            out["est_s"].append(e.status)
            map_to_odom = e.map_to_odom
        elif loc.window is not None:  # no estimate, a lost track's window open
            out["dead_t"].append(stamps[i])
            out["dead_p"].append(loc.window.pose)
        if map_to_odom is not None:  # every scan from the first fix on
            out["held_t"].append(stamps[i])
            out["held_p"].append(compose_many(map_to_odom, odo[i]))
    return out


def visit_ros2(path, folder, options, stamps, half, ros2: tuple) -> dict:
    """The second half through the ROS 2 node's core in localise mode (``localise_ros2``;
    ``ros2``: more node parameters and the odometry's frame): what :func:`visit_cli` gives,
    from the poses the node publishes; no smoothing (the node publishes online poses only)."""
    extra, frame = ros2
    run = replay(path, folder, options, float(stamps[half]), extra=extra, odometry_frame=frame)
    out = published(run, stamps)
    c = run.core.counts
    out.update(loc=run.core.estimator, slam=None, slam_cpu=0.0, estimates=[])
    out["node"] = {
        "parameters": {k: v for k, v in run.parameters.items() if k != "map"},
        "scans_given": run.scans_given,
        "processed": c.processed,
        "no_fix": c.no_fix,
        "no_odometry": c.no_odometry,
        "malformed": c.malformed,
        "still_waiting": len(run.core.pending),
        "messages": run.messages,
    }
    return out


def later_visit(
    path,
    cache,
    name,
    scans,
    odo,
    stamps,
    relations,
    full_traj,
    options,
    split: float = 0.5,
    ros2: tuple | None = None,
) -> dict:
    """Map the first half, localise the second half (see the module notes); ``ros2`` (node
    parameters, maybe none): through the ROS 2 node's core (:func:`visit_ros2`) instead of
    the ``Localiser`` directly."""
    half = int(len(scans) * split)
    tag = "half" if split == 0.5 else f"split{split:g}"
    folder = cached_map(path, cache / f"{name}-{tag}", stop_scan=half)
    saved = load_map(folder)
    map_t, map_p = read_tum(folder / "trajectory.tum")
    if ros2 is not None:
        v = visit_ros2(path, folder, options, stamps, half, ros2)
    else:
        v = visit_cli(saved, options, scans, odo, stamps, half)
    loc, slam, estimates = v["loc"], v["slam"], v["estimates"]
    est_t, est_p, est_i, est_s = v["est_t"], v["est_p"], v["est_i"], v["est_s"]
    held_t, held_p, dead_t, dead_p = v["held_t"], v["held_p"], v["dead_t"], v["dead_p"]
    cpu_tracking, given = v["cpu_tracking"], v["given"]
    est_p = np.array(est_p).reshape(-1, 3)
    truth, anchor = anchored_truth(map_t, map_p, *full_traj, stamps[np.array(est_i, int)])
    err = np.array([pose_error(e, t)[0] for e, t in zip(est_p, truth, strict=True)])
    t_half = stamps[half]
    first = map_t < t_half
    joined_t = np.r_[map_t[first], np.array(est_t)]
    joined_p = np.vstack([map_p[first], est_p])
    rel = relations[(relations[:, 0] >= t_half) | (relations[:, 1] >= t_half)]
    spanning = (rel[:, 0] < t_half) | (rel[:, 1] < t_half)
    ours = relation_metrics(joined_t, joined_p, rel)
    # the same with the lost tracks' dead-reckoned poses filling the gaps while the window is
    # open (the localiser gives no estimate there: what a caller could do with Localiser.window)
    order = np.argsort(np.r_[joined_t, dead_t], kind="stable")
    dead = relation_metrics(
        np.r_[joined_t, dead_t][order],
        np.vstack([joined_p, np.reshape(dead_p, (-1, 3))])[order],
        rel,
    )
    full = relation_metrics(full_traj[0], full_traj[1], rel)
    # only the relations whose two stamps have a pose (no interpolation across a gap)
    have = np.r_[map_t[first], np.array(est_t)]
    have.sort()

    def posed(t: np.ndarray) -> np.ndarray:
        k = np.clip(np.searchsorted(have, t), 1, max(len(have) - 1, 1))
        return np.minimum(abs(have[k] - t), abs(have[k - 1] - t)) <= 0.1

    both = posed(rel[:, 0]) & posed(rel[:, 1]) if len(have) > 1 else np.zeros(len(rel), bool)
    ours_posed = relation_metrics(joined_t, joined_p, rel[both])
    full_posed = relation_metrics(full_traj[0], full_traj[1], rel[both])
    # held: the first half's poses, then every scan from the first fix on; the relations
    # with a stamp between the two (before the first fix) are left out
    held_tt = np.r_[map_t[first], np.array(held_t)]
    held_pp = np.vstack([map_p[first], np.array(held_p).reshape(-1, 3)])
    gap = (rel[:, :2] >= t_half) & (rel[:, :2] < (held_t[0] if held_t else np.inf))
    kept = rel[~gap.any(axis=1)]
    ours_held = relation_metrics(held_tt, held_pp, kept)
    full_held = relation_metrics(full_traj[0], full_traj[1], kept)
    smoothed = None
    if slam is not None:
        smoothed = smoothed_visit(
            slam, estimates, options, (map_t[first], map_p[first]), rel, spanning, full_traj
        )
        smoothed["slam_cpu_ms_per_scan"] = v["slam_cpu"] * 1e3 / (len(scans) - half)
        truth, dist = anchored_truth(map_t, map_p, *full_traj, smoothed.pop("stamps"))
        off = np.array(
            [pose_error(p, t)[0] for p, t in zip(smoothed.pop("poses"), truth, strict=True)]
        )
        smoothed["off_05"] = int((off > 0.5).sum())
        # the reference is only as good as its anchor (the nearest first-half pose) is near
        smoothed["off_05_near"] = int(((off > 0.5) & (dist < 2.0)).sum())
        smoothed["near"] = int((dist < 2.0).sum())
        smoothed["off_anchor_median"] = float(np.median(dist[off > 0.5])) if off.size else None
    return {
        "online": (np.array(est_t), est_p),  # popped by run_log (not in the JSON)
        "node": v.get("node"),
        "smoothed": smoothed,
        "relations": len(rel),
        "spanning": int(spanning.sum()),
        "covered": ours.n_covered,
        "joined_trans": ours.trans_mean,
        "joined_rot": ours.rot_deg_mean,
        "dead_reckoned": len(dead_t),
        "joined_dead_trans": dead.trans_mean,
        "full_trans": full.trans_mean,
        "full_rot": full.rot_deg_mean,
        "spanning_trans": relation_metrics(joined_t, joined_p, rel[spanning]).trans_mean,
        "posed": int(both.sum()),
        "posed_spanning": int((both & spanning).sum()),
        "posed_trans": ours_posed.trans_mean,
        "posed_full_trans": full_posed.trans_mean,
        "held": len(kept),
        "held_trans": ours_held.trans_mean,
        "held_full_trans": full_held.trans_mean,
        "first_fix_travel": loc.fixes[0].travel if loc.fixes else None,
        "first_fix_driven": driven(odo, half, given[loc.fixes[0].scan_index])
        if loc.fixes
        else None,
        "reacquired": loc.counts["reacquired"],
        "fixes": [
            {
                "scan": given[f.scan_index],
                "travel": f.travel,
                "error": float(e),
                "window": f.windowed,
            }
            for f, e in zip(
                loc.fixes,
                [err[est_i.index(given[f.scan_index])] for f in loc.fixes],
                strict=True,
            )
        ],
        "estimates": len(est_t),
        "scans": len(scans) - half,
        "lost": loc.counts["lost"],
        "wrong": int((err > 0.5).sum()),
        "local": loc.counts["local"],
        "wrong_local": int(((err > 0.5) & (np.array(est_s) == "local")).sum()),
        "wrong_anchor_median": float(np.median(anchor[err > 0.5])) if (err > 0.5).any() else None,
        "error_max": float(err.max()) if len(err) else None,
        "cpu_ms_tracking_mean": float(np.mean(cpu_tracking)) if cpu_tracking else None,
        "worst": worst_relations(joined_t, joined_p, rel, t_half, both),
        "error_median": float(np.median(err)) if len(err) else None,
        "error_p95": float(np.percentile(err, 95)) if len(err) else None,
        "anchor_p95": float(np.percentile(anchor, 95)) if len(anchor) else None,
    }


def driven(odo: np.ndarray, first: int, last: int) -> float:
    """Metres driven (odometry translation, turns not counted) from scan ``first`` to ``last``:
    the localiser's travel counts a turn as 0.5 m per radian."""
    return float(np.hypot(*np.diff(odo[first : last + 1, :2], axis=0).T).sum())


def smoothed_visit(slam, estimates, options, first_half, rel, spanning, full_traj) -> dict:
    """The smoothed trajectory (``localise.smooth``) of the second half joined to the map's
    first half, scored as the joined one; its poses and stamps for the caller's check."""
    result = slam.result()
    cpu = time.process_time()
    positions = np.array([e.scan_index for e in estimates], dtype=np.int64)
    sm = smooth(estimates, positions, result, options)
    solve_s = time.process_time() - cpu
    joined_t, joined_p = np.r_[first_half[0], sm.stamps], np.vstack([first_half[1], sm.poses])

    def ratio(mask: np.ndarray) -> list[float]:
        ours = relation_metrics(joined_t, joined_p, rel[mask])
        full = relation_metrics(full_traj[0], full_traj[1], rel[mask])
        return [ours.trans_mean, ours.rot_deg_mean, full.trans_mean, full.rot_deg_mean]

    return {
        "all": ratio(np.ones(len(rel), bool)),
        "spanning": ratio(spanning),
        "within": ratio(~spanning),
        "placed": len(sm.index),
        "anchors": sm.anchors,
        "closures": sm.closures,
        "segments_dropped": sm.segments_dropped,
        "cuts": len(result.cuts),
        "solve_cpu_s": solve_s,
        "stamps": sm.stamps,
        "poses": sm.poses,
    }


def worst_relations(stamps, poses, rel, t_half, posed, n: int = 5) -> dict:
    """Where the joined trajectory's relation error sits: the share of the summed error
    carried by the worst 5 % of the relations, by the relations with a stamp in a gap (no
    pose within 0.1 s), and the ``n`` worst (stamps from the half, error m, posed)."""
    err = np.array(
        [relation_metrics(stamps, poses, rel[k : k + 1]).trans_mean for k in range(len(rel))]
    )
    err = np.nan_to_num(err)
    total = max(float(err.sum()), 1e-12)
    order = np.argsort(-err)
    top = order[: max(1, len(err) // 20)]
    return {
        "top5pct_share": float(err[top].sum() / total),
        "gap_share": float(err[~posed].sum() / total),
        "gap_relations": int((~posed).sum()),
        "worst": [
            [
                round(float(rel[k, 0] - t_half), 1),
                round(float(rel[k, 1] - t_half), 1),
                round(float(err[k]), 3),
                bool(posed[k]),
            ]
            for k in order[:n]
        ],
    }


def run_log(name: str, args, options) -> dict:
    path = REAL / f"{name}.bag"
    relations = read_relations(REAL / f"{name}.relations")
    folder = cached_map(path, args.cache / f"{name}-full", None)
    saved = load_map(folder)
    scans, odo, stamps = read_log(path)
    odo = compose_many(args.odometry_frame, odo)  # the localiser's odometry: a frame of its own
    traj = read_tum(folder / "trajectory.tum")
    # the same scans: stamps equal up to the TUM file's rounding (never the next scan's)
    idx = np.clip(np.searchsorted(traj[0], stamps - 1e-4), 0, len(traj[0]) - 1)
    ref = traj[1][idx]
    starts = np.linspace(0, len(scans) - args.scans - 1, args.starts).astype(int)
    k_starts = np.linspace(0, len(scans) - 900 - args.kidnap - 1, args.starts).astype(int)
    result = {"log": name, "scans": len(scans)}
    if "same" in args.protocols:
        result["same_log"] = same_log(saved, scans, odo, stamps, ref, starts, args.scans, options)
        result["kidnap"] = kidnap(saved, scans, odo, stamps, ref, k_starts, args.kidnap, options)
    if "later" not in args.protocols:
        return result
    visit = (path, args.cache, name, scans, odo, stamps, relations, traj, options, args.split)
    result["later"] = later_visit(*visit)
    online = result["later"].pop("online")
    if args.ros2:
        ros2 = (parse_parameters(args.ros2_param), args.odometry_frame)
        result["later_ros2"] = later_visit(*visit, ros2=ros2)
        result["later_ros2"]["agreement"] = agreement(online, result["later_ros2"].pop("online"))
    if args.yardstick:
        t_half = stamps[int(len(scans) * args.split)]
        rel = relations[(relations[:, 0] >= t_half) | (relations[:, 1] >= t_half)]
        slam = slam_online(scans, odo, stamps, saved.mount)
        result["later"]["slam_online_trans"] = relation_metrics(stamps, slam, rel).trans_mean
        result["later"]["short"] = short_relations(relations, t_half, online, slam, stamps, traj)
    return result


SHORT = 2.0
"""Relations whose stamps are at most this far apart (s): the yardstick's short ones."""


def short_relations(relations, t_half, online, slam, stamps, full_traj) -> dict:
    """The relations within the second half at most :data:`SHORT` s apart, scored on the
    localiser's online estimates, the full-log SLAM's online estimates and its final
    trajectory: what an estimate given at each scan costs where drift cannot matter."""
    rel = relations[(relations[:, 0] >= t_half) & (relations[:, 1] - relations[:, 0] <= SHORT)]
    est_t, est_p = online
    return {
        "relations": len(rel),
        "localiser": relation_metrics(est_t, est_p, rel).trans_mean,
        "slam_online": relation_metrics(stamps, slam, rel).trans_mean,
        "final": relation_metrics(full_traj[0], full_traj[1], rel).trans_mean,
    }


def agreement(cli, node) -> dict:
    """The node's published poses against the CLI localiser's, by scan stamp: scans with an
    estimate in both, in one only, and the largest difference (m, deg) where both have one."""
    (t_cli, p_cli), (t_node, p_node) = cli, node
    common, a, b = np.intersect1d(t_cli, t_node, return_indices=True)
    d = between_many(p_cli[a], p_node[b]).reshape(-1, 3)
    return {
        "both": len(common),
        "cli_only": len(t_cli) - len(common),
        "node_only": len(t_node) - len(common),
        "max_m": float(np.hypot(d[:, 0], d[:, 1]).max()) if len(d) else None,
        "max_deg": float(np.degrees(np.abs(d[:, 2])).max()) if len(d) else None,
    }


def slam_online(scans, odo, stamps, mount) -> np.ndarray:
    """The full-log SLAM's online pose of every scan (the yardstick, module notes)."""
    slam = Slam(SlamOptions(), mount)
    return np.array([slam.add(s, o, t)[0] for s, o, t in zip(scans, odo, stamps, strict=True)])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("logs", nargs="*", default=["fr079", "aces", "intel"])
    default_cache = Path(tempfile.gettempdir()) / "laser-corners-localise"
    parser.add_argument("--cache", type=Path, default=default_cache)
    parser.add_argument("--starts", type=int, default=5)
    parser.add_argument("--scans", type=int, default=1200)
    parser.add_argument("--kidnap", type=int, default=300)
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--set", action="append", default=[])
    parser.add_argument("--protocols", nargs="+", default=["same", "later"])
    parser.add_argument(
        "--split", type=float, default=0.5, help="later visit: share of the scans mapped"
    )
    parser.add_argument("--yardstick", action="store_true", help="the SLAM's online ratio too")
    parser.add_argument(
        "--odometry-frame",
        type=lambda v: np.array([float(x) for x in v.split(",")]),
        default=np.array(ODOMETRY_FRAME),
        help="x,y,yaw of the localiser's odometry frame in the log's (module notes)",
    )
    parser.add_argument("--table", type=Path, default=None, help="write the tables here")
    parser.add_argument(
        "--ros2",
        action="store_true",
        help="later visit also through the ROS 2 node's localise mode (localise_ros2.py)",
    )
    parser.add_argument(
        "--ros2-param",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="with --ros2: a node parameter (tf_wait=5, odom_topic=tf), over the options'",
    )
    args = parser.parse_args()
    options = LocaliseOptions().with_overrides(args.set) if args.set else LocaliseOptions()
    results = []
    for name in args.logs:
        start = time.perf_counter()
        results.append(run_log(name, args, options))
        results[-1]["wall_s"] = time.perf_counter() - start
        print(json.dumps(results[-1], default=float), flush=True)
    if args.json:
        args.json.write_text(json.dumps(results, indent=1, default=float))
    lines = table(results) + yardstick_table(results)
    print(os.linesep.join(lines))
    if args.table:
        write_table(args.table, "Localisation on the Freiburg logs (bench_localise)", lines)


def yardstick_table(results: list[dict]) -> list[str]:
    """The later visit's online ratio beside the full-log SLAM's own online estimates'."""
    rows = [r for r in results if "slam_online_trans" in r.get("later", {})]
    if not rows:
        return []
    lines = [
        "",
        "| log | localiser online / full-log SLAM (final) | full-log SLAM online / final "
        f"| relations ≤ {SHORT:g} s apart in the second half: count, final m "
        "| there: localiser online / final | there: full-log SLAM online / final |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        v, short = r["later"], r["later"]["short"]
        lines.append(
            f"| {r['log']} | {v['joined_trans'] / v['full_trans']:.2f} "
            f"| {v['slam_online_trans'] / v['full_trans']:.2f} "
            f"| {short['relations']}, {short['final']:.4f} "
            f"| {short['localiser'] / short['final']:.2f} "
            f"| {short['slam_online'] / short['final']:.2f} |"
        )
    return lines


def table(results: list[dict]) -> list[str]:
    lines = [
        "| log | fix travel m (5 starts) | correct fixes | share ≤0.3 m/3° | wrong | lost "
        "| tracking ms wall mean / median / p95, CPU mean "
        "| kidnaps relocalised (travel m) | kidnap wrong |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        if "same_log" not in r:
            continue
        s, k = r["same_log"], r["kidnap"]
        share = ", ".join(f"{x['share_within']:.3f}" for x in s)
        travel = ", ".join("-" if x["fix_travel"] is None else f"{x['fix_travel']:.1f}" for x in s)
        ms = [x["ms_tracking_mean"] for x in s if x["ms_tracking_mean"] is not None]
        p95 = [x["ms_tracking_p95"] for x in s if x["ms_tracking_p95"] is not None]
        med = [x["ms_tracking_median"] for x in s if x["ms_tracking_median"] is not None]
        cpu = [x["cpu_ms_tracking_mean"] for x in s if x["cpu_ms_tracking_mean"] is not None]
        kt = ", ".join("-" if x["reloc_travel"] is None else f"{x['reloc_travel']:.1f}" for x in k)
        lines.append(
            f"| {r['log']} | {travel} | {sum(x['fix_correct'] for x in s)}/{len(s)} "
            f"| {share} "
            f"| {sum(x['wrong'] for x in s)} | {sum(x['lost'] for x in s)} "
            f"| {np.mean(ms):.2f} / {np.mean(med):.2f} / {np.mean(p95):.2f}, {np.mean(cpu):.2f} "
            f"| {sum(x['relocalised'] for x in k)}/{len(k)} ({kt}) | {sum(x['wrong'] for x in k)} |"
        )
    rows = [smoothed_same_log(r) for r in results if "same_log" in r]
    if any(rows):
        lines += [
            "",
            "| log | smoothed: share ≤0.3 m/3° | smoothed > 0.5 m off "
            "| kidnaps: smoothed > 0.5 m off |",
            "|---|---|---|---|",
            *[row for row in rows if row],
        ]
    lines += later_table(results)
    lines += ros2_table(results)
    lines += smoothed_table(results)
    return lines


def later_table(results: list[dict]) -> list[str]:
    """The later visit's online (causal) estimates, one row per log."""
    if not any("later" in r for r in results):
        return []
    lines = [
        "",
        "| log | relations (spanning) | covered | joined m / deg | full-log SLAM m / deg "
        "| ratio | ROS 2 core online ratio "
        "| gaps dead-reckoned in the window: m, ratio (poses) | spanning m "
        "| posed relations (spanning) | posed: joined / full m, ratio "
        "| held relations: joined / full m, ratio "
        "| first fix travel m (driven m) | estimates / scans (local) | lost | wrong (local) "
        "| error median / p95 m | error share: worst 5 % of relations, gap relations |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        if "later" not in r:
            continue
        v = r["later"]
        ratio = v["joined_trans"] / v["full_trans"] if v["full_trans"] else math.nan
        node = r.get("later_ros2")
        node_ratio = f"{node['joined_trans'] / node['full_trans']:.2f}" if node else "-"
        fix = "-"
        if v["first_fix_travel"] is not None:
            fix = f"{v['first_fix_travel']:.1f} ({v['first_fix_driven']:.2f})"
        lines.append(
            f"| {r['log']} | {v['relations']} ({v['spanning']}) | {v['covered']} "
            f"| {v['joined_trans']:.4f} / {v['joined_rot']:.3f} "
            f"| {v['full_trans']:.4f} / {v['full_rot']:.3f} | {ratio:.2f} | {node_ratio} "
            f"| {v['joined_dead_trans']:.4f}, {v['joined_dead_trans'] / v['full_trans']:.2f} "
            f"({v['dead_reckoned']}) "
            f"| {v['spanning_trans']:.4f} | {v['posed']} ({v['posed_spanning']}) "
            f"| {v['posed_trans']:.4f} / {v['posed_full_trans']:.4f}, "
            f"{v['posed_trans'] / v['posed_full_trans']:.2f} "
            f"| {v['held']}: {v['held_trans']:.4f} / {v['held_full_trans']:.4f}, "
            f"{v['held_trans'] / v['held_full_trans']:.2f} "
            f"| {fix} | {v['estimates']} / {v['scans']} ({v['local']}) | {v['lost']} "
            f"| {v['wrong']} ({v['wrong_local']}) "
            f"| {v['error_median']:.3f} / {v['error_p95']:.3f} "
            f"| {v['worst']['top5pct_share']:.2f}, {v['worst']['gap_share']:.2f} |"
        )
    return lines


def ros2_table(results: list[dict]) -> list[str]:
    """The later visit through the ROS 2 node's core beside the CLI's localiser, one row per
    log (``--ros2``)."""
    rows = [r for r in results if "later_ros2" in r]
    if not rows:
        return []
    lines = [
        "",
        "| log | CLI online ratio | ROS 2 core online ratio | held ratio CLI / ROS 2 core "
        "| estimates CLI / ROS 2 core | scans given / processed / no fix / dropped (no "
        "odometry) / still waiting | estimates in both (CLI only, node only) "
        "| max pose difference m / deg | node parameters |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        v, n = r["later"], r["later_ros2"]
        node, agree = n["node"], n["agreement"]
        diff = "-" if agree["max_m"] is None else f"{agree['max_m']:.2g} / {agree['max_deg']:.2g}"
        params = ", ".join(f"{k}={val}" for k, val in node["parameters"].items())
        lines.append(
            f"| {r['log']} | {v['joined_trans'] / v['full_trans']:.2f} "
            f"| {n['joined_trans'] / n['full_trans']:.2f} "
            f"| {v['held_trans'] / v['held_full_trans']:.2f} / "
            f"{n['held_trans'] / n['held_full_trans']:.2f} "
            f"| {v['estimates']} / {n['estimates']} "
            f"| {node['scans_given']} / {node['processed'] + node['no_fix']} / {node['no_fix']} "
            f"/ {node['no_odometry']} / {node['still_waiting']} "
            f"| {agree['both']} ({agree['cli_only']}, {agree['node_only']}) | {diff} "
            f"| {params} |"
        )
    return lines


def smoothed_same_log(r: dict) -> str:
    """Same log and kidnaps with the smoothed trajectory: shares within 0.3 m / 3° and the
    poses more than 0.5 m off."""
    s = [x["smoothed"] for x in r["same_log"] if x.get("smoothed")]
    k = [x["smoothed"] for x in r["kidnap"] if x.get("smoothed")]
    if not s:
        return ""
    share = ", ".join(f"{x['share_within']:.3f}" for x in s)
    return (
        f"| {r['log']} | {share} | {sum(x['wrong'] for x in s)} "
        f"| {sum(x['wrong'] for x in k)} ({sum(x['placed'] for x in k)} poses) |"
    )


def smoothed_table(results: list[dict]) -> list[str]:
    """The later visit's smoothed trajectory (``localise.smooth``), one row per log."""
    if not any(r.get("later", {}).get("smoothed") for r in results):
        return []
    lines = [
        "",
        "| log | smoothed joined m / deg | full-log SLAM m / deg | ratio (rot) "
        "| spanning ratio | within ratio | scans placed / second half | anchors | closures "
        "| cuts (dropped) | poses > 0.5 m off (reference within 2 m of the half map: off / all)"
        " | SLAM CPU ms/scan | solve CPU s |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        v = r.get("later", {}).get("smoothed")
        if not v:
            continue
        a, sp, wi = v["all"], v["spanning"], v["within"]
        lines.append(
            f"| {r['log']} | {a[0]:.4f} / {a[1]:.3f} | {a[2]:.4f} / {a[3]:.3f} "
            f"| {a[0] / a[2]:.2f} ({a[1] / a[3]:.2f}) | {sp[0] / sp[2]:.2f} | {wi[0] / wi[2]:.2f} "
            f"| {v['placed']} / {r['later']['scans']} | {v['anchors']} | {v['closures']} "
            f"| {v['cuts']} ({v['segments_dropped']}) "
            f"| {v['off_05']} ({v['off_05_near']} / {v['near']}) "
            f"| {v['slam_cpu_ms_per_scan']:.2f} | {v['solve_cpu_s']:.2f} |"
        )
    return lines


if __name__ == "__main__":
    main()
