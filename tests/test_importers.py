"""The FMUs in importers we did not write (issue 14): libcosim via libcosimpy, Ecos via ecospy.

Each importer runs the FMU with constant inputs; the result must equal fmpy's to 1e-9 relative.
An importer that cannot be imported on this machine skips with the reason (never passes silently).
"""

import importlib
import json
import platform
import re
import subprocess
import sys
from pathlib import Path

import mapsfixture
import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

#: Where the [test] extras install libcosimpy, ecospy and tbb (their wheels: Linux on x86_64). There an
#: importer that does not load fails the test; elsewhere the test skips and says why.
EXTRAS_PLATFORM = sys.platform == "linux" and platform.machine() == "x86_64"


def _load_or_skip(what: str, load):
    """``load()``, or fail (where the extras install ``what``) or skip with the reason."""
    try:
        return load()
    except ImportError as exc:
        if EXTRAS_PLATFORM:
            pytest.fail(f"{what} is in the [test] extras for this platform but cannot be loaded: {exc}")
        pytest.skip(f"{what} cannot be imported here: {exc}")


@pytest.fixture(scope="module")
def maps_dir(tmp_path_factory):
    return mapsfixture.write_maps(tmp_path_factory.mktemp("importers") / "maps")


def _fmpy_last(fmu, drive_mode, u, x_m, stop_s):
    import fmpy

    res = fmpy.simulate_fmu(str(fmu), fmi_type="CoSimulation", stop_time=stop_s, step_size=1e-4,
                            output_interval=1e-4, output=["psi_Wb", "F_N"],
                            start_values={"drive_mode": drive_mode, "U_V" if drive_mode == 1 else "i_A": u,
                                          "x_m": x_m})
    return {"psi_Wb": float(res["psi_Wb"][-1]), "F_N": float(res["F_N"][-1])}


def _example(name):
    """The module ``examples/<name>.py``."""
    sys.path.insert(0, str(EXAMPLES))
    try:
        return importlib.import_module(name)
    finally:
        sys.path.pop(0)


def _check_like_fmpy(results):
    """Each importer run of an example's ``run()`` equals fmpy's; the current drive is reachable."""
    assert set(results) == {("c", 1), ("c", 2), ("python", 1)}
    for (backend, drive), got in results.items():
        ref = _fmpy_last(got["fmu"], drive, got["u"], 1.5e-3, 0.05)
        for key in ("psi_Wb", "F_N"):
            assert got[key] == pytest.approx(ref[key], rel=1e-9), (backend, drive, key)
    # the current-driven mode is reachable (drive_mode an Integer): its flux differs from the voltage run's
    assert abs(results[("c", 2)]["psi_Wb"] - results[("c", 1)]["psi_Wb"]) > 1e-3


def test_libcosim_runs_both_backends_and_both_drive_modes_like_fmpy(maps_dir, tmp_path):
    _load_or_skip("libcosimpy (libcosim, OSP)", lambda: importlib.import_module("libcosimpy"))
    _check_like_fmpy(_example("ex_libcosim").run(maps_dir, tmp_path))


_FMIL_LOG = """
import sys
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
from libcosimpy.CosimSlave import CosimLocalSlave

log_output_level(CosimLogLevel.TRACE)  # FMI Library's messages go to stderr through libcosim's log
execution = CosimExecution.from_step_size(100_000)
execution.add_local_slave(CosimLocalSlave(sys.argv[1], "solenoid"))
execution.simulate_until(1_000_000)
"""


