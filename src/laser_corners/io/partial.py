"""Outputs written under a temporary name and renamed when complete; never over an input.

* :class:`PartialOutput`: an output written under a temporary name in its folder
  (``STEM.XXXXXXXX.partial.SUFFIX``) and renamed to its final name when complete, so a killed
  run never leaves a half-written file under the final name; it gets the mode any new file
  gets (``0o666`` less the umask, :func:`file_mode`), not ``mkstemp``'s 0600;
* :func:`refuse_input`: an output that is one of the inputs (same file by inode, also through
  a link) is refused before anything is written;
* :func:`staging_folder` and :func:`publish_folder`: an output folder written whole beside its
  final name (``.NAME.XXXXXXXX.partial``) and then swapped in, so a killed run leaves either
  the previous folder or the new one under the final name, never a mix of the two;
* :class:`ClosesOnExit`: a writer used in a ``with`` block is closed on the way out (also on
  errors).
"""

from __future__ import annotations

import ctypes
import errno
import os
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from types import TracebackType
from typing import TypeVar

from laser_corners.errors import OutputError

__all__ = [
    "PARTIAL_SUFFIX",
    "ClosesOnExit",
    "PartialOutput",
    "file_mode",
    "publish_folder",
    "refuse_input",
    "staging_folder",
]

_W = TypeVar("_W", bound="ClosesOnExit")


class ClosesOnExit:
    """A writer as a context manager: ``with`` gives the writer and closes it on the way out."""

    def close(self) -> None:
        """Finish the output (subclasses)."""
        raise NotImplementedError

    def __enter__(self: _W) -> _W:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


PARTIAL_SUFFIX = ".partial"
"""An output path ending in this is a caller's own temporary name (see :class:`PartialOutput`)."""


def file_mode() -> int:
    """The mode ``open()`` gives a new file: ``0o666`` less the process umask.

    The umask is read from ``/proc/self/status`` (Linux), else set and restored (which is not
    thread-safe, hence the first way).
    """
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return 0o666 & ~int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return 0o666 & ~mask


def refuse_input(output: Path, inputs: Sequence[Path]) -> None:
    """Refuse an output that is one of the inputs (the same file or folder, by inode).

    Raises
    ------
    OutputError
        ``output`` exists and is the same file as one of ``inputs`` (also through a link).
    """
    for source in inputs:
        try:
            same = os.path.samefile(output, source)
        except OSError:  # either does not exist (or cannot be looked at): not the same
            continue
        if same:
            raise OutputError(
                f"{output}: the output is the input {source} (the same file); writing it would "
                "destroy the recording, choose another output name"
            )


