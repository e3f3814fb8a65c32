"""Which reader and which writer: the only module that imports them all.

``open_scans(path)`` guesses the kind of recording from the path and its first bytes (ROS 1 bag,
ROS 2 bag with sqlite3 or MCAP storage, CARMEN log plain or gzip, a ``.g2o`` file holding
laser lines, NPZ or CSV arrays) and returns a :class:`~laser_corners.io.base.ScanSource`.
``open_keypoint_writer(path, source)`` picks the writer from the suffix of ``path``.
Problems that make the whole file unusable raise :class:`~laser_corners.errors.InputError`
(one line naming the file and position); output paths that cannot be written raise
:class:`~laser_corners.errors.OutputError`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from laser_corners.errors import InputError, OutputError
from laser_corners.io.arrays import CsvSource, NpzSource
from laser_corners.io.bagwriter import BagKeypointWriter
from laser_corners.io.base import (
    BAG_KINDS,
    KINDS,
    KeypointWriter,
    ScanSource,
    SourceKind,
    read_head,
    refuse_input,
)
from laser_corners.io.carmen import CARMEN_SUFFIXES, CARMEN_WORDS, CarmenSource
from laser_corners.io.rosbag import BagSource
from laser_corners.io.writers import CsvKeypointWriter, ParquetKeypointWriter

__all__ = ["KINDS", "detect_kind", "open_keypoint_writer", "open_scans"]


def detect_kind(path: str | Path) -> SourceKind:
    """The kind of recording at ``path`` (from the suffix, else from the first bytes).

    Raises
    ------
    InputError
        When ``path`` is missing, empty or of no known kind.
    """
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such file or directory")
    if path.is_dir():
        if (path / "metadata.yaml").is_file():
            return "mcap" if any(path.glob("*.mcap")) else "ros2"
        raise InputError(
            f"{path}: a directory without metadata.yaml is not a ROS 2 bag; give a bag file, "
            "a ROS 2 bag directory, a CARMEN log, an .npz or a .csv"
        )
    if path.stat().st_size == 0:
        raise InputError(f"{path}: file is empty")
    head = read_head(path)
    suffixes = [s.lower() for s in path.suffixes]
    suffix = suffixes[-1] if suffixes else ""
    if suffix == ".bag" or head.startswith(b"#ROSBAG"):
        return "ros1"
    if suffix == ".mcap" or head.startswith(b"\x89MCAP"):
        return "mcap"
    if suffix == ".db3" or head.startswith(b"SQLite format 3"):
        return "ros2"
    if suffix == ".npz" or head.startswith(b"PK\x03\x04"):
        return "npz"
    if suffix == ".csv":
        return "csv"
    if suffix == ".gz" or set(suffixes) & CARMEN_SUFFIXES or head.startswith(b"\x1f\x8b"):
        return "carmen"
    if head.lstrip().startswith(CARMEN_WORDS):
        return "carmen"
    raise InputError(
        f"{path}: unknown kind of recording; expected a ROS 1 .bag, a ROS 2 bag (directory, "
        ".db3 or .mcap), a CARMEN log (.clf, .log, .g2o, .gz), an .npz or a .csv"
    )


def open_scans(
    path: str | Path, topic: str | None = None, *, odom_topic: str | None = None
) -> ScanSource:
    """Open a recording of 2D laser scans; the kind is inferred from the path and content.

    Parameters
    ----------
    path : str or Path
        A ROS 1 ``.bag``, a ROS 2 bag (directory with ``metadata.yaml``, a ``.db3`` or an
        ``.mcap`` file), a CARMEN log (plain or ``.gz``; also the laser lines of a ``.g2o``
        file), an ``.npz`` or a ``.csv`` of scans (layouts in ``docs/io-and-cli.md``).
    topic : str, optional
        The ``sensor_msgs/LaserScan`` topic of a bag. Default: the only LaserScan topic.
    odom_topic : str, optional
        The odometry of a bag's scan poses: a ``nav_msgs/Odometry`` topic, or ``"tf"`` for
        ``/tf``. Default: the only Odometry topic, ``/tf`` when there is none. Other kinds
        have no choice (a CARMEN log's poses are those of its laser lines).

    Returns
    -------
    ScanSource
        Iterate it for :class:`~laser_corners.LaserScan` objects.

    Raises
    ------
    InputError
        Missing, empty, unreadable or corrupt file, unknown kind, a topic that is not a
        LaserScan (an odometry topic that is not an Odometry), several LaserScan (Odometry)
        topics and no ``topic`` (``odom_topic``): a ``TopicChoiceError``, or ``topic`` or
        ``odom_topic`` given for a file without topics.

    Examples
    --------
    >>> source = open_scans("../shared/data/real/fr079.bag")  # doctest: +SKIP
    >>> for scan in source:  # doctest: +SKIP
    ...     print(scan.stamp, scan.pose)
    """
    path = Path(path)
    kind = detect_kind(path)
    if kind in BAG_KINDS:
        return BagSource(path, kind, topic, odom_topic=odom_topic)
    if topic is not None:
        raise InputError(f"{path}: a {kind} file has no topics; a topic applies to bags only")
    if odom_topic is not None:
        poses = "the laser lines' poses" if kind == "carmen" else "its own poses"
        raise InputError(
            f"{path}: a {kind} file has no odometry topics (it gives {poses}); "
            "an odometry topic applies to bags only"
        )
    if kind == "carmen":
        return CarmenSource(path)
    return NpzSource(path) if kind == "npz" else CsvSource(path)


def open_keypoint_writer(
    path: str | Path | None,
    source: ScanSource,
    *,
    with_map: bool,
    metadata: dict[str, str] | None = None,
    **options: Any,
) -> KeypointWriter:
    """The writer for ``path``, chosen by its suffix.

    Every file is written under a temporary name in the same folder
    (``STEM.XXXXXXXX.partial.SUFFIX``) and renamed to ``path`` by ``close()``.

    Parameters
    ----------
    path : str, Path or None
        ``.csv``, ``.parquet``, ``.bag`` (ROS 1 input) or ``.mcap`` (ROS 2/MCAP input); None:
        a writer that writes nothing.
    source : ScanSource
        The recording being processed (the bag writers copy it).
    with_map : bool
        Add ``map_x, map_y`` columns (the recording has poses).
    metadata : dict of str to str, optional
        Stored in the Parquet schema metadata.
    **options
        Passed on to the writer (``flush_every``; ``ns``, ``lifetime``, ``compression`` for
        bags).

    Raises
    ------
    InputError
        A bag output for an input that is not a bag.
    OutputError
        Unknown suffix, a path that cannot be written, or the input itself.
    """
    if path is None:
        return KeypointWriter()
    path = Path(path)
    refuse_input(path, [source.path] if source is not None else [])
    suffix = path.suffix.lower()
    if options.get("compression") is not None and suffix != ".bag":
        raise OutputError(f"{path}: chunk compression applies to a ROS 1 .bag output only")
    options = {k: v for k, v in options.items() if v is not None}
    if suffix == ".csv":
        return CsvKeypointWriter(path, with_map, **options)
    if suffix in (".parquet", ".pq"):
        return ParquetKeypointWriter(path, with_map, metadata=metadata, **options)
    if suffix in (".bag", ".mcap"):
        if not isinstance(source, BagSource):
            kind = getattr(source, "kind", "non-bag")
            raise InputError(
                f"{path}: a bag output needs a bag input, {source.path} is a {kind} file; "
                "write .csv or .parquet"
            )
        return BagKeypointWriter(path, source, **options)
    raise OutputError(
        f"{path}: unknown output kind {suffix or '(no suffix)'!r}; "
        "use .csv, .parquet, .bag or .mcap"
    )
