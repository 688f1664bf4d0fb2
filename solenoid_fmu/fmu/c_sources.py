"""C sources of the native FMU, generated from the Python definitions (no C is written by hand here).

:func:`generate_sources` writes into the FMU's ``sources/``:

* ``solenoid_model.h`` (:func:`model_header`): the model's constants (:mod:`solenoid_fmu.realtime.model`:
  ``ROS2_GAMMA``, Newton limits, drive modes, ``MAX_SUBSTEPS``, ``STATE_LAYOUT``), its state list
  (``enum ST_*`` from ``STATE_NAMES``, ``enum FX_*`` from ``EFFECT_STATE_NAMES``), the counts of its
  parameters and effects, and the value references of the FMU interface (``enum VR_*`` from
  :func:`solenoid_fmu.fmu.interface.interface_for`). The C model uses these names, so C and Python
  are equal by construction; :func:`check_implemented` stops a build when model.py has states,
  parameters or effects the C source does not implement yet (it declares ``IMPLEMENTS_*``).
* ``solenoid_maps.h`` (:func:`maps_header`): the maps as constant arrays (the cell cubics of
  :meth:`solenoid_fmu.realtime.MapTables.tables`, never recomputed in C), the default of every
  parameter of ``DEFAULT_PARAMS`` for these maps (``SOL_<NAME>_DEFAULT``) and the effect data.
* the model source ``c/solenoid_fmu.c`` with the parts it includes (:data:`C_PARTS`: the model by job, one
  translation unit, so the build compiles ``solenoid_fmu.c`` alone), the FMI 2.0 headers shipped with fmpy
  and a ``CMakeLists.txt``.

Every number is written as the shortest round-trip literal (``repr``), checked finite first.
"""

from __future__ import annotations

import hashlib
import re
import shutil
import uuid
from pathlib import Path

import numpy as np

from .._version import __version__
from ..errors import FmuBuildError
from ..realtime import STATE_LAYOUT, STATE_NAMES, MapTables, ModelError, SolenoidModel, effects_data
from ..realtime import model as M
from .interface import EFFECT_VARIABLES, MODEL_IDENTIFIER, VARIABLES

__all__ = [
    "C_PARTS",
    "C_SOURCE",
    "C_SOURCE_FMI3",
    "FMI3_HEADERS",
    "FMI_HEADERS",
    "check_implemented",
    "default_params",
    "fmi_header_dir",
    "generate_sources",
    "maps_header",
    "model_header",
    "param_types",
]

#: The model source (package data) copied into the FMU's ``sources/``.
C_SOURCE = Path(__file__).with_name("c") / "solenoid_fmu.c"
#: The parts of the model that ``solenoid_fmu.c`` includes (``#include "sol_....c"``), by job: types and
#: logging, map lookup, parameters, the step, the effects' step, model-exchange evaluation.
C_PARTS = tuple(Path(__file__).with_name("c") / name for name in (
    "sol_core.h", "sol_lookup.c", "sol_params.c", "sol_step.c", "sol_effects.c", "sol_me.c"))
#: The FMI 3.0 functions: they include ``solenoid_fmu.c`` (fmi2 names prefixed, not exported) and call it.
C_SOURCE_FMI3 = Path(__file__).with_name("c") / "solenoid_fmi3.c"
#: FMI 2.0 headers copied from fmpy's ``c-code`` directory.
FMI_HEADERS = ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h")
#: FMI 3.0 headers copied from fmpy's ``c-code`` directory too (2-clause BSD licence in each header).
FMI3_HEADERS = ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")


def fmi_header_dir() -> Path:
    """Directory of the FMI 2.0 headers shipped with fmpy (``fmpy/c-code``)."""
    import fmpy  # third-party, loaded only when C sources are written

    d = Path(fmpy.__file__).parent / "c-code"
    missing = [h for h in (*FMI_HEADERS, *FMI3_HEADERS) if not (d / h).is_file()]
    if missing:
        raise FmuBuildError(f"{d}: fmpy {fmpy.__version__} does not ship {', '.join(missing)}")
    return d


