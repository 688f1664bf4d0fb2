"""Atomic file output: a result file is either complete or not there, never half-written.

Also the checks every writer runs before any work (an output must not overwrite its inputs) and
:func:`jsonable`, which makes results JSON can hold (``null`` for non-finite numbers).

Every writer of the package (maps, recordings, materials, FMUs, figures) writes to a temporary file in
the destination's directory and renames it over the destination. The temporary file gets the mode a
plain ``open()`` would give (0666 less the umask), not ``mkstemp``'s private 0600. A write that fails
(full disk, quota, read-only folder) is one :class:`OutputError` naming the destination, and the earlier
file stays as it was.

:func:`dir_lock` lets one process at a time write a folder (``maps -o``, ``pipeline -o``,
:func:`solenoid_fmu.maps.save_maps`); :func:`resolved` turns a symlink loop into an error naming the path.
"""

from __future__ import annotations

import errno
import math
import os
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .errors import SolenoidError

try:  # POSIX; elsewhere folders are not locked (dir_lock is a no-op)
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None


class OutputError(SolenoidError):
    """An output path that would destroy an input, or that cannot be written."""


_HELD: dict = {}  # resolved folder -> [fd, depth]: the locks this process holds (re-entrant)
_HELD_GUARD = threading.Lock()


def resolved(path) -> Path:
    """``Path(path).resolve()``, with a symlink loop reported as :class:`OutputError` naming the path
    (Python raises RuntimeError or OSError ELOOP)."""
    try:
        return Path(path).resolve()
    except RuntimeError:
        raise OutputError(f"{path}: symlink loop (a link that points back to itself); give another path") from None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise OutputError(f"{path}: symlink loop (a link that points back to itself); give another path") from None
        raise


def check_output_name(path) -> Path:
    """``path`` as a Path, unless its file name has a control character (a line break, a tab ...): such a
    name would travel into recording headers, FMU names and logs, so it is refused before any work."""
    path = Path(path)
    if any(ord(ch) < 32 or ord(ch) == 127 for ch in path.name):
        raise OutputError(f"{str(path)!r}: the output's file name has a control character (line break, tab ...); "
                          "give a name without one")
    return path


def write_failure(path, exc: OSError) -> OutputError:
    """The one-line error of a write to ``path`` that failed with ``exc`` (the earlier file is kept)."""
    reason = {errno.ENOSPC: "no space left on the device", errno.EDQUOT: "disk quota exceeded",
              errno.EFBIG: "file too large for the file system or limit", errno.EROFS: "read-only file system",
              errno.EACCES: "permission denied", errno.EPERM: "permission denied"}.get(
        exc.errno, exc.strerror or type(exc).__name__)
    return OutputError(f"{path}: cannot write: {reason}; an earlier file of that name is unchanged")


def _make_directory(directory: Path, target: Path, label: str) -> None:
    """Create ``directory`` (and its parents) to write ``target`` there; a failure is an :class:`OutputError`
    that starts with ``label`` (a parent that is a file) or names ``target`` (:func:`write_failure`)."""
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise OutputError(f"{label}: cannot write there, a parent path is a file, not a directory") from None
    except OSError as exc:
        raise write_failure(target, exc) from None


@contextmanager
def dir_lock(directory, what: str = "-o") -> Iterator[Path]:
    """Hold an exclusive lock on ``directory`` (created) while writing it: another process (or a second
    command) writing the same folder is refused at once with :class:`OutputError`, instead of the two
    mixing their files. The lock is ``flock`` on the folder itself (no file is added); the kernel releases
    it when the holder exits, also on ``kill -9``. Re-entrant within one process."""
    directory = Path(directory)
    _make_directory(directory, directory, f"{what} {directory}")
    key = resolved(directory)
    with _HELD_GUARD:
        held = _HELD.get(key)
        if held is not None:
            held[1] += 1
    if held is not None:
        try:
            yield directory
        finally:
            with _HELD_GUARD:
                held[1] -= 1
        return
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError as exc:
        raise write_failure(directory, exc) from None
    try:
        if fcntl is not None:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise OutputError(f"{what} {directory}: being written by another solenoid-fmu process; wait for it "
                                  "to finish or choose another folder") from None
        with _HELD_GUARD:
            _HELD[key] = [fd, 1]
        try:
            yield directory
        finally:
            with _HELD_GUARD:
                del _HELD[key]
    finally:
        os.close(fd)  # releases the flock


