"""The maps file format: one writer (:func:`save_maps`) and one reader (:func:`load_maps`) of a maps directory.

A maps directory holds ``maps.npz`` (the arrays of :data:`solenoid_fmu.maps.tables.ARRAY_UNITS`,
float64, no pickles) and ``maps.json`` (schema name and version, units, coil, stroke, eddy,
provenance, interpolation, and the npz file's sha256 and shapes under ``"arrays"``). The files are
read by :func:`solenoid_fmu.realtime.read_maps_dir`, the reader the real-time model carries into every
FMU; :func:`load_maps` adds the checks of what the content means and returns a
:class:`~solenoid_fmu.maps.tables.CharacteristicMaps`.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import shutil
from pathlib import Path

import numpy as np

from ..errors import MapsError
from ..fileio import OutputError, atomic_write_bytes, dir_lock, write_failure
from ..realtime import (
    MAPS_JSON,
    MAPS_NPZ,
    MAPS_PREVIOUS,
    MAPS_SCHEMA,
    MAPS_SCHEMA_VERSION,
    MapTables,
    ModelMapsError,
    coil_problems,
    eddy_problems,
    maps_pair_consistent,
    read_maps_dir,
)
from .consistency import consistency_problems
from .tables import ARRAY_UNITS, FORCE_METHODS, CharacteristicMaps, array_problems, problem_message

__all__ = ["encode_maps", "load_maps", "maps_tables", "name_problem", "save_maps"]


def save_maps(maps: CharacteristicMaps, directory) -> Path:
    """Write ``maps.npz`` + ``maps.json`` into ``directory`` (created) atomically; never pickle.

    The pair is written crash-safe: a reader sees the earlier pair or the new one, whole, whenever the
    writer is killed. Both files are first written under temporary names (flushed); the earlier pair,
    if whole, is kept as hard links in ``.maps-previous/`` (:data:`MAPS_PREVIOUS`); then ``maps.npz``
    and ``maps.json`` are renamed into place and ``.maps-previous/`` is removed. The sidecar records the
    npz file's sha256 (``"arrays"``): a reader that finds a mismatched pair (killed between the two
    renames) reads ``.maps-previous/`` instead (:func:`solenoid_fmu.realtime.read_maps_dir`). The folder is
    locked while written (:func:`solenoid_fmu.fileio.dir_lock`): a second writer is refused.

    Parameters
    ----------
    maps : CharacteristicMaps
    directory : path-like
        Target directory, e.g. ``maps/ps45-literature``.

    Returns
    -------
    Path
        The directory.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    npz, sidecar = encode_maps(maps, default_name=directory.name)
    with dir_lock(directory):
        _commit_pair(directory, npz, sidecar)
    return directory


def encode_maps(maps: CharacteristicMaps, default_name: str = "maps") -> tuple[bytes, bytes]:
    """The bytes of ``maps.npz`` and ``maps.json`` as :func:`save_maps` writes them (nothing is written).

    Parameters
    ----------
    maps : CharacteristicMaps
    default_name : str
        The sidecar's ``name`` when the metadata has none (:func:`save_maps`: the directory's name).

    Returns
    -------
    (bytes, bytes)
        The npz (float64 arrays, no pickles) and the UTF-8 JSON sidecar (schema, units, the npz's sha256
        and shapes under ``"arrays"``).
    """
    buf = io.BytesIO()
    np.savez(buf, **{k: np.ascontiguousarray(v, dtype=np.float64) for k, v in maps.arrays().items()})
    npz = buf.getvalue()
    meta = {
        "schema": MAPS_SCHEMA,
        "schema_version": MAPS_SCHEMA_VERSION,
        **{k: v for k, v in maps.metadata.items() if k not in ("schema", "schema_version", "arrays")},
        "units": dict(ARRAY_UNITS),
        "arrays": {
            "file": MAPS_NPZ,
            "sha256": hashlib.sha256(npz).hexdigest(),
            "shapes": {k: list(v.shape) for k, v in maps.arrays().items()},
        },
    }
    meta.setdefault("name", default_name)
    return npz, (json.dumps(meta, indent=2, allow_nan=False) + "\n").encode("utf-8")


def maps_tables(maps: CharacteristicMaps, where: str | None = None) -> MapTables:
    """The real-time model's :class:`~solenoid_fmu.realtime.MapTables` of ``maps``, in memory.

    The same tables :func:`solenoid_fmu.realtime.load_tables` reads from the maps' directory written by
    :func:`save_maps` (the sidecar as ``meta``, the sweep's top current as ``i_fem_max_A``), after the checks
    of :func:`load_maps` (metadata, consistency of the tables).

    Parameters
    ----------
    maps : CharacteristicMaps
    where : str, optional
        The name in error messages (default: the maps' name).

    Raises
    ------
    MapsError
        The maps' metadata or tables are not what :func:`load_maps` accepts.
    """
    _, sidecar = encode_maps(maps)
    meta = json.loads(sidecar)
    where = where or meta["name"]
    problems = _meta_problems(meta) or consistency_problems(maps)
    if problems:
        raise MapsError(problem_message(where, problems))
    try:
        return MapTables(maps.psi_Wb, maps.x_m, maps.i_f_A, maps.force_N, extrapolated=maps.extrapolated, meta=meta,
                         where=where, i_fem_max_A=float(np.max(maps.i_A)) if maps.i_A.size else None)
    except ModelMapsError as exc:
        raise MapsError(str(exc)) from None


def _fsync_dir(directory: Path) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:  # pragma: no cover - platforms without directory fds
        return
    try:
        os.fsync(fd)
    except OSError:  # pragma: no cover
        pass
    finally:
        os.close(fd)


