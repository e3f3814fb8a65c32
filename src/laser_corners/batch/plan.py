"""Planning: which jobs a batch runs, their output names, and which inputs are skipped.

One job per recording, one per LaserScan topic of a bag with several. An input that exists but
is not a recording (a ``.relations`` file, a README) is skipped with a reason instead of
failing; a missing or damaged recording still gets a job, which fails with the reader's
one-line error and is recorded in the manifest.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Iterable
from pathlib import Path

from laser_corners.batch.manifest import BatchJob, SkippedInput
from laser_corners.errors import InputError, first_line
from laser_corners.io import detect_kind
from laser_corners.pipeline import laser_topics

__all__ = ["check_globs", "not_a_recording", "plan_inputs", "plan_jobs", "short_hash"]

_BAG_KINDS = ("ros1", "ros2", "mcap")


def _stem(path: Path) -> str:
    name = path.name
    for suffix in (
        ".gz",
        ".bz2",
        ".bag",
        ".mcap",
        ".db3",
        ".clf",
        ".log",
        ".npz",
        ".csv",
        ".carmen",
        ".txt",
        ".gfs",
    ):
        if name.lower().endswith(suffix) and len(name) > len(suffix):
            name = name[: -len(suffix)]
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name) or "input"


def _topic_part(topic: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", topic.strip("/")) or "topic"


def short_hash(text: str) -> str:
    return hashlib.sha1(text.encode("utf-8")).hexdigest()[:8]


def plan_jobs(
    inputs: Iterable[str | Path],
    topic: str | None = None,
    reserved: dict[str, str] | None = None,
    odom_topic: str | None = None,
) -> list[BatchJob]:
    """The jobs for ``inputs``: one per recording, one per LaserScan topic of a bag with several.

    Parameters
    ----------
    inputs : iterable of str or Path
        Recordings (any kind :func:`laser_corners.io.open_scans` reads).
    topic : str, optional
        The LaserScan topic to read from every bag (other kinds have no topics). Default:
        every LaserScan topic of each bag, one job each.
    reserved : dict of str to str, optional
        Output names already used in the folder, by job key (from the manifest): a job keeps
        its earlier name; other jobs never take it.
    odom_topic : str, optional
        The odometry of every bag (a ``nav_msgs/Odometry`` topic or ``"tf"``; other kinds
        have none). Default: each bag's only one.

    Returns
    -------
    list of BatchJob
        An input that cannot be opened still gets a job (it fails when run, with the
        reader's one-line error, and the manifest records it).
    """
    reserved = dict(reserved or {})
    wanted: list[tuple[str, str | None, str, int, str | None]] = []  # + size, odometry
    seen: set[str] = set()
    for item in inputs:
        path = Path(item).expanduser().resolve()
        size = _input_size(path)
        topics: list[str | None] = [None]
        try:
            kind = detect_kind(path)
        except InputError:
            kind = None
        if kind in _BAG_KINDS:
            if topic is not None:
                topics = [topic]
            else:
                try:
                    found = laser_topics(path)
                    topics = list(found) if len(found) > 1 else [None]
                except InputError:
                    topics = [None]  # the job reports the error
        for one_topic in topics:
            key = str(path) + (f"#{one_topic}" if one_topic else "")
            if key in seen:
                continue
            seen.add(key)
            base = _stem(path) + (f".{_topic_part(one_topic)}" if one_topic else "")
            odom = odom_topic if kind in _BAG_KINDS else None
            wanted.append((str(path), one_topic, base, size // len(topics), odom))
    # names: the earlier name of the job, else the base name unless it clashes (with another
    # input of this run or a name used in the folder before), else base-<hash of the key>
    counts: dict[str, int] = {}
    for _, _, base, _, _ in wanted:
        counts[base] = counts.get(base, 0) + 1
    taken = {name: key for key, name in reserved.items()}
    jobs = []
    for input_path, one_topic, base, size, odom in wanted:
        key = input_path + (f"#{one_topic}" if one_topic else "")
        name = reserved.get(key)
        if name is None:
            name = f"{base}.parquet"
            if counts[base] > 1 or taken.get(name, key) != key:
                name = f"{base}-{short_hash(key)}.parquet"
            taken[name] = key
        jobs.append(BatchJob(input_path, one_topic, name, size, odom))
    return jobs


def _input_size(path: Path) -> int:
    try:
        if path.is_dir():
            return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())
        return path.stat().st_size
    except OSError:
        return 0


_LASER_WORDS = (b"FLASER", b"ROBOTLASER1", b"RAWLASER")
_PEEK_BYTES = 256 * 1024


def not_a_recording(path: str | Path) -> str | None:
    """Why ``path`` is not a recording (a few words), or None when it is one or may be one.

    Only a file or folder that exists and is of no known kind, or a text file without any
    CARMEN laser line at its start (a README), is "not a recording"; a missing or empty file is
    a recording that failed (its job says so).
    """
    path = Path(path).expanduser()
    try:
        if not path.exists() or (path.is_file() and path.stat().st_size == 0):
            return None
        kind = detect_kind(path)
        if kind == "carmen" and path.is_file():
            with path.open("rb") as handle:
                head = handle.read(_PEEK_BYTES)
            if not head.startswith(b"\x1f\x8b") and not any(w in head for w in _LASER_WORDS):
                return "text without CARMEN laser lines"
    except InputError as exc:
        reason = first_line(exc).removeprefix(f"{path}: ")
        return reason.split(";")[0]
    except OSError:
        return None
    return None


_GLOB = re.compile(r"[*?[]")


def check_globs(inputs: Iterable[str | Path]) -> None:
    """Refuse an input that does not exist and holds a glob character (``*``, ``?``, ``[``).

    A shell leaves a pattern that matches no file as it is; such an input is a typo or an
    empty folder, not a recording to run a job for.

    Raises
    ------
    InputError
        Naming the first such pattern.
    """
    for item in inputs:
        if _GLOB.search(str(item)) and not Path(item).expanduser().exists():
            raise InputError(f"{item}: no file matches this pattern")


def plan_inputs(
    inputs: Iterable[str | Path],
    topic: str | None = None,
    reserved: dict[str, str] | None = None,
    odom_topic: str | None = None,
) -> tuple[list[BatchJob], list[SkippedInput]]:
    """:func:`plan_jobs` for the recordings of ``inputs``, and the inputs that are not one."""
    recordings: list[str | Path] = []
    skipped: list[SkippedInput] = []
    for item in inputs:
        reason = not_a_recording(item)
        if reason is None:
            recordings.append(item)
        else:
            skipped.append(SkippedInput(str(item), reason))
    return plan_jobs(recordings, topic, reserved, odom_topic), skipped
