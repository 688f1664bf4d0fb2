"""The parent's side of the identification's worker processes (:mod:`.point_worker`, whose docstring has the
protocol): how many, which strokes each takes, the pool that talks to them, and the messages' encoding.

A message is no pickle: a length-prefixed JSON document, then the arrays it refers to, each in NumPy's ``.npy``
format read with ``allow_pickle=False`` (:func:`send`, :func:`receive`). JSON carries numbers, strings, lists,
dicts with any keys (``{"__dict__": [[k, v], ...]}``), and three kinds of object by their fields: a B(H) curve
(its knots: rebuilt exactly), a geometry (its dataclasses) and an exception (class name and message; a class
of :mod:`solenoid_fmu.errors` or a builtin one is raised as such, any other as RuntimeError)."""

from __future__ import annotations

import builtins
import dataclasses
import io
import json
import os
import struct
import subprocess
import sys
import weakref
from pathlib import Path

import numpy as np

from ..errors import SolenoidError
from ..field import BHCurve, Coil, Domain, Geometry, Region, Stroke

__all__ = ["MAX_WORKERS", "WORKERS_ENV", "default_workers", "split_by_stroke", "WorkerPool", "send", "receive"]

#: What a worker process runs (``python -c``; ``-m`` would import the module twice).
_START = "from solenoid_fmu.identification.point_worker import main; main()"
#: At most this many workers per identification (a campaign has 3-6 strokes).
MAX_WORKERS = 4


#: Environment variable with the default number of workers (a whole number >= 1), for a machine whose cores are
#: already busy otherwise (``make test``: pytest-xdist runs one test per core, nested workers only add start-up).
WORKERS_ENV = "SOLENOID_FMU_WORKERS"


def default_workers() -> int:
    """Workers an identification uses when not told: :data:`WORKERS_ENV` if set, else the cores this process may
    run on, at most :data:`MAX_WORKERS`."""
    text = os.environ.get(WORKERS_ENV, "").strip()
    if text:
        try:
            n = int(text)
        except ValueError:
            n = 0
        if n < 1:
            raise SolenoidError(f"environment variable {WORKERS_ENV}={text!r}: must be a whole number >= 1")
        return n
    try:
        n = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        n = os.cpu_count() or 1
    return max(1, min(n, MAX_WORKERS))


def split_by_stroke(x_m, weight, workers: int) -> list:
    """Indices of the points per worker: whole strokes (``x_m`` equal), the heaviest first onto the least
    loaded worker; ``weight`` is each point's cost. Fewer lists than ``workers`` when there are fewer strokes."""
    strokes: dict = {}
    for k, x in enumerate(x_m):
        strokes.setdefault(float(x), []).append(k)
    order = sorted(strokes.values(), key=lambda ks: (-sum(weight[k] for k in ks), ks[0]))
    bins = [[] for _ in range(min(workers, len(order)))]
    load = [0.0] * len(bins)
    for ks in order:
        j = min(range(len(bins)), key=lambda b: (load[b], b))
        bins[j] += ks
        load[j] += sum(weight[k] for k in ks)
    return [sorted(b) for b in bins if b]


class WorkerPool:
    """The parent's side: one worker process per list of point indices (see the module docstring).

    Parameters
    ----------
    geometry, mesh_size, start_curve
        As for :class:`~.point_model.PointModel`.
    points : list of (kind, i_A, x_m)
    groups : list of list of int
        The indices into ``points`` each worker takes (:func:`split_by_stroke`).
    """

    def __init__(self, geometry, points, mesh_size: float, start_curve, groups):
        self.groups = [list(g) for g in groups]
        env = dict(os.environ)
        root = str(Path(__file__).resolve().parents[2])  # the folder that holds the package
        env["PYTHONPATH"] = os.pathsep.join([root, *filter(None, [env.get("PYTHONPATH")])])
        self.procs = []
        self._finalizer = weakref.finalize(self, _shutdown, self.procs)
        for g in self.groups:
            p = subprocess.Popen([sys.executable, "-c", _START], stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env)
            self.procs.append(p)
            send(p.stdin, ("init", geometry, [points[k] for k in g], mesh_size, start_curve))
        self.ask_all(None)  # the workers' meshes and solvers are ready

    def ask_all(self, msg) -> list:
        """Send ``msg`` to every worker (all first, so that they work at once) and collect
        ``(result, counters)`` per worker; a worker's exception is raised here."""
        if msg is not None:
            for p in self.procs:
                try:
                    send(p.stdin, msg)
                except (BrokenPipeError, OSError) as exc:
                    raise self._died(p) from exc
        answers = []
        for p in self.procs:
            try:
                answers.append(receive(p.stdout))
            except (EOFError, ValueError, OSError) as exc:
                raise self._died(p) from exc
        for a in answers:
            if a[0] == "err":
                raise a[1]
        return [(a[1], a[2]) for a in answers]

    def _died(self, p) -> SolenoidError:
        self.close()
        return SolenoidError(f"identification: a FEM worker process (pid {p.pid}) stopped with exit code "
                             f"{p.poll()}; its error is on standard error above (run with workers=1 to see it "
                             "in this process)")

    def close(self) -> None:
        """Stop the workers (also at garbage collection and at exit)."""
        self._finalizer()


