"""Benchmark: B(H) identification on PS45 from the demo campaign, default method vs the paper's.

Both methods fit the same measured commutation curve (``fitting/ps45-demo`` flux recordings at
x = 1.5 mm, hysteresis and noise included) at the same mesh size, in the same run:

- ``gn`` (default): scale + stretch of the literature curve, then projected Levenberg-Marquardt on
  all parameters, Jacobians from one adjoint linear solve per current;
- ``auglag``: nlopt AUGLAG around LN_BOBYQA (derivative-free) on the mean absolute flux error
  with the paper's constraints, from the literature curve, with a budget of AUGLAG_EVALS sweeps
  (the paper used ~2000 ANSYS iterations).

Prints wall time, FEM operating-point solves, full sweeps and equivalent sweeps (all linear solves
/ those of one sweep), the flux errors and, because the demo's true steel is known, the largest
B error over the identified H range; then the ratios auglag / gn.
Goal (issue 6): default method under 5 minutes and under 150 equivalent sweeps.
Usage: python benchmarks/bench_identify.py [AUGLAG_EVALS]   (default 150)
"""

import glob
import sys
import time

import numpy as np

from solenoid_fmu.field.geometry import load_geometry
from solenoid_fmu.field.material import load_material
from solenoid_fmu.identification import DEFAULT_MESH_SIZE, choose_currents, hysteresis_half_width, identify_bh
from solenoid_fmu.measure import commutation_curve, read_recording

DEMO = "fitting/ps45-demo"


def b_error(res, true) -> float:
    lo, hi = res.identified_H_range_A_per_m
    if hi <= 0:
        return float("nan")
    H = np.geomspace(max(lo, 10.0), hi, 50)
    return float(np.max(np.abs(res.curve.B_of_H(H) / true.B_of_H(H) - 1.0)))


def main():
    evals = int(sys.argv[1]) if len(sys.argv) > 1 else 150
    recs = [read_recording(p) for p in sorted(glob.glob(f"{DEMO}/recordings/*_flux_*.csv"))]
    cc = commutation_curve(recs)
    i, psi = choose_currents(cc.i_A, cc.psi_Wb)
    sigma = hysteresis_half_width(cc, i)
    geom, lit = load_geometry(), load_material()
    true = load_material(f"{DEMO}/truth/true-steel.csv")  # benchmark only: to score the result
    rows = {}
    for method in ("gn", "auglag"):
        t0 = time.perf_counter()
        res = identify_bh(i, psi, cc.position_m, geom, lit, mesh_size=DEFAULT_MESH_SIZE, method=method,
                          sigma_Wb=sigma, max_eval_auglag=evals)
        rows[method] = (time.perf_counter() - t0, res)
    print(f"PS45, x = {cc.position_m * 1e3:g} mm, {len(i)} currents, mesh size {DEFAULT_MESH_SIZE:g}; "
          f"AUGLAG budget {evals} evaluations")
    print(f"{'method':<8} {'wall [s]':>9} {'FEM solves':>11} {'sweeps':>7} {'equiv.':>7} {'RMS w [%]':>10} "
          f"{'RMS [%]':>8} {'MAE [%]':>8} {'B err [%]':>9}  status")
    for method, (wall, r) in rows.items():
        w = np.asarray(r.extra["weights"])
        e = (r.psi_after_Wb - r.psi_meas_Wb) / np.max(r.psi_meas_Wb) * w
        rms_w = np.sqrt(np.sum(e**2) / np.sum(w**2))
        print(f"{method:<8} {wall:9.1f} {r.fem_solves:11d} {r.sweeps:7.1f} {r.equivalent_sweeps:7.1f} "
              f"{rms_w * 100:10.3f} {r.rms_after * 100:8.3f} {r.mae_after * 100:8.3f} {b_error(r, true) * 100:9.2f}  "
              f"{r.status}")
    (tg, g), (ta, a) = rows["gn"], rows["auglag"]
    print(f"ratios auglag / gn: wall {ta / tg:.1f}x, FEM solves {a.fem_solves / g.fem_solves:.1f}x, "
          f"equivalent sweeps {a.equivalent_sweeps / g.equivalent_sweeps:.1f}x")
    met = tg < 300 and g.equivalent_sweeps < 150
    print(f"goal: gn under 300 s and 150 equivalent sweeps: {'met' if met else 'NOT met'}")


if __name__ == "__main__":
    main()
