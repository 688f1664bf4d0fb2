"""The FEM sweep over (i, x) that builds the characteristic maps (paper section 5).

One task per armature working-gap position ``x_m``, warm-started along the current list inside
:func:`solenoid_fmu.field.sweep_currents`, runs on any :class:`concurrent.futures.Executor` with a
progress bar; the result is inverted by :func:`solenoid_fmu.maps.invert.invert_maps` and carries its
provenance (geometry, material, code version, solver statistics) in the metadata.
"""

from __future__ import annotations

import concurrent.futures as cf
import datetime as _dt
import json
import math
import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from .._version import __version__
from ..errors import MapsError, SolenoidError
from ..field import sweep_currents
from .invert import invert_maps
from .refine import refine_tables, refined_positions
from .tables import CharacteristicMaps

__all__ = [
    "DEFAULT_CURRENT_FACTOR",
    "DEFAULT_CURRENT_POWER",
    "DEFAULT_NI",
    "DEFAULT_NX",
    "MAX_GRID_POINTS",
    "InlineExecutor",
    "build_maps",
    "process_pool",
    "default_currents",
    "default_positions",
]

#: Default grid: positions over the whole stroke, currents 0 .. 1.25 x the coil's max current.
DEFAULT_NX = 27
DEFAULT_NI = 26
DEFAULT_CURRENT_FACTOR = 1.25
#: Exponent of the default current spacing (:func:`default_currents`): the shipped maps, the rig's CLI and the
#: coarse presets (``quick``, ``smoke``); finer campaign grids take :data:`CAMPAIGN_CURRENT_POWER`.
DEFAULT_CURRENT_POWER = 1.5
#: Most points of one sweep grid (positions or currents): 1000 x 1000 FEM solves is already days.
MAX_GRID_POINTS = 1000
#: The checkout (the package's parent folder): source paths inside it are stored relative to it.
CHECKOUT = Path(__file__).resolve().parents[2]


#: How often [s] a pool worker checks that the process that started it is still alive.
PARENT_POLL_S = 0.2


def _watch_parent(parent_pid: int) -> None:
    """Pool-worker initializer: a daemon thread ends the worker when its parent is gone (``kill -9`` of
    the parent leaves the workers blocked on the task queue otherwise: orphans using memory forever)."""
    import threading
    import time

    def watch():
        while os.getppid() == parent_pid:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name="solenoid-fmu-parent-watch", daemon=True).start()


def process_pool(workers: int | None = None) -> cf.ProcessPoolExecutor:
    """A process pool (``workers`` processes, default all cores) whose workers exit within
    :data:`PARENT_POLL_S` when the process that made it dies, even by ``kill -9``."""
    return cf.ProcessPoolExecutor(max_workers=workers or os.cpu_count() or 1, initializer=_watch_parent,
                                  initargs=(os.getpid(),))


class InlineExecutor(cf.Executor):
    """An executor that runs each task at once in the calling thread (``--workers 1``, baselines)."""

    def submit(self, fn, /, *args, **kwargs):
        future: cf.Future = cf.Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except Exception as exc:  # handed to the caller through the future, as other executors do
            future.set_exception(exc)
        return future



def _default_sweep() -> Callable:
    """The sweep :func:`build_maps` runs when none is given (a function, so that tests can replace it)."""
    return sweep_currents


