"""Atomic file output: a result file is either complete or not there, never half-written.

Also the checks every writer runs before any work (an output must not overwrite its inputs) and
:func:`jsonable`, which makes results JSON can hold (``null`` for non-finite numbers).

Every writer of the package (maps, recordings, materials, FMUs) writes to a temporary file in the
destination's directory and renames it over the destination. The temporary file gets the mode a
plain ``open()`` would give (0666 less the umask), not ``mkstemp``'s private 0600.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .errors import SolenoidError


class OutputError(SolenoidError):
    """An output path that would destroy an input, or that cannot be written."""


def refuse_overwriting_inputs(output, inputs, written=None) -> Path:
    """``output`` as a Path, unless writing it would destroy or pollute an input: then
    :class:`OutputError` naming both. After resolving symlinks, an input must not be ``output`` itself,
    nor equal to or lie under one of ``written`` (the paths the command writes; default ``[output]``,
    i.e. everything under an output directory; ``[]`` checks ``output`` alone), and ``output`` must
    not lie inside an input directory (results would mix with, and be read back as, the inputs).
    A result must never replace the measured data it came from."""
    out = Path(output)
    target = out.resolve()
    targets = [target] if written is None else [Path(w).resolve() for w in written]
    for item in inputs:
        if item is None:
            continue
        src = Path(item).resolve()
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
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise OutputError(f"{path}: cannot write there, a parent path is a file, not a directory") from None
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=directory)
    os.close(fd)
    tmp = Path(tmp)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~umask())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (flushed to disk before the rename)."""
    with temp_beside(path) as tmp, open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())
    return Path(path)


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
