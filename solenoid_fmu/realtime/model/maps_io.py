"""The maps file format as the model reads it: ``maps.json`` + ``maps.npz``, their checks, :func:`load_tables`.

Part of the FMU payload (:mod:`solenoid_fmu.realtime.model`): numpy and the standard library only.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import os
import zipfile

import numpy as np

from .definitions import ModelMapsError
from .tables import MapTables

#: Schema name and version of a maps directory (``maps.json``) this model reads.
MAPS_SCHEMA = "solenoid-fmu-maps"
MAPS_SCHEMA_VERSION = 1
#: The two files of a maps directory (:func:`read_maps_dir`).
MAPS_JSON = "maps.json"
MAPS_NPZ = "maps.npz"
#: Folder in a map directory holding the earlier whole pair while a writer replaces it (maps.io.save_maps).
MAPS_PREVIOUS = ".maps-previous"
#: Most elements one array of a maps.npz may declare (a 1000 x 1000 grid is far beyond any sweep).
MAPS_MAX_ARRAY_ELEMENTS = 10_000_000

def _first_non_finite(obj, where: str = ""):
    """(key path, value) of the first NaN or infinite number in parsed JSON ``obj``, or None."""
    if isinstance(obj, float) and not math.isfinite(obj):
        return where or "(top level)", obj
    items = obj.items() if isinstance(obj, dict) else enumerate(obj) if isinstance(obj, list) else ()
    for key, value in items:
        found = _first_non_finite(value, f"{where}[{key}]" if isinstance(key, int) else
                                  f"{where}.{key}" if where else str(key))
        if found is not None:
            return found
    return None


def _npz_member_problems(raw: bytes, shapes) -> list:
    """Problems of the members of a maps.npz read from their .npy headers (not their data): a dtype that
    is not numeric or boolean, a shape other than maps.json's ``arrays.shapes`` says, or more than
    :data:`MAPS_MAX_ARRAY_ELEMENTS` elements (a small file must not make the reader allocate gigabytes)."""
    problems = []
    with zipfile.ZipFile(io.BytesIO(raw)) as zf:
        for info in zf.infolist():
            name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
            with zf.open(info) as fh:
                try:
                    version = np.lib.format.read_magic(fh)
                    if version == (1, 0):
                        shape, _, dtype = np.lib.format.read_array_header_1_0(fh)
                    else:
                        shape, _, dtype = np.lib.format.read_array_header_2_0(fh)
                except ValueError as exc:
                    problems.append(f"member {name!r}: not a .npy array ({exc})")
                    continue
            if dtype.kind not in "fiub":
                problems.append(f"member {name!r}: dtype {dtype} is not numeric")
            n = int(np.prod(shape, dtype=np.float64))
            if n > MAPS_MAX_ARRAY_ELEMENTS:
                problems.append(f"member {name!r}: declares {n} elements (shape {shape}), more than "
                                f"{MAPS_MAX_ARRAY_ELEMENTS}")
            elif isinstance(shapes, dict) and name in shapes and list(shape) != list(shapes[name]):
                problems.append(f"{name} has shape {tuple(shape)}, expected {tuple(shapes[name])} "
                                f"(maps.json arrays.shapes)")
    return problems


def maps_pair_consistent(maps_dir) -> bool:
    """True if ``maps_dir`` holds ``maps.json`` and ``maps.npz`` written together: the sidecar parses and
    records the npz file's sha256, and it matches."""
    try:
        with open(os.path.join(maps_dir, MAPS_JSON), encoding="utf-8") as fh:
            meta = json.load(fh)
        with open(os.path.join(maps_dir, MAPS_NPZ), "rb") as fh:
            digest = hashlib.sha256(fh.read()).hexdigest()
    except (OSError, ValueError):
        return False
    entry = meta.get("arrays") if isinstance(meta, dict) else None
    return isinstance(entry, dict) and entry.get("sha256") == digest


def _read_sidecar(json_path: str) -> dict:
    """The parsed ``maps.json`` after the checks of its own (JSON, finite numbers, schema and version)."""
    try:
        with open(json_path, encoding="utf-8") as fh:
            meta = json.load(fh)
    except json.JSONDecodeError as exc:
        raise ModelMapsError(f"{json_path}:{exc.lineno}: not valid JSON: {exc.msg}") from None
    except UnicodeDecodeError:
        raise ModelMapsError(f"{json_path}: not UTF-8 text") from None
    except OSError as exc:
        raise ModelMapsError(f"{json_path}: cannot be read: {exc.strerror}") from None
    if not isinstance(meta, dict):
        raise ModelMapsError(f"{json_path}: top level must be a JSON object")
    bad = _first_non_finite(meta)
    if bad is not None:
        raise ModelMapsError(f"{json_path}: {bad[0]} = {bad[1]!r} is not a finite number (NaN and Infinity are "
                             "not JSON and would reach the FMU)")
    if meta.get("schema") != MAPS_SCHEMA:
        raise ModelMapsError(f"{json_path}: schema is {meta.get('schema')!r}, expected {MAPS_SCHEMA!r}: "
                             "not a map file")
    version = meta.get("schema_version")
    if version != MAPS_SCHEMA_VERSION or isinstance(version, bool):
        raise ModelMapsError(
            f"{json_path}: schema_version {version!r} is not supported; this reader reads schema_version "
            f"{MAPS_SCHEMA_VERSION} (rebuild the maps with `solenoid-fmu maps`)")
    return meta


