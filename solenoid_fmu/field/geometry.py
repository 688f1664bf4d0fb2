"""Solenoid geometry: read the TOML description (mm) into a frozen SI ``Geometry`` and check it.

The file format is that of ``reference-solenoid.toml`` (PS45, shipped as the default):
named regions as polygons in the (r, z) half-plane, in millimetres; a ``[coil]`` table naming the
winding region with its turns and resistance; a ``[stroke]`` table; a ``[domain]`` air box.
The moving region (``moves = true``) is given at working gap x = 0 and is shifted by +x along z.

Extensions used by the analytic test cases (all optional):

- ``[domain] natural = ["outer", "top", "bottom"]``: sides with a natural (zero tangential H)
  boundary condition instead of A = 0. The axis always has u = r*A = 0.
- ``[[region]] ampere_turns = 1000.0``: a region carrying a fixed current (N*I in A) besides
  the coil, e.g. the second coil of the coil-coil force check.

Everything inside is SI (metres); millimetres exist only in the TOML file.
"""

from __future__ import annotations

import dataclasses
import hashlib
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from ..errors import GeometryError
from ..realtime import COPPER_ALPHA_PER_K

MM = 1e-3

#: Materials with mu = mu0 (the steel regions use the B(H) curve).
NONMAGNETIC = frozenset({"air", "copper", "aluminium", "brass", "plastic", "ptfe", "vacuum"})
MAGNETIC = frozenset({"steel"})
SIDES = frozenset({"outer", "top", "bottom"})


@dataclass(frozen=True)
class Region:
    """One named polygon region.

    Parameters
    ----------
    name : str
    material : str
        ``"steel"`` (nonlinear B(H)) or a non-magnetic name such as ``"air"``/``"copper"``.
    polygon_m : tuple of (r, z) pairs
        Vertices in metres; closed implicitly; for a moving region at x = 0.
    moves : bool
        True for the armature, which is shifted by +x along z.
    ampere_turns : float
        Fixed N*I of a source region other than the coil [A]; 0 for passive regions.
    """

    name: str
    material: str
    polygon_m: tuple[tuple[float, float], ...]
    moves: bool = False
    ampere_turns: float = 0.0

    def polygon_at(self, x_m: float) -> np.ndarray:
        """Vertices (n, 2) in metres at working gap ``x_m`` (shifted along z if the region moves)."""
        p = np.array(self.polygon_m, dtype=float)
        if self.moves:
            p[:, 1] += x_m
        return p

    @property
    def area_m2(self) -> float:
        """Cross-section area in the (r, z) plane [m^2] (shoelace formula)."""
        p = np.array(self.polygon_m)
        r, z = p[:, 0], p[:, 1]
        return 0.5 * abs(np.dot(r, np.roll(z, -1)) - np.dot(z, np.roll(r, -1)))


@dataclass(frozen=True)
class Coil:
    """The excitation winding: region name, turns, resistance at 20 C [ohm], copper coefficient [1/K]."""

    region: str
    turns: float
    resistance_ohm_20C: float
    temperature_coefficient_per_K: float = COPPER_ALPHA_PER_K
    max_current_A: float = 1.0


@dataclass(frozen=True)
class Stroke:
    """Armature travel: the whole stroke and the working range, in metres (gap x)."""

    min_m: float
    max_m: float
    working_min_m: float
    working_max_m: float


@dataclass(frozen=True)
class Domain:
    """The air box [0, r_max] x [z_min, z_max] in metres and the sides with natural conditions."""

    r_max_m: float
    z_min_m: float
    z_max_m: float
    natural: tuple[str, ...] = ()


@dataclass(frozen=True)
class Geometry:
    """A validated solenoid geometry in SI units. Immutable; build with :func:`load_geometry`."""

    name: str
    regions: tuple[Region, ...]
    coil: Coil
    stroke: Stroke
    domain: Domain
    source_path: Path | None = None
    sha256: str = ""
    extra: dict = field(default_factory=dict, compare=False, hash=False)

    def region(self, name: str) -> Region:
        """The region called ``name`` (KeyError if absent)."""
        for reg in self.regions:
            if reg.name == name:
                return reg
        raise KeyError(name)

    @property
    def moving(self) -> tuple[Region, ...]:
        """The regions that move with the armature."""
        return tuple(r for r in self.regions if r.moves)

    @property
    def coil_region(self) -> Region:
        return self.region(self.coil.region)

    def with_coil(self, **changes) -> Geometry:
        """A copy with coil fields replaced (e.g. ``turns=...``)."""
        return dataclasses.replace(self, coil=dataclasses.replace(self.coil, **changes))

    def validate(self) -> list[str]:
        """Every problem of this geometry as a list of messages (empty when valid)."""
        return check_geometry(self)


