"""The parent's side of the identification's worker processes (:mod:`.point_worker`, whose docstring has the
protocol): how many, which strokes each takes, and the pool that talks to them."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import weakref
from pathlib import Path

from ..errors import SolenoidError

__all__ = ["MAX_WORKERS", "WORKERS_ENV", "default_workers", "split_by_stroke", "WorkerPool"]

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
            pickle.dump(("init", geometry, [points[k] for k in g], mesh_size, start_curve), p.stdin)
            p.stdin.flush()
        self.ask_all(None)  # the workers' meshes and solvers are ready

    def ask_all(self, msg) -> list:
        """Send ``msg`` to every worker (all first, so that they work at once) and collect
        ``(result, counters)`` per worker; a worker's exception is raised here."""
        if msg is not None:
            for p in self.procs:
                try:
                    pickle.dump(msg, p.stdin)
                    p.stdin.flush()
                except (BrokenPipeError, OSError) as exc:
                    raise self._died(p) from exc
        answers = []
        for p in self.procs:
            try:
                answers.append(pickle.load(p.stdout))
            except (EOFError, pickle.UnpicklingError, OSError) as exc:
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
            pickle.dump(("stop",), p.stdin)
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