def _shutdown(procs) -> None:
    for p in procs:
        try:
            send(p.stdin, ("stop",))
            p.stdin.close()
        except (BrokenPipeError, OSError, ValueError):
            pass
    for p in procs:
        try:
            p.wait(timeout=10)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()
        if p.stdout is not None:
            p.stdout.close()


# -- messages ------------------------------------------------------------------------------------------------
_CURVE_FIELDS = ("B_T", "nu_d", "H_A_per_m", "table_H_A_per_m", "table_B_T")


def _encode(obj, arrays: list):
    if isinstance(obj, np.ndarray):
        arrays.append(obj)
        return {"__nd__": len(arrays) - 1}
    if isinstance(obj, BHCurve):
        return {"__curve__": {**{f: _encode(np.asarray(getattr(obj, f)), arrays) for f in _CURVE_FIELDS},
                              "name": obj.name, "sha256": obj.sha256,
                              "source_path": None if obj.source_path is None else str(obj.source_path)}}
    if isinstance(obj, Geometry):
        d = dataclasses.asdict(obj)
        d["source_path"] = None if obj.source_path is None else str(obj.source_path)
        return {"__geometry__": d}
    if isinstance(obj, BaseException):
        return {"__err__": [type(obj).__name__, str(obj)]}
    if isinstance(obj, dict):
        return {"__dict__": [[_encode(k, arrays), _encode(v, arrays)] for k, v in obj.items()]}
    if isinstance(obj, list | tuple):
        return [_encode(v, arrays) for v in obj]
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    if obj is None or isinstance(obj, bool | int | float | str):
        return obj
    raise TypeError(f"point worker message: cannot encode {type(obj).__name__}")


def _solenoid_errors() -> dict:
    """The package's exception classes by name (SolenoidError and every subclass)."""
    out, todo = {}, [SolenoidError]
    while todo:
        cls = todo.pop()
        out[cls.__name__] = cls
        todo += cls.__subclasses__()
    return out


def _decode(obj, arrays: list):
    if isinstance(obj, list):
        return tuple(_decode(v, arrays) for v in obj)
    if not isinstance(obj, dict):
        return obj
    if "__nd__" in obj:
        return arrays[obj["__nd__"]]
    if "__dict__" in obj:
        return {_decode(k, arrays): _decode(v, arrays) for k, v in obj["__dict__"]}
    if "__curve__" in obj:
        c = obj["__curve__"]
        return BHCurve(**{f: _decode(c[f], arrays) for f in _CURVE_FIELDS}, name=c["name"], sha256=c["sha256"],
                       source_path=None if c["source_path"] is None else Path(c["source_path"]))
    if "__geometry__" in obj:
        g = obj["__geometry__"]
        regions = tuple(Region(r["name"], r["material"], tuple(tuple(p) for p in r["polygon_m"]), r["moves"],
                               r["ampere_turns"]) for r in g["regions"])
        return Geometry(g["name"], regions, Coil(**g["coil"]), Stroke(**g["stroke"]),
                        Domain(**{**g["domain"], "natural": tuple(g["domain"]["natural"])}),
                        None if g["source_path"] is None else Path(g["source_path"]), g["sha256"], g["extra"])
    if "__err__" in obj:
        name, message = obj["__err__"]
        cls = _solenoid_errors().get(name) or getattr(builtins, name, None)
        if isinstance(cls, type) and issubclass(cls, Exception):
            try:
                return cls(message)
            except Exception:
                pass
        return RuntimeError(f"{name}: {message}")
    raise ValueError(f"point worker message: unknown object {sorted(obj)}")


def send(stream, obj) -> None:
    """Write ``obj`` (module docstring) to the binary ``stream`` and flush it."""
    arrays: list = []
    doc = json.dumps(_encode(obj, arrays), allow_nan=True).encode()
    buf = io.BytesIO()
    for a in arrays:
        np.lib.format.write_array(buf, np.ascontiguousarray(a), allow_pickle=False)
    blob = buf.getvalue()
    stream.write(struct.pack("<QQQ", len(doc), len(arrays), len(blob)) + doc + blob)
    stream.flush()


def _read(stream, n: int) -> bytes:
    data = stream.read(n)
    if len(data) != n:
        raise EOFError(f"point worker message: {len(data)} of {n} bytes")
    return data


def receive(stream):
    """Read one object written by :func:`send` from the binary ``stream`` (EOFError at its end)."""
    n_doc, n_arr, n_blob = struct.unpack("<QQQ", _read(stream, 24))
    doc = json.loads(_read(stream, n_doc))
    blob = io.BytesIO(_read(stream, n_blob))  # whole, in memory: NumPy would read a real file past the buffer
    arrays = [np.lib.format.read_array(blob, allow_pickle=False) for _ in range(n_arr)]
    return _decode(doc, arrays)