def default_geometry_path() -> Path:
    """Path of the packaged PS45 reference geometry."""
    return Path(str(resources.files("solenoid_fmu") / "data" / "ps45.toml"))


def load_geometry(path: str | Path | None = None) -> Geometry:
    """Read and validate a solenoid TOML file (mm) into an SI :class:`Geometry`.

    Parameters
    ----------
    path : path-like, optional
        The TOML file; ``None`` loads the packaged PS45.

    Raises
    ------
    GeometryError
        Listing every problem, each naming the region or key at fault.
    """
    path = Path(path) if path is not None else default_geometry_path()
    raw = path.read_bytes()
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise GeometryError(str(path), [f"not valid TOML: {exc}"]) from None
    geom, problems = _from_dict(data, path)
    if geom is not None:
        problems += check_geometry(geom)
    if problems:
        raise GeometryError(str(path), problems)
    return dataclasses.replace(geom, source_path=path.resolve(), sha256=hashlib.sha256(raw).hexdigest())


def geometry_from_dict(data: dict, name: str = "<dict>", require_moving: bool = False) -> Geometry:
    """Build and validate a geometry from a dict with the TOML file's structure (lengths in mm).

    Unlike a geometry file (:func:`load_geometry`: exactly one moving region), a programmatic
    geometry may have none (``require_moving=False``, static analytic cases); never more than one.
    """
    geom, problems = _from_dict(data, Path(name), require_moving)
    if geom is not None:
        problems += check_geometry(geom)
    if problems:
        raise GeometryError(name, problems)
    return geom


def _num(table: dict, key: str, where: str, problems: list[str], default=None) -> float | None:
    value = table.get(key, default)
    if value is None:
        problems.append(f"{where}: missing key '{key}'")
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value):
        problems.append(f"{where}: '{key}' must be a finite number, got {value!r}")
        return None
    return float(value)


#: Keys each table may hold; any other key is an error (a misspelled ``mooves`` must not silently
#: give a geometry without a moving region, i.e. F = 0 N everywhere).
_KEYS = {
    "": {"name", "description", "units", "region", "coil", "stroke", "domain", "notes"},
    "region": {"name", "material", "polygon", "moves", "ampere_turns", "description", "notes"},
    "coil": {"region", "turns", "resistance_ohm_20C", "temperature_coefficient_per_K", "max_current_A",
             "description", "notes"},
    "stroke": {"min_mm", "max_mm", "working_min_mm", "working_max_mm", "description", "notes"},
    "domain": {"r_max_mm", "z_min_mm", "z_max_mm", "natural", "description", "notes"},
}


def _unknown_keys(data: dict) -> list[str]:
    """Problems for keys the format does not know, naming table and key."""
    out = [f"unknown key '{k}' at the top level (known: {sorted(_KEYS[''])})" for k in data if k not in _KEYS[""]]
    for table in ("coil", "stroke", "domain"):
        t = data.get(table)
        if isinstance(t, dict):
            out += [f"[{table}]: unknown key '{k}' (known: {sorted(_KEYS[table])})" for k in t if k not in _KEYS[table]]
    regions = data.get("region")
    if isinstance(regions, list):
        for k, reg in enumerate(regions):
            if isinstance(reg, dict):
                where = f"region '{reg.get('name')}'" if isinstance(reg.get("name"), str) else f"region #{k + 1}"
                out += [f"{where}: unknown key '{key}' (known: {sorted(_KEYS['region'])})" for key in reg
                        if key not in _KEYS["region"]]
    return out


def _from_dict(data: dict, path: Path, require_moving: bool = True) -> tuple[Geometry | None, list[str]]:
    """The geometry of a parsed geometry file and every problem found (None with problems), in the file's
    order: unknown keys, units, the regions, [coil], [stroke], [domain], the moving region."""
    problems: list[str] = _unknown_keys(data)
    units = data.get("units", "mm")
    if units != "mm":
        problems.append(f"units must be \"mm\", got {units!r}")
    raw_regions = data.get("region", [])
    if not isinstance(raw_regions, list) or not raw_regions:
        problems.append("no [[region]] entries")
        raw_regions = []
    regions: list[Region] = []
    seen: set[str] = set()
    for k, reg in enumerate(raw_regions):
        region = _region(reg, k, seen, problems)
        if region is not None:
            regions.append(region)
    coil = _coil(data.get("coil"), seen, problems)
    stroke = _stroke(data.get("stroke"), problems)
    domain = _domain(data.get("domain"), problems)
    n_moving = sum(r.moves for r in regions)
    if regions and (n_moving > 1 or (require_moving and n_moving == 0)):
        problems.append(f"exactly one region must have 'moves = true' (the armature), found {n_moving}"
                        + ("" if n_moving else ": without one every force would be 0 N"))
    if problems or coil is None or stroke is None or domain is None:
        return None, problems
    geom = Geometry(
        name=str(data.get("name", path.stem)),
        regions=tuple(regions),
        coil=coil,
        stroke=stroke,
        domain=domain,
        source_path=None,
    )
    return geom, problems


