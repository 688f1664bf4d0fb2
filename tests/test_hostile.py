"""Hostile but fair input (issue 13): code injection, unbounded sub-steps, NaN states, data loss, file modes."""

import json
import math
import os
import stat
import time

import mapsfixture
import numpy as np
import pytest

from solenoid_fmu.fmu import build_fmu, simulate_recording
from solenoid_fmu.measure import make_recording, write_recording
from solenoid_fmu.realtime.model import MAX_SUBSTEPS, ModelInputError, SolenoidModel, load_tables

HOSTILE = 'x */ int evil = 1; /* "\\ #include <stdlib.h> //'


@pytest.fixture(scope="module")
def hostile_maps(tmp_path_factory):
    d = mapsfixture.write_maps(tmp_path_factory.mktemp("hostile") / "maps")
    meta = json.loads((d / "maps.json").read_text())
    meta["name"] = HOSTILE
    (d / "maps.json").write_text(json.dumps(meta))
    return d


@pytest.fixture(scope="module")
def native(hostile_maps, tmp_path_factory):
    return build_fmu(hostile_maps, tmp_path_factory.mktemp("hostile_fmu") / "h.fmu", backend="c")


def test_a_hostile_maps_name_cannot_inject_c(native):
    import zipfile

    with zipfile.ZipFile(native) as zf:
        header = zf.read("sources/solenoid_maps.h").decode()
    first_comment = header[:header.index("*/") + 2]
    assert "evil" not in header.split("*/", 1)[1]  # nothing of the name after the first comment closes
    assert "#include <stdlib.h>" not in header and "\\" not in first_comment
    assert first_comment.count("\n") == 3  # the name added no line


def test_a_maps_name_with_control_characters_is_refused_by_name(hostile_maps, tmp_path):
    import shutil

    from solenoid_fmu.errors import SolenoidError

    d = tmp_path / "m"
    shutil.copytree(hostile_maps, d)
    meta = json.loads((d / "maps.json").read_text())
    meta["name"] = "line one\n#include <evil.h>"
    (d / "maps.json").write_text(json.dumps(meta))
    with pytest.raises(SolenoidError, match="'name' must be one line"):
        build_fmu(d, tmp_path / "x.fmu", backend="c")
    assert not (tmp_path / "x.fmu").exists()


def test_fmus_are_written_with_the_mode_open_would_give(native):
    mask = os.umask(0)
    os.umask(mask)
    assert stat.S_IMODE(native.stat().st_mode) == 0o666 & ~mask


_SLAVE = """
def step(s, t, h):
    try:
        s.doStep(t, h)
        return "ok"
    except Exception:
        return "error"

case = sys.argv[2]
if case == "nan":
    s, vr = slave(fmu, drive_mode=2, i_A=1.0, x_m=1.5e-3)
    out["first"] = step(s, 0.0, 1e-3)
    out["psi_ok"] = s.getReal([vr["psi_Wb"]])[0]
    s.setReal([vr["i_A"]], [1e307])
    out["huge_i"] = step(s, 1e-3, 1e-3)
    out["after"] = s.getReal([vr["psi_Wb"], vr["F_N"], vr["U_V"]])
    s2, vr = slave(fmu, drive_mode=2, G_eddy_S=1e308, i_A=1.0, x_m=1.5e-3)
    out["huge_G"] = step(s2, 0.0, 1e-3)
    out["after_G"] = s2.getReal([vr["psi_Wb"], vr["F_N"]])
else:
    s, vr = slave(fmu, drive_mode=1, h_sub_max_s=1e-300, U_V=12.0, x_m=1.5e-3)
    t0 = time.perf_counter()
    out["first"] = step(s, 0.0, 1.0)
    out["seconds"] = time.perf_counter() - t0
"""


def _run_slave(fmu, case: str) -> dict:
    """Drive the FMU in a fresh process (as a host would; no state shared with other tests' FMUs)."""
    from test_hostile_fmu import _run  # its script head: slave(), fmu = sys.argv[1], out = {}

    return _run(_SLAVE, fmu, case)[0]