def _c_double(v: float) -> str:
    """A C double literal: ``repr`` of a float checked finite (the shortest round-trip form: the C
    compiler reads back the same double). :func:`_refuse_non_finite` names the table first."""
    v = float(v)
    if not np.isfinite(v):
        raise FmuBuildError(f"{v!r} in the maps data is not finite; cannot generate C")
    return repr(v)


def _refuse_non_finite(where: str, named: dict) -> None:
    """Refuse non-finite numbers before any C is written, naming the table, the flat index and the value."""
    for name, values in named.items():
        flat = np.asarray(values, dtype=float).ravel()
        bad = np.flatnonzero(~np.isfinite(flat))
        if bad.size:
            k = int(bad[0])
            raise FmuBuildError(f"{where}: {name}[{k}] = {float(flat[k])!r} is not finite ({bad.size} such value(s)); "
                                "cannot generate C")


_C_COMMENT_SAFE = re.compile(r"[^A-Za-z0-9 _.,:+=()\[\]-]")


def _c_comment_text(text, limit: int = 80) -> str:
    """``text`` made safe for a C comment: characters outside ``[A-Za-z0-9 _.,:+=()[]-]`` become ``_``
    (no ``*/``, no line break, no quote or backslash can reach the compiler), cut to ``limit``."""
    safe = _C_COMMENT_SAFE.sub("_", str(text))
    return safe if len(safe) <= limit else safe[:limit - 3] + "..."


def _c_array(values, per_line: int = 4, rows: bool = False) -> str:
    """Comma-separated C literals, ``per_line`` a line (``rows``: each line braced as a row)."""
    flat = [_c_double(v) for v in np.asarray(values, dtype=float).ravel()]
    lines = [", ".join(flat[k:k + per_line]) for k in range(0, len(flat), per_line)]
    if rows:
        lines = ["{" + line + "}" for line in lines]
    return "    " + ",\n    ".join(lines)


def _c_bool(v) -> str:
    return "1" if v else "0"


def _c_table(name: str, values, comment: str) -> str:
    """A constant C array (at least one element: C99 has no empty arrays; the count macro says how many)."""
    vals = list(values) or [0.0]
    return f"/* {comment} */\nstatic const double {name}[{len(vals)}] = {{\n{_c_array(vals)}\n}};\n"


def _effects_header(tables: MapTables, params: dict) -> str:
    """The effect sub-models' data (maps.json ``effects``) as C macros and constant arrays."""
    try:
        fx = effects_data(tables)
    except ModelError as exc:
        raise FmuBuildError(f"{tables.where}: {exc}") from None
    hy = fx.get("hysteresis") or {}
    lad = fx.get("eddy_ladder") or {}
    fx_reals = [v.name for v in EFFECT_VARIABLES if v.causality == "parameter" and v.type == "Real"]
    _refuse_non_finite(f"{tables.where}: maps.json effects", {
        "eddy_ladder.G_S": lad.get("G_S", ()), "eddy_ladder.tau_s": lad.get("tau_s", ()),
        "hysteresis.thresholds": hy.get("r", ()), "hysteresis.weights": hy.get("w", ()),
        "hysteresis.shape.b_nodes": hy.get("gb", ()), "hysteresis.shape.g_nodes": hy.get("gg", ()),
        **{key: (params[key],) for key in fx_reals}})
    lines = [
        "/* effect sub-models (maps.json effects; model.py effects_data, SolenoidModel._step_fx) */",
        f"#define SOL_HAS_FX {_c_bool(tables.effects.active)}   /* the FMU has the effect variables (interface_for) */",
        f"#define SOL_FX_HYST {_c_bool('hysteresis' in fx)}",
        f"#define SOL_FX_LAD {_c_bool('eddy_ladder' in fx)}",
        f"#define SOL_FX_HEAT {_c_bool('heating' in fx)}",
        f"#define SOL_FX_FRIC {_c_bool('friction' in fx)}",
        f"#define SOL_N_LAD {len(lad.get('G_S', ()))}     /* eddy-ladder sections */",
        f"#define SOL_N_PLAY {len(hy.get('r', ()))}    /* play operators */",
        f"#define SOL_N_SHAPE {len(hy.get('gb', ()))}   /* nodes of the hysteresis shape g(Psi) (0: g = 1) */",
    ]
    out = "\n".join(lines) + "\n"
    out += _c_table("SOL_LAD_G", lad.get("G_S", ()), "eddy-ladder section conductances G_k [S]")
    out += _c_table("SOL_LAD_TAU", lad.get("tau_s", ()), "eddy-ladder section time constants tau_k [s]")
    out += _c_table("SOL_PLAY_R", hy.get("r", ()), "play thresholds r_j [Wb]")
    out += _c_table("SOL_PLAY_W", hy.get("w", ()), "play weights w_j [A/Wb]")
    out += _c_table("SOL_SHAPE_B", hy.get("gb", ()), "shape nodes Psi [Wb] (increasing)")
    out += _c_table("SOL_SHAPE_G", hy.get("gg", ()), "shape factors g [-]")
    return out


