"""Native FMU backend: generated C, no Python at run time, FMI 2.0 co-simulation and model exchange.

``solenoid-fmu export maps/NAME -o build/NAME.fmu --backend c`` (or
``build_fmu(maps_dir, dest, backend="c")``) writes the maps as constant C arrays
(``solenoid_maps.h``: the cell cubics of :meth:`solenoid_fmu.model.MapTables.tables`, never
recomputed in C), copies the model source ``solenoid_fmu/c/solenoid_fmu.c`` and the FMI 2.0
headers shipped with fmpy (``fmpy/c-code/fmi2*.h``) into the FMU's ``sources/`` and compiles
``binaries/linux64/SolenoidFmu.so`` with the machine's C compiler (``$CC``, else ``gcc``, else
``cc``) using :data:`CFLAGS` (``-std=c99 -O2 -Wall -Wextra -Werror -ffp-contract=off``: no fused
multiply-add, so the arithmetic is the one of :mod:`solenoid_fmu.model`). ``sources/`` also holds a
``CMakeLists.txt``, so a source FMU importer (fmpy, Simulink) or a Windows user builds the binary
for another platform. ``resources/`` carries ``maps.npz`` and ``maps.json`` (read by
:func:`solenoid_fmu.fmu.simulate_recording`, not by the binary).

The C code reproduces :class:`solenoid_fmu.model.SolenoidModel` step for step (co-simulation:
ROS2 sub-steps of at most ``h_sub_max_s``, the safeguarded Newton iteration in current mode
with ``G_eddy = 0``, the same excursion flags and messages); ``fmi2DoStep`` allocates nothing.
A NaN or infinite input, ``R_ohm <= 0`` or ``G_eddy_S < 0`` is logged and returns ``fmi2Error``
with the state unchanged.

Effect sub-models (maps.json ``effects``; :data:`solenoid_fmu.fmu.EFFECT_VARIABLES`): the effect
data (play thresholds, weights and shape table; eddy-ladder ``G_k``, ``tau_k``) become constant
arrays in ``solenoid_maps.h`` (:func:`_effects_header`); switches and scalars are FMU parameters
with the defaults of :class:`solenoid_fmu.model.SolenoidModel`; the outputs ``i_hyst_A`` and
``T_rise_K`` exist. Co-simulation reproduces ``SolenoidModel._step_fx`` step for step (1e-9, in
practice bit for bit); the effect states are part of the FMU state. The variable list is
:func:`solenoid_fmu.fmu.interface_for` (value references = positions), then the model-exchange
locals of :func:`me_variables`.

Model exchange (same binary, same variables): the continuous state is the local
``psi_state_Wb`` [Wb] with derivative ``der(psi_state_Wb)`` [V] (paper eqs. 1-2 solved for
dPsi/dt: voltage mode ``(U - R i_f) / (1 + R G)``, current mode ``(i - i_f) / G``). Current mode
with ``G_eddy = 0`` is algebraic: the state is frozen (derivative 0), ``Psi`` is solved from the
input at each evaluation (no events), ``dpsi_dt_V = i_eddy_A = 0`` and ``U_out_V = R i`` (an ME
FMU gets no di/dt). The outputs are instantaneous in both modes; since they depend on the
inputs in model exchange, ``ModelStructure/Outputs`` lists those dependencies (for co-simulation,
where the outputs are held from the last step, this is a conservative superset).

:func:`finish_model_description` runs after :func:`solenoid_fmu.fmu.finalize_model_description`
and adds what model exchange needs (element, the two local variables, ``Derivatives``,
dependencies, source file lists).

Model exchange with effects: the continuous states are ``psi_state_Wb``, one
``ladder_state_<k>_A`` per eddy-ladder section and ``T_state_K`` (when the maps carry heating), each
with its ``der(...)`` local (``tau_k di_k/dt = G_k dPsi/dt - i_k``; ``C_th dT/dt = R(T) i^2 - T /
R_th`` with the instantaneous current; a switched-off effect has derivative 0). Hysteresis and
friction are rate independent: ME evaluates them from the memory committed at the last accepted
step (``fmi2CompletedIntegratorStep``, ``fmi2NewDiscreteStates``) moved to the current Psi and x,
which is continuous in the states, exact for monotone motion between accepted steps and needs no
events. Current mode with ``G_eddy_S = 0`` and the ladder on is a differential-algebraic system and
is refused in model exchange (error at initialization); co-simulation supports it.
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
import uuid
import zipfile
from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import FmuBuildError
from ..realtime import model as _model

__all__ = [
    "CFLAGS",
    "C_PARAMS",
    "C_SOURCE",
    "C_STATE_LAYOUT",
    "C_STATE_NAMES",
    "FMI_HEADERS",
    "ME_VARIABLES",
    "me_variables",
    "build_c_fmu",
    "compile_shared_library",
    "finish_model_description",
    "fmi_header_dir",
    "find_compiler",
    "generate_sources",
]

#: The model source (package data) copied into the FMU's ``sources/``.
C_SOURCE = Path(__file__).with_name("c") / "solenoid_fmu.c"
#: FMI 2.0 headers copied from fmpy's ``c-code`` directory.
FMI_HEADERS = ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h")
#: Compiler flags of the binary (gcc/clang syntax).
CFLAGS = ("-std=c99", "-O2", "-fPIC", "-shared", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror")
#: The state layout and parameters solenoid_fmu/c/solenoid_fmu.c implements (enum ST_*, struct Core).
#: :func:`build_c_fmu` refuses to build when :mod:`solenoid_fmu.model` has moved on (new states,
#: parameters or effects): the C code must then gain the same states and parameters first.
C_STATE_LAYOUT = 1
C_STATE_NAMES = ("state_layout", "time_s", "psi_Wb", "initialized", "excursion_psi", "excursion_x",
                 "excursion_extrapolated", "out_i_A", "out_U_V", "out_F_N", "out_dpsi_dt_V", "out_i_eddy_A")
C_PARAMS = ("R_ohm", "G_eddy_S", "drive_mode", "Psi0_Wb", "h_sub_max_s", "hysteresis_on", "hyst_gain",
            "eddy_ladder_on", "heating_on", "C_th_J_per_K", "R_th_K_per_W", "alpha_per_K", "friction_on",
            "friction_N", "presliding_m")
#: The effect sub-models and effect states the C template implements (model.EFFECT_NAMES,
#: model.EFFECT_STATE_NAMES; then one ladder_k per eddy section and one play_k per play operator).
C_EFFECT_NAMES = ("hysteresis", "eddy_ladder", "heating", "friction")
C_EFFECT_STATE_NAMES = ("T_rise_K", "F_friction_N", "x_prev_m", "i_hyst_A")
#: Model-exchange locals after the 15 variables of :data:`solenoid_fmu.fmu.VARIABLES`:
#: (name, unit, description); value references 15 and 16.
ME_VARIABLES = (
    ("psi_state_Wb", "Wb", "continuous state of model exchange: flux linkage Psi [Wb] (frozen in current mode "
                           "with G_eddy_S = 0, where Psi follows the input algebraically)"),
    ("der(psi_state_Wb)", "V", "dPsi/dt [V] of the model-exchange state (paper eqs. 1-2 solved for dPsi/dt)"),
)


def me_variables(tables: _model.MapTables) -> tuple:
    """Model-exchange locals of the native FMU for these maps: (name, unit, description) of the
    continuous states, then of their derivatives (value references from ``len(interface_for(tables))``).

    Without effects: :data:`ME_VARIABLES`. With effects, after ``psi_state_Wb``: one
    ``ladder_state_<k>_A`` per eddy-ladder section and ``T_state_K`` when the maps carry heating.
    """
    fx = _model._effects_data(tables) if tables.meta.get("effects") else {}
    states = [ME_VARIABLES[0]]
    for k in range(len((fx.get("eddy_ladder") or {}).get("G_S", ()))):
        states.append((f"ladder_state_{k}_A", "A", f"continuous state of model exchange: current of eddy-ladder "
                                                   f"section {k} [A] (tau_k di_k/dt = G_k dPsi/dt - i_k)"))
    if "heating" in fx:
        states.append(("T_state_K", "K", "continuous state of model exchange: coil temperature rise [K] "
                                         "(C_th dT/dt = R(T) i^2 - T / R_th)"))
    ders = [ME_VARIABLES[1]] + [(f"der({n})", u + "/s", f"time derivative of {n}") for n, u, _ in states[1:]]
    return tuple(states) + tuple(ders)


def fmi_header_dir() -> Path:
    """Directory of the FMI 2.0 headers shipped with fmpy (``fmpy/c-code``)."""
    import fmpy

    d = Path(fmpy.__file__).parent / "c-code"
    missing = [h for h in FMI_HEADERS if not (d / h).is_file()]
    if missing:
        raise FmuBuildError(f"{d}: fmpy {fmpy.__version__} does not ship {', '.join(missing)}")
    return d


def find_compiler() -> str:
    """Path of the C compiler: ``$CC``, else ``gcc``, else ``cc``."""
    for name in (os.environ.get("CC"), "gcc", "cc"):
        if name:
            path = shutil.which(name)
            if path:
                return path
    raise FmuBuildError("no C compiler found (set CC or install gcc); the native FMU backend compiles C")


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


def _effects_header(tables: _model.MapTables, params: dict) -> str:
    """The effect sub-models' data (maps.json ``effects``) as C macros and constant arrays."""
    try:
        fx = _model._effects_data(tables)
    except _model.ModelError as exc:
        raise FmuBuildError(f"{tables.where}: {exc}") from None
    hy = fx.get("hysteresis") or {}
    lad = fx.get("eddy_ladder") or {}
    keys = ("hyst_gain", "C_th_J_per_K", "R_th_K_per_W", "alpha_per_K", "friction_N", "presliding_m")
    _refuse_non_finite(f"{tables.where}: maps.json effects", {
        "eddy_ladder.G_S": lad.get("G_S", ()), "eddy_ladder.tau_s": lad.get("tau_s", ()),
        "hysteresis.thresholds": hy.get("r", ()), "hysteresis.weights": hy.get("w", ()),
        "hysteresis.shape.b_nodes": hy.get("gb", ()), "hysteresis.shape.g_nodes": hy.get("gg", ()),
        **{key: (params[key],) for key in keys}})
    lines = [
        "/* effect sub-models (maps.json effects; model.py _effects_data, SolenoidModel._step_fx) */",
        f"#define SOL_HAS_FX {_c_bool(tables.meta.get('effects'))}   /* the FMU has the effect variables */",
        f"#define SOL_FX_HYST {_c_bool('hysteresis' in fx)}",
        f"#define SOL_FX_LAD {_c_bool('eddy_ladder' in fx)}",
        f"#define SOL_FX_HEAT {_c_bool('heating' in fx)}",
        f"#define SOL_FX_FRIC {_c_bool('friction' in fx)}",
        f"#define SOL_N_LAD {len(lad.get('G_S', ()))}     /* eddy-ladder sections */",
        f"#define SOL_N_PLAY {len(hy.get('r', ()))}    /* play operators */",
        f"#define SOL_N_SHAPE {len(hy.get('gb', ()))}   /* nodes of the hysteresis shape g(Psi) (0: g = 1) */",
        "#define SOL_HYST_ON_DEFAULT " + _c_bool(params.get("hysteresis_on")),
        "#define SOL_LAD_ON_DEFAULT " + _c_bool(params.get("eddy_ladder_on")),
        "#define SOL_HEAT_ON_DEFAULT " + _c_bool(params.get("heating_on")),
        "#define SOL_FRIC_ON_DEFAULT " + _c_bool(params.get("friction_on")),
    ]
    for key in keys:
        lines.append(f"static const double SOL_{key.upper()}_DEFAULT = {_c_double(params[key])};")
    out = "\n".join(lines) + "\n"
    out += _c_table("SOL_LAD_G", lad.get("G_S", ()), "eddy-ladder section conductances G_k [S]")
    out += _c_table("SOL_LAD_TAU", lad.get("tau_s", ()), "eddy-ladder section time constants tau_k [s]")
    out += _c_table("SOL_PLAY_R", hy.get("r", ()), "play thresholds r_j [Wb]")
    out += _c_table("SOL_PLAY_W", hy.get("w", ()), "play weights w_j [A/Wb]")
    out += _c_table("SOL_SHAPE_B", hy.get("gb", ()), "shape nodes Psi [Wb] (increasing)")
    out += _c_table("SOL_SHAPE_G", hy.get("gg", ()), "shape factors g [-]")
    return out


