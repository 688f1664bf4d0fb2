"""Per-step cost of each effect sub-model in ``model.py`` (issue 7: every effect stays real-time capable).

Usage::

    python benchmarks/bench_effects.py

PS45 maps (``maps/ps45-literature``) with one effect at a time switched on, voltage drive, a 10 A/s
ramp-like input at 1e-4 s communication steps (one ROS2 sub-step each), against the plain model in
the same run; minimum over 5 blocks of 20000 steps. Parameters: a 12-play hysteresis operator, a
3-section eddy ladder, heating, friction with a moving armature.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EFFECTS = {
    "hysteresis": {"thresholds": [0.01 * (k + 1) for k in range(12)], "weights": [0.05] * 12,
                   "shape": {"b_nodes": [0.0, 0.2, 0.4], "g_nodes": [1.0, 0.8, 0.3]}},
    "eddy_ladder": {"G_S": [1e-3, 2e-3, 1e-3], "tau_s": [3e-4, 1e-3, 3e-3]},
    "heating": {"C_th_J_per_K": 300.0, "R_th_K_per_W": 1.0, "alpha_per_K": 0.00393},
    "friction": {"force_N": 2.5, "presliding_m": 2e-5},
}


def _time(tab, n=20000, blocks=5) -> float:
    from solenoid_fmu.realtime.model import SolenoidModel

    m = SolenoidModel(tab, {"drive_mode": "voltage"})
    m.initialize(0.0, 1.5e-3)
    best = float("inf")
    for _ in range(blocks):
        t0 = time.perf_counter()
        for k in range(n):
            m.step(1e-4, 12.0 * ((k % 5000) / 5000.0), 1.5e-3 + 1e-6 * (k % 100), None)
        best = min(best, (time.perf_counter() - t0) / n)
    return best


def main() -> None:
    from solenoid_fmu.loop import with_effects
    from solenoid_fmu.realtime.model import load_tables

    base = load_tables(ROOT / "maps" / "ps45-literature")
    t_base = _time(base)
    print(f"plain model.py step: {t_base * 1e6:.2f} us")
    rows = {}
    for name, section in EFFECTS.items():
        t = _time(with_effects(base, {name: section}))
        rows[name] = t
        print(f"{name:<12} {t * 1e6:7.2f} us/step   ratio to plain {t / t_base:5.2f}")
    t_all = _time(with_effects(base, EFFECTS))
    print(f"{'all four':<12} {t_all * 1e6:7.2f} us/step   ratio to plain {t_all / t_base:5.2f}")
    print(json.dumps({"plain_us": t_base * 1e6, **{k: v * 1e6 for k, v in rows.items()}, "all_us": t_all * 1e6}))


if __name__ == "__main__":
    main()
