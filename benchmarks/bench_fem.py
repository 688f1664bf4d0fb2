"""Benchmark: one FEM operating point on PS45 (default mesh), cold and warm-started.

Prints the median wall time and Newton iterations of a cold solve (from u = 0) and of a warm
solve (from the solution at a neighbouring current, as the map sweep does), and as a baseline
measured in the same run the same cold solve on the mesh refined twice (mesh_size 0.25).
Goal (issue 2): under 0.3 s cold and 0.1 s warm on a 2-core machine.
"""

import statistics
import time

from solenoid_fmu.field.fem import Solver
from solenoid_fmu.field.geometry import load_geometry
from solenoid_fmu.field.linear_solver import LINEAR_SOLVER
from solenoid_fmu.field.material import load_material


def median_time(fn, repeat=5):
    times, its = [], []
    for _ in range(repeat):
        t0 = time.perf_counter()
        sol = fn()
        times.append(time.perf_counter() - t0)
        its.append(sol.newton_iterations)
    return statistics.median(times), statistics.median(its)


def main():
    geom, mat = load_geometry(), load_material()
    t0 = time.perf_counter()
    solver = Solver(geom, mat)
    setup = time.perf_counter() - t0
    solver.solve(0.5, 1.5e-3)  # symbolic factorization, caches for this gap
    ref = solver.solve(1.45, 1.5e-3)
    cold_t, cold_it = median_time(lambda: solver.solve(1.5, 1.5e-3))
    warm_t, warm_it = median_time(lambda: solver.solve(1.5, 1.5e-3, u0=ref.u))
    fine = Solver(geom, mat, mesh_size=0.25)
    fine.solve(0.5, 1.5e-3)
    fine_t, fine_it = median_time(lambda: fine.solve(1.5, 1.5e-3), repeat=3)
    print(f"linear solver: {LINEAR_SOLVER}; unknowns {solver.ndofs} (fine: {fine.ndofs})")
    print(f"mesh + setup (once per geometry): {setup:.3f} s")
    print(f"cold solve (i = 1.5 A, x = 1.5 mm): {cold_t:.3f} s median, {cold_it:.0f} Newton iterations")
    print(f"warm solve (from 1.45 A):          {warm_t:.3f} s median, {warm_it:.0f} Newton iterations")
    print(f"baseline, mesh refined twice, cold: {fine_t:.3f} s, {fine_it:.0f} iterations; "
          f"ratio default/fine = {cold_t / fine_t:.2f}")


if __name__ == "__main__":
    main()