def _region(reg: dict, k: int, seen: set, problems: list[str]) -> Region | None:
    """Region ``k`` (0-based) of the file, its name added to ``seen``; None with its problem appended."""
    where = f"region #{k + 1}"
    name = reg.get("name")
    if not isinstance(name, str) or not name:
        problems.append(f"{where}: missing 'name'")
        return None
    where = f"region '{name}'"
    if name in seen:
        problems.append(f"{where}: duplicate region name")
    seen.add(name)
    material = reg.get("material")
    if material not in NONMAGNETIC | MAGNETIC:
        problems.append(
            f"{where}: unknown material {material!r} (use 'steel' or one of {sorted(NONMAGNETIC)})"
        )
        return None
    poly = reg.get("polygon")
    try:
        arr = np.array(poly, dtype=float)
    except (TypeError, ValueError):
        arr = None
    if arr is None or arr.ndim != 2 or arr.shape[1] != 2:
        problems.append(f"{where}: 'polygon' must be a list of [r, z] pairs in mm")
        return None
    if not np.all(np.isfinite(arr)):
        problems.append(f"{where}: polygon has non-finite coordinates")
        return None
    if len(arr) > 1 and np.allclose(arr[0], arr[-1]):
        arr = arr[:-1]  # an explicitly closed polygon is accepted
    if len(arr) < 3:
        problems.append(f"{where}: open polygon: needs at least 3 distinct vertices, has {len(arr)}")
        return None
    at = reg.get("ampere_turns", 0.0)
    moves = reg.get("moves", False)
    if not isinstance(moves, bool):
        problems.append(f"{where}: 'moves' must be true or false (a TOML boolean, no quotes), got {moves!r}")
        return None
    if isinstance(at, bool) or not isinstance(at, int | float) or not np.isfinite(at):
        problems.append(f"{where}: 'ampere_turns' must be a finite number, got {at!r}")
        return None
    return Region(
        name=name,
        material=material,
        polygon_m=tuple((float(r) * MM, float(z) * MM) for r, z in arr),
        moves=moves,
        ampere_turns=float(at),
    )


def _coil(coil_t, seen: set, problems: list[str]) -> Coil | None:
    """The [coil] table (its region among the names in ``seen``); None with its problems appended."""
    if not isinstance(coil_t, dict):
        problems.append("no [coil] table")
        return None
    region = coil_t.get("region")
    turns = _num(coil_t, "turns", "[coil]", problems)
    res = _num(coil_t, "resistance_ohm_20C", "[coil]", problems)
    alpha = _num(coil_t, "temperature_coefficient_per_K", "[coil]", problems, COPPER_ALPHA_PER_K)
    imax = _num(coil_t, "max_current_A", "[coil]", problems, 1.0)
    if not isinstance(region, str):
        problems.append("[coil]: missing 'region'")
    elif region not in seen:
        problems.append(f"[coil]: region '{region}' is not defined")
    if turns is not None and turns <= 0:
        problems.append(f"[coil]: turns must be > 0, got {turns:g}")
    if res is not None and res <= 0:
        problems.append(f"[coil]: resistance_ohm_20C must be > 0, got {res:g}")
    if imax is not None and imax <= 0:
        problems.append(f"[coil]: max_current_A must be > 0, got {imax:g}")
    if None not in (turns, res, alpha, imax) and isinstance(region, str):
        return Coil(region, turns, res, alpha, imax)
    return None


