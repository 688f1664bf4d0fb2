"""Benchmark: ``simulate_model`` over the demo campaign's recordings, compiled step against the Python step.

The loop (improve, validate, diagnose, the lot) simulates the lumped model over every recording many times.
:mod:`solenoid_fmu.fmu.native_sim` runs the native FMU's step there (one call per recording); the Python model
(``SOLENOID_FMU_SIMULATOR=python``) is the baseline measured in the same run. Both on the same maps with all four
effects (the demo's literature maps with hysteresis, an eddy ladder, heating and friction), every output compared
bit for bit. Prints the time per communication step of each and their ratio, and the one-off compile of the
library (a fresh cache folder).
"""

import json
import os
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from solenoid_fmu.fmu import simulate_model
from solenoid_fmu.measure import read_recording
from solenoid_fmu.realtime import load_tables

ROOT = Path(__file__).resolve().parents[1]
EFFECTS = {
    "hysteresis": {"thresholds": [0.01, 0.03, 0.06], "weights": [2.0, 1.0, 0.5], "shape": None},
    "eddy_ladder": {"G_S": [3e-3, 2e-3], "tau_s": [3e-4, 3e-3]},
    "heating": {"C_th_J_per_K": 60.0, "R_th_K_per_W": 2.0, "alpha_per_K": 0.00393},
    "friction": {"force_N": 0.5, "presliding_m": 2e-5},
}


def _timed(mode, tables, recs):
    os.environ["SOLENOID_FMU_SIMULATOR"] = mode
    t0 = time.perf_counter()
    out = [simulate_model(tables, r).recording for r in recs]
    return time.perf_counter() - t0, out


def main():
    recs = [read_recording(p) for p in sorted((ROOT / "fitting/ps45-demo/recordings").glob("*.csv"))]
    steps = sum(r.time_s.size - 1 for r in recs)
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["SOLENOID_FMU_CACHE"] = str(Path(tmp) / "cache")
        maps = Path(tmp) / "maps"
        maps.mkdir()
        for name in ("maps.npz", "maps.json"):
            shutil.copyfile(ROOT / "maps/ps45-literature" / name, maps / name)
        meta = json.loads((maps / "maps.json").read_text())
        meta["effects"] = EFFECTS
        (maps / "maps.json").write_text(json.dumps(meta))
        tables = load_tables(maps)
        first, _ = _timed("native", tables, recs[:1])
        native, a = _timed("native", tables, recs)
        python, b = _timed("python", tables, recs)
    equal = all(np.array_equal(getattr(x, k), getattr(y, k)) for x, y in zip(a, b, strict=True)
                for k in ("current_A", "voltage_V", "force_N"))
    print(f"{len(recs)} recordings of the demo campaign, {steps} communication steps, maps with all four effects")
    print(f"first call (compiles the library into a fresh cache): {first:.2f} s")
    print(f"native step (solenoid_fmu.fmu.native_sim): {native:.3f} s, {native / steps * 1e6:.2f} us per step")
    print(f"Python step (baseline, same run):           {python:.3f} s, {python / steps * 1e6:.2f} us per step")
    print(f"ratio Python / native: {python / native:.0f}; outputs equal bit for bit: {equal}")


if __name__ == "__main__":
    main()
