"""Typed records of the metadata in ``maps.json``: the coil, the eddy conductance, the effects section.

Part of the FMU payload (:mod:`solenoid_fmu.realtime.model`): the standard library only.
Each record reads its section of the parsed sidecar (:meth:`from_dict`, which refuses a wrong type naming
the section and key) and writes it back unchanged (:meth:`as_dict`: the same keys, in the same order, with
the same values; keys a record does not know are kept). The rules a value must meet are stated here once:
:func:`coil_problems` and :func:`eddy_problems` are what ``solenoid_fmu.maps.load_maps`` checks too.
:class:`~.tables.MapTables` gives the records as ``tables.coil``, ``tables.eddy`` and ``tables.effects``;
:func:`replace_meta` is the one way to a sidecar with other sections (:meth:`MapTables.with_meta`).
"""

from __future__ import annotations

import copy
import json
import math
from dataclasses import dataclass, field, fields

from .definitions import COPPER_ALPHA_PER_K, EFFECT_NAMES, ModelMapsError

#: The numbers of maps.json's ``coil`` section; all but the temperature coefficient must be > 0.
COIL_KEYS = ("turns", "resistance_ohm_20C", "temperature_coefficient_per_K", "max_current_A")
_COIL_MAY_BE_ZERO_OR_LESS = ("temperature_coefficient_per_K",)


def _finite_number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def coil_problems(raw, *, complete: bool = True) -> list[str]:
    """What is wrong with maps.json's ``coil`` section ``raw`` (empty: nothing).

    Every key of :data:`COIL_KEYS` is a finite number, > 0 but for the temperature coefficient; with
    ``complete=False`` (the model's reader) a key may be missing or null.
    """
    if raw is None and not complete:
        return []
    if not isinstance(raw, dict):
        return ["'coil' must be an object"]
    problems = []
    for key in COIL_KEYS:
        v = raw.get(key)
        if v is None and not complete:
            continue
        if not _finite_number(v):
            problems.append(f"coil.{key} must be a finite number, got {v!r}")
        elif key not in _COIL_MAY_BE_ZERO_OR_LESS and v <= 0:
            problems.append(f"coil.{key} must be > 0, got {v!r}")
    return problems


def eddy_problems(raw, *, complete: bool = True) -> list[str]:
    """What is wrong with maps.json's ``eddy`` section ``raw`` (empty: nothing): ``G_eddy_S`` is null or a
    finite number >= 0 [S], ``measured`` (optional) null or a boolean; with ``complete=False`` the section or
    the key may be missing."""
    if raw is None and not complete:
        return []
    if not isinstance(raw, dict) or ("G_eddy_S" not in raw and complete):
        return ["'eddy' must be an object with 'G_eddy_S' (number or null)"]
    g = raw.get("G_eddy_S")
    if g is not None and (not _finite_number(g) or g < 0):
        return [f"eddy.G_eddy_S must be null or a finite number >= 0 S, got {g!r}"]
    m = raw.get("measured")
    if m is not None and not isinstance(m, bool):
        return [f"eddy.measured must be null, true or false, got {m!r}"]
    return []


def _refuse(where: str, problems: list[str]) -> None:
    if problems:
        raise ModelMapsError(f"{where}: maps.json " + "; ".join(problems))


def _split(cls, raw: dict) -> tuple[dict, dict, tuple]:
    """(known fields, other keys, the keys in the file's order) of a section for record ``cls``."""
    names = [f.name for f in fields(cls) if f.name not in ("extra", "keys")]
    known = {k: raw[k] for k in names if k in raw}
    extra = {k: copy.deepcopy(v) for k, v in raw.items() if k not in names}
    return known, extra, tuple(raw)


def _as_dict(record) -> dict:
    """The section of ``record`` as maps.json holds it: its keys in the file's order (those it was read
    with; a field set since and not among them follows), unknown keys kept."""
    values = {f.name: getattr(record, f.name) for f in fields(record) if f.name not in ("extra", "keys")}
    out = {}
    for key in record.keys + tuple(k for k in values if k not in record.keys):
        if key in values:
            if values[key] is not None or key in record.keys or key in record.always:
                out[key] = values[key]
        elif key in record.extra:
            out[key] = copy.deepcopy(record.extra[key])
    return out


@dataclass(frozen=True)
class _Section:
    """Reading and writing of a section record (:class:`CoilRecord`, :class:`EddyRecord`): the record's own
    fields are the section's known keys.

    Attributes
    ----------
    extra : dict
        Keys of the section the record does not know, kept for :meth:`as_dict`.
    keys : tuple of str
        The section's keys in the file's order.
    """

    extra: dict = field(default_factory=dict, compare=False, repr=False, kw_only=True)
    keys: tuple = field(default=(), compare=False, repr=False, kw_only=True)
    #: Keys written even when null (the file format requires them).
    always = ()

    @staticmethod
    def problems(raw) -> list[str]:
        """What is wrong with the section ``raw`` for the model's reader (keys may be missing)."""
        raise NotImplementedError

    @classmethod
    def from_dict(cls, raw, where: str = "maps"):
        """The record of a parsed section (None: an empty record); ModelMapsError naming ``where``, the file
        and the key when a value has the wrong type (:meth:`problems`)."""
        _refuse(where, cls.problems(raw))
        if raw is None:
            return cls()
        known, extra, keys = _split(cls, raw)
        return cls(**known, extra=extra, keys=keys)

    def as_dict(self) -> dict:
        """The section as maps.json holds it (see the module docstring)."""
        return _as_dict(self)