def _read_npz_arrays(raw: bytes, shapes, npz_path: str) -> dict:
    """The members of a ``maps.npz`` (its bytes), checked on their headers first, read without pickle."""
    try:
        problems = _npz_member_problems(raw, shapes)
    except zipfile.BadZipFile as exc:
        raise ModelMapsError(f"{npz_path}: not a npz (zip) file: {exc}") from None
    if problems:
        raise ModelMapsError("\n".join([f"{npz_path}: {len(problems)} problem(s)"] + [f"  - {p}" for p in problems]))
    try:
        with np.load(io.BytesIO(raw), allow_pickle=False) as data:
            arrays = {k: np.array(data[k]) for k in data.files}
    except ValueError as exc:  # object arrays refused by allow_pickle=False, corrupt members
        raise ModelMapsError(f"{npz_path}: cannot read arrays without pickle: {exc}") from None
    except Exception as exc:  # zipfile.BadZipFile, EOFError, OSError and friends
        raise ModelMapsError(f"{npz_path}: not a readable npz file: {type(exc).__name__}: {exc}") from None
    return arrays


def read_maps_dir(maps_dir, check_meta=None) -> tuple:
    """Read a maps directory as stored: the ``maps.json`` sidecar and the ``maps.npz`` arrays.

    The one reader of the maps file format: :func:`load_tables` (the model, also inside every FMU)
    and ``solenoid_fmu.maps.load_maps`` (which adds the checks of what the content means) build on it.
    It refuses, naming the file: a missing file, JSON that is not valid (with its line), NaN or
    Infinity anywhere in the sidecar, a schema or schema version other than :data:`MAPS_SCHEMA`
    :data:`MAPS_SCHEMA_VERSION`, a ``maps.npz`` whose sha256 is not the one the sidecar records under
    ``"arrays"`` (files without that entry, written by other tools in the shared format, are
    accepted), members that are not numeric, larger than :data:`MAPS_MAX_ARRAY_ELEMENTS` or shaped
    other than the sidecar says (checked on their headers before any data is read), and pickles.
    A pair that does not match because its writer was killed between its two renames is read from
    the earlier whole pair the writer kept in :data:`MAPS_PREVIOUS` (so a reader sees the old or the
    new maps, whole).

    Parameters
    ----------
    maps_dir : str or path-like
        Directory holding ``maps.json`` and ``maps.npz``.
    check_meta : callable, optional
        ``check_meta(meta, json_path)``, called once the sidecar's schema is checked and before the
        npz is read; it raises to refuse the sidecar.

    Returns
    -------
    meta : dict
        The sidecar as parsed.
    arrays : dict
        The npz members by name, as stored (numeric ndarrays).

    Raises
    ------
    ModelMapsError
    """
    maps_dir = os.fspath(maps_dir)
    json_path = os.path.join(maps_dir, MAPS_JSON)
    npz_path = os.path.join(maps_dir, MAPS_NPZ)
    if not os.path.isdir(maps_dir):
        raise ModelMapsError(f"{maps_dir}: no such map directory")
    for p in (json_path, npz_path):
        if not os.path.isfile(p):
            raise ModelMapsError(f"{p}: missing (a map directory holds {MAPS_JSON} and {MAPS_NPZ})")
    meta = _read_sidecar(json_path)
    if check_meta is not None:
        check_meta(meta, json_path)
    try:
        with open(npz_path, "rb") as fh:
            raw = fh.read()
    except OSError as exc:
        raise ModelMapsError(f"{npz_path}: cannot be read: {exc.strerror}") from None
    entry = meta.get("arrays") if isinstance(meta.get("arrays"), dict) else {}
    recorded = entry.get("sha256")
    digest = hashlib.sha256(raw).hexdigest()
    if isinstance(recorded, str) and digest != recorded:
        previous = os.path.join(maps_dir, MAPS_PREVIOUS)
        if maps_pair_consistent(previous):  # a writer was killed between its renames: the earlier pair
            return read_maps_dir(previous, check_meta)
        raise ModelMapsError(f"{npz_path}: sha256 {digest[:12]}... does not match the {recorded[:12]}... recorded "
                             f"in {MAPS_JSON}; the two files were not written together")
    return meta, _read_npz_arrays(raw, entry.get("shapes"), npz_path)


def load_tables(maps_dir) -> MapTables:
    """Read a maps directory (``maps.npz`` + ``maps.json``, :func:`read_maps_dir`) into :class:`MapTables`.

    Parameters
    ----------
    maps_dir : str or path-like
        Directory holding ``maps.npz`` (loaded with ``allow_pickle=False``) and ``maps.json``.

    Returns
    -------
    MapTables

    Raises
    ------
    ModelMapsError
        Missing files, wrong schema or version, missing arrays, or maps the model cannot use.
    """
    meta, arrays = read_maps_dir(maps_dir)
    npz_path = os.path.join(os.fspath(maps_dir), MAPS_NPZ)
    missing = [k for k in ("psi_Wb", "x_m", "i_f_A", "force_N") if k not in arrays]
    if missing:
        raise ModelMapsError(f"{npz_path}: missing array(s) {', '.join(missing)}")
    i_sweep = arrays.get("i_A")
    i_fem_max = float(np.max(i_sweep)) if i_sweep is not None and np.size(i_sweep) else None
    return MapTables(arrays["psi_Wb"], arrays["x_m"], arrays["i_f_A"], arrays["force_N"],
                     extrapolated=arrays.get("extrapolated"), meta=meta, where=os.fspath(maps_dir),
                     i_fem_max_A=i_fem_max)

