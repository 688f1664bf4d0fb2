"""Worker processes of :class:`~.point_model.PointModel`: the operating points of some strokes, solved in
another process, so that an identification uses the machine's cores (issue 20: under 60 s on 2 cores).

Each worker is a plain Python subprocess (``python -c`` calling :func:`main`), not a
``multiprocessing`` child: those re-run a user's script on spawn (a script without a ``__main__`` guard would
start identifying again) and fork a parent whose MKL/OpenMP threads may be running. The worker holds a
:class:`PointModel` of its points (its own mesh, solver and warm starts) and answers the parent over its
standard input and output (:func:`~.point_pool.send` / :func:`~.point_pool.receive`: JSON and ``.npy`` arrays,
no pickle; the worker's own ``print`` goes to standard error):

* ``("values", curve)`` -> Psi [Wb] / F [N] at its points for that BHCurve (:meth:`PointModel._solve_all`);
* ``("fields",)`` -> the Jacobian's per-point fields at the last curve (:meth:`PointModel.point_fields`);
* ``("stop",)`` or end of input -> exit.

Every answer is ``("ok", result, counters)`` (the solves, Newton steps and adjoint solves it made) or
``("err", exception)``. Each point is computed as in one process (same warm starts along its stroke), so the
result does not depend on how many workers there are. Each worker runs its linear algebra on one thread.
"""

from __future__ import annotations

import os
import sys

from ..field import single_threaded
from .point_model import PointModel
from .point_pool import receive, send

COUNTERS = ("solves", "newton_steps", "adjoint_solves")


def _counters(pm) -> tuple:
    return tuple(getattr(pm, c) for c in COUNTERS)


def serve(inp, out) -> None:
    """Answer requests from ``inp`` on ``out`` (binary streams) until ``stop`` or the end of ``inp``."""
    holder = {}
    _, geometry, points, mesh_size, start_curve = receive(inp)
    with single_threaded():
        pm = PointModel(geometry, points, lambda _theta: holder["curve"], mesh_size, start_curve)
        send(out, ("ok", None, _counters(pm)))
        while True:
            try:
                msg = receive(inp)
            except EOFError:
                return
            if msg[0] == "stop":
                return
            before = _counters(pm)
            try:
                if msg[0] == "values":
                    holder["curve"] = msg[1]
                    result = pm._solve_all(None)
                elif msg[0] == "fields":
                    result = pm.point_fields()
                else:
                    raise ValueError(f"point worker: unknown request {msg[0]!r}")
                answer = ("ok", result, tuple(a - b for a, b in zip(_counters(pm), before, strict=True)))
            except Exception as exc:  # handed to the parent, which raises it
                answer = ("err", exc)
            send(out, answer)


def main() -> None:
    """Entry point of a worker process (see the module docstring)."""
    inp = os.fdopen(os.dup(sys.stdin.fileno()), "rb")
    out = os.fdopen(os.dup(sys.stdout.fileno()), "wb")
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())  # stray output must not corrupt the answers
    serve(inp, out)


if __name__ == "__main__":
    main()