@dataclass(frozen=True)
class CoilRecord(_Section):
    """maps.json's ``coil`` section: the coil the maps were computed for.

    Attributes
    ----------
    turns : float or None
        Number of turns [-].
    resistance_ohm_20C : float or None
        Resistance at 20 degC [ohm].
    temperature_coefficient_per_K : float or None
        Temperature coefficient of the resistance [1/K] (:attr:`alpha_per_K` with the default).
    max_current_A : float or None
        Rated (largest) current [A], the top of the FEM sweep.
    extra, keys
        What the section holds besides, and its order (:class:`_Section`).
    """

    turns: float | None = None
    resistance_ohm_20C: float | None = None
    temperature_coefficient_per_K: float | None = None
    max_current_A: float | None = None

    @staticmethod
    def problems(raw) -> list[str]:
        """:func:`coil_problems`, keys may be missing."""
        return coil_problems(raw, complete=False)

    @property
    def alpha_per_K(self) -> float:
        """The temperature coefficient [1/K]: the file's, else copper's (:data:`COPPER_ALPHA_PER_K`)."""
        a = self.temperature_coefficient_per_K
        return COPPER_ALPHA_PER_K if a is None else float(a)


@dataclass(frozen=True)
class EddyRecord(_Section):
    """maps.json's ``eddy`` section: the eddy-current conductance of paper eq. (2).

    Attributes
    ----------
    G_eddy_S : float or None
        Conductance [S] (A per V of dPsi/dt); None: not identified.
    source : str or None
        Where the value comes from (a fit, a refit by ``improve``).
    measured : bool or None
        The fit that set ``G_eddy_S`` measured an eddy current (:attr:`solenoid_fmu.maps.EddyFit.measurable`):
        the loop's evidence for its eddy ladder (:func:`solenoid_fmu.loop.improve_tables`). None: not said
        (older maps, a value set by hand).
    extra, keys
        What the section holds besides, and its order (:class:`_Section`).
    """

    G_eddy_S: float | None = None
    source: str | None = None
    measured: bool | None = None
    always = ("G_eddy_S",)  # the file format requires the key, null when not identified

    @staticmethod
    def problems(raw) -> list[str]:
        """:func:`eddy_problems`, the section or key may be missing."""
        return eddy_problems(raw, complete=False)


@dataclass(frozen=True)
class EffectsRecord:
    """maps.json's ``effects`` section: one entry per effect sub-model, each an object or null.

    The sections are kept as the file has them; :func:`~.effects.effects_data` checks their numbers and
    prepares them for the step.

    Attributes
    ----------
    hysteresis, eddy_ladder, heating, friction : dict or None
        The effect's section (null or missing: the effect is off).
    keys : tuple of str
        The effects named in the file (null ones too), in its order.
    """

    hysteresis: dict | None = None
    eddy_ladder: dict | None = None
    heating: dict | None = None
    friction: dict | None = None
    keys: tuple = ()

    @classmethod
    def from_dict(cls, raw, where: str = "maps") -> EffectsRecord:
        """The record of a parsed ``effects`` section (None or empty: no effects); ModelMapsError naming
        ``where`` when it is not an object, names an unknown effect or an effect that is not an object."""
        raw = raw or {}
        where = f"{where}: maps.json effects"
        if not isinstance(raw, dict):
            raise ModelMapsError(f"{where}: must be an object")
        for name, data in raw.items():
            if name not in EFFECT_NAMES:
                raise ModelMapsError(f"{where}: unknown effect {name!r}; known: {', '.join(EFFECT_NAMES)}")
            if data is not None and not isinstance(data, dict):
                raise ModelMapsError(f"{where}.{name}: must be an object")
        return cls(**{name: copy.deepcopy(data) for name, data in raw.items()}, keys=tuple(raw))

    def as_dict(self) -> dict:
        """The section as maps.json holds it: the effects named in the file (null ones too), in its order,
        then any set since."""
        names = self.keys + tuple(n for n in EFFECT_NAMES if n not in self.keys and getattr(self, n) is not None)
        return {name: copy.deepcopy(getattr(self, name)) for name in names}

    def items(self) -> list[tuple[str, dict | None]]:
        """``(name, section)`` of the effects named in the file, in its order."""
        return [(name, getattr(self, name)) for name in self.keys]

    @property
    def named(self) -> bool:
        """True when the file names any effect, null ones too (a null effect is no effect: whether the FMUs have
        the effect variables is :attr:`active`)."""
        return bool(self.keys)

    @property
    def active(self) -> bool:
        """True when at least one effect has a non-empty section: the one predicate of "the maps have effects"
        (both FMUs then have the effect variables: :func:`solenoid_fmu.fmu.interface.interface_for`, the native
        FMU's ``SOL_HAS_FX``)."""
        return any(getattr(self, name) for name in EFFECT_NAMES)


#: maps.json sections with a record, and the record's class.
RECORDS = {"coil": CoilRecord, "eddy": EddyRecord, "effects": EffectsRecord}
_RECORD_TYPES = tuple(RECORDS.values())


def replace_meta(meta: dict, **sections) -> dict:
    """A copy of the parsed sidecar ``meta`` with the given top-level sections replaced.

    Each value is a record (written with its :meth:`as_dict`) or plain data (copied); ``meta`` is left
    unchanged (the copy is a deep one, as JSON reads it back).
    """
    out = json.loads(json.dumps(meta))
    for key, value in sections.items():
        out[key] = value.as_dict() if isinstance(value, _RECORD_TYPES) else copy.deepcopy(value)
    return out