def _maps_header(tables: _model.MapTables, params: dict, guid: str) -> str:
    """Text of ``solenoid_maps.h``: the maps as constant arrays plus the parameter defaults."""
    t = tables.tables()
    n_psi, n_x = tables.n_psi, tables.n_x
    ci = t["i_f_coef"].reshape(-1, 8)
    cf = t["force_coef"].reshape(-1, 8)
    x_start = 0.5 * (tables.x_min_m + tables.x_max_m)
    _refuse_non_finite(tables.where, {
        "x_m": tables.x_m, "1/dx": tables.inv_dx, "i_f cell cubics": ci, "force cell cubics": cf,
        "dpsi_Wb": (tables.dpsi_Wb,), "psi_max_Wb": (tables.psi_max_Wb,), "i_fem_max_A": (tables.i_fem_max_A,),
        **{key: (params[key],) for key in ("R_ohm", "G_eddy_S", "Psi0_Wb", "h_sub_max_s")}})
    name = _c_comment_text(tables.meta.get("name", "maps"))
    return f"""/* solenoid_maps.h: characteristic maps of '{name}' as C arrays.
 * Generated by solenoid_fmu.fmu_c (solenoid-fmu {__version__}); do not edit.
 * SOL_CI / SOL_CF: for flux cell k and gap cell j (row k * (SOL_N_X - 1) + j) the cubic coefficients
 * c0..c3 of column j and their differences e0..e3 to column j + 1 (model.MapTables.tables()). */
#ifndef SOLENOID_MAPS_H
#define SOLENOID_MAPS_H
#include <math.h>

#define SOL_GUID "{guid}"
#define SOL_N_PSI {n_psi}
#define SOL_N_X {n_x}
#define SOL_DRIVE_DEFAULT {int(params["drive_mode"])}

static const double SOL_DPSI = {_c_double(tables.dpsi_Wb)};          /* flux grid step [Wb] */
static const double SOL_INV_DPSI = {_c_double(tables.inv_dpsi)};    /* 1 / dpsi [1/Wb] */
static const double SOL_PSI_MAX = {_c_double(tables.psi_max_Wb)};   /* largest |Psi| of the map [Wb] */
static const double SOL_I_FEM_MAX = {_c_double(tables.i_fem_max_A)}; /* largest FEM sweep current [A] */
static const double SOL_R_DEFAULT = {_c_double(params["R_ohm"])};    /* coil resistance at 20 degC [ohm] */
static const double SOL_G_DEFAULT = {_c_double(params["G_eddy_S"])}; /* eddy conductance [S] */
static const double SOL_PSI0_DEFAULT = {_c_double(params["Psi0_Wb"])};  /* initial flux [Wb] */
static const double SOL_HSUB_DEFAULT = {_c_double(params["h_sub_max_s"])}; /* largest sub-step [s] */
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
{_effects_header(tables, params)}
#endif
"""


