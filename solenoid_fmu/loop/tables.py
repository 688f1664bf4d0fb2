"""The model's maps with effects: read them from an FMU, add effect sections, the improved maps.

The improved FMU carries the effects as switchable sub-models with parameters, from the
``effects`` section of its maps.json (:data:`ADDABLE` names the section of each effect); their
equations are in :meth:`solenoid_fmu.realtime.model.SolenoidModel._step_fx`.
"""

from __future__ import annotations

import dataclasses
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from ..errors import MapsError, SolenoidError
from ..maps import CharacteristicMaps, load_maps, maps_tables
from ..realtime import MAPS_JSON, MAPS_NPZ, MapTables

#: Effects ``improve`` can add, by the names ``diagnose`` uses, and their maps.json section.
ADDABLE = {"hysteresis": "hysteresis", "eddy": "eddy_ladder", "heating": "heating", "friction": "friction"}


class ImproveError(SolenoidError):
    """The improvement loop cannot run (no recordings, an FMU without maps, ...)."""


def maps_from_fmu(fmu_path) -> CharacteristicMaps:
    """The maps an FMU carries (``resources/maps.npz`` + ``maps.json``), read once and checked as
    :func:`solenoid_fmu.maps.load_maps` checks a maps directory."""
    fmu_path = Path(fmu_path)
    if not fmu_path.is_file():
        raise ImproveError(f"{fmu_path}: FMU file not found")
    try:
        with zipfile.ZipFile(fmu_path) as zf, tempfile.TemporaryDirectory(prefix="solenoid_improve_") as tmp:
            for name in (MAPS_NPZ, MAPS_JSON):
                Path(tmp, name).write_bytes(zf.read(f"resources/{name}"))
            return load_maps(tmp)
    except (KeyError, zipfile.BadZipFile, OSError) as exc:
        raise ImproveError(f"{fmu_path}: not a solenoid-fmu FMU with maps in resources/ ({exc})") from None
    except MapsError as exc:  # the maps are not readable or not valid
        raise ImproveError(f"{fmu_path}: {exc}") from None


def tables_from_fmu(fmu_path) -> MapTables:
    """The model's tables of the maps an FMU carries (:func:`maps_from_fmu`; maps.json as ``.meta``)."""
    try:
        return maps_tables(maps_from_fmu(fmu_path), where=str(fmu_path))
    except MapsError as exc:
        raise ImproveError(f"{fmu_path}: {exc}") from None


def with_maps_meta(maps: CharacteristicMaps, tables: MapTables) -> CharacteristicMaps:
    """``maps`` with the maps.json meta of ``tables`` (the effects the loop added, a refit G_eddy): the
    improved maps, written by :func:`solenoid_fmu.maps.save_maps` and packed into the improved FMU."""
    meta = {k: v for k, v in tables.meta.items() if k not in ("schema", "schema_version", "arrays")}
    return dataclasses.replace(maps, metadata=meta)


def with_effects(tables: MapTables, effects: dict, G_eddy_S: float | None = None,
                 G_eddy_source: str = "") -> MapTables:
    """A copy of ``tables`` whose maps.json meta carries ``effects``.

    ``G_eddy_S`` [S], if given, *replaces* the maps' eddy conductance (maps.json ``eddy.G_eddy_S``,
    fitted by :func:`solenoid_fmu.maps.fit_eddy`); ``G_eddy_source`` then says where the new value
    comes from and becomes ``eddy.source``, so the improved maps do not claim the old fit for it.
    """
    if G_eddy_S is None:
        return tables.with_meta(effects=effects)
    eddy = dataclasses.replace(tables.eddy, G_eddy_S=float(G_eddy_S), source=G_eddy_source or tables.eddy.source)
    return tables.with_meta(effects=effects, eddy=eddy)


#: maps.json keys that describe the file, not the model (:func:`simulates_alike` leaves them out).
_FILE_KEYS = ("schema", "schema_version", "arrays")


def simulates_alike(a: MapTables, b: MapTables) -> bool:
    """Whether ``a`` and ``b`` give the same simulations: the same arrays the lookups use
    (:meth:`MapTables.tables`), the same extrapolation flags and the same maps.json sections (the file's own
    keys aside). The improved maps round-tripped through their maps.json against the loop's tables in memory."""
    ta, tb = a.tables(), b.tables()
    if ta.keys() != tb.keys() or not all(np.array_equal(ta[k], tb[k]) for k in ta):
        return False
    if (a.extrapolated is None) != (b.extrapolated is None) or (
            a.extrapolated is not None and not np.array_equal(a.extrapolated, b.extrapolated)):
        return False
    return ({k: v for k, v in a.meta.items() if k not in _FILE_KEYS}
            == {k: v for k, v in b.meta.items() if k not in _FILE_KEYS})