class PartialOutput:
    """An output written under a temporary name beside its final name, renamed when complete.

    The temporary name is ``STEM.XXXXXXXX.partial.SUFFIX`` in the same folder (same file
    system, so the rename is atomic). A process killed before :meth:`publish` leaves only that
    file (or folder), never a half-written file under the final name.

    A ``path`` whose name ends in :data:`PARTIAL_SUFFIX` is a temporary name already (its
    caller renames it when it is done, as ``laser-corners batch`` does): it is written
    directly, so a kill leaves the one file the caller knows about.

    Parameters
    ----------
    path : Path
        The final name.
    overwrite : bool
        Replace an existing ``path`` when publishing (tables); with False an existing ``path``
        is an :class:`OutputError`, checked now and when publishing (bags).
    create : bool
        Create the temporary file (empty). With False the name is reserved but left free,
        for writers that create their output themselves and refuse an existing one (rosbags'
        bag writers).
    folder : bool
        The output is written by a writer that makes a folder (a ROS 2 bag): it writes
        ``STEM.XXXXXXXX.partial/NAME`` (not created here), and :meth:`publish` moves that
        folder, or the one file of it that is the output (``member``), to ``path``.
    temporary : Path, optional
        A fixed temporary name in the same folder, ending in :data:`PARTIAL_SUFFIX`, instead
        of a new one (``batch``: ``NAME.parquet.partial``, so a re-run replaces the leftover
        of a killed run); it is not created.

    Raises
    ------
    OutputError
        Missing folder, no permission, or an existing ``path`` with ``overwrite=False``.
    """

    def __init__(
        self,
        path: Path,
        *,
        overwrite: bool,
        create: bool = True,
        folder: bool = False,
        temporary: Path | None = None,
    ) -> None:
        self.path = path
        self.overwrite = overwrite
        if not overwrite and path.exists():
            raise OutputError(f"{path}: exists already; remove it or choose another name")
        parent = path.parent
        if not parent.is_dir():
            raise OutputError(f"{path}: the folder {parent} does not exist")
        if temporary is not None or path.name.endswith(PARTIAL_SUFFIX):
            self.temporary, self._holder = temporary or path, None
            return
        self._holder: Path | None = None
        try:
            if folder:
                self._holder = Path(
                    tempfile.mkdtemp(prefix=f"{path.stem}.", suffix=".partial", dir=parent)
                )
                self.temporary = self._holder / path.name
                return
            handle, name = tempfile.mkstemp(
                prefix=f"{path.stem}.", suffix=f".partial{path.suffix}", dir=parent
            )
        except OSError as exc:
            raise OutputError(f"{path}: cannot write in {parent} ({exc.strerror})") from None
        try:  # mkstemp makes it 0600; an output gets the mode any new file gets (umask)
            os.fchmod(handle, file_mode())
        finally:
            os.close(handle)
        self.temporary = Path(name)
        if not create:
            self.temporary.unlink()  # the writer creates it itself

    def publish(self, member: Path | None = None) -> None:
        """Give the complete output its final name.

        Parameters
        ----------
        member : Path, optional
            With ``folder``: the file inside the temporary folder that is the output (the
            ``.mcap`` file of a ROS 2 bag folder); the rest of the folder is removed.

        Raises
        ------
        OutputError
            ``path`` appeared meanwhile and must not be overwritten.
        """
        done = member if member is not None else self.temporary
        if done == self.path or not done.exists():
            return
        if self.path.exists() and not self.overwrite:
            raise OutputError(f"{self.path}: appeared while writing; the output is kept as {done}")
        try:
            os.replace(done, self.path)
        except OSError as exc:
            raise OutputError(
                f"{self.path}: cannot give the output its name ({exc.strerror}); it is kept as "
                f"{done}"
            ) from None
        if self._holder is not None:
            shutil.rmtree(self._holder, ignore_errors=True)

    @contextmanager
    def writing(self) -> Iterator[Path]:
        """Yield the temporary path to write in one go; publish it on success, else remove it.

        Raises
        ------
        OutputError
            The file cannot be written (the ``OSError`` named in one line).
        """
        try:
            yield self.temporary
        except OSError as exc:
            self.discard()
            raise OutputError(f"{self.path}: cannot write ({exc.strerror or exc})") from None
        except BaseException:
            self.discard()
            raise
        self.publish()

    def discard(self) -> None:
        """Remove the temporary file or folder (a writer that failed to open)."""
        if self._holder is not None:
            shutil.rmtree(self._holder, ignore_errors=True)
        elif self.temporary.is_dir():
            shutil.rmtree(self.temporary, ignore_errors=True)
        else:
            self.temporary.unlink(missing_ok=True)


_AT_FDCWD = -100
_RENAME_EXCHANGE = 2  # linux/fs.h


def staging_folder(final: Path) -> Path:
    """A new, empty folder ``.NAME.XXXXXXXX.partial`` beside ``final`` to write it in, with the
    mode a new folder gets (``final``'s own when it exists).

    Raises
    ------
    OutputError
        The parent folder is missing or cannot be written.
    """
    parent = final.parent
    try:
        staging = Path(
            tempfile.mkdtemp(prefix=f".{final.name}.", suffix=PARTIAL_SUFFIX, dir=parent)
        )
    except OSError as exc:
        raise OutputError(f"{final}: cannot write in {parent} ({exc.strerror})") from None
    new = file_mode() | (file_mode() & 0o444) >> 2  # searchable where readable
    os.chmod(staging, final.stat().st_mode & 0o7777 if final.is_dir() else new)
    return staging


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths atomically (Linux ``renameat2(RENAME_EXCHANGE)``); False where the
    system cannot."""
    try:
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    done = renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE)
    if done == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP):
        return False
    raise OSError(code, os.strerror(code), str(b))


def publish_folder(staging: Path, final: Path) -> None:
    """Give the complete folder ``staging`` (from :func:`staging_folder`) the name ``final``.

    An existing ``final`` is replaced whole, and only now: swapped atomically where the system
    can (Linux), else renamed aside first; the previous folder is then removed.

    Raises
    ------
    OutputError
        The rename failed (``staging`` is kept and named).
    """
    try:
        if not final.exists():
            os.rename(staging, final)
            return
        if not _exchange(staging, final):
            aside = Path(
                tempfile.mkdtemp(prefix=f".{final.name}.", suffix=".old", dir=final.parent)
            )
            os.rename(final, aside / final.name)
            os.rename(staging, final)
            staging = aside
    except OSError as exc:
        raise OutputError(
            f"{final}: cannot give the output folder its name ({exc.strerror}); it is kept as "
            f"{staging}"
        ) from None
    shutil.rmtree(staging, ignore_errors=True)  # the previous folder
