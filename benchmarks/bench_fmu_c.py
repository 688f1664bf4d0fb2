"""Cost of one step of the native (C) FMU: in a plain C host, through fmpy, and against the pythonfmu FMU.

Usage::

    python benchmarks/bench_fmu_c.py [MAPS_DIR]

MAPS_DIR defaults to ``maps/ps45-literature`` when it exists, else synthetic maps from
``tests/mapsfixture.py``. Both FMUs (``--backend c`` and ``--backend python``) are built from the
same maps in this run. Printed:

- the C host (``tests/c/host.c``, dlopen, no Python in the process): ns per communication
  cycle (set 2 inputs, ``fmi2DoStep`` at 1e-4 s, get 3 outputs), 1e6 voltage-driven steps;
  goal under 1 us; and 1e6 current-driven steps with ``G_eddy = 0`` (the Newton path);
- the same C host on a native FMU of the same maps plus all four effect sub-models switched on
  (:data:`EFFECTS`, as in ``bench_effects.py``: 12 play operators with a shape table, a 3-section
  eddy ladder, heating, friction with a moving armature): ns per cycle and the ratio to the plain
  model;
- through fmpy (ctypes) for the native and the pythonfmu FMU, ``doStep`` alone and the full cycle,
  timed in alternating blocks, minimum over the blocks; the ratio pythonfmu / native.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_effects import EFFECTS  # noqa: E402  (the same effect parameters as bench_effects.py)
from bench_fmu import _block, _load, maps_for_bench  # noqa: E402  (sibling benchmark script)


def _host_ns(host, fmu, tmp, n_host, runs, *extra):
    """Run tests/c/host.c on an FMU ``runs`` times; (ns per voltage cycle, ns per current G=0 cycle) lists."""
    import fmpy

    from solenoid_fmu.fmu import MODEL_IDENTIFIER

    unzip = Path(fmpy.extract(str(fmu)))
    md = fmpy.read_model_description(str(fmu))
    lib = unzip / "binaries" / "linux64" / f"{MODEL_IDENTIFIER}.so"
    ns, ns_g0 = [], []
    for _ in range(runs):
        proc = subprocess.run([str(host), str(lib), md.guid, str(tmp / "ramp.csv"), str(n_host), *extra],
                              capture_output=True, text=True, check=True)
        ns.append(float(re.search(r"ns_per_step ([0-9.]+)", proc.stdout).group(1)))
        ns_g0.append(float(re.search(r"ns_per_step_current_G0 ([0-9.]+)", proc.stdout).group(1)))
    shutil.rmtree(unzip, ignore_errors=True)
    return ns, ns_g0


def main(argv: list[str]) -> int:
    import fmpy

    from solenoid_fmu.fmu import build_fmu
    from solenoid_fmu.fmu import native as fmu_c
    from solenoid_fmu.realtime import model as M

    h = 1e-4
    n_block, n_rep, n_host = 2000, 15, 1_000_000
    with tempfile.TemporaryDirectory(prefix="bench_fmu_c_") as tmp:
        tmp = Path(tmp)
        maps_dir = maps_for_bench(argv, tmp)
        print(f"maps: {maps_dir}")
        c_fmu = build_fmu(maps_dir, tmp / "native.fmu", backend="c")
        py_fmu = build_fmu(maps_dir, tmp / "python.fmu", backend="python")

        # the same maps with all four effect sub-models
        fx_dir = tmp / "with_effects"
        fx_dir.mkdir()
        shutil.copyfile(maps_dir / "maps.npz", fx_dir / "maps.npz")
        meta = json.loads((maps_dir / "maps.json").read_text(encoding="utf-8"))
        meta["effects"] = EFFECTS
        (fx_dir / "maps.json").write_text(json.dumps(meta), encoding="utf-8")
        fx_fmu = build_fmu(fx_dir, tmp / "native_fx.fmu", backend="c")

        # -- plain C host ------------------------------------------------------------------------
        unzip = Path(fmpy.extract(str(c_fmu)))
        host = tmp / "host"
        subprocess.run([fmu_c.find_compiler(), "-std=c99", "-O2", f"-I{unzip}/sources", "-o", str(host),
                        str(ROOT / "tests" / "c" / "host.c"), "-ldl", "-lm"], check=True)
        shutil.rmtree(unzip, ignore_errors=True)
        host_ns, host_ns_g0, fx_ns, fx_ns_g0 = [], [], [], []
        for _ in range(3):  # alternate plain and effects runs
            a, b = _host_ns(host, c_fmu, tmp, n_host, 1)
            host_ns += a
            host_ns_g0 += b
            a, b = _host_ns(host, fx_fmu, tmp, n_host, 1, "fx")
            fx_ns += a
            fx_ns_g0 += b

        # -- both FMUs through fmpy --------------------------------------------------------------
        tab = M.load_tables(maps_dir)
        x_m = 0.5 * (tab.x_min_m + tab.x_max_m)
        U = 0.6 * (tab.resistance_ohm_20C or 10.0) * (tab.i_fem_max_A if tab.i_fem_max_A < 1e9 else 1.0)
        fc, vr_c, unzip_c = _load(c_fmu, {"U_V": U, "x_m": x_m})
        fp, vr_p, unzip_p = _load(py_fmu, {"U_V": U, "x_m": x_m})
        cyc_c = ([vr_c["U_V"], vr_c["x_m"]], [U, x_m], [vr_c["i_out_A"], vr_c["F_N"], vr_c["psi_Wb"]])
        cyc_p = ([vr_p["U_V"], vr_p["x_m"]], [U, x_m], [vr_p["i_out_A"], vr_p["F_N"], vr_p["psi_Wb"]])
        _block(fc, 500, 0.0, h)
        _block(fp, 500, 0.0, h)
        t_c = t_p = 500 * h
        step_c, step_p, full_c, full_p = [], [], [], []
        for _ in range(n_rep):
            step_p.append(_block(fp, n_block, t_p, h))
            t_p += n_block * h
            step_c.append(_block(fc, n_block, t_c, h))
            t_c += n_block * h
            full_p.append(_block(fp, n_block, t_p, h, cyc_p))
            t_p += n_block * h
            full_c.append(_block(fc, n_block, t_c, h, cyc_c))
            t_c += n_block * h
        for fmu in (fc, fp):
            fmu.terminate()
            fmu.freeInstance()
        shutil.rmtree(unzip_c, ignore_errors=True)
        shutil.rmtree(unzip_p, ignore_errors=True)

    host_min = min(host_ns)
    ds_c, ds_p, cy_c, cy_p = min(step_c), min(step_p), min(full_c), min(full_p)
    print(f"C host (dlopen, no Python), {n_host} cycles at h = {h:g} s (set 2 inputs + doStep + get 3 outputs):")
    print(f"  native FMU   : {host_min:8.1f} ns per cycle   (goal < 1000 ns; runs: "
          + ", ".join(f"{v:.1f}" for v in host_ns) + ")")
    print(f"  current mode, G_eddy = 0 (Newton solve per step): {min(host_ns_g0):8.1f} ns per cycle")
    print(f"  all four effects on (12 plays, 3 ladder sections, heating, friction): {min(fx_ns):8.1f} ns per cycle "
          f"(ratio to the plain model {min(fx_ns) / host_min:.2f}; runs: " + ", ".join(f"{v:.1f}" for v in fx_ns) + ")")
    print(f"  all effects, current mode, G_eddy = 0 (ladder: ROS2 with m = 0): {min(fx_ns_g0):8.1f} ns per cycle "
          f"(ratio {min(fx_ns_g0) / min(host_ns_g0):.2f})")
    print(f"through fmpy (ctypes), min over {n_rep} blocks of {n_block}:")
    print(f"  doStep       : native {ds_c * 1e6:7.2f} us   pythonfmu {ds_p * 1e6:7.2f} us   "
          f"ratio {ds_p / ds_c:6.1f}")
    print(f"  full cycle   : native {cy_c * 1e6:7.2f} us   pythonfmu {cy_p * 1e6:7.2f} us   "
          f"ratio {cy_p / cy_c:6.1f}")
    print(f"pythonfmu doStep through fmpy / native cycle in the C host: {ds_p * 1e9 / host_min:.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
