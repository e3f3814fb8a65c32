"""TUM trajectories: ``stamp x y z qx qy qz qw`` per line, the format evo and the TUM tools read.

A planar pose ``(x, y, yaw)`` is written with ``z = 0`` and the quaternion of a rotation by
``yaw`` about z, ``(0, 0, sin(yaw/2), cos(yaw/2))``; reading takes x, y and the yaw of the
quaternion (a tilted quaternion is read for its yaw only). ``#`` starts a comment; blank lines
are skipped.

:class:`TumWriter` writes one pose at a time under a temporary name and gives the file its
final name on :meth:`~TumWriter.close` (:class:`~laser_corners.io.base.PartialOutput`), so a
killed run never leaves a half-written ``trajectory.tum``. A ``with`` block left by an error
discards it instead (:meth:`~TumWriter.discard`): a failed run leaves the file of an earlier
run as it was, and no header-only file.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from types import TracebackType
from typing import TextIO

import numpy as np
from numpy.typing import ArrayLike, NDArray

from laser_corners.errors import InputError, OutputError
from laser_corners.io.base import PartialOutput
from laser_corners.io.partial import ClosesOnExit

__all__ = ["TumWriter", "read_numeric_table", "read_tum", "write_tum", "yaw_quaternion"]


def yaw_quaternion(yaw: ArrayLike) -> NDArray[np.float64]:
    """Unit quaternions ``(qx, qy, qz, qw)`` of rotations by ``yaw`` about z, shape (..., 4)."""
    half = 0.5 * np.asarray(yaw, dtype=np.float64)
    zeros = np.zeros_like(half)
    return np.stack([zeros, zeros, np.sin(half), np.cos(half)], axis=-1)


def _line(stamp: float, x: float, y: float, yaw: float) -> str:
    half = 0.5 * yaw
    return f"{stamp:.9f} {x:.9g} {y:.9g} 0 0 0 {math.sin(half):.9g} {math.cos(half):.9g}\n"


class TumWriter(ClosesOnExit):
    """Write planar poses to a TUM trajectory, one line per :meth:`write`.

    Parameters
    ----------
    path : Path
        The final file name (replaced if it exists, when :meth:`close` publishes it).
    header : str, optional
        A comment written first (each line prefixed by ``#``).

    Raises
    ------
    OutputError
        The folder is missing or cannot be written.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> with TumWriter(folder / "t.tum") as writer:
    ...     writer.write(0.0, (1.0, 2.0, 0.5))
    >>> stamps, poses = read_tum(folder / "t.tum")
    >>> poses.round(6).tolist()
    [[1.0, 2.0, 0.5]]
    """

    def __init__(self, path: str | Path, header: str | None = None) -> None:
        self.path = Path(path)
        self._partial = PartialOutput(self.path, overwrite=True)
        try:
            self._handle: TextIO | None = self._partial.temporary.open("w", encoding="utf-8")
        except OSError as exc:
            self._partial.discard()
            raise OutputError(f"{self.path}: cannot write ({exc.strerror})") from None
        self.n_poses = 0
        if header:
            self._handle.write("".join(f"# {line}\n" for line in header.splitlines()))

    def write(self, stamp: float, pose: ArrayLike) -> None:
        """Append the pose ``(x, y, yaw)`` at time ``stamp`` (seconds)."""
        if self._handle is None:
            raise OutputError(f"{self.path}: written after close()")
        x, y, yaw = (float(v) for v in np.asarray(pose, dtype=np.float64).reshape(3))
        self._handle.write(_line(float(stamp), x, y, yaw))
        self.n_poses += 1

    def write_many(self, stamps: ArrayLike, poses: ArrayLike) -> None:
        """Append many poses at once: ``stamps`` (N,), ``poses`` (N, 3)."""
        if self._handle is None:
            raise OutputError(f"{self.path}: written after close()")
        t = np.asarray(stamps, dtype=np.float64).reshape(-1)
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        if len(t) != len(p):
            raise ValueError(f"{len(t)} stamps but {len(p)} poses")
        q = yaw_quaternion(p[:, 2])
        table = np.column_stack([t, p[:, 0], p[:, 1], np.zeros(len(t)), q])
        np.savetxt(self._handle, table, fmt=["%.9f"] + ["%.9g"] * 7)
        self.n_poses += len(t)

    def close(self) -> None:
        """Flush the file and give it its final name (idempotent)."""
        if self._handle is None:
            return
        handle, self._handle = self._handle, None
        try:
            handle.close()
        except OSError as exc:
            self._partial.discard()
            raise OutputError(f"{self.path}: cannot write ({exc.strerror})") from None
        self._partial.publish()

    def discard(self) -> None:
        """Drop what was written: the file under the final name is left as it was."""
        if self._handle is not None:
            handle, self._handle = self._handle, None
            handle.close()
        self._partial.discard()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.close()
        else:
            self.discard()


def write_tum(
    path: str | Path, stamps: ArrayLike, poses: ArrayLike, header: str | None = None
) -> None:
    """Write a whole trajectory: ``stamps`` (N,) seconds, ``poses`` (N, 3) ``x, y, yaw``."""
    with TumWriter(path, header) as writer:
        writer.write_many(stamps, poses)


def read_numeric_table(
    path: str | Path,
    fields: str,
    what: str,
    check: Callable[[list[float]], str | None] | None = None,
) -> NDArray[np.float64]:
    """Rows of whitespace- (or comma-) separated numbers, one per line: TUM trajectories,
    Freiburg ``.relations``; blank lines and ``#`` comments skipped.

    Parameters
    ----------
    path : str or Path
        The text file.
    fields : str
        The names of the columns, space-separated (``"t1 t2 x y z roll pitch yaw"``): their
        number is the number of columns, and messages name them.
    what : str
        What a line is, for messages (``"TUM"``, ``"relations"``).
    check : callable, optional
        Called with each row's numbers: what is wrong with them, or None.

    Raises
    ------
    InputError
        Missing or unreadable file, a folder; ``FILE:LINE`` for a line without that many
        finite numbers or one ``check`` refuses; a file without lines.
    """
    path = Path(path)
    n_columns = len(fields.split())
    if path.is_dir():
        inside = [p.name for p in sorted(path.glob("*.tum" if what == "TUM" else f"*.{what}"))]
        hint = f"; pass a file such as {path / inside[0]}" if inside else ""
        raise InputError(f"{path}: is a folder, not a {what} file{hint}")
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    rows: list[list[float]] = []
    try:
        with path.open(encoding="utf-8", errors="replace") as handle:
            for line_no, line in enumerate(handle, start=1):
                text = line.split("#", 1)[0].strip()
                if not text:
                    continue
                tokens = text.replace(",", " ").split()
                if len(tokens) != n_columns:
                    raise InputError(
                        f"{path}:{line_no}: a {what} line needs {n_columns} numbers "
                        f"({fields}), got {len(tokens)}"
                    )
                try:
                    values = [float(t) for t in tokens]
                except ValueError:
                    raise InputError(f"{path}:{line_no}: not a number in {text[:60]!r}") from None
                if not all(map(math.isfinite, values)):
                    raise InputError(f"{path}:{line_no}: non-finite value")
                problem = None if check is None else check(values)
                if problem is not None:
                    raise InputError(f"{path}:{line_no}: {problem}")
                rows.append(values)
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror})") from None
    if not rows:
        raise InputError(f"{path}: no {what} lines ({fields})")
    return np.asarray(rows, dtype=np.float64)


def _quaternion_problem(row: list[float]) -> str | None:
    """A TUM row whose quaternion ``qx qy qz qw`` is (near) zero: no rotation at all."""
    norm = math.sqrt(sum(v * v for v in row[4:8]))
    return (
        None if norm > 1e-6 else f"zero quaternion (qx qy qz qw = {' '.join(map(str, row[4:8]))})"
    )


def read_tum(path: str | Path) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Read a TUM trajectory as planar poses, in file order.

    Returns
    -------
    stamps : ndarray, shape (N,)
        Seconds.
    poses : ndarray, shape (N, 3)
        ``x, y, yaw`` (yaw of the quaternion, radians).

    Raises
    ------
    InputError
        Missing file, or ``FILE:LINE`` for a line without 8 finite numbers or with a zero
        quaternion; a file without poses.
    """
    table = read_numeric_table(path, "stamp x y z qx qy qz qw", "TUM", _quaternion_problem)
    qx, qy, qz, qw = table[:, 4], table[:, 5], table[:, 6], table[:, 7]
    yaw = np.arctan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
    return table[:, 0].copy(), np.column_stack([table[:, 1], table[:, 2], yaw])