def _c_name(prefix: str, name: str) -> str:
    """The C identifier of a model or interface name (``psi_Wb`` -> ``ST_PSI_WB``)."""
    ident = f"{prefix}{name.upper()}"
    if not re.fullmatch(r"[A-Z_][A-Z0-9_]*", ident):
        raise FmuBuildError(f"{name!r} gives no C identifier ({ident!r}); rename it in model.py or interface.py")
    return ident


def _c_enum(prefix: str, names, last: str | None = None, first: int = 0) -> str:
    items = [_c_name(prefix, n) for n in names]
    items[0] += f" = {first}"
    if last:
        items.append(last)
    lines = []
    for k in range(0, len(items), 4):
        lines.append("    " + ", ".join(items[k:k + 4]) + ("," if k + 4 < len(items) else ""))
    return "enum {\n" + "\n".join(lines) + "\n};\n"


def param_types() -> dict:
    """FMI type of every model parameter (``DEFAULT_PARAMS``), from the interface table."""
    types = {v.name: v.type for v in VARIABLES + EFFECT_VARIABLES if v.causality == "parameter"}
    missing = [name for name in M.DEFAULT_PARAMS if name not in types]
    if missing:
        raise FmuBuildError(f"model.py parameters {', '.join(missing)} are not FMU variables: add them to "
                            "solenoid_fmu/fmu/interface.py and port them to solenoid_fmu/fmu/c/solenoid_fmu.c")
    return types


def model_header() -> str:
    """Text of ``solenoid_model.h``: model.py's constants, state list and parameter count, and the
    value references of the interface table, as C (the same for every maps)."""
    vr_base = [v.name for v in VARIABLES]
    vr_fx = [v.name for v in EFFECT_VARIABLES]
    return f"""/* solenoid_model.h: definitions of the real-time model for solenoid_fmu.c.
 * Generated by solenoid_fmu.fmu.c_sources (solenoid-fmu {__version__}) from solenoid_fmu/realtime/model.py
 * and solenoid_fmu/fmu/interface.py; do not edit. */
#ifndef SOLENOID_MODEL_H
#define SOLENOID_MODEL_H

/* model.py constants */
#define ROS2_GAMMA {_c_double(M.ROS2_GAMMA)}
#define NEWTON_MAX_ITER {int(M.NEWTON_MAX_ITER)}
#define NEWTON_TOL_REL {_c_double(M.NEWTON_TOL_REL)}
#define DRIVE_VOLTAGE {int(M.DRIVE_VOLTAGE)}
#define DRIVE_CURRENT {int(M.DRIVE_CURRENT)}
/* Bound of the work of one fmi2DoStep: ceil(h / h_sub_max_s) sub-steps at most (else fmi2Error). */
#define MAX_SUBSTEPS {_c_double(M.MAX_SUBSTEPS)}
/* Range of T_start_excess_K [K] (model.py T_START_EXCESS_RANGE_K). */
#define SOL_T_START_EXCESS_MIN_K {_c_double(M.T_START_EXCESS_RANGE_K[0])}
#define SOL_T_START_EXCESS_MAX_K {_c_double(M.T_START_EXCESS_RANGE_K[1])}

/* The state vector of model.py (STATE_NAMES, STATE_LAYOUT). */
#define STATE_LAYOUT {int(STATE_LAYOUT)}
{_c_enum("ST_", STATE_NAMES, "N_STATE")}
/* Effect states (model.py EFFECT_STATE_NAMES, then ladder_k, then play_k), kept in Core.fx. */
{_c_enum("FX_", M.EFFECT_STATE_NAMES, "FX_LAD")}
/* model.py DEFAULT_PARAMS and EFFECT_NAMES: how many (solenoid_fmu.c says which it implements) */
#define SOL_N_PARAMS {len(M.DEFAULT_PARAMS)}
#define SOL_N_EFFECTS {len(M.EFFECT_NAMES)}
#define SOL_N_EFFECT_STATES {len(M.EFFECT_STATE_NAMES)}

/* Value references (interface.py: VARIABLES, then EFFECT_VARIABLES when the maps carry effects). */
{_c_enum("VR_", vr_base + vr_fx)}#define SOL_N_VR {len(vr_base)}
#define SOL_N_VR_FX {len(vr_base) + len(vr_fx)}

#endif
"""


