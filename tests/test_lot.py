"""A production lot through the pipeline (``solenoid-fmu batch``): local process pool against a Dask LocalCluster,
the outlier rule, restart after a kill, failing units, bad input.

The lot (``tests/lotdata.py``): 8 units of PS45 around the nominal steel DC03 with batch variation (B ~1 %,
coil resistance 0.3 %), 2 of them with an undeclared in-spec effect (coil heating, eddy ladder), 3 out of spec
(another steel, 4 x friction, 0.85 x the turns), plus a unit with a malformed recording. Truth maps shipped in
``tests/data/lot-truths/`` (per-stroke meshes of size 0.7; the identification's differ). Every unit runs the
pipeline's ``smoke`` preset, its identification starting from the nominal steel (``--start-material``).

The lot runs in one test (so that under ``pytest -n 2`` one xdist worker runs it, on its own 2 processes, once):
the local run interrupted and run again, the Dask run (three of the units), then the checks, each a function
below.
"""

import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import lotdata
import numpy as np
import pytest

from solenoid_fmu.lot import FEATURES, RULE, LotError, run_batch, unit_complete
from solenoid_fmu.lot import execute as lot_execute
from solenoid_fmu.lot.outliers import Z_THRESHOLD, robust_z, stand_out
from solenoid_fmu.lot.units import input_sha256, publish_unit, remove_leftovers

OUT_OF_SPEC = {u.name for u in lotdata.plan() if u.kind == "out-of-spec"}
BAD = "u09-bad"


# -- cheap tests: the rule, the unit folders, bad input ------------------------------------------------------------

def test_robust_z_flags_the_far_values_and_the_floor_keeps_a_tight_lot_quiet():
    v = [1.00, 1.01, 0.99, 1.005, 0.995, 1.15]  # five within 1 %, one 15 % off
    z = robust_z(v)
    assert abs(z[-1]) > Z_THRESHOLD and np.all(np.abs(z[:-1]) < Z_THRESHOLD)
    tight = [1.0, 1.0 + 1e-9, 1.0 - 1e-9, 1.0 + 2e-9, 1.0 + 0.01]  # MAD ~1e-9: the floor (0.5 % of 1) decides
    assert np.all(np.abs(robust_z(tight)) < Z_THRESHOLD)
    rows = [{"unit": f"u{k}", "a": x, "friction_N": 1.0} for k, x in enumerate(v)]
    assert [u for u, f in stand_out(rows, ["a", "friction_N"]).items() if f["flagged_by"]] == ["u5"]