def test_native_fmu_refuses_a_non_finite_state_and_keeps_the_last_one(native):
    r = _run_slave(native, "nan")
    assert r["first"] == "ok" and r["huge_i"] == "error" and r["huge_G"] == "error"
    assert all(math.isfinite(v) for v in r["after"] + r["after_G"])
    assert r["after"][0] == r["psi_ok"]  # the refused step left the state as it was


def test_native_fmu_caps_sub_steps_on_the_first_step_too(native):
    r = _run_slave(native, "cap")
    assert r["first"] == "error" and r["seconds"] < 1.0


def test_python_model_refuses_an_unbounded_number_of_sub_steps(hostile_maps):
    tab = load_tables(hostile_maps)
    m = SolenoidModel(tab, {"drive_mode": "voltage", "h_sub_max_s": 1e-300})
    m.initialize(12.0, 1.5e-3)
    t0 = time.perf_counter()
    with pytest.raises(ModelInputError, match="sub-steps"):
        m.step(1.0, 12.0, 1.5e-3)
    m2 = SolenoidModel(tab, {"drive_mode": "voltage"})
    m2.initialize(12.0, 1.5e-3)
    with pytest.raises(ModelInputError, match=f"more than {MAX_SUBSTEPS:.0f}"):
        m2.step(1e5, 12.0, 1.5e-3)  # a recording with a 1e5 s gap
    m2.step(1e-3, 12.0, 1.5e-3)  # the state is intact: the next ordinary step works
    assert math.isfinite(m2.psi_Wb) and time.perf_counter() - t0 < 1.0


def test_simulate_refuses_to_overwrite_its_input(hostile_maps, tmp_path, capsys):
    from solenoid_fmu.cli import main

    fmu = build_fmu(hostile_maps, tmp_path / "p.fmu")
    t = np.arange(200) * 1e-3
    rec = write_recording(tmp_path / "r.csv", make_recording("flux", "X", t, 0.5 * np.sin(t * 10) ** 2,
                                                            voltage_V=np.ones_like(t), position_m=1.5e-3,
                                                            coil_resistance_ohm=12.0))
    before = rec.read_bytes()
    link = tmp_path / "link.csv"
    link.symlink_to(rec)
    for out in (rec, link):
        assert main(["simulate", str(fmu), str(rec), "-o", str(out)]) != 0
        assert "would overwrite the input" in capsys.readouterr().err
    assert rec.read_bytes() == before
    assert main(["simulate", str(fmu), str(rec), "-o", str(tmp_path / "sim.csv")]) == 0
    assert simulate_recording(fmu, rec).recording.time_s.size == 200


# -- inputs that gave a wrong answer without a word ---------------------------------------------------
def _geometry_text(**replace):
    from solenoid_fmu.field.geometry import default_geometry_path

    text = default_geometry_path().read_text()
    for old, new in replace.items():
        assert old.replace("_", " ") in text or old in text
        text = text.replace(old, new, 1)
    return text


@pytest.mark.parametrize(("old", "new", "message"), [
    ("moves = true", "mooves = true", "unknown key 'mooves'"),
    ("moves = true", "moves = \"false\"", "'moves' must be true or false"),
    ("moves = true", "", "exactly one region must have 'moves = true'"),
])
def test_geometry_file_refuses_unknown_keys_wrong_types_and_no_armature(tmp_path, old, new, message):
    from solenoid_fmu.errors import GeometryError
    from solenoid_fmu.field.geometry import default_geometry_path, load_geometry

    text = default_geometry_path().read_text()
    assert old in text
    path = tmp_path / "g.toml"
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(GeometryError, match=message):
        load_geometry(path)


def test_recording_with_an_acquisition_gap_is_refused_naming_the_line(tmp_path):
    from solenoid_fmu.errors import RecordingError
    from solenoid_fmu.measure import read_recording

    t = np.arange(100) * 1e-3
    t[50:] += 1e5  # a 1e5 s gap (it would have made simulate run for hours)
    path = write_recording(tmp_path / "gap.csv", make_recording("flux", "X", t, np.zeros(100), voltage_V=np.zeros(100),
                                                              position_m=1e-3))
    with pytest.raises(RecordingError, match=r"gap\.csv:56: time gap of 100000\.001"):
        read_recording(path)