def _fmil_complaints(fmu, cwd) -> list[str]:
    """FMI Library's warning and error lines when libcosim loads and runs ``fmu`` (a subprocess)."""
    run = subprocess.run([sys.executable, "-c", _FMIL_LOG, str(fmu)], capture_output=True, text=True, cwd=cwd,
                         timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    log = (run.stdout + run.stderr).splitlines()  # libcosim's log goes to stdout
    assert any("FMI Library" in ln for ln in log), "no FMI Library log captured"
    return [ln for ln in log if "FMI Library" in ln and re.search(r"\[(warning|error)\]", ln)]


@pytest.mark.fmu
def test_fmi_library_log_has_no_warning_for_either_fmu(maps_dir, tmp_path):
    """Issue 14: FMI Library (inside libcosim) logs no warning or error for either backend's FMU;
    a copy with a foreign attribute in its modelDescription shows the check can see one."""
    import zipfile

    _load_or_skip("libcosimpy (libcosim, OSP)", lambda: importlib.import_module("libcosimpy"))
    from solenoid_fmu.fmu import build_fmu

    fmus = [build_fmu(maps_dir, tmp_path / f"{b}.fmu", backend=b) for b in ("c", "python")]
    for fmu in fmus:
        assert _fmil_complaints(fmu, tmp_path) == [], fmu.name
    bad = tmp_path / "foreign-attribute.fmu"
    with zipfile.ZipFile(fmus[0]) as zi, zipfile.ZipFile(bad, "w") as zo:
        for item in zi.infolist():
            data = zi.read(item.filename)
            if item.filename == "modelDescription.xml":
                data = data.replace(b"<ScalarVariable ", b'<ScalarVariable foo="1" ', 1)
            zo.writestr(item, data)
    assert any("foo" in line for line in _fmil_complaints(bad, tmp_path))


def test_ecos_runs_both_backends_and_both_drive_modes_like_fmpy(maps_dir, tmp_path):
    ex_ecos = _example("ex_ecos")
    _load_or_skip("ecospy (Ecos)", ex_ecos.load_ecospy)
    _check_like_fmpy(ex_ecos.run(maps_dir, tmp_path))


def test_ecos_runs_the_fmi3_native_fmu_like_the_fmi2_one(maps_dir, tmp_path):
    """Ecos imports FMI 3.0 co-simulation: the native FMI 3.0 FMU gives the FMI 2.0 FMU's results, both drive modes."""
    ex_ecos = _example("ex_ecos")
    _load_or_skip("ecospy (Ecos)", ex_ecos.load_ecospy)
    from solenoid_fmu.fmu import build_fmu

    fmu2 = build_fmu(maps_dir, tmp_path / "s2.fmu", backend="c")
    fmu3 = build_fmu(maps_dir, tmp_path / "s3.fmu", backend="c", fmi_version=3)
    for drive, u in ((1, 12.0), (2, 1.0)):
        got = ex_ecos.run_ecos(fmu3, drive, u, 1.5e-3, 0.05)
        ref = ex_ecos.run_ecos(fmu2, drive, u, 1.5e-3, 0.05)
        assert got["psi_Wb"] > 0.01 and got == ref


_REMOTE = """
import json, os, sys
sys.path[:0] = [sys.argv[1], os.path.dirname(sys.argv[1])]  # examples/ and this checkout's solenoid_fmu
import ex_ecos
print(json.dumps(ex_ecos.run_ecos(sys.argv[2], 1, 12.0, 1.5e-3, 0.05, remote=True)))
"""


def _result_line(stdout):
    """The JSON result the _REMOTE script printed (Ecos logs on the same stream), None if absent."""
    lines = [line for line in stdout.splitlines() if line.startswith("{")]
    return json.loads(lines[-1]) if lines else None


def _run_remote(cmd, env, cwd):
    """Run the _REMOTE script in ``cwd`` (proxyfmu logs to logs/ there); remove the socket file
    proxyfmu leaves in /tmp when the host aborts."""
    proc = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True, timeout=120)
    for handle in re.findall(r"instantiated using handle '([^']+)'", proc.stdout + proc.stderr):
        Path(handle).unlink(missing_ok=True)
    return proc


def test_ecos_runs_the_pythonfmu_fmu_in_its_cpp_host_process_with_libpython_preloaded(maps_dir, tmp_path):
    """Ecos's proxyfmu (a C++ process) hosts the pythonfmu FMU with the README's LD_PRELOAD recipe, like fmpy."""
    ex_ecos = _example("ex_ecos")
    env = _load_or_skip("ecospy (Ecos)", lambda: ex_ecos.remote_env(tmp_path / "bin"))
    env["TMPDIR"] = str(tmp_path)  # Ecos unpacks the FMU there (an aborted host leaves it behind)
    fmu = ex_ecos.build_fmu(maps_dir, tmp_path / "solenoid-python.fmu", backend="python")
    cmd = [sys.executable, "-c", _REMOTE, str(EXAMPLES), str(fmu)]
    proc = _run_remote(cmd, env, tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    got = _result_line(proc.stdout)
    ref = _fmpy_last(fmu, 1, 12.0, 1.5e-3, 0.05)
    for key in ("psi_Wb", "F_N"):
        assert got[key] == pytest.approx(ref[key], rel=1e-9), key
    # without libpython preloaded the C++ host cannot run the pythonfmu FMU (it aborts or returns no result)
    env.pop("LD_PRELOAD")
    proc = _run_remote(cmd, env, tmp_path)
    assert proc.returncode != 0 or _result_line(proc.stdout) != got
