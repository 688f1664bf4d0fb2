"""Step cost of the native FMU's other binaries: win64 under wine against linux64, FMI 3.0 against FMI 2.0.

Usage::

    python benchmarks/bench_fmu_platforms.py [MAPS_DIR]

MAPS_DIR defaults to ``maps/ps45-literature`` (else synthetic maps). Built in this run from the same
maps: the FMI 2.0 FMU (``binaries/linux64`` and ``binaries/win64``) and the FMI 3.0 FMU. Printed:

- the C host (``tests/c/host.c``), one cycle = set 2 inputs + ``fmi2DoStep`` at 1e-4 s + get 3
  outputs, 200 000 cycles voltage-driven and 200 000 current-driven with ``G_eddy = 0``: linux64
  natively and the same host built for win64 (mingw-w64) on ``binaries/win64`` under wine, alternating,
  3 runs each, minimum; the ratio win64 / linux64; and whether the output digests are equal;
- the FMI 3.0 binary in ``tests/c/host_fmi3.c`` (the same cycles through the fmi3 functions) against
  host.c on the FMI 2.0 binary, alternating, minimum; ratio FMI 3 / FMI 2, digests equal;
- through fmpy: ``doStep`` loop (FMU2Slave / FMU3Slave) and ``simulate_fmu`` in model exchange
  (CVode, 0.05 s, 1e-4 s output points), alternating, minimum; ratio FMI 3 / FMI 2.

Without mingw-w64 or wine the win64 part is skipped with the missing package named.
"""

from __future__ import annotations

import re
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tests"))

from bench_fmu import _block, _load, maps_for_bench  # noqa: E402  (sibling benchmark script)
from test_fmu_c_win64 import wine_command, wine_env  # noqa: E402  (how the tests run wine)

N_HOST = 200_000
RUNS = 5


def _parse(stdout: str) -> dict:
    out = dict(re.findall(r"^(ns_per_step\S*|digest_\S+) (\S+)\s*$", stdout.replace("\r\n", "\n"), re.M))
    return {k: (v if k.startswith("digest") else float(v)) for k, v in out.items()}


def _run(cmd, env=None) -> dict:
    proc = subprocess.run(cmd, capture_output=True, text=True, check=True, env=env, stdin=subprocess.DEVNULL)
    return _parse(proc.stdout)


def _compile(cc, src, out, inc, *extra):
    subprocess.run([cc, "-std=c99", "-O2", f"-I{inc}", f"-I{src.parent}", "-o", str(out), str(src), *extra],
                   check=True)


def _fmpy_cs(fmu_path: Path, inputs: dict, n_block=2000, n_rep=10, h=1e-4) -> float:
    """Minimum per-step ``doStep`` time through fmpy (FMI 2.0: bench_fmu._load; FMI 3.0: FMU3Slave)."""
    import fmpy
    from fmpy.fmi3 import FMU3Slave

    md = fmpy.read_model_description(str(fmu_path))
    if md.fmiVersion == "2.0":
        fmu, _, _ = _load(fmu_path, inputs)
    else:
        fmu = FMU3Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu_path)),
                        modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench3")
        fmu.instantiate()
        fmu.enterInitializationMode(startTime=0.0)
        vr = {v.name: v.valueReference for v in md.modelVariables}
        fmu.setFloat64([vr[k] for k in inputs], list(inputs.values()))
        fmu.exitInitializationMode()
    t, best = 0.0, []
    for _ in range(n_rep):
        best.append(_block(fmu, n_block, t, h))
        t += n_block * h
    fmu.terminate()
    fmu.freeInstance()
    return min(best)