#: What solenoid_fmu.c declares it implements (``#define IMPLEMENTS_<KEY> <n>``) and model.py's value.
_IMPLEMENTS = {
    "STATE_LAYOUT": lambda: int(STATE_LAYOUT),
    "N_PARAMS": lambda: len(M.DEFAULT_PARAMS),
    "N_EFFECTS": lambda: len(M.EFFECT_NAMES),
    "N_EFFECT_STATES": lambda: len(M.EFFECT_STATE_NAMES),
}


def check_implemented(source: str | None = None) -> None:
    """Refuse to generate C for a model.py with states, parameters or effects the C source lacks.

    The C source declares what it implements (``#define IMPLEMENTS_STATE_LAYOUT 1`` ...); it also
    stops at compile time (``#error``) when the generated ``solenoid_model.h`` disagrees. These are counts
    only: that both do the same arithmetic is checked by ``tests/test_backends_equal.py`` (bit for bit).
    """
    source = C_SOURCE.read_text(encoding="utf-8") if source is None else source
    diff = []
    for key, value in _IMPLEMENTS.items():
        m = re.search(rf"^#define IMPLEMENTS_{key} (\d+)\s*$", source, re.M)
        if m is None:
            raise FmuBuildError(f"{C_SOURCE}: no '#define IMPLEMENTS_{key}' line")
        if int(m.group(1)) != value():
            diff.append(f"{key.lower()} {m.group(1)} in C, {value()} in model.py")
    if diff:
        raise FmuBuildError(
            f"the native backend implements another model than solenoid_fmu/realtime/model.py ({'; '.join(diff)}; "
            f"model states {', '.join(STATE_NAMES)}; parameters {', '.join(M.DEFAULT_PARAMS)}). Port the new "
            "effects to solenoid_fmu/fmu/c/solenoid_fmu.c (struct Core, sol_step, the IMPLEMENTS_* lines), or "
            "export with --backend python")
    param_types()


def default_params(tables: MapTables) -> dict:
    """The model's parameters for these maps (``SolenoidModel(tables).params``); model errors become FmuBuildError."""
    try:
        return dict(SolenoidModel(tables).params)
    except ModelError as exc:
        raise FmuBuildError(f"{tables.where}: {exc}") from None