_CMAKE = """# Build the native solenoid FMU binary from these sources (FMI 2.0 source FMU).
#   cmake -S . -B build && cmake --build build --config Release
# Produces @ID@.so / .dll / .dylib; copy it to binaries/<platform>/ of the FMU.
cmake_minimum_required(VERSION 3.10)
project(@ID@ C)
add_library(@ID@ SHARED solenoid_fmu.c)
set_target_properties(@ID@ PROPERTIES PREFIX "" C_STANDARD 99)
if(NOT MSVC)
  target_compile_options(@ID@ PRIVATE -ffp-contract=off)
  target_link_libraries(@ID@ m)
endif()
"""


def _check_model_version() -> None:
    """Refuse to generate C for a model.py whose states or parameters the C template lacks."""
    if (_model.STATE_LAYOUT != C_STATE_LAYOUT or tuple(_model.STATE_NAMES) != C_STATE_NAMES
            or tuple(_model.DEFAULT_PARAMS) != C_PARAMS or tuple(_model.EFFECT_NAMES) != C_EFFECT_NAMES
            or tuple(_model.EFFECT_STATE_NAMES) != C_EFFECT_STATE_NAMES):
        raise FmuBuildError(
            f"the native backend implements model state layout {C_STATE_LAYOUT} ({len(C_STATE_NAMES)} states, "
            f"parameters {', '.join(C_PARAMS)}); solenoid_fmu/model.py has layout {_model.STATE_LAYOUT} "
            f"({len(_model.STATE_NAMES)} states, parameters {', '.join(_model.DEFAULT_PARAMS)}). Port the new "
            "effects to solenoid_fmu/c/solenoid_fmu.c (enum ST_*, struct Core, sol_step) and update "
            "solenoid_fmu.fmu_c.C_STATE_NAMES / C_PARAMS, or export with --backend python")