def _stroke(st, problems: list[str]) -> Stroke | None:
    """The [stroke] table in m; None with its problems appended."""
    if not isinstance(st, dict):
        problems.append("no [stroke] table")
        return None
    vals = [_num(st, k, "[stroke]", problems) for k in ("min_mm", "max_mm")]
    wmin = _num(st, "working_min_mm", "[stroke]", problems, vals[0])
    wmax = _num(st, "working_max_mm", "[stroke]", problems, vals[1])
    if None in vals or None in (wmin, wmax):
        return None
    lo, hi = vals
    if not lo < hi:
        problems.append(f"[stroke]: min_mm ({lo:g}) must be below max_mm ({hi:g})")
    if lo < 0:
        problems.append(f"[stroke]: min_mm must be >= 0 (a working gap), got {lo:g}")
    if not lo <= wmin < wmax <= hi:
        problems.append(
            f"[stroke]: need min_mm <= working_min_mm < working_max_mm <= max_mm, "
            f"got {lo:g}, {wmin:g}, {wmax:g}, {hi:g}"
        )
    return Stroke(lo * MM, hi * MM, wmin * MM, wmax * MM)


def _domain(dom, problems: list[str]) -> Domain | None:
    """The [domain] table (the air box) in m; None with its problems appended."""
    if not isinstance(dom, dict):
        problems.append("no [domain] table")
        return None
    vals = [_num(dom, k, "[domain]", problems) for k in ("r_max_mm", "z_min_mm", "z_max_mm")]
    natural = tuple(dom.get("natural", ()))
    bad = [s for s in natural if s not in SIDES]
    if bad:
        problems.append(f"[domain]: unknown natural side(s) {bad}; use {sorted(SIDES)}")
    if None in vals:
        return None
    rmax, zmin, zmax = vals
    if rmax <= 0 or zmin >= zmax:
        problems.append(f"[domain]: empty air box r_max={rmax:g}, z from {zmin:g} to {zmax:g}")
    return Domain(rmax * MM, zmin * MM, zmax * MM, natural)


def check_geometry(geom: Geometry) -> list[str]:
    """Check a geometry; returns every problem found (empty list when valid).

    Checks: polygons simple (no self-intersection) with positive area; regions inside the air box
    and at r >= 0; no two regions overlapping; the moving regions collide with nothing over the
    whole stroke; a coil region with turns > 0.
    """
    from shapely.geometry import Polygon, box  # loaded when a geometry is checked, not on import
    from shapely.validation import explain_validity

    problems: list[str] = []
    tol = 1e-12  # m^2: overlaps smaller than this are touching edges
    d = geom.domain
    air_box = box(0.0, d.z_min_m, d.r_max_m, d.z_max_m)
    if geom.coil.turns <= 0:
        problems.append(f"coil: turns must be > 0, got {geom.coil.turns:g}")
    names = [r.name for r in geom.regions]
    if geom.coil.region not in names:
        problems.append(f"coil: region '{geom.coil.region}' is not defined")

    def shape(reg: Region, x_m: float):
        return Polygon(reg.polygon_at(x_m))

    def label(reg):
        return f"region '{reg.name}'"

    valid: list[Region] = []
    x_positions = [geom.stroke.min_m, geom.stroke.max_m]
    for reg in geom.regions:
        poly = shape(reg, geom.stroke.min_m)
        if not poly.is_valid:
            problems.append(f"{label(reg)}: self-intersecting polygon ({explain_validity(poly)}, in m)")
            continue
        if poly.area <= tol:
            problems.append(f"{label(reg)}: polygon has zero area")
            continue
        for x in x_positions if reg.moves else [0.0]:
            p = shape(reg, x)
            if not air_box.buffer(1e-12).contains(p):
                where = f" at x = {x * 1e3:g} mm" if reg.moves else ""
                problems.append(f"{label(reg)}: lies (partly) outside the air box{where}")
                break
        valid.append(reg)
    fixed = [r for r in valid if not r.moves]
    moving = [r for r in valid if r.moves]
    for a_i, a in enumerate(fixed):
        pa = shape(a, 0.0)
        for b in fixed[a_i + 1 :]:
            if pa.intersection(shape(b, 0.0)).area > tol:
                problems.append(f"regions '{a.name}' and '{b.name}' overlap")
    # The moving regions must not touch anything over the whole stroke: sample densely, and
    # check the swept area exactly (the union of the two end positions' convex hull with the
    # path is a superset for convex parts; sampling covers the rest).
    xs = np.linspace(geom.stroke.min_m, geom.stroke.max_m, 101)
    for m in moving:
        for f in fixed:
            pf = shape(f, 0.0)
            hit = [x for x in xs if shape(m, x).intersection(pf).area > tol]
            if hit:
                problems.append(
                    f"moving region '{m.name}' collides with '{f.name}' within the stroke "
                    f"(first at x = {hit[0] * 1e3:.3f} mm)"
                )
    return problems