def _code_version() -> dict:
    commit, dirty = "unknown", None
    here = Path(__file__).resolve().parent
    try:
        out = subprocess.run(
            ["git", "-C", str(here), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=5
        )
        if out.returncode == 0 and out.stdout.strip():
            commit = out.stdout.strip()
            st = subprocess.run(
                ["git", "-C", str(here), "status", "--porcelain", "--untracked-files=no"],
                capture_output=True, text=True, timeout=5,
            )
            dirty = bool(st.stdout.strip()) if st.returncode == 0 else None
    except (OSError, subprocess.SubprocessError):
        pass
    short = commit[:12] if commit != "unknown" else "unknown"
    return {"code_version": f"{__version__}+{short}", "git_commit": commit, "git_dirty": dirty}


def _source(obj) -> dict:
    """Path (relative to the checkout when inside it, so shipped maps do not carry this machine's
    directories), sha256 and name of a geometry or material."""
    path = getattr(obj, "source_path", None)
    if path is not None:
        path = Path(path).resolve()
        path = path.relative_to(CHECKOUT).as_posix() if path.is_relative_to(CHECKOUT) else str(path)
    return {"path": path, "sha256": str(getattr(obj, "sha256", "") or ""),
            "name": str(getattr(obj, "name", "") or "")}


def _grid(values, default, what: str, unit: str, scale: float) -> np.ndarray:
    if values is None:
        return default
    if np.size(values) > MAX_GRID_POINTS:
        raise MapsError(f"{what} grid has {np.size(values)} points, more than {MAX_GRID_POINTS}")
    try:
        arr = np.array(values, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        raise MapsError(f"{what} grid is not numeric: {values!r}") from None
    if arr.size < 2 or not np.isfinite(arr).all() or (np.diff(arr) <= 0).any():
        raise MapsError(
            f"{what} grid must hold at least 2 finite, strictly increasing values [{unit}], got "
            f"{np.array2string(arr * scale, precision=4)}"
        )
    return arr


def default_positions(x_min_m: float, x_max_m: float, n: int = DEFAULT_NX) -> np.ndarray:
    """Default sweep positions [m]: ``n`` points over [x_min, x_max], clustered at both stops.

    Cosine (Chebyshev-Lobatto) spacing: Psi and F bend most near the stops (at the small gap the
    field concentrates in the working gap; at full stroke the armature leaves the control cone),
    and the maps are read linearly in x between positions, whose error grows with the square of
    the spacing. With n = 27 over PS45's 3.3 mm stroke the steps run from 0.01 mm at the stops to
    0.2 mm mid-stroke, and the round trip Psi -> i_f -> Psi stays within 0.1 % between positions.
    """
    s = np.linspace(0.0, 1.0, n)
    x = x_min_m + (x_max_m - x_min_m) * 0.5 * (1.0 - np.cos(np.pi * s))
    x[0], x[-1] = x_min_m, x_max_m
    return x


def default_currents(i_top_A: float, n: int = DEFAULT_NI, power: float = DEFAULT_CURRENT_POWER) -> np.ndarray:
    """Default sweep currents [A]: ``i_top (k / (n - 1))^power``, k = 0 .. n - 1.

    Denser at low currents, where the iron leaves its linear range and Psi(i) and F(i) bend
    sharply (for PS45 with the literature curve the knee lies near 0.2 A); for n = 26 and
    ``i_top = 2.5 A`` the steps grow from 0.02 A to 0.15 A.
    """
    return i_top_A * (np.arange(n) / (n - 1)) ** power


#: The maps sweep of a campaign reaches at least this multiple of the largest |current| [A] in its recordings.
CAMPAIGN_CURRENT_MARGIN = 1.25
#: Exponent of the campaign maps' current spacing (:func:`default_currents`) for grids of 18 currents or more
#: (the pipeline's ``medium`` and ``full`` presets). Measured (stop 40) against direct solves of the same FEM (mesh
#: 2.0) at 100 currents 0.02-2 A x 4 strokes, on random-0, 9SMn28K, Permenorm and random-2's steels: 18 currents at
#: power 2 read Psi within 0.8-1.4 % (power 1.5: 1.7-2.5 %; the worst in the first interval) and F within
#: 0.05-0.22 % of full scale (0.26-0.36 %); 26 currents within 0.25-0.34 % and 0.04-0.05 % (0.5-0.8 % and
#: 0.09-0.18 %). The iron's knee lies at tens to hundreds of mA. Coarse grids keep 1.5: with 6 currents power 2
#: steps 0.9 A at the top, and the force read there at 0.2 mm turned negative.
CAMPAIGN_CURRENT_POWER = 2.0


def maps_current_grid(rated_current_A: float, recordings, n_i: int | None = None,
                      power: float = DEFAULT_CURRENT_POWER) -> np.ndarray:
    """Currents [A] of the maps sweep, from 0 to the larger of ``DEFAULT_CURRENT_FACTOR`` (1.25) x the coil's
    rated current and ``CAMPAIGN_CURRENT_MARGIN`` (1.25) x the largest |current| in ``recordings``.

    The spacing is :func:`default_currents`'s at ``power`` (denser at low currents; the presets of 18 currents
    or more ask for :data:`CAMPAIGN_CURRENT_POWER`).
    When the campaign pushes the top up, the number of currents grows with ``top^(1/power)`` so the first step
    (near the iron's knee) stays as fine as with ``n_i`` currents up to the rated top (within 0.2 %: a top pushed
    up by measurement noise adds no current).

    Parameters
    ----------
    rated_current_A : float
        The coil's rated current ``geometry.coil.max_current_A`` [A].
    recordings : iterable of Recording
        The campaign; their ``current_A`` columns (non-finite samples ignored).
    n_i : int, optional
        Number of currents up to the rated top (default :data:`DEFAULT_NI`).
    power : float
        Exponent of the spacing (:func:`default_currents`).
    """
    n_i = DEFAULT_NI if n_i is None else int(n_i)
    rated_top = DEFAULT_CURRENT_FACTOR * rated_current_A
    peaks = [float(np.max(np.abs(c[np.isfinite(c)]), initial=0.0))
             for c in (np.asarray(r.current_A, dtype=float) for r in recordings)]
    top = max([rated_top] + [CAMPAIGN_CURRENT_MARGIN * p for p in peaks])
    if top > rated_top:
        n_i = math.ceil((n_i - 1) * (top / rated_top) ** (1 / power) - 0.01) + 1  # 0.01: no extra point for noise
    return default_currents(top, n_i, power)


def build_maps(
    geometry,
    material,
    x_m=None,
    i_A=None,
    mesh_size: float = 1.0,
    executor: cf.Executor | None = None,
    progress: bool = True,
    sweep: Callable | None = None,
    name: str | None = None,
    npsi: int | None = None,
    refine_x: int = 1,
) -> CharacteristicMaps:
    """Sweep the FEM over (i, x) and build the characteristic maps (paper section 5, eqs. 2-3).

    One task per position x runs ``sweep(geometry, material, x, i_A, mesh_size)`` (warm-started
    along the current list); tasks run on ``executor``. The result is inverted by
    :func:`solenoid_fmu.maps.invert.invert_maps`.

    Parameters
    ----------
    geometry : Geometry
        Solenoid geometry (:func:`solenoid_fmu.field.load_geometry`); uses ``name``, ``source_path``,
        ``sha256``, ``coil`` and ``stroke``.
    material : BHCurve
        B(H) curve (:func:`solenoid_fmu.field.load_material`); uses ``source_path``, ``sha256``, ``name``.
    x_m : array-like, optional
        Working-gap positions [m], inside the stroke; default 27 positions (cosine spacing) over
        ``[stroke.min_m, stroke.max_m]``, graded towards small gaps (:func:`default_positions`).
    i_A : array-like, optional
        Currents [A], starting at 0; default 26 currents from 0 to 1.25 x ``coil.max_current_A``,
        denser at low currents (:func:`default_currents`).
    mesh_size : float
        Mesh-size factor handed to the sweep (1.0 = the FEM's default, larger = coarser).
    executor : concurrent.futures.Executor, optional
        Runs the per-position tasks: a ``ProcessPoolExecutor`` (default, ``os.cpu_count()`` workers),
        a ``ThreadPoolExecutor``, :class:`InlineExecutor`, or a Dask/Ray executor. An executor passed
        in is not shut down.
    progress : bool
        Show a tqdm progress bar with the time left on stderr.
    sweep : callable, optional
        ``sweep(geometry, material, x_m, i_A, mesh_size) -> dict`` with arrays ``psi_Wb``,
        ``force_N``, ``force_stress_N`` (and optionally ``newton_iterations``, ``newton_recovered``) of length
        ``len(i_A)``;
        default :func:`solenoid_fmu.field.sweep_currents`. Must be picklable for process pools.
    name : str, optional
        Map name stored in the metadata; default the geometry's name.
    npsi : int, optional
        Flux-grid size (see :func:`solenoid_fmu.maps.invert.invert_maps`).
    refine_x : int
        Map columns per FEM interval in x (1: the FEM positions alone); ``r > 1`` puts ``r - 1`` columns into each
        interval by a cubic spline in x at fixed flux (:mod:`solenoid_fmu.maps.refine`), named in the
        provenance's ``solver.x_refined``.

    Returns
    -------
    CharacteristicMaps

    Raises
    ------
    MapsError
        Bad grids, a failed FEM task (naming x), non-monotone Psi(i) (naming x and i).
    """
    x_m, i_A = _checked_grids(geometry, x_m, i_A, mesh_size)
    refined_positions(x_m, refine_x)  # a bad factor fails before the FEM runs
    sweep = sweep if sweep is not None else _default_sweep()
    own_executor = executor is None
    if own_executor:
        executor = process_pool()
    t0 = time.perf_counter()
    try:
        psi, force, stress, newton, recovered = _run_sweep(sweep, geometry, material, x_m, i_A, mesh_size, executor,
                                                           progress)
    finally:
        if own_executor:
            executor.shutdown(wait=True, cancel_futures=True)
    solver = _solver_record(sweep, executor, mesh_size, time.perf_counter() - t0, x_m, i_A, newton, recovered)
    x_m, psi, force, stress = _refined(solver, x_m, i_A, psi, force, stress, refine_x)
    metadata = _metadata(geometry, material, name, mesh_size, solver)
    return invert_maps(x_m, i_A, psi, force, stress, metadata=metadata, npsi=npsi)


def _refined(solver: dict, x_m, i_A, psi, force, stress, refine_x: int) -> tuple:
    """The FEM tables with ``refine_x - 1`` columns in each interval (:func:`refine_tables`), their method in
    ``solver["x_refined"]``; as given for ``refine_x == 1``."""
    if refine_x == 1:
        return x_m, psi, force, stress
    solver["x_refined"] = {"factor": int(refine_x), "fem_positions_mm": [float(x) * 1e3 for x in x_m],
                           "method": "not-a-knot cubic spline in x at fixed flux linkage of the FEM columns' "
                                     "i(Psi), F(Psi) and Maxwell-stress force, inverted at the sweep's currents"}
    return refine_tables(x_m, i_A, psi, force, stress, refine_x)


def _solver_record(sweep, executor, mesh_size, wall_s: float, x_m, i_A, newton, recovered) -> dict:
    """The provenance's ``solver`` entry: the sweep function, executor, wall time [s], Newton counts, the points
    Newton recovered, and the FEM's ``SOLVER_SETTINGS`` where the sweep's module has them."""
    solver = {
        "sweep": f"{getattr(sweep, '__module__', '?')}.{getattr(sweep, '__qualname__', repr(sweep))}",
        "mesh_size": float(mesh_size),
        "warm_start": "along the current list at each position",
        "executor": type(executor).__name__,
        "workers": getattr(executor, "_max_workers", None),
        "wall_time_s": round(wall_s, 3),
        "operating_points": int(newton.size),
        "newton_iterations_total": int(newton.sum()),
        "newton_iterations_max": int(newton.max()),
        # (x [mm], i [A]) of the points where Newton stalled (accepted) or was recovered by load stepping
        "newton_recovered_x_mm_i_A": [[float(x_m[j]) * 1e3, float(i_A[k])] for k, j in np.argwhere(recovered)],
    }
    fem_settings = getattr(sys.modules.get(getattr(sweep, "__module__", ""), None), "SOLVER_SETTINGS", None)
    if isinstance(fem_settings, dict):
        solver["fem_settings"] = json.loads(json.dumps(fem_settings, default=str))
    return solver


def _checked_grids(geometry, x_m, i_A, mesh_size) -> tuple[np.ndarray, np.ndarray]:
    """The sweep's positions [m] and currents [A] (defaults filled in), checked against the geometry."""
    stroke, coil = geometry.stroke, geometry.coil
    x_default = default_positions(stroke.min_m, stroke.max_m, DEFAULT_NX)
    i_default = default_currents(DEFAULT_CURRENT_FACTOR * coil.max_current_A, DEFAULT_NI)
    x_m = _grid(x_m, x_default, "position", "mm", 1e3)
    i_A = _grid(i_A, i_default, "current", "A", 1.0)
    if i_A[0] != 0.0:
        raise MapsError(
            f"the current grid must start at 0 A (maps hold i_f from Psi = 0), starts at {i_A[0]:g} A"
        )
    if len(i_A) < 3:
        raise MapsError(f"the current grid needs at least 3 currents, got {len(i_A)}")
    tol = 1e-9
    outside = (x_m < stroke.min_m - tol) | (x_m > stroke.max_m + tol)
    if outside.any():
        raise MapsError(
            f"position {x_m[np.argmax(outside)] * 1e3:.4g} mm is outside the stroke of {geometry.name} "
            f"[{stroke.min_m * 1e3:.4g}, {stroke.max_m * 1e3:.4g}] mm"
        )
    if not (isinstance(mesh_size, int | float) and math.isfinite(mesh_size) and mesh_size > 0):
        raise MapsError(f"mesh_size must be a finite number > 0, got {mesh_size!r}")
    return x_m, i_A


def _run_sweep(sweep, geometry, material, x_m, i_A, mesh_size, executor, progress: bool) -> tuple:
    """One task per position on ``executor``; the tables (i, x) of Psi, force (co-energy and Maxwell stress),
    Newton iterations and recovered points. A failed task cancels the others (:func:`build_maps`)."""
    ni, nx = len(i_A), len(x_m)
    psi = np.empty((ni, nx))
    force = np.empty((ni, nx))
    stress = np.empty((ni, nx))
    newton = np.zeros((ni, nx))
    recovered = np.zeros((ni, nx))
    bar = tqdm(total=ni * nx, desc="FEM sweep", unit="pt", file=sys.stderr, disable=not progress,
               dynamic_ncols=True)
    futures: dict[cf.Future, int] = {}
    pending: set[cf.Future] = set()

    def harvest(fut: cf.Future) -> None:
        j = futures[fut]
        try:
            result = fut.result()
        except SolenoidError as exc:
            raise MapsError(f"FEM sweep at x = {x_m[j] * 1e3:.4g} mm failed: {exc}") from exc
        psi[:, j], force[:, j], stress[:, j], newton[:, j], recovered[:, j] = _sweep_columns(result, ni, x_m[j])
        bar.update(ni)
        pending.discard(fut)

    try:
        for j, x in enumerate(x_m):
            fut = executor.submit(sweep, geometry, material, float(x), i_A.copy(), mesh_size)
            futures[fut] = j
            pending.add(fut)
            for done in [f for f in pending if f.done()]:  # inline executors: progress, early errors
                harvest(done)
        for fut in cf.as_completed(list(pending)):
            harvest(fut)
    except BaseException:
        for fut in futures:
            fut.cancel()
        raise
    finally:
        bar.close()
    return psi, force, stress, newton, recovered


def _metadata(geometry, material, name, mesh_size, solver: dict) -> dict:
    """The maps' metadata (maps.json without the arrays' entries): name, coil, stroke, eddy, provenance."""
    stroke, coil = geometry.stroke, geometry.coil
    version = _code_version()
    return {
        "name": name or str(geometry.name),
        "force_method": "coenergy",
        "coil": {
            "turns": float(coil.turns),
            "resistance_ohm_20C": float(coil.resistance_ohm_20C),
            "temperature_coefficient_per_K": float(coil.temperature_coefficient_per_K),
            "max_current_A": float(coil.max_current_A),
        },
        "stroke": {
            "min_m": float(stroke.min_m), "max_m": float(stroke.max_m),
            "working_min_m": float(stroke.working_min_m), "working_max_m": float(stroke.working_max_m),
        },
        "eddy": {"G_eddy_S": None, "source": "not identified (the FEM is magnetostatic)"},
        "provenance": {
            "geometry": _source(geometry),
            "material": _source(material),
            "mesh_size": float(mesh_size),
            "code_version": version["code_version"],
            "git_commit": version["git_commit"],
            "git_dirty": version["git_dirty"],
            "created_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            "solver": solver,
        },
    }


def _sweep_columns(result, ni: int, x: float):
    where = f"FEM sweep at x = {x * 1e3:.4g} mm"
    if not isinstance(result, dict):
        raise MapsError(f"{where} returned {type(result).__name__}, expected a dict of arrays")
    cols = []
    for key in ("psi_Wb", "force_N", "force_stress_N"):
        if key not in result:
            raise MapsError(f"{where} returned no {key!r}")
        col = np.asarray(result[key], dtype=np.float64).ravel()
        if col.shape != (ni,):
            raise MapsError(f"{where}: {key!r} has {col.size} values for {ni} currents")
        if not np.isfinite(col).all():
            k = int(np.argmax(~np.isfinite(col)))
            raise MapsError(f"{where}: {key!r} has NaN/inf at current index {k}")
        cols.append(col)
    for key in ("newton_iterations", "newton_recovered"):
        extra = np.asarray(result.get(key, np.zeros(ni)), dtype=np.float64).ravel()
        cols.append(extra if extra.shape == (ni,) else np.zeros(ni))
    return cols