def _default_params(tables: _model.MapTables) -> dict:
    try:
        return dict(_model.SolenoidModel(tables).params)
    except _model.ModelError as exc:
        raise FmuBuildError(f"{tables.where}: {exc}") from None


def generate_sources(tables: _model.MapTables, dest_dir, *, guid: str | None = None) -> str:
    """Write the FMU's C sources (model, maps header, FMI headers, CMakeLists.txt) into ``dest_dir``.

    Parameters
    ----------
    tables : solenoid_fmu.model.MapTables
        The maps to embed.
    dest_dir : path-like
        Directory to write (created).
    guid : str, optional
        GUID compiled into the binary; default: derived from the sources and the maps.

    Returns
    -------
    str
        The GUID (``{...}`` form) the binary checks in ``fmi2Instantiate``.
    """
    from .export import MODEL_IDENTIFIER

    dest = Path(dest_dir)
    dest.mkdir(parents=True, exist_ok=True)
    params = _default_params(tables)
    source = C_SOURCE.read_text(encoding="utf-8")
    if guid is None:
        h = hashlib.sha256(source.encode())
        h.update(_maps_header(tables, params, "").encode())
        guid = "{" + str(uuid.UUID(bytes=h.digest()[:16], version=4)) + "}"
    (dest / "solenoid_maps.h").write_text(_maps_header(tables, params, guid), encoding="utf-8")
    (dest / "solenoid_fmu.c").write_text(source, encoding="utf-8")
    hdr = fmi_header_dir()
    for name in FMI_HEADERS:
        shutil.copyfile(hdr / name, dest / name)
    (dest / "CMakeLists.txt").write_text(_CMAKE.replace("@ID@", MODEL_IDENTIFIER), encoding="utf-8")
    return guid