def test_grids_and_budgets_are_bounded_with_a_message(capsys):
    from solenoid_fmu.cli import main

    with pytest.raises(SystemExit) as exc:  # argparse: usage and one line, exit status 2
        main(["maps", "--x-mm", "0.5:2.5:1000000000", "-o", "/nonexistent/never"])
    assert exc.value.code == 2 and "is more than 1000 points" in capsys.readouterr().err
    assert main(["identify", "x.csv", "--max-evals", "0", "-o", "/nonexistent/x.csv"]) != 0
    assert "--max-evals must be >= 1" in capsys.readouterr().err


def test_flux_on_a_moving_armature_says_the_width_is_motion(tmp_path):
    from solenoid_fmu.measure import flux_linkage

    t = np.arange(2000) * 1e-3
    i = np.interp(t, [0, 0.2, 1.0, 1.8, 2.0], [0, 0, 1.0, 0, 0])
    x = np.interp(t, [0, 0.5, 1.5, 2.0], [2e-3, 2e-3, 1e-3, 1e-3])
    rec = make_recording("force_stroke", "X", t, i, voltage_V=12 * i, force_N=np.zeros_like(t), position_m=x,
                         coil_resistance_ohm=12.0)
    assert any("armature moves by 1 mm" in n for n in flux_linkage(rec).notes)


def _npz_with_member(src_dir, dst_dir, name, header_array):
    """Copy a maps dir, adding to maps.npz a member whose .npy header declares ``header_array``'s
    dtype and a huge shape (the data is not there), with the sha256 in maps.json updated."""
    import hashlib
    import io
    import shutil
    import zipfile

    shutil.copytree(src_dir, dst_dir)
    buf = io.BytesIO()
    np.lib.format.write_array_header_2_0(buf, {"descr": np.lib.format.dtype_to_descr(header_array.dtype),
                                               "fortran_order": False, "shape": header_array.shape})
    with zipfile.ZipFile(dst_dir / "maps.npz", "a") as zf:
        zf.writestr(f"{name}.npy", b"\x93NUMPY\x02\x00" + buf.getvalue()[8:] + b"\x00" * 64)
    meta = json.loads((dst_dir / "maps.json").read_text())
    meta.setdefault("arrays", {})["sha256"] = hashlib.sha256((dst_dir / "maps.npz").read_bytes()).hexdigest()
    (dst_dir / "maps.json").write_text(json.dumps(meta))
    return dst_dir


def test_npz_members_are_checked_before_they_are_loaded(tmp_path):
    from solenoid_fmu.errors import MapsError
    from solenoid_fmu.maps import load_maps

    src = mapsfixture.write_maps(tmp_path / "src")
    huge = np.lib.stride_tricks.as_strided(np.zeros(1), shape=(100_000, 10_000), strides=(0, 0))  # 8 GB declared
    d = _npz_with_member(src, tmp_path / "huge", "junk", huge)
    t0 = time.perf_counter()
    with pytest.raises(MapsError, match=r"member 'junk': declares 1000000000 elements"):
        load_maps(d)
    assert time.perf_counter() - t0 < 2.0
    with pytest.raises(MapsError, match=r"member 'names': dtype <U5 is not numeric"):
        load_maps(_npz_with_member(src, tmp_path / "str", "names", np.array(["abcde"])))


def test_rebuilding_a_map_directory_removes_the_earlier_exports(tmp_path):
    from solenoid_fmu.maps.export import DERIVED_PLOTS, remove_stale_exports

    d = mapsfixture.write_maps(tmp_path / "m")
    (d / "plots").mkdir()
    for name in ("maps.mat", "i_f_A.txt", "force_N.txt"):
        (d / name).write_text("old grid")
    (d / "plots" / DERIVED_PLOTS[0]).write_text("old")
    (d / "notes.md").write_text("mine")
    removed = remove_stale_exports(d)
    assert len(removed) == 4 and not (d / "plots").exists()
    assert (d / "notes.md").is_file() and (d / "maps.npz").is_file() and (d / "maps.json").is_file()


