"""Where numba caches the package's kernels: a folder keyed by their sources.

numba keys a cached kernel (``cache=True``) by its own source file only, but a kernel's
compiled code holds every kernel it calls from other files (``merge.detect_xy`` links the
walk of ``kernel/neighbourhood.py``): after an edit to one file, kernels of other files kept
the old code until their cache files were deleted. :func:`use_keyed_cache` (run by
``import laser_corners``, before any kernel module is imported) points numba at
``<base>/laser-corners-<key>``, where the key hashes the contents of every source file of the
package that imports numba (and the Python version; a file that only names numba in a
docstring or a help text does not count): any edit to a kernel gives a fresh
folder, so no kernel can be loaded with another file's old code. numba's own index still
checks numba's version. ``<base>`` is ``NUMBA_CACHE_DIR`` when set (so an empty folder there
still means a cold cache), else the package's ``__pycache__`` when writable, else the user's
cache folder (``$XDG_CACHE_HOME`` or ``~/.cache``, then ``laser-corners``). A folder that
cannot be written is replaced by one in the system's temporary folder
(``laser-corners-numba-<uid>``), with one warning line: numba would otherwise refuse to
import any cached kernel.

Reading the kernel sources on every import would cost ~10-20 ms; the key is memoised in
``<base>/laser-corners-keys/`` under a hash of the names, sizes and modification times of
the package's source files (about 2 ms to compute), so it is recomputed only after a file
changed. The folder is set in the environment (numba reads it when imported; child
processes inherit it) and, when numba is already imported, in ``numba.config``. Folders of
earlier keys are not deleted.
"""

from __future__ import annotations

import os
import sys
import zlib
from pathlib import Path

__all__ = ["PREFIX", "kernel_key", "source_key", "use_keyed_cache"]

PREFIX = "laser-corners-"
"""Name prefix of the keyed cache folders (a ``NUMBA_CACHE_DIR`` ending in one, inherited
from a parent process, is taken as its base)."""

PACKAGE = Path(__file__).resolve().parent


def _sources(folder: str, prefix: str = "") -> list[tuple[str, os.DirEntry]]:
    """The package's ``.py`` files (name relative to the package, entry), sorted by name
    (``__pycache__`` left out); plain strings and ``os.scandir``: a few ms for ~150 files."""
    found = []
    with os.scandir(folder) as entries:
        for entry in sorted(entries, key=lambda e: e.name):
            if entry.is_dir() and entry.name != "__pycache__":
                found += _sources(entry.path, f"{prefix}{entry.name}/")
            elif entry.name.endswith(".py"):
                found.append((prefix + entry.name, entry))
    return found


def kernel_key(package: Path = PACKAGE) -> str:
    """Hash of the contents of the package's source files that import numba, with their
    paths relative to the package, and the Python version (16 hex digits)."""
    return source_key(package, kernels_only=True)


def source_key(package: Path = PACKAGE, kernels_only: bool = False) -> str:
    """Hash of the contents of the package's source files (``kernels_only``: those that import
    numba), with their paths relative to the package, and the Python version (16 hex
    digits): what a cached result was made by."""
    import hashlib  # only when the memo misses (importing hashlib costs milliseconds)

    digest = hashlib.blake2b(digest_size=8)
    digest.update(f"{sys.version_info[:2]}".encode())
    for name, entry in _sources(str(package)):
        with open(entry.path, "rb") as source:
            data = source.read()
        kernel = b"import numba" in data or b"from numba" in data  # a kernel file, not a mention
        if kernel or not kernels_only:
            digest.update(name.encode() + b"\0" + data + b"\0")
    return digest.hexdigest()


def _stat_key(package: Path) -> str:
    """Checksum (CRC-32 and Adler-32) of the names, sizes and modification times of the
    package's source files and the Python version."""
    text = f"{sys.version_info[:2]}"
    for name, entry in _sources(str(package)):
        st = entry.stat()
        text += f"\0{name}\0{st.st_size}\0{st.st_mtime_ns}"
    data = text.encode()
    return f"{zlib.crc32(data):08x}{zlib.adler32(data):08x}"


def _base() -> Path:
    """The folder that holds the keyed cache folders (see the module's docstring)."""
    given = os.environ.get("NUMBA_CACHE_DIR", "")
    if given:
        base = Path(given)
        return base.parent if base.name.startswith(PREFIX) else base
    pycache = PACKAGE / "__pycache__"
    if os.access(pycache if pycache.is_dir() else PACKAGE, os.W_OK):
        return pycache
    home = os.path.expanduser("~")  # "~" itself when HOME is unset and no passwd entry
    user = os.environ.get("XDG_CACHE_HOME") or os.path.join(home, ".cache")
    return Path(user) / "laser-corners" if os.path.isabs(user) else _temporary_base()


def _temporary_base() -> Path:
    """The fallback base in the system's temporary folder, one per user."""
    import tempfile  # only when the usual folders cannot be written

    user = os.getuid() if hasattr(os, "getuid") else os.environ.get("USERNAME", "user")
    return Path(tempfile.gettempdir()) / f"laser-corners-numba-{user}"


def _writable(folder: Path) -> str | None:
    """Create ``folder`` and check it can be written (as numba does before caching there):
    the reason it cannot be, or None when it can."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return exc.strerror or type(exc).__name__
    return None if os.access(folder, os.W_OK) else "not writable"


def _memoised_key(base: Path, package: Path) -> str:
    """:func:`kernel_key`, memoised under the stat key (written atomically; a folder that
    cannot be written only costs the recomputation)."""
    memo = base / f"{PREFIX}keys" / _stat_key(package)
    try:
        key = memo.read_text(encoding="ascii").strip()
        if len(key) == 16:
            return key
    except OSError:
        pass
    key = kernel_key(package)
    try:
        memo.parent.mkdir(parents=True, exist_ok=True)
        partial = memo.with_name(f"{memo.name}.{os.getpid()}.tmp")
        partial.write_text(key, encoding="ascii")
        os.replace(partial, memo)
    except OSError:
        pass
    return key


def use_keyed_cache() -> Path:
    """Point numba's cache at the folder keyed by the kernel sources; returns it.

    A folder that cannot be written (a package installed by another user, HOME unset, a
    NUMBA_CACHE_DIR that is not a folder) would make numba refuse to import any cached kernel
    ("cannot cache function ... no locator available"): the folder then lives in the system's
    temporary folder instead, said in one warning line on stderr.
    """
    base = _base()
    key = _memoised_key(base, PACKAGE)
    folder = base / f"{PREFIX}{key}"
    problem = _writable(folder)
    if problem is not None:
        fallback = _temporary_base() / f"{PREFIX}{key}"
        if _writable(fallback) is None:
            sys.stderr.write(
                f"laser-corners: warning: cannot cache the numba kernels in {folder} "
                f"({problem}); caching them in {fallback}\n"
            )
            folder = fallback
    os.environ["NUMBA_CACHE_DIR"] = str(folder)
    config = sys.modules.get("numba.core.config")
    if config is not None:  # numba already imported: it read the environment then
        config.CACHE_DIR = str(folder)  # type: ignore[attr-defined]
    return folder