def _platform() -> tuple[str, str]:
    if sys.platform.startswith("linux") and sys.maxsize > 2**32:
        return "linux64", ".so"
    if sys.platform == "darwin":
        return "darwin64", ".dylib"
    raise FmuBuildError(f"the native backend compiles on linux64 and darwin64, not {sys.platform}; build the "
                        "binary from the FMU's sources/ with CMake on this platform")


def compile_shared_library(src_dir, out_path, *, extra_flags=()) -> Path:
    """Compile ``src_dir/solenoid_fmu.c`` into the shared library ``out_path`` with :data:`CFLAGS`.

    Raises
    ------
    FmuBuildError
        No compiler, or the compiler failed (its output is in the message).
    """
    cc = find_compiler()
    src_dir = Path(src_dir)
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    cmd = [cc, *CFLAGS, *extra_flags, f"-I{src_dir}", "-o", str(out_path), str(src_dir / "solenoid_fmu.c"), "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    if proc.returncode != 0:
        raise FmuBuildError(f"compiling the native FMU failed ({' '.join(cmd)}):\n{proc.stderr.strip()}")
    return out_path


def _raw_model_description(guid: str, params: dict, tables: _model.MapTables) -> bytes:
    """A minimal co-simulation description with the interface variables (interface_for) and their start values.

    :func:`solenoid_fmu.fmu.finalize_model_description` completes it; then
    :func:`finish_model_description` adds model exchange.
    """
    from lxml import etree

    from .export import MODEL_IDENTIFIER, VARIABLES, interface_for

    root = etree.Element("fmiModelDescription", fmiVersion="2.0", modelName="solenoid", guid=guid,
                         numberOfEventIndicators="0")
    etree.SubElement(root, "CoSimulation", modelIdentifier=MODEL_IDENTIFIER)
    cats = etree.SubElement(root, "LogCategories")
    for name, desc in (("logStatusWarning", "Log messages with fmi2Warning status (map excursions)."),
                       ("logStatusDiscard", "Log messages with fmi2Discard status."),
                       ("logStatusError", "Log messages with fmi2Error status (invalid inputs or parameters)."),
                       ("logStatusFatal", "Log messages with fmi2Fatal status."),
                       ("logAll", "Log all messages.")):
        etree.SubElement(cats, "Category", name=name, description=desc)
    starts = {"U_V": 0.0, "i_A": 0.0, "x_m": 0.5 * (tables.x_min_m + tables.x_max_m), "R_ohm": params["R_ohm"],
              "G_eddy_S": params["G_eddy_S"], "drive_mode": params["drive_mode"], "Psi0_Wb": params["Psi0_Wb"],
              "h_sub_max_s": params["h_sub_max_s"]}
    variables = interface_for(tables)
    starts.update({v.name: params[v.name] for v in variables[len(VARIABLES):] if v.causality == "parameter"})
    mv = etree.SubElement(root, "ModelVariables")
    for k, v in enumerate(variables):
        sv = etree.SubElement(mv, "ScalarVariable", name=v.name, valueReference=str(k))
        el = etree.SubElement(sv, "Integer" if v.type == "Enumeration" else v.type)
        if v.name in starts:
            start = starts[v.name]
            el.set("start", repr(float(start)) if v.type == "Real" else ("true" if start else "false")
                   if v.type == "Boolean" else str(int(start)))
    etree.SubElement(root, "ModelStructure")
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8")


def build_c_fmu(maps_dir, dest, tables: _model.MapTables) -> str:
    """Generate, compile and pack the native FMU into ``dest`` (description not yet final).

    Returns the ``generationTool`` string. :func:`solenoid_fmu.fmu.build_fmu` then runs
    :func:`solenoid_fmu.fmu.finalize_model_description` and :func:`finish_model_description`.
    """
    from .export import MODEL_IDENTIFIER

    _check_model_version()
    maps_dir = Path(maps_dir)
    platform, ext = _platform()
    params = _default_params(tables)
    with tempfile.TemporaryDirectory(prefix="solenoid_fmu_c_") as tmp:
        tmp = Path(tmp)
        src = tmp / "sources"
        guid = generate_sources(tables, src)
        lib = compile_shared_library(src, tmp / "binaries" / platform / f"{MODEL_IDENTIFIER}{ext}")
        with zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.writestr("modelDescription.xml", _raw_model_description(guid, params, tables))
            zf.write(lib, f"binaries/{platform}/{lib.name}")
            for p in sorted(src.iterdir()):
                zf.write(p, f"sources/{p.name}")
            for name in ("maps.npz", "maps.json"):
                zf.write(maps_dir / name, f"resources/{name}")
    cc = Path(find_compiler()).name
    return f"solenoid-fmu {__version__} (c backend: generated C99, compiled with {cc})"


_DOC_C = ("<li>Native FMU (generated C, no Python at run time): co-simulation and model exchange in one "
          "binary; <code>sources/</code> builds it for other platforms (CMakeLists.txt). Model exchange: "
          "state psi_state_Wb (with effects also the eddy-ladder currents and the temperature rise); "
          "instantaneous outputs; current mode with G_eddy_S = 0 is algebraic (no continuous state, "
          "dpsi_dt_V = 0, U_out_V = R i); with effects, current mode with G_eddy_S = 0 and the eddy "
          "ladder on is co-simulation only.</li>")


def finish_model_description(fmu_path, tables: _model.MapTables) -> None:
    """Add model exchange to a finalized description of a native FMU (in place).

    Adds the ``ModelExchange`` element, ``SourceFiles`` in both interfaces, the local variables of
    :func:`me_variables` (value references after the interface: 15, 16 without effects),
    ``ModelStructure/Derivatives``, the
    model-exchange dependencies of the outputs and the two new initial unknowns; updates the
    documentation page for the native backend.
    """
    from lxml import etree

    from .export import DOC_PYTHON_BACKEND as _DOC_PY
    from .export import MODEL_IDENTIFIER, interface_for

    variables = interface_for(tables)
    fmu_path = Path(fmu_path)
    with zipfile.ZipFile(fmu_path) as zf:
        entries = [(info, zf.read(info.filename)) for info in zf.infolist()]
    md = next(data for info, data in entries if info.filename == "modelDescription.xml")
    root = etree.fromstring(md, etree.XMLParser(remove_blank_text=True))
    root.set("numberOfEventIndicators", "0")
    cs = root.find("CoSimulation")
    cs.set("canNotUseMemoryManagementFunctions", "false")
    me = etree.Element("ModelExchange", modelIdentifier=MODEL_IDENTIFIER, needsExecutionTool="false",
                       completedIntegratorStepNotNeeded="false", canBeInstantiatedOnlyOncePerProcess="false",
                       canNotUseMemoryManagementFunctions="false", canGetAndSetFMUstate="true",
                       canSerializeFMUstate="true", providesDirectionalDerivative="false")
    for el in (me, cs):
        for child in el.findall("SourceFiles"):
            el.remove(child)
        files = etree.SubElement(el, "SourceFiles")
        etree.SubElement(files, "File", name="solenoid_fmu.c")
    root.insert(list(root).index(cs), me)

    index = {v.name: k + 1 for k, v in enumerate(variables)}
    mv = root.find("ModelVariables")
    n0 = len(variables)
    locals_ = me_variables(tables)
    nx = len(locals_) // 2
    for k, (name, unit, desc) in enumerate(locals_):
        sv = etree.SubElement(mv, "ScalarVariable", name=name, valueReference=str(n0 + k), description=desc,
                              causality="local", variability="continuous", initial="calculated")
        real = etree.SubElement(sv, "Real", unit=unit)
        if k == 0:
            real.set("displayUnit", "mWb")
        elif k >= nx:
            real.set("derivative", str(n0 + 1 + k - nx))
    units = root.find("UnitDefinitions")
    have = {el.get("name") for el in units}
    for name, exps in (("A/s", {"A": "1", "s": "-1"}), ("K/s", {"K": "1", "s": "-1"})):
        if name not in have and any(unit == name for _, unit, _ in locals_):
            etree.SubElement(etree.SubElement(units, "Unit", name=name), "BaseUnit", **exps)
    i_states = tuple(range(n0 + 1, n0 + 1 + nx))
    i_ders = tuple(range(n0 + 1 + nx, n0 + 1 + 2 * nx))
    u, i, x = index["U_V"], index["i_A"], index["x_m"]
    # union over both drive modes of the model-exchange dependencies (see the module docstring); with
    # effects every output may depend on every state (conservative)
    st = i_states[:1] if nx == 1 else i_states
    deps = {"i_out_A": (u, i, x, *st), "U_out_V": (u, i, x, *st), "F_N": (i, x, *st),
            "psi_Wb": (i, x, *st), "dpsi_dt_V": (u, i, x, *st), "i_eddy_A": (u, i, x, *st),
            "out_of_map": (i, x, *st), "i_hyst_A": (i, x, *st), "T_rise_K": (u, i, x, *st)}
    ms = root.find("ModelStructure")
    outputs = ms.find("Outputs")
    for unk in outputs:
        name = variables[int(unk.get("index")) - 1].name
        unk.set("dependencies", " ".join(str(d) for d in deps[name]))
    derivs = etree.Element("Derivatives")
    for idx in i_ders:
        etree.SubElement(derivs, "Unknown", index=str(idx), dependencies=" ".join(str(d) for d in (u, i, x, *st)))
    ms.insert(list(ms).index(outputs) + 1, derivs)
    initial = ms.find("InitialUnknowns")
    knowns = " ".join(str(index[v.name]) for v in variables if v.causality in ("input", "parameter"))
    for idx in i_states + i_ders:
        etree.SubElement(initial, "Unknown", index=str(idx), dependencies=knowns)
    xml = etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)

    fd, tmp_name = tempfile.mkstemp(prefix=".md.", suffix=".fmu", dir=fmu_path.parent)
    os.close(fd)
    try:
        with zipfile.ZipFile(tmp_name, "w", zipfile.ZIP_DEFLATED) as out:
            for info, data in entries:
                if info.filename == "modelDescription.xml":
                    data = xml
                elif info.filename == "documentation/index.html":
                    text = data.decode("utf-8")
                    if _DOC_PY not in text:
                        raise FmuBuildError("documentation page changed; update solenoid_fmu.fmu.DOC_PYTHON_BACKEND")
                    text = text.replace(_DOC_PY, _DOC_C).replace("fmi2DoStep returns fmi2Discard",
                                                                 "fmi2DoStep returns fmi2Error")
                    data = text.encode("utf-8")
                out.writestr(info, data)
        os.replace(tmp_name, fmu_path)
    finally:
        if os.path.exists(tmp_name):
            os.unlink(tmp_name)