def _param_defaults(tables: MapTables, params: dict) -> str:
    """``SOL_<NAME>_DEFAULT`` of every model parameter: a double, or a macro for Integer and Boolean."""
    types = param_types()
    fx = {v.name for v in EFFECT_VARIABLES}
    for where, names in ((tables.where, [n for n in M.DEFAULT_PARAMS if n not in fx]),
                         (f"{tables.where}: maps.json effects", [n for n in M.DEFAULT_PARAMS if n in fx])):
        _refuse_non_finite(where, {n: (params[n],) for n in names if types[n] == "Real"})
    lines = ["/* parameter defaults for these maps (model.py DEFAULT_PARAMS, SolenoidModel(tables).params) */"]
    for name in M.DEFAULT_PARAMS:
        if types[name] == "Real":
            lines.append(f"static const double {_c_name('SOL_', name)}_DEFAULT = {_c_double(params[name])};")
        elif types[name] == "Boolean":
            lines.append(f"#define {_c_name('SOL_', name)}_DEFAULT {_c_bool(params[name])}")
        else:
            lines.append(f"#define {_c_name('SOL_', name)}_DEFAULT {int(params[name])}")
    return "\n".join(lines) + "\n"


def maps_header(tables: MapTables, params: dict, guid: str) -> str:
    """Text of ``solenoid_maps.h``: the maps as constant arrays plus the parameter defaults."""
    t = tables.tables()
    n_psi, n_x = tables.n_psi, tables.n_x
    ci = t["i_f_coef"].reshape(-1, 8)
    cf = t["force_coef"].reshape(-1, 8)
    x_start = 0.5 * (tables.x_min_m + tables.x_max_m)
    _refuse_non_finite(tables.where, {
        "x_m": tables.x_m, "1/dx": tables.inv_dx, "i_f cell cubics": ci, "force cell cubics": cf,
        "dpsi_Wb": (tables.dpsi_Wb,), "psi_max_Wb": (tables.psi_max_Wb,), "i_fem_max_A": (tables.i_fem_max_A,)})
    effects = _effects_header(tables, params)
    defaults = _param_defaults(tables, params)
    name = _c_comment_text("maps" if tables.name is None else tables.name)
    return f"""/* solenoid_maps.h: characteristic maps of '{name}' as C arrays.
 * Generated by solenoid_fmu.fmu.c_sources (solenoid-fmu {__version__}); do not edit.
 * SOL_CI / SOL_CF: for flux cell k and gap cell j (row k * (SOL_N_X - 1) + j) the cubic coefficients
 * c0..c3 of column j and their differences e0..e3 to column j + 1 (model.MapTables.tables()). */
#ifndef SOLENOID_MAPS_H
#define SOLENOID_MAPS_H
#include <math.h>

#define SOL_GUID "{guid}"
#define SOL_N_PSI {n_psi}
#define SOL_N_X {n_x}

static const double SOL_DPSI = {_c_double(tables.dpsi_Wb)};          /* flux grid step [Wb] */
static const double SOL_INV_DPSI = {_c_double(tables.inv_dpsi)};    /* 1 / dpsi [1/Wb] */
static const double SOL_PSI_MAX = {_c_double(tables.psi_max_Wb)};   /* largest |Psi| of the map [Wb] */
static const double SOL_I_FEM_MAX = {_c_double(tables.i_fem_max_A)}; /* largest FEM sweep current [A] */
static const double SOL_X_START = {_c_double(x_start)};             /* start value of x_m [m] */

/* gap grid [m] and 1 / (x_j+1 - x_j) [1/m] */
static const double SOL_X[SOL_N_X] = {{
{_c_array(tables.x_m)}
}};
static const double SOL_INV_DX[SOL_N_X - 1] = {{
{_c_array(tables.inv_dx)}
}};
/* i_f(Psi, x) [A] cell cubics */
static const double SOL_CI[(SOL_N_PSI - 1) * (SOL_N_X - 1)][8] = {{
{_c_array(ci, 8, rows=True)}
}};
/* F(Psi, x) [N] cell cubics */
static const double SOL_CF[(SOL_N_PSI - 1) * (SOL_N_X - 1)][8] = {{
{_c_array(cf, 8, rows=True)}
}};
{defaults}{effects}
#endif
"""