def refuse_overwriting_inputs(output, inputs, written=None) -> Path:
    """``output`` as a Path, unless writing it would destroy or pollute an input: then
    :class:`OutputError` naming both. After resolving symlinks, an input must not be ``output`` itself,
    nor equal to or lie under one of ``written`` (the paths the command writes; default ``[output]``,
    i.e. everything under an output directory; ``[]`` checks ``output`` alone), and ``output`` must
    not lie inside an input directory (results would mix with, and be read back as, the inputs).
    A result must never replace the measured data it came from."""
    out = check_output_name(output)
    target = resolved(out)
    targets = [target] if written is None else [resolved(w) for w in written]
    for item in inputs:
        if item is None:
            continue
        src = resolved(item)
        if target == src or any(src == w or w in src.parents for w in targets):
            raise OutputError(f"{out}: the output would overwrite the input {item}; choose another path")
        if src in target.parents and src.is_dir():
            raise OutputError(f"{out}: the output lies inside the input folder {item}; choose a path outside it")
    return out


def require_directory(path, what: str = "output") -> Path:
    """``path`` as a Path, unless it or one of its parents is an existing non-directory: then
    :class:`OutputError` naming that file (checked before any work, so a long run cannot fail at
    its last step)."""
    path = Path(path)
    resolved(path)
    for p in (path, *path.parents):
        if p.exists() and not p.is_dir():
            where = "" if p == path else f"{p} "
            raise OutputError(f"{what} {path}: {where}is a file, not a directory")
    return path


def umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def temp_beside(path: str | Path, suffix: str = ".tmp") -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success it replaces ``path``, on error it is removed."""
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise OutputError(f"{path}: is a directory; give a file name to write")
    _make_directory(directory, path, str(path))
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=directory)
    except OSError as exc:  # a read-only folder: name the file to write, not the hidden temporary one
        raise write_failure(path, exc) from None
    os.close(fd)
    tmp = Path(tmp)
    try:
        try:
            yield tmp
            os.chmod(tmp, 0o666 & ~umask())
            os.replace(tmp, path)
        except OSError as exc:
            if exc.errno in WRITE_ERRNOS:
                raise write_failure(path, exc) from None
            raise
    finally:
        tmp.unlink(missing_ok=True)


#: errno values of a write that failed for want of room or rights (reported by write_failure).
WRITE_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS, errno.EACCES, errno.EPERM, errno.EIO}


def save_figure(fig, path, **savefig_kw) -> Path:
    """Save a matplotlib figure as PNG to ``path`` atomically (rendered in memory first)."""
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", **savefig_kw)
    return atomic_write_bytes(path, buf.getvalue())


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (flushed to disk before the rename)."""
    with temp_beside(path) as tmp, open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())
    return Path(path)


def write_files(folder, files: dict, what: str) -> None:
    """Write ``files`` (``{relative path: bytes}``) under ``folder``, creating sub-folders.

    Raises ``ValueError("{what} {rel!r} leaves {folder name}")`` before writing a path that would leave
    ``folder`` (``..``, an absolute path, a link out), so that data from elsewhere (a lot's worker, a client)
    cannot write beside it.
    """
    folder = Path(folder)
    root = folder.resolve()
    for rel, data in files.items():
        dest = folder / rel
        if not dest.resolve().is_relative_to(root):
            raise ValueError(f"{what} {rel!r} leaves the folder {folder.name}")
        dest.parent.mkdir(parents=True, exist_ok=True)
        dest.write_bytes(data)


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write UTF-8 ``text`` with ``\\n`` line ends to ``path`` atomically."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def jsonable(obj):
    """``obj`` with what JSON cannot hold made writable: tuples as lists, numpy scalars as Python
    numbers, non-finite floats (nan, inf) as None (JSON ``null``); dicts and lists recursively."""
    if isinstance(obj, dict):
        return {k: jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, np.generic):
        return jsonable(obj.item())
    return obj