def test_unit_folder_is_complete_only_when_whole_and_for_the_same_inputs(tmp_path):
    files = {"recordings/a.csv": b"x"}
    sha = input_sha256(files, "smoke", None)
    assert sha != input_sha256({"recordings/a.csv": b"y"}, "smoke", None) != input_sha256(files, "quick", None)
    publish_unit(tmp_path, "u1", {"summary.json": b"{}", "maps/m.json": b"{}"},
                 {"unit": "u1", "status": "ok", "input_sha256": sha})
    assert unit_complete(tmp_path / "u1", sha) and not unit_complete(tmp_path / "u1", "other")
    (tmp_path / "u1" / "pipeline.incomplete").write_text("")
    assert not unit_complete(tmp_path / "u1", sha)
    publish_unit(tmp_path, "u1", {"summary.json": b"{}"}, {"unit": "u1", "status": "ok", "input_sha256": sha})
    assert unit_complete(tmp_path / "u1", sha) and not (tmp_path / "u1" / "maps").exists()  # replaced whole
    (tmp_path / ".tmp-u2-1234").mkdir()  # what a batch killed while writing leaves
    remove_leftovers(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["u1"]
    with pytest.raises(LotError, match="leaves"):
        publish_unit(tmp_path, "u3", {"../evil": b""}, {"unit": "u3"})


def test_bad_input_gives_one_line_naming_it(tmp_path, monkeypatch):
    (tmp_path / "a" / "u1").mkdir(parents=True)
    (tmp_path / "b" / "u1").mkdir(parents=True)
    with pytest.raises(LotError, match="nowhere: campaign folder not found"):
        run_batch([tmp_path / "nowhere"], tmp_path / "out")
    with pytest.raises(LotError, match="two campaign folders give the unit name 'u1'"):
        run_batch([tmp_path / "a" / "u1", tmp_path / "b" / "u1"], tmp_path / "out")
    monkeypatch.setattr(lot_execute, "CONNECT_TIMEOUT_S", 1)
    with pytest.raises(LotError, match=r"cannot reach the Dask scheduler at 'tcp://127.0.0.1:9'") as err:
        run_batch([tmp_path / "a" / "u1"], tmp_path / "out", scheduler="tcp://127.0.0.1:9")
    assert "\n" not in str(err.value)
    with pytest.raises(LotError, match=r"not a Dask scheduler address: 'tcp://'"):
        run_batch([tmp_path / "a" / "u1"], tmp_path / "out", scheduler="tcp://")
    r = subprocess.run([sys.executable, "-m", "solenoid_fmu", "batch", str(tmp_path / "nowhere"), "-o",
                        str(tmp_path / "out")], capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and r.stderr.strip().splitlines()[-1].startswith("error: ")
    assert "nowhere" in r.stderr


# -- the lot ----------------------------------------------------------------------------------------------------------

def _draw_lot(base: Path) -> list[Path]:
    """The lot's campaign folders (8 units and one with a malformed flux recording)."""
    dirs = lotdata.draw(base / "campaigns")
    bad = base / "campaigns" / BAD
    shutil.copytree(dirs[0], bad)
    rec = next((bad / "recordings").glob("*flux*.csv"))
    lines = rec.read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if not line.startswith("#")) + 5
    lines[k] = "0.1,oops," + lines[k].split(",", 2)[-1]  # a number that is not one
    rec.write_text("\n".join(lines) + "\n")
    return [*dirs, bad]


def _complete(out: Path, names) -> dict:
    """unit -> run id of the units complete (status ok) in ``out``."""
    got = {}
    for n in names:
        try:
            rec = json.loads((out / n / "unit.json").read_text())
        except (OSError, ValueError):
            continue
        if rec["status"] == "ok" and unit_complete(out / n, rec["input_sha256"]):
            got[n] = rec["run_id"]
    return got


def _local_run(dirs, out: Path) -> dict:
    """The batch from the command line on a local pool of 1 process (at most one unit lost to the interruption),
    interrupted (Ctrl-C) once 2 units are complete, then run again to the end on 2 processes."""
    names = [d.name for d in dirs]
    cmd = [sys.executable, "-m", "solenoid_fmu", "batch", *map(str, dirs), "-o", str(out), "--workers", "1",
           "--preset", "smoke", "--start-material", str(lotdata.NOMINAL_STEEL_CSV)]
    # Ctrl-C's SIGINT at its default disposition in the batch: a test run started in the background of a shell
    # without job control inherits SIGINT ignored, and Python then installs no KeyboardInterrupt handler
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    t0 = time.monotonic()
    deadline = t0 + 600
    while len(_complete(out, names)) < 2 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    assert proc.poll() is None, "the batch ended before it could be interrupted"
    at_sigint = {"s": round(time.monotonic() - t0, 1), "complete": sorted(_complete(out, names))}
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=120)
    first = _complete(out, names)
    rerun = run_batch(dirs, out, workers=2, preset="smoke", start_material=lotdata.NOMINAL_STEEL_CSV, progress=False)
    return {"out": out, "rc": proc.returncode, "stderr": stderr, "first": first, "rerun": rerun, "at_sigint": at_sigint,
            "after": _complete(out, names), "names": names, "dirs": dirs}


def _cluster_dirs(dirs) -> list[Path]:
    """The part of the lot the Dask run takes: an in-spec unit, an out-of-spec one and the malformed one
    (the engines are compared unit by unit; the lot's flags come from those rows on the client either way)."""
    inspec = next(d for d in dirs if d.name not in OUT_OF_SPEC and d.name != BAD)
    out = next(d for d in dirs if d.name in OUT_OF_SPEC)
    return [inspec, out, dirs[-1]]