_CMAKE = """# Build the native solenoid FMU binary from these sources (FMI @VER@ source FMU).
#   cmake -S . -B build && cmake --build build --config Release
# Produces @ID@.so / .dll / .dylib; copy it to binaries/<platform>/ of the FMU.
cmake_minimum_required(VERSION 3.10)
project(@ID@ C)
add_library(@ID@ SHARED @SRC@)
set_target_properties(@ID@ PROPERTIES PREFIX "" C_STANDARD 99 C_VISIBILITY_PRESET hidden)
if(NOT MSVC)
  target_compile_options(@ID@ PRIVATE -ffp-contract=off)
  target_link_libraries(@ID@ m)
endif()
"""

#: ``sources/buildDescription.xml`` of an FMI 3.0 source FMU (what fmpy and other importers compile).
_BUILD_DESCRIPTION = """<?xml version="1.0" encoding="UTF-8"?>
<fmiBuildDescription fmiVersion="3.0">
  <BuildConfiguration modelIdentifier="@ID@">
    <SourceFileSet language="C99">
      <SourceFile name="solenoid_fmi3.c"/>
    </SourceFileSet>
  </BuildConfiguration>
</fmiBuildDescription>
"""


def generate_sources(tables: MapTables, dest_dir, *, guid: str | None = None, fmi_version: int = 2) -> str:
    """Write the FMU's C sources (model, model and maps headers, FMI headers, CMakeLists.txt) into ``dest_dir``.

    Parameters
    ----------
    tables : solenoid_fmu.realtime.MapTables
        The maps to embed.
    dest_dir : path-like
        Directory to write (created).
    guid : str, optional
        GUID compiled into the binary; default: derived from the sources and the maps.
    fmi_version : int
        2, or 3: also ``solenoid_fmi3.c`` (the FMI 3.0 functions, built instead of ``solenoid_fmu.c``
        which it includes), the FMI 3.0 headers and ``buildDescription.xml``.

    Returns
    -------
    str
        The GUID (``{...}`` form; FMI 3.0: the instantiation token) the binary checks when instantiated.
    """
    if fmi_version not in (2, 3):
        raise FmuBuildError(f"FMI version {fmi_version!r}: the native backend writes FMI 2 or 3")
    source = C_SOURCE.read_text(encoding="utf-8")
    source3 = C_SOURCE_FMI3.read_text(encoding="utf-8") if fmi_version == 3 else ""
    parts = {p.name: p.read_text(encoding="utf-8") for p in C_PARTS}
    check_implemented(source)
    dest = Path(dest_dir)
    params = default_params(tables)
    model_h = model_header()
    if guid is None:
        h = hashlib.sha256(source.encode())
        for name, text in parts.items():
            h.update(name.encode() + b"\0" + text.encode())
        h.update(source3.encode())
        h.update(model_h.encode())
        h.update(maps_header(tables, params, "").encode())
        guid = "{" + str(uuid.UUID(bytes=h.digest()[:16], version=4)) + "}"
    maps_h = maps_header(tables, params, guid)
    dest.mkdir(parents=True, exist_ok=True)
    (dest / "solenoid_model.h").write_text(model_h, encoding="utf-8")
    (dest / "solenoid_maps.h").write_text(maps_h, encoding="utf-8")
    (dest / "solenoid_fmu.c").write_text(source, encoding="utf-8")
    for name, text in parts.items():
        (dest / name).write_text(text, encoding="utf-8")
    hdr = fmi_header_dir()
    for name in FMI_HEADERS + (FMI3_HEADERS if fmi_version == 3 else ()):
        shutil.copyfile(hdr / name, dest / name)
    main = "solenoid_fmi3.c" if fmi_version == 3 else "solenoid_fmu.c"
    if fmi_version == 3:
        (dest / main).write_text(source3, encoding="utf-8")
        (dest / "buildDescription.xml").write_text(_BUILD_DESCRIPTION.replace("@ID@", MODEL_IDENTIFIER),
                                                   encoding="utf-8")
    cmake = _CMAKE.replace("@ID@", MODEL_IDENTIFIER).replace("@SRC@", main).replace("@VER@", f"{fmi_version}.0")
    (dest / "CMakeLists.txt").write_text(cmake, encoding="utf-8")
    return guid
