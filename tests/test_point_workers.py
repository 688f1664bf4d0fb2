"""The identification's FEM points solved in worker processes (:mod:`solenoid_fmu.identification.point_worker`):
the same numbers as in one process, whole strokes per worker, a worker's failure named in the parent."""

from __future__ import annotations

import numpy as np
import pytest

from solenoid_fmu.errors import SolenoidError
from solenoid_fmu.field import load_geometry, load_material
from solenoid_fmu.identification.parametrization import scaled_curve
from solenoid_fmu.identification.point_model import PointModel
from solenoid_fmu.identification.point_pool import MAX_WORKERS, WORKERS_ENV, default_workers, split_by_stroke

#: Points at three strokes (flux and force, one force point at the stroke's end in the test below).
POINTS = [("psi", 0.5, 1.0e-3), ("force", 0.8, 1.0e-3), ("psi", 1.5, 2.0e-3), ("force", 1.6, 2.0e-3),
          ("psi", 0.3, 0.5e-3), ("force", 0.3, 0.5e-3), ("psi", 1.0, 0.5e-3)]


def _model(workers: int) -> PointModel:
    lit = load_material()
    return PointModel(load_geometry(), POINTS, lambda p: scaled_curve(lit, p[0], p[1]), 3.0, lit, workers=workers)


def test_strokes_are_split_whole_and_balanced():
    x = [1.0, 1.0, 2.0, 3.0, 3.0, 3.0, 4.0]
    w = [1.0] * len(x)
    groups = split_by_stroke(x, w, 2)
    assert sorted(k for g in groups for k in g) == list(range(len(x)))
    for g in groups:  # a stroke never spans two workers (its warm starts run along it)
        assert all(x[k] not in {x[j] for h in groups if h is not g for j in h} for k in g)
    assert sorted(len(g) for g in groups) == [3, 4]
    assert len(split_by_stroke(x, w, 8)) == 4  # no more workers than strokes
    assert split_by_stroke(x, w, 1) == [list(range(len(x)))]
    assert 1 <= default_workers() <= MAX_WORKERS


def test_workers_give_the_numbers_of_one_process():
    """Values, Jacobian and solve counts with three workers (one stroke each) equal those of one process; the
    workers stop at close and the model still answers (in this process) afterwards."""
    theta = np.array([0.05, 0.3])
    one, three = _model(1), _model(3)
    try:
        assert three.pool is not None and len(three.pool.procs) == 3
        v1, v3 = one.values(theta), three.values(theta)
        np.testing.assert_allclose(v3, v1, rtol=1e-7)
        J1, J3 = one.jacobian(theta), three.jacobian(theta)
        np.testing.assert_allclose(J3, J1, rtol=1e-6, atol=1e-6 * np.abs(J1).max())
        assert (three.solves, three.adjoint_solves, three.evaluations) == (one.solves, one.adjoint_solves,
                                                                           one.evaluations)
        procs = list(three.pool.procs)
    finally:
        three.close()
    assert all(p.wait(timeout=10) == 0 for p in procs)
    # in this process the closed model solves from zero, ``one`` from its last solutions: both stop somewhere below
    # Newton's target (NEWTON_RTOL_IDENTIFY, 1e-5), where the values lie within ~5e-7 of the converged ones (2.1e-7
    # apart measured here at stop 53): they agree to that, not to the arithmetic's last digits
    np.testing.assert_allclose(three.values(theta + 0.01), one.values(theta + 0.01), rtol=2e-6)


def test_a_worker_error_is_raised_in_the_parent():
    pm = _model(2)
    try:
        with pytest.raises(ValueError, match="unknown request 'bogus'"):
            pm._ask(("bogus",))
        np.testing.assert_allclose(pm.values(np.zeros(2)), _model(1).values(np.zeros(2)), rtol=1e-7)  # still usable
        pm.pool.procs[1].kill()
        pm.pool.procs[1].wait()
        with pytest.raises(SolenoidError, match=r"FEM worker process \(pid \d+\) stopped with exit code"):
            pm.values(np.array([0.1, 0.0]))
    finally:
        pm.close()


def test_the_default_follows_the_environment_and_refuses_nonsense(monkeypatch):
    monkeypatch.setenv(WORKERS_ENV, "3")
    assert default_workers() == 3
    for bad in ("0", "two", "-1"):
        monkeypatch.setenv(WORKERS_ENV, bad)
        with pytest.raises(SolenoidError, match=f"{WORKERS_ENV}='{bad}': must be a whole number >= 1"):
            default_workers()
    monkeypatch.delenv(WORKERS_ENV)
    assert 1 <= default_workers() <= MAX_WORKERS


def test_messages_round_trip_without_pickle():
    """The workers' messages (JSON and .npy, no pickle): the curve rebuilt bit for bit, the geometry equal, dict
    keys and arrays kept, an exception raised as its own class; a truncated message is an EOFError."""
    import io

    from solenoid_fmu.errors import SolverError
    from solenoid_fmu.identification.point_pool import receive, send

    geom, lit = load_geometry(), load_material()
    buf = io.BytesIO()
    send(buf, ("init", geom, POINTS, 3.0, lit))
    send(buf, ("ok", ({4: (np.arange(3.0), np.array([np.nan]))}, [(2, 2e-6, (np.ones(2), np.ones(2)))]), (1, 2, 3)))
    send(buf, ("err", SolverError("Newton did not converge at 1.5 A")))
    buf.seek(0)
    _, g, pts, mesh, curve = receive(buf)
    assert g == geom and pts == tuple(POINTS) and mesh == 3.0
    for name in ("B_T", "nu_d", "H_A_per_m", "_w"):
        np.testing.assert_array_equal(getattr(curve, name), getattr(lit, name))
    _, (flux, force), counters = receive(buf)
    assert list(flux) == [4] and np.isnan(flux[4][1][0]) and force[0][:2] == (2, 2e-6) and counters == (1, 2, 3)
    err = receive(buf)[1]
    assert type(err) is SolverError and "1.5 A" in str(err)
    with pytest.raises(EOFError):
        receive(io.BytesIO(buf.getvalue()[:40]))