def _cluster_run(dirs, out: Path) -> dict:
    """Part of the lot through a Dask LocalCluster of 2 worker processes (one thread each), by its address."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        res = run_batch(_cluster_dirs(dirs), out, scheduler=cluster.scheduler_address, preset="smoke",
                        start_material=lotdata.NOMINAL_STEEL_CSV, progress=False)
    return {"out": out, "res": res}


@pytest.mark.slow  # 11 smoke units and a few wasted by the interruption
def test_a_lot_on_a_local_pool_and_on_a_dask_cluster(tmp_path):
    dirs = _draw_lot(tmp_path)
    local = _local_run(dirs, tmp_path / "out-local")
    cluster = _cluster_run(dirs, tmp_path / "out-cluster")
    _ctrl_c_keeps_finished_units_and_the_rerun_redoes_only_the_rest(local)
    _dask_cluster_gives_the_local_results(local, cluster)
    _the_lot_flags_exactly_the_out_of_spec_units(local)
    _a_malformed_recording_fails_its_unit_only(local)


def _ctrl_c_keeps_finished_units_and_the_rerun_redoes_only_the_rest(r):
    assert r["rc"] == 130, (r["at_sigint"], r["stderr"][-2000:])  # when Ctrl-C came, and what the batch said
    first, names = r["first"], r["names"]
    assert 2 <= len(first) < len(names) - 1, first
    # exactly the units not complete at the interruption ran again; the complete ones kept their run
    assert sorted(r["rerun"]["ran"]) == sorted(set(names) - set(first))
    assert sorted(r["rerun"]["skipped"]) == sorted(first)
    assert all(r["after"][n] == run_id for n, run_id in first.items())
    assert not list(r["out"].glob(".tmp-*")) and not list(r["out"].glob(".old-*"))
    # and a third run has only the failed unit to try again
    again = run_batch(r["dirs"], r["out"], workers=2, preset="smoke", start_material=lotdata.NOMINAL_STEEL_CSV,
                      progress=False)
    assert again["ran"] == [BAD] and sorted(again["skipped"]) == sorted(set(names) - {BAD})


def _dask_cluster_gives_the_local_results(local_run, cluster_run):
    local = {row["unit"]: row for row in local_run["rerun"]["rows"]}
    cluster = {row["unit"]: row for row in cluster_run["res"]["rows"]}
    assert set(cluster) == {d.name for d in _cluster_dirs(local_run["dirs"])}
    assert {cluster[n]["status"] for n in cluster} == {"ok", "failed"}
    for name, row in ((n, local[n]) for n in cluster):
        assert row["status"] == cluster[name]["status"], name
        for f in FEATURES:
            a, b = row[f], cluster[name][f]
            assert (math.isnan(a) and math.isnan(b)) or abs(a - b) <= 1e-12 * max(1.0, abs(a)), (name, f, a, b)
        if row["status"] == "ok":
            sub = "material/material.csv"
            assert (local_run["out"] / name / sub).read_text() == (cluster_run["out"] / name / sub).read_text()
            sa = json.loads((local_run["out"] / name / "summary.json").read_text())
            sb = json.loads((cluster_run["out"] / name / "summary.json").read_text())
            assert sa["effects_found"] == sb["effects_found"]
            for ea, eb in zip(sa["errors"], sb["errors"], strict=True):
                assert ea["after"] == pytest.approx(eb["after"], rel=1e-12, abs=1e-15)


def _the_lot_flags_exactly_the_out_of_spec_units(local_run):
    res = local_run["rerun"]
    rows = {r["unit"]: r for r in res["rows"]}
    zmax = {u: max(abs(r[f"z_{f}"]) for f in FEATURES) for u, r in rows.items() if r["status"] == "ok"}
    assert set(res["flagged"]) == OUT_OF_SPEC, zmax
    # with margins on both sides (physics, not luck): in-spec units well inside, out-of-spec ones far out
    assert max(z for u, z in zmax.items() if u not in OUT_OF_SPEC) < 0.8 * Z_THRESHOLD, zmax
    assert min(z for u, z in zmax.items() if u in OUT_OF_SPEC) > 2 * Z_THRESHOLD, zmax
    # and by the features that physics says: the other steel by B, the friction by friction, the coil by R
    plan = {u.name: u for u in lotdata.plan()}
    for name in OUT_OF_SPEC:
        by = rows[name]["flagged_by"]
        if "friction" in plan[name].reason:
            assert by == "friction_N"
        elif "turns" in plan[name].reason:
            assert "R20_ohm" in by
        else:
            assert "B_T_at" in by and "R20_ohm" not in by
    html = (local_run["out"] / "lot.html").read_text()
    assert RULE.split(";")[0] in html.replace("&#x27;", "'") and html.count("data:image/png;base64") >= 1
    header = (local_run["out"] / "lot.csv").read_text().splitlines()[0].split(",")
    assert {"unit", "status", "error", "stands_out", "R20_ohm", "friction_N", "effects_found", "wall_s"} <= set(header)


def _a_malformed_recording_fails_its_unit_only(local_run):
    rows = {r["unit"]: r for r in local_run["rerun"]["rows"]}
    assert rows[BAD]["status"] == "failed" and "\n" not in rows[BAD]["error"] and "oops" in rows[BAD]["error"]
    assert str(local_run["dirs"][-1] / "recordings") in rows[BAD]["error"]  # the client's path, not the worker's
    assert all(r["status"] == "ok" for n, r in rows.items() if n != BAD)
    assert not rows[BAD]["stands_out"]  # a failed unit has no features, it is listed as failed, not flagged
    assert f"{BAD},failed," in (local_run["out"] / "lot.csv").read_text()
    assert os.path.isfile(local_run["out"] / BAD / "unit.json")