def test_messages_are_one_line_not_tracebacks(hostile_maps, tmp_path, capsys):
    from solenoid_fmu.cli import main

    binary = tmp_path / "steel.csv"
    binary.write_bytes(b"H,B\n\xff\xfe\x00\x01garbage")
    assert main(["solve", "--x-mm", "1.5", "--i-A", "1", "--material", str(binary)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "not a text (UTF-8) CSV" in err and "Traceback" not in err
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["export", str(hostile_maps), "-o", str(blocker / "x.fmu")]) == 1  # parent is a file
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "Traceback" not in err
    (tmp_path / "dir.fmu").mkdir()
    assert main(["export", str(hostile_maps), "-o", str(tmp_path / "dir.fmu")]) == 1  # output is a directory
    err = capsys.readouterr().err
    assert "dir.fmu" in err and ".dir." not in err  # names the output, not the hidden temporary file


def test_ctrl_c_during_start_up_is_one_line(monkeypatch, capsys):
    from solenoid_fmu import cli

    def interrupted():
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "build_parser", interrupted)
    assert cli.main(["maps"]) == 130
    assert capsys.readouterr().err.strip() == "interrupted"


def test_solve_reports_the_plot_file_it_wrote(tmp_path, capsys):
    from solenoid_fmu.cli import main

    assert main(["solve", "--x-mm", "1.5", "--i-A", "1", "--mesh-size", "3", "--plot", str(tmp_path / "field")]) == 0
    out = capsys.readouterr().out
    assert f"field plot: {tmp_path / 'field.png'}" in out and (tmp_path / "field.png").is_file()


def test_export_says_which_backend_suits_which_host(hostile_maps, tmp_path, capsys):
    import re
    import zipfile

    from solenoid_fmu.cli import main

    assert main(["export", str(hostile_maps), "-o", str(tmp_path / "p.fmu")]) == 0
    out = capsys.readouterr().out
    lib = re.search(r"LD_PRELOAD=(\S+)", out).group(1)
    assert os.path.isfile(lib) and "libpython" in lib and "--backend c" in out
    doc = zipfile.ZipFile(tmp_path / "p.fmu").read("documentation/index.html").decode()
    assert "LD_PRELOAD" in doc and "_Py_NoneStruct" in doc
    assert main(["export", str(hostile_maps), "-o", str(hostile_maps / "maps.json")]) == 1  # never over an input
    assert "would overwrite the input" in capsys.readouterr().err


_STATE = """
import sys, fmpy
fmu, case = sys.argv[1], sys.argv[2]
md = fmpy.read_model_description(fmu)
s = fmpy.instantiate_fmu(fmpy.extract(fmu), md, fmi_type="CoSimulation")
vr = {v.name: v.valueReference for v in md.modelVariables}
s.setupExperiment(startTime=0.0); s.enterInitializationMode()
s.setReal([vr["U_V"]], [12.0]); s.exitInitializationMode()
s.doStep(0.0, 1e-3)
good = bytes(s.serializeFMUstate(s.getFMUstate()))
psi = s.getReal([vr["psi_Wb"]])[0]
bad = {"bytes": b"\\xff\\xfe garbage", "json": b'{"layout": 999}', "good": good}[case]
try:
    s.setFMUstate(s.deSerializeFMUstate(bad))
    print("STATUS ok")
except Exception as exc:
    print("STATUS refused", exc)
print("SAME", s.getReal([vr["psi_Wb"]])[0] == psi)
s.doStep(1e-3, 1e-3)
s.terminate(); s.freeInstance()
print("FREED")
"""


@pytest.mark.parametrize("case", ["bytes", "json", "good"])
def test_pythonfmu_refuses_a_foreign_state_and_keeps_its_own(hostile_maps, tmp_path, case):
    import subprocess
    import sys

    fmu = build_fmu(hostile_maps, tmp_path / "p.fmu")
    proc = subprocess.run([sys.executable, "-c", _STATE, str(fmu), case], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr[-1500:]  # no crash, also not on free
    out = proc.stdout
    assert "SAME True" in out and "FREED" in out
    if case == "good":
        assert "STATUS ok" in out
    else:  # pythonfmu's wrapper can only refuse with fmi2Fatal (status 4); never a silent OK
        assert "STATUS refused" in out and "status 4" in out
