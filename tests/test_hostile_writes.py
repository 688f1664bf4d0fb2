"""Hostile but fair runs of the writers (issue 14, items 1-4): a writer killed between the two renames of a
map set, two writers of the same map directory, an interrupted pipeline over an earlier complete run,
``kill -9`` of a sweep with pool workers. Every hostile run is a fresh process (killed for real)."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import mapsfixture
import numpy as np
import pytest

from solenoid_fmu.fileio import dir_lock
from solenoid_fmu.maps import load_maps, save_maps

REPO = Path(__file__).resolve().parents[1]
TINY = ["--x-mm", "0.5:2.5:2", "--i-A", "0:1:3", "--mesh-size", "3", "--workers", "1", "-q"]


def _python(code: str, *args, timeout=60) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, cwd=REPO)


def _cli(*args, timeout=60) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "solenoid_fmu", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, cwd=REPO)


@pytest.fixture(scope="module")
def maps_pair(tmp_path_factory):
    """Two different whole map sets (the analytic fixture and the same with the force scaled by 1.5)."""
    old = load_maps(mapsfixture.write_maps(tmp_path_factory.mktemp("pair") / "maps"))
    arrays = old.arrays()
    arrays.update(force_ix_N=arrays["force_ix_N"] * 1.5, force_stress_ix_N=arrays["force_stress_ix_N"] * 1.5,
                  force_N=arrays["force_N"] * 1.5)
    new = type(old)(**arrays, metadata=old.metadata)
    return old, new


_KILL_BETWEEN = """
import os, sys
from solenoid_fmu.maps import load_maps, save_maps
new = load_maps(sys.argv[2])
after = sys.argv[3]  # kill -9 right after this file is renamed into place
real = os.replace
def replace(src, dst, *a, **k):
    real(src, dst, *a, **k)
    if os.path.basename(str(dst)) == after:
        os.kill(os.getpid(), 9)
os.replace = replace
save_maps(new, sys.argv[1])
"""


@pytest.mark.parametrize("after", ["maps.npz", "maps.json", ".maps-previous"])
def test_a_map_set_killed_mid_write_reads_old_or_new_whole(maps_pair, tmp_path, after):
    old, new = maps_pair
    target, source = tmp_path / "m", tmp_path / "new"
    save_maps(old, target)
    save_maps(new, source)
    proc = _python(_KILL_BETWEEN, target, source, after)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    got = load_maps(target)  # before: "sha256 ... does not match": the pair no longer loaded, the old one lost
    expect = new if after == "maps.json" else old
    for name, arr in expect.arrays().items():
        np.testing.assert_array_equal(got.arrays()[name], arr, err_msg=name)
    save_maps(new, target)  # the next writer finishes the job and leaves no trace of the kill
    np.testing.assert_array_equal(load_maps(target).force_N, new.force_N)
    assert sorted(p.name for p in target.iterdir()) == ["maps.json", "maps.npz"]


def test_a_second_writer_of_a_map_directory_is_refused_before_any_work(maps_pair, tmp_path):
    target = tmp_path / "m"
    save_maps(maps_pair[0], target)
    before = {p.name: p.read_bytes() for p in target.iterdir() if p.name.startswith("maps")}
    with dir_lock(target):  # another process is writing it
        t0 = time.perf_counter()
        proc = _cli("maps", "-o", target, *TINY)
        took = time.perf_counter() - t0
    assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert proc.stderr.startswith(f"error: -o {target}: being written by another solenoid-fmu process")
    assert took < 20 and {n: (target / n).read_bytes() for n in before} == before


def test_two_concurrent_maps_runs_never_leave_a_directory_that_does_not_load(tmp_path):
    target = tmp_path / "same"
    procs = [subprocess.Popen([sys.executable, "-m", "solenoid_fmu", "maps", "-o", str(target), *TINY], cwd=REPO,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    results = [(p.wait(timeout=120), p.stderr.read()) for p in procs]
    assert any(rc == 0 for rc, _ in results), results
    for rc, err in results:
        assert rc == 0 or "being written by another solenoid-fmu process" in err, err
    assert load_maps(target).shape[1] == 2


def _children(pid: int) -> list[int]:
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            out.append(int(stat.parent.name))
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc (Linux)")
def test_kill_9_of_a_sweep_leaves_no_pool_workers_behind(tmp_path):
    proc = subprocess.Popen([sys.executable, "-m", "solenoid_fmu", "maps", "-o", str(tmp_path / "m"), "--workers",
                             "2", "--mesh-size", "3", "-q"], cwd=REPO, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        workers = []
        while len(workers) < 2 and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.1)
            workers = _children(proc.pid)
        assert len(workers) >= 2, "the sweep did not start its 2 workers"
    finally:
        proc.kill()
        proc.wait()
    deadline = time.monotonic() + 5
    while any(map(_alive, workers)) and time.monotonic() < deadline:
        time.sleep(0.1)
    left = [w for w in workers if _alive(w)]
    for w in left:  # clean up what the test found (before the fix: both workers)
        os.kill(w, signal.SIGKILL)
    assert left == [], f"orphaned pool workers {left}"


_INTERRUPTED = """
import os, sys
from pathlib import Path
import solenoid_fmu.pipeline as p
def identify(paths, out_csv, **kw):  # identification wrote material/, then the run is killed
    Path(out_csv).parent.mkdir(parents=True, exist_ok=True)
    Path(out_csv).write_text("new material")
    os.kill(os.getpid(), 9)
p.identify_from_recordings = identify
p.run_pipeline(sys.argv[1], sys.argv[2], preset="quick", workers=1, progress=None)
"""


def test_an_interrupted_pipeline_over_an_earlier_run_is_marked_incomplete(tmp_path):
    from solenoid_fmu.measure import make_recording, write_recording
    from solenoid_fmu.pipeline import INCOMPLETE_MARKER, pipeline_incomplete

    camp = tmp_path / "camp"
    t = np.arange(400) * 1e-3
    write_recording(camp / "f.csv", make_recording("flux", "X", t, 0.5 * np.sin(t * 10) ** 2,
                                                   voltage_V=np.ones_like(t), position_m=1.5e-3,
                                                   coil_resistance_ohm=12.0))
    out = tmp_path / "out"
    (out / "material").mkdir(parents=True)
    (out / "material" / "material.csv").write_text("old material")
    for name in ("summary.json", "report.html", "camp.fmu"):
        (out / name).write_text("earlier complete run")
    assert pipeline_incomplete(out) is None  # an earlier run without a marker counts as complete
    proc = _python(_INTERRUPTED, camp, out)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    assert (out / "material" / "material.csv").read_text() == "new material"
    assert not (out / "summary.json").exists() and not (out / "report.html").exists()  # nothing to trust
    marker = json.loads((out / INCOMPLETE_MARKER).read_text())
    assert marker["campaign"] == str(camp) and "incomplete" in marker["note"]
    assert "incomplete" in pipeline_incomplete(out)