def _commit_pair(directory: Path, npz: bytes, sidecar: bytes) -> None:
    """Replace the pair in ``directory`` so that a reader sees the old or the new one whole (save_maps)."""
    staged = {MAPS_NPZ: directory / f".{MAPS_NPZ}.new", MAPS_JSON: directory / f".{MAPS_JSON}.new"}
    previous, building = directory / MAPS_PREVIOUS, directory / f"{MAPS_PREVIOUS}.tmp"
    try:
        for name, data in ((MAPS_NPZ, npz), (MAPS_JSON, sidecar)):
            try:
                atomic_write_bytes(staged[name], data)
            except OutputError:  # name the file of the set, not its hidden staging copy
                raise OutputError(f"{directory / name}: cannot write (no space, quota or rights); the earlier "
                                  "maps are unchanged") from None
        if maps_pair_consistent(directory):  # keep the earlier whole pair until the new one is in place
            shutil.rmtree(building, ignore_errors=True)
            building.mkdir()
            for name in (MAPS_NPZ, MAPS_JSON):
                try:
                    os.link(directory / name, building / name)
                except OSError:  # no hard links here: a copy
                    shutil.copyfile(directory / name, building / name)
            _fsync_dir(building)
            shutil.rmtree(previous, ignore_errors=True)
            os.replace(building, previous)
            _fsync_dir(directory)
        # a pair that is not whole (an earlier writer was killed) keeps the .maps-previous/ it has
        os.replace(staged[MAPS_NPZ], directory / MAPS_NPZ)
        os.replace(staged[MAPS_JSON], directory / MAPS_JSON)
        _fsync_dir(directory)
        shutil.rmtree(previous, ignore_errors=True)
    except OSError as exc:
        raise write_failure(directory / MAPS_NPZ, exc) from None
    finally:
        for p in staged.values():
            p.unlink(missing_ok=True)
        shutil.rmtree(building, ignore_errors=True)


def name_problem(name) -> str | None:
    """What is wrong with a maps name (None if nothing): it travels into modelDescription.xml,
    recording headers and C comments, so it must be one line of at most 200 characters."""
    if not isinstance(name, str):
        return "'name' must be a string"
    if any(ord(ch) < 32 or ord(ch) == 127 for ch in name) or len(name) > 200:
        return f"'name' must be one line of at most 200 characters without control characters, got {name[:60]!r}"
    return None


def _meta_problems(meta: dict) -> list[str]:
    problems = []
    if (problem := name_problem(meta.get("name"))) is not None:
        problems.append(problem)
    if meta.get("force_method") not in FORCE_METHODS:
        problems.append(
            f"'force_method' must be one of {list(FORCE_METHODS)}, got {meta.get('force_method')!r}"
        )
    units = meta.get("units")
    if not isinstance(units, dict):
        problems.append("'units' must be an object mapping array names to units")
    else:
        for name, unit in ARRAY_UNITS.items():
            if units.get(name) != unit:
                problems.append(f"units of {name} must be {unit!r}, file says {units.get(name)!r}")
    problems += coil_problems(meta.get("coil"))  # the rules of the typed records, every key required
    problems += eddy_problems(meta.get("eddy"))
    if not isinstance(meta.get("provenance"), dict):
        problems.append("'provenance' must be an object")
    arrays = meta.get("arrays")
    if arrays is not None and (not isinstance(arrays, dict) or not isinstance(arrays.get("sha256"), str)):
        problems.append("'arrays', when present, must be an object with the sha256 of maps.npz")
    return problems


def _refuse_meta(meta: dict, json_path) -> None:
    """The reader's ``check_meta``: refuse a sidecar with problems before its npz is read."""
    problems = _meta_problems(meta)
    if problems:
        raise MapsError(problem_message(str(json_path), problems))


def load_maps(directory) -> CharacteristicMaps:
    """Read maps written by :func:`save_maps`, refusing anything malformed.

    Parameters
    ----------
    directory : path-like
        The map directory (or its ``maps.json``/``maps.npz``).

    Returns
    -------
    CharacteristicMaps
        Its metadata is the sidecar without the ``schema``, ``schema_version`` and ``arrays`` entries.

    Raises
    ------
    MapsError
        Naming the file and every problem: missing file, invalid JSON, wrong schema name or version,
        missing arrays, wrong shapes, NaN/inf, non-monotone grids, fewer than 3 flux points, wrong units, a
        npz that does not belong to the sidecar, and tables that contradict each other
        (:mod:`solenoid_fmu.maps.consistency`: i_f not inverting Psi, negative force, F(Psi, x) not F(i, x)).
    """
    directory = Path(directory)
    if directory.is_file() and directory.name in (MAPS_NPZ, MAPS_JSON):
        directory = directory.parent
    try:
        meta, stored = read_maps_dir(directory, check_meta=_refuse_meta)
    except ModelMapsError as exc:
        raise MapsError(str(exc)) from None
    npz_path = directory / MAPS_NPZ
    arrays: dict[str, np.ndarray] = {}
    problems = []
    for name, arr in stored.items():
        if name not in ARRAY_UNITS:
            continue
        if arr.dtype.kind not in "fiu":
            problems.append(f"array {name} has dtype {arr.dtype}, expected float64")
            continue
        arrays[name] = arr.astype(np.float64)
    problems += array_problems(arrays) if not problems else []
    if problems:
        raise MapsError(problem_message(str(npz_path), problems))
    metadata = {k: v for k, v in meta.items() if k not in ("schema", "schema_version", "arrays")}
    maps = CharacteristicMaps(**arrays, metadata=metadata)
    problems = consistency_problems(maps)
    if problems:
        raise MapsError(problem_message(str(npz_path), problems))
    return maps