def main(argv: list[str]) -> int:
    import fmpy

    from solenoid_fmu.fmu import MODEL_IDENTIFIER, build_fmu, native

    host_c = ROOT / "tests" / "c" / "host.c"
    with tempfile.TemporaryDirectory(prefix="bench_fmu_platforms_") as tmp:
        tmp = Path(tmp)
        maps_dir = maps_for_bench(argv, tmp)
        print(f"maps: {maps_dir}")
        fmu2 = build_fmu(maps_dir, tmp / "fmi2.fmu", backend="c")
        fmu3 = build_fmu(maps_dir, tmp / "fmi3.fmu", backend="c", fmi_version=3)
        for name, fmu in (("fmi2", fmu2), ("fmi3", fmu3)):
            with zipfile.ZipFile(fmu) as zf:
                zf.extractall(tmp / name)
        guid2 = fmpy.read_model_description(str(fmu2)).guid
        token3 = fmpy.read_model_description(str(fmu3)).guid
        cc = native.find_compiler()
        _compile(cc, host_c, tmp / "host", tmp / "fmi2" / "sources", "-ldl", "-lm")
        _compile(cc, host_c.with_name("host_fmi3.c"), tmp / "host3", tmp / "fmi3" / "sources", "-ldl", "-lm")
        lin = [str(tmp / "host"), str(tmp / "fmi2" / "binaries" / "linux64" / f"{MODEL_IDENTIFIER}.so"), guid2,
               str(tmp / "ramp.csv"), str(N_HOST)]
        fmi3 = [str(tmp / "host3"), str(tmp / "fmi3" / "binaries" / "x86_64-linux" / f"{MODEL_IDENTIFIER}.so"),
                token3, str(N_HOST)]

        mingw, wine = native.cross_compiler(native.WIN64), wine_command()
        win = None
        if mingw is None or wine is None:
            missing = native.WIN64.package if mingw is None else "wine64"
            print(f"win64 under wine: skipped (Debian package {missing} missing; `make setup-system` as root)")
        else:
            _compile(mingw, host_c, tmp / "host.exe", tmp / "fmi2" / "sources", "-D__USE_MINGW_ANSI_STDIO=1", "-lm")
            win = [wine, str(tmp / "host.exe"), str(tmp / "fmi2" / "binaries" / "win64" / f"{MODEL_IDENTIFIER}.dll"),
                   guid2, str(tmp / "ramp_win.csv"), str(N_HOST)]
            env = wine_env(tmp / "wineprefix")
            subprocess.run([*win[:4], str(tmp / "warm.csv"), "10"], check=True, env=env, capture_output=True,
                           stdin=subprocess.DEVNULL)   # creates the wine prefix outside the timing

        res = {"linux64": [], "win64": [], "fmi3": []}
        for _ in range(RUNS):
            res["linux64"].append(_run(lin))
            if win:
                res["win64"].append(_run(win, env))
            res["fmi3"].append(_run(fmi3))

        def best(key, what):
            return min(r[what] for r in res[key])

        def digests(key):
            return {k: v for k, v in res[key][0].items() if k.startswith("digest")}

        print(f"C host, {N_HOST} cycles at 1e-4 s (set 2 inputs + doStep + get 3 outputs), min of {RUNS} runs:")
        for what, label in (("ns_per_step", "voltage mode"), ("ns_per_step_current_G0", "current mode, G = 0")):
            ref = best("linux64", what)
            line = f"  {label:20s}: linux64 {ref:7.1f} ns"
            if win:
                line += f" | win64 under wine {best('win64', what):7.1f} ns (ratio {best('win64', what) / ref:.2f})"
            line += f" | FMI 3.0 {best('fmi3', what):7.1f} ns (ratio FMI 3 / FMI 2 {best('fmi3', what) / ref:.2f})"
            print(line)
        if win:
            print("  outputs win64 == linux64 bit for bit (digests of both runs):",
                  digests("win64") == digests("linux64"))
        print("  outputs FMI 3.0 == FMI 2.0 bit for bit (digests of both runs):", digests("fmi3") == digests("linux64"))

        inputs = {"U_V": 24.0, "x_m": 1e-3}
        cs2, cs3, me2, me3 = [], [], [], []
        for _ in range(RUNS):
            cs2.append(_fmpy_cs(fmu2, inputs))
            cs3.append(_fmpy_cs(fmu3, inputs))
            for fmu, acc in ((fmu2, me2), (fmu3, me3)):
                t0 = time.perf_counter()
                fmpy.simulate_fmu(str(fmu), fmi_type="ModelExchange", stop_time=0.05, output_interval=1e-4,
                                  start_values=inputs, output=["psi_Wb", "F_N"])
                acc.append(time.perf_counter() - t0)
        print("through fmpy, min over alternating runs:")
        print(f"  doStep       : FMI 2.0 {min(cs2) * 1e6:6.2f} us   FMI 3.0 {min(cs3) * 1e6:6.2f} us   "
              f"ratio {min(cs3) / min(cs2):.2f}")
        print(f"  ME simulate_fmu (CVode, 0.05 s): FMI 2.0 {min(me2) * 1e3:6.1f} ms   "
              f"FMI 3.0 {min(me3) * 1e3:6.1f} ms   ratio {min(me3) / min(me2):.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
