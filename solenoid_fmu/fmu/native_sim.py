"""The fast path of :func:`solenoid_fmu.fmu.simulate_model`: the native model's step, compiled once per model
structure and run over a whole recording in one call.

The loop (``improve``, ``validate``, ``diagnose``, the lot) simulates the lumped model over every recording many
times; in Python that is ~0.1 ms a communication step (ROS2 sub-steps, table lookups, play operators), most of
the loop's time. The native FMU's C step (``fmu/c/sol_*.c``) does the same IEEE-754 operations in the same
order and equals the Python step bit for bit (``tests/test_backends_equal.py``, random maps, effects and inputs),
so running it gives the same numbers ~100x sooner. Nothing else changes: the Python model stays the reference,
the pythonfmu payload and the path wherever this one is not available.

How: ``fmu/c/sol_sim.c`` includes the FMU's model source with a ``solenoid_maps.h`` of :func:`sim_maps_header`,
whose maps and effect data are pointers and variables bound at run time (``sim_bind``), so one shared library
serves every maps of the same *structure* (which effects, ladder sections and play operators, the Boolean and
Integer parameter defaults); the values (grids, cell cubics, effect data, Real parameter defaults) are passed
with each call (:func:`bind_data`). The library is compiled with the machine's C compiler
(:func:`solenoid_fmu.fmu.native.find_compiler`, :data:`SIM_CFLAGS`: no fused multiply-add, as the FMU) into
:func:`cache_dir` under the hash of its sources and flags, and loaded with ctypes; it drives the FMI 2.0
functions as :func:`solenoid_fmu.fmu.simulate_recording` drives an FMU.

Used when ``SOLENOID_FMU_SIMULATOR`` is ``auto`` (the default) or ``native`` and a C compiler builds the library;
``python`` turns it off. Where the model refuses an input (NaN, a step beyond ``MAX_SUBSTEPS``) the caller runs the
Python model, whose error message is the one users see. With ``native``, a missing compiler is an error.
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import os
import subprocess
import tempfile
import threading
import uuid
from pathlib import Path

import numpy as np

from ..errors import FmuBuildError
from ..realtime import MapTables, effects_data
from ..realtime import model as M
from .c_sources import (
    C_PARTS,
    C_SOURCE,
    FMI_HEADERS,
    check_implemented,
    default_params,
    fmi_header_dir,
    model_header,
    param_types,
)
from .interface import interface_for
from .native import find_compiler

__all__ = ["SIM_CFLAGS", "SIM_SOURCE", "NativeRun", "bind_data", "cache_dir", "library_file", "native_run",
           "sim_maps_header", "simulator_mode"]

#: The driver (not part of any FMU).
SIM_SOURCE = Path(__file__).with_name("c") / "sol_sim.c"
#: Flags of the simulator library: those of the FMU's binary that fix the arithmetic (C99, no fused multiply-add);
#: warnings are the FMU build's business (:data:`solenoid_fmu.fmu.native.CFLAGS`).
SIM_CFLAGS = ("-std=c99", "-O2", "-fPIC", "-shared", "-ffp-contract=off")
#: Scalars bound at run time, in ``sim_bind``'s order (then the Real parameter defaults).
_SCALARS = ("SOL_DPSI", "SOL_INV_DPSI", "SOL_PSI_MAX", "SOL_I_FEM_MAX", "SOL_X_START")
#: Arrays bound at run time, in ``sim_bind``'s order: (C name, C type of the pointer's target).
_ARRAYS = (("SOL_X", "double"), ("SOL_INV_DX", "double"), ("SOL_CI", "row"), ("SOL_CF", "row"),
           ("SOL_LAD_G", "double"), ("SOL_LAD_TAU", "double"), ("SOL_PLAY_R", "double"), ("SOL_PLAY_W", "double"),
           ("SOL_SHAPE_B", "double"), ("SOL_SHAPE_G", "double"))
#: ``sim_bind``'s integer dimensions.
_DIMS = ("SOL_N_PSI", "SOL_N_X", "SOL_N_SHAPE")
_KIND = {"Real": 0, "Integer": 1, "Enumeration": 1, "Boolean": 2}
_MSG_LEN = 600

_LOCK = threading.Lock()
_LIBS: dict = {}  # library file -> loaded ctypes library
_FAILED: dict = {}  # source hash -> the FmuBuildError of its build


def simulator_mode() -> str:
    """``SOLENOID_FMU_SIMULATOR``: ``auto`` (default), ``native`` or ``python``."""
    mode = os.environ.get("SOLENOID_FMU_SIMULATOR", "auto").strip().lower() or "auto"
    if mode not in ("auto", "native", "python"):
        raise FmuBuildError(f"SOLENOID_FMU_SIMULATOR={mode!r}: use auto, native or python")
    return mode


def cache_dir() -> Path:
    """Where compiled simulator libraries are kept: ``$SOLENOID_FMU_CACHE``, else ``$XDG_CACHE_HOME/solenoid-fmu``
    (``~/.cache/solenoid-fmu``), each under ``simulator/``; a file name is the hash of what built it."""
    root = os.environ.get("SOLENOID_FMU_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"), "solenoid-fmu")
    return Path(root) / "simulator"


def _structure(tables: MapTables, params: dict) -> tuple[dict, dict]:
    """(effect data of :func:`effects_data`, the header's macros: effect switches and sizes)."""
    fx = effects_data(tables)
    hy = fx.get("hysteresis") or {}
    lad = fx.get("eddy_ladder") or {}
    flag = {True: "1", False: "0"}
    macros = {"SOL_HAS_FX": flag[bool(tables.effects.active)], "SOL_FX_HYST": flag["hysteresis" in fx],
              "SOL_FX_LAD": flag["eddy_ladder" in fx], "SOL_FX_HEAT": flag["heating" in fx],
              "SOL_FX_FRIC": flag["friction" in fx], "SOL_N_LAD": str(len(lad.get("G_S", ()))),
              "SOL_N_PLAY": str(len(hy.get("r", ())))}
    types = param_types()
    for name in M.DEFAULT_PARAMS:
        if types[name] == "Boolean":
            macros[f"SOL_{name.upper()}_DEFAULT"] = flag[bool(params[name])]
        elif types[name] != "Real":
            macros[f"SOL_{name.upper()}_DEFAULT"] = str(int(params[name]))
    return fx, macros


def _real_defaults() -> list[str]:
    types = param_types()
    return [name for name in M.DEFAULT_PARAMS if types[name] == "Real"]


def sim_maps_header(tables: MapTables, params: dict) -> str:
    """Text of the simulator's ``solenoid_maps.h``: the structure as macros, the data as variables and pointers
    that ``sim_bind(dims, scalars, arrays)`` sets (orders of :data:`_DIMS`, :data:`_SCALARS` + the Real parameter
    defaults, :data:`_ARRAYS`; :func:`bind_data` packs them)."""
    _, macros = _structure(tables, params)
    reals = [f"SOL_{name.upper()}_DEFAULT" for name in _real_defaults()]
    lines = ["/* solenoid_maps.h of the simulator library (solenoid_fmu.fmu.native_sim): data bound at run time */",
             "#ifndef SOLENOID_MAPS_H", "#define SOLENOID_MAPS_H", "#include <math.h>",
             '#define SOL_GUID "solenoid-fmu-simulator"']
    lines += [f"#define {k} {v}" for k, v in macros.items()]
    lines += [f"static int {name};" for name in _DIMS]
    lines += [f"static double {name};" for name in (*_SCALARS, *reals)]
    lines += [f"static const double (*{name})[8];" if kind == "row" else f"static const double *{name};"
              for name, kind in _ARRAYS]
    body = [f"    {name} = dims[{k}];" for k, name in enumerate(_DIMS)]
    body += [f"    {name} = scalars[{k}];" for k, name in enumerate((*_SCALARS, *reals))]
    body += [f"    {name} = (const double (*)[8])arrays[{k}];" if kind == "row" else f"    {name} = arrays[{k}];"
             for k, (name, kind) in enumerate(_ARRAYS)]
    lines += ["static void sim_bind(const int *dims, const double *scalars, const double *const *arrays)", "{",
              *body, "}", "#endif", ""]
    return "\n".join(lines)


def bind_data(tables: MapTables, params: dict) -> tuple[np.ndarray, np.ndarray, list]:
    """(dims int32, scalars float64, arrays: C-contiguous float64, at least one element each) for ``sim_bind``:
    the values :func:`solenoid_fmu.fmu.c_sources.maps_header` writes as literals, as the same doubles."""
    fx, _ = _structure(tables, params)
    hy = fx.get("hysteresis") or {}
    lad = fx.get("eddy_ladder") or {}
    t = tables.tables()
    x_start = 0.5 * (tables.x_min_m + tables.x_max_m)
    scalars = [tables.dpsi_Wb, tables.inv_dpsi, tables.psi_max_Wb, tables.i_fem_max_A, x_start]
    scalars += [params[name] for name in _real_defaults()]
    arrays = [tables.x_m, tables.inv_dx, t["i_f_coef"], t["force_coef"], lad.get("G_S", ()), lad.get("tau_s", ()),
              hy.get("r", ()), hy.get("w", ()), hy.get("gb", ()), hy.get("gg", ())]
    arrays = [np.ascontiguousarray(np.asarray(a, dtype=float).ravel() if len(a) else np.zeros(1)) for a in arrays]
    dims = np.array([tables.n_psi, tables.n_x, len(hy.get("gb", ()))], dtype=np.int32)
    return dims, np.asarray(scalars, dtype=float), arrays


@functools.lru_cache(maxsize=1)
def _fixed_sources() -> tuple:
    """(file name, text) of the library's sources but the maps header (FMI headers read from fmpy)."""
    check_implemented()
    files = {"solenoid_model.h": model_header(), "solenoid_fmu.c": C_SOURCE.read_text(),
             "sol_sim.c": SIM_SOURCE.read_text()}
    files.update({p.name: p.read_text() for p in C_PARTS})
    hdr = fmi_header_dir()
    files.update({name: (hdr / name).read_text() for name in FMI_HEADERS})
    return tuple(sorted(files.items()))


def library_file(header: str) -> Path:
    """The simulator library of this maps header (:func:`sim_maps_header`) in :func:`cache_dir`, compiled there
    first when missing; its name is the hash of the sources, the compiler and :data:`SIM_CFLAGS`.
    :class:`FmuBuildError` without a compiler or when it fails (remembered in this process)."""
    files = dict(_fixed_sources())
    files["solenoid_maps.h"] = header
    cc = find_compiler()
    h = hashlib.sha256(("\0".join([cc, *SIM_CFLAGS])).encode())
    for name in sorted(files):
        h.update(name.encode() + b"\0" + files[name].encode() + b"\0")
    key = h.hexdigest()[:32]
    with _LOCK:
        failed = _FAILED.get(key)
        if failed is not None:
            raise failed
        try:
            return _compiled(files, cc, key)
        except FmuBuildError as exc:
            _FAILED[key] = exc
            raise


def _library(header: str):
    """The loaded library of :func:`library_file`."""
    path = library_file(header)
    with _LOCK:
        lib = _LIBS.get(path)
        if lib is None:
            lib = _LIBS[path] = _load(path)
    return lib


def _compiled(files: dict, cc: str, key: str) -> Path:
    """The library file of ``key`` in :func:`cache_dir` (compiled there first when missing; atomic)."""
    user = getattr(os, "getuid", lambda: "user")()  # no getuid on Windows
    for root in (cache_dir(), Path(tempfile.gettempdir()) / f"solenoid-fmu-simulator-{user}"):
        lib = root / f"sim-{key}.so"
        if lib.is_file():
            return lib
        try:
            root.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryDirectory(dir=root, prefix=".build-") as tmp:
                for name, text in files.items():
                    Path(tmp, name).write_text(text)
                out = Path(tmp, f"{uuid.uuid4().hex}.so")
                cmd = [cc, *SIM_CFLAGS, f"-I{tmp}", "-o", str(out), str(Path(tmp, "sol_sim.c")), "-lm"]
                proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
                if proc.returncode != 0:
                    raise FmuBuildError(f"compiling the simulator library failed ({' '.join(cmd)}):\n"
                                        f"{proc.stderr.strip()[-2000:]}")
                os.replace(out, lib)
            return lib
        except OSError:
            continue  # the cache is not writable: the temporary directory next
        except subprocess.SubprocessError as exc:
            raise FmuBuildError(f"compiling the simulator library failed: {exc}") from None
    raise FmuBuildError(f"no writable folder for the simulator library ({cache_dir()}, {tempfile.gettempdir()})")


def _load(path: Path):
    lib = ctypes.CDLL(str(path))
    dp = ctypes.POINTER(ctypes.c_double)
    ip = ctypes.POINTER(ctypes.c_int)
    up = ctypes.POINTER(ctypes.c_uint)
    lib.sol_sim_run.restype = ctypes.c_int
    lib.sol_sim_run.argtypes = [ip, dp, ctypes.POINTER(dp), ctypes.c_int, ip, up, dp, up, ctypes.c_int, up,
                                ctypes.c_long, dp, dp, dp, dp, dp, ctypes.c_char_p, ctypes.c_int]
    return lib


class NativeRun:
    """Outcome of :func:`native_run`: ``out`` (samples x outputs) or, where the model refused, ``failed_at`` (the
    sample) and ``message`` (the C model's)."""

    def __init__(self, out: np.ndarray | None, failed_at: int = 0, message: str = ""):
        self.out, self.failed_at, self.message = out, failed_at, message


def native_run(tables: MapTables, settings: list, drive_voltage: bool, t, x, u0: float, u_step,
               outputs: list) -> NativeRun | None:
    """Run the native model over a recording, or None where it is not to be used (:func:`simulator_mode`
    ``python``, no compiler or a failed build in ``auto``, a setting the FMU interface lacks).

    Parameters
    ----------
    tables : MapTables
    settings : list of (name, value)
        Set in this order in initialization mode (``drive_mode`` first, as ``simulate_recording``).
    drive_voltage : bool
        The drive input is ``U_V`` (else ``i_A``).
    t, x : arrays [s], [m]
        Sample times and gaps.
    u0 : float
        The drive input at ``t[0]``.
    u_step : array
        The input held over each step (``t.size - 1``).
    outputs : list of str
        FMU output names (``U_out_V``, ``i_out_A``, ...), one column each.
    """
    mode = simulator_mode()
    if mode == "python":
        return None
    variables = {v.name: (k, v.type) for k, v in enumerate(interface_for(tables))}
    if any(name not in variables for name, _ in settings) or any(name not in variables for name in outputs):
        return None
    params = default_params(tables)
    try:
        lib = _library(sim_maps_header(tables, params))
    except FmuBuildError:
        if mode == "native":
            raise
        return None
    dims, scalars, arrays = bind_data(tables, params)
    dp = ctypes.POINTER(ctypes.c_double)
    arr_ptrs = (dp * len(arrays))(*[a.ctypes.data_as(dp) for a in arrays])
    kind = np.array([_KIND[variables[name][1]] for name, _ in settings], dtype=np.intc)
    vr = np.array([variables[name][0] for name, _ in settings], dtype=np.uintc)
    val = np.array([float(v) for _, v in settings], dtype=float)
    in_vr = np.array([variables["U_V" if drive_voltage else "i_A"][0], variables["x_m"][0]], dtype=np.uintc)
    out_vr = np.array([variables[name][0] for name in outputs], dtype=np.uintc)
    t = np.ascontiguousarray(t, dtype=float)
    x = np.ascontiguousarray(x, dtype=float)
    u_step = np.ascontiguousarray(u_step, dtype=float)
    u0_arr = np.array([float(u0)])
    out = np.empty((t.size, len(outputs)))
    msg = ctypes.create_string_buffer(_MSG_LEN)

    def p(a, ct=ctypes.c_double):
        return a.ctypes.data_as(ctypes.POINTER(ct))

    with _LOCK:  # the bound data are the library's globals
        rc = lib.sol_sim_run(p(dims, ctypes.c_int), p(scalars), arr_ptrs, len(settings), p(kind, ctypes.c_int),
                             p(vr, ctypes.c_uint), p(val), p(in_vr, ctypes.c_uint), len(outputs),
                             p(out_vr, ctypes.c_uint), t.size, p(t), p(x), p(u0_arr), p(u_step), p(out), msg,
                             _MSG_LEN)
    if rc:
        return NativeRun(None, rc - 1, msg.value.decode("utf-8", "replace"))
    return NativeRun(out)
