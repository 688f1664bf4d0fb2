"""Hostile but fair file input/output (issue 13): every writer refuses to destroy or pollute its inputs,
outputs under a file are one line naming that file, maps names are checked before a sweep, Ctrl-C in a
sweep worker is one line. All refusals happen before any FEM work, so these tests take seconds."""

import concurrent.futures as cf

import mapsfixture
import numpy as np
import pytest

from solenoid_fmu.cli import main
from solenoid_fmu.field.geometry import default_geometry_path
from solenoid_fmu.fileio import OutputError, refuse_overwriting_inputs, require_directory
from solenoid_fmu.measure import make_recording, write_recording


@pytest.fixture(scope="module")
def maps_dir(tmp_path_factory):
    return mapsfixture.write_maps(tmp_path_factory.mktemp("io") / "maps")


def _recording(path):
    t = np.arange(200) * 1e-3
    return write_recording(path, make_recording("flux", "X", t, 0.5 * np.sin(t * 10) ** 2, voltage_V=np.ones_like(t),
                                                position_m=1.5e-3, coil_resistance_ohm=12.0))


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err, err
    return err


def test_the_helper_refuses_inputs_under_what_is_written_and_outputs_inside_input_folders(tmp_path):
    (tmp_path / "camp").mkdir()
    rec = _recording(tmp_path / "camp" / "r.csv")
    link = tmp_path / "link.csv"
    link.symlink_to(rec)
    with pytest.raises(OutputError, match="would overwrite the input"):
        refuse_overwriting_inputs(link, [rec])  # symlinks resolved
    with pytest.raises(OutputError, match="would overwrite the input"):
        refuse_overwriting_inputs(tmp_path, [rec])  # the input lies under an output directory
    with pytest.raises(OutputError, match="inside the input folder"):
        refuse_overwriting_inputs(tmp_path / "camp" / "out", [tmp_path / "camp"])
    # only what is written counts: an input beside the written files is fine, so is None
    assert refuse_overwriting_inputs(tmp_path / "camp", [rec, None], written=[tmp_path / "camp" / "x.csv"])
    with pytest.raises(OutputError, match=r"cannot write there|r\.csv is a file, not a directory"):
        require_directory(rec / "sub", "-o")
    assert require_directory(tmp_path / "new" / "dir") == tmp_path / "new" / "dir"


def test_every_writer_refuses_an_output_that_destroys_an_input(maps_dir, tmp_path, capsys):
    camp = tmp_path / "camp"
    camp.mkdir()
    rec = _recording(camp / "r.csv")
    png = _recording(tmp_path / "r.png")  # a recording a PNG could overwrite
    material = tmp_path / "m" / "maps.json"
    material.parent.mkdir()
    material.write_text("H_A_per_m,B_T\n0,0\n")
    tab = tmp_path / "x.tab"
    tab.write_text("H_A_per_m,B_T\n0,0\n")
    truth = tmp_path / "c" / "truth.json"
    truth.parent.mkdir()
    truth.write_text("{}")
    plot = tmp_path / "plots" / "force_psi_x.png"  # a geometry named like a plot the maps write
    plot.parent.mkdir()
    plot.write_bytes(default_geometry_path().read_bytes())
    files = {p: p.read_bytes() for p in (rec, png, material, tab, truth, plot)}
    cases = [
        (["flux", str(png), "--plot", str(png)], "would overwrite the input"),
        (["maps", "-o", str(material.parent), "--material", str(material), "--x-mm", "0.5:2:3", "--i-A", "0:1:3"],
         "would overwrite the input"),
        (["maps", "-o", str(tmp_path / "new"), "--geometry", str(plot), "--plot", str(plot.parent)],
         "would overwrite the input"),
        (["rig", "--maps", str(maps_dir), "--campaign", str(truth), "-o", str(truth.parent)],
         "would overwrite the input"),
        (["identify", str(rec), "--start-material", str(tab), "-o", str(tmp_path / "x.csv")],
         "would overwrite the input"),  # identify writes x.tab beside x.csv
        (["pipeline", str(camp), "-o", str(camp / "out")], "inside the input folder"),
        (["pipeline", str(camp), "-o", str(tmp_path)], "would overwrite the input"),
        (["validate", str(tmp_path / "a.fmu"), str(rec), "--report", str(rec)], "is a file, not a directory"),
    ]
    for argv, message in cases:
        assert main(argv) == 1, argv
        assert message in _one_line_error(capsys), argv
    assert {p: p.read_bytes() for p in files} == files
    assert sorted(p.name for p in camp.iterdir()) == ["r.csv"]  # nothing written into the campaign


def test_flux_plot_is_a_png_beside_never_over_the_recording(tmp_path, capsys):
    rec = _recording(tmp_path / "r.csv")
    before = rec.read_bytes()
    assert main(["flux", str(rec), "--plot", str(rec)]) == 0  # matplotlib would refuse '.csv' with a traceback
    assert f"plot: {rec}.png" in capsys.readouterr().out
    assert rec.read_bytes() == before and (tmp_path / "r.csv.png").read_bytes()[:4] == b"\x89PNG"


def test_an_output_under_a_file_is_one_line_naming_the_file(maps_dir, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    rec = _recording(tmp_path / "r.csv")
    cases = [
        ["export", str(maps_dir), "-o", str(blocker / "x.fmu")],
        ["maps", "-o", str(blocker), "--x-mm", "0.5:2:3", "--i-A", "0:1:3"],
        ["maps", "--from", str(maps_dir), "--plot", str(blocker / "plots")],
        ["validate", str(tmp_path / "a.fmu"), str(rec), "--report", str(blocker / "rep")],
        ["identify", str(rec), "-o", str(blocker / "m.csv")],
        ["pipeline", str(tmp_path), "-o", str(blocker / "out")],
        ["rig", "--maps", str(maps_dir), "-o", str(blocker / "c")],
        ["flux", str(rec), "--plot", str(blocker / "f.png")],
    ]
    for argv in cases:
        assert main(argv) == 1, argv
        err = _one_line_error(capsys)
        assert f"{blocker} is a file, not a directory" in err or f"{blocker}: is a file, not a directory" in err, err
        assert ".file." not in err  # never the hidden temporary file
    assert blocker.read_text() == "x"


def test_a_maps_name_with_control_characters_is_refused_before_the_sweep(tmp_path, capsys):
    bad = tmp_path / "bad\x01name"
    assert main(["maps", "-o", str(bad), "--x-mm", "0.5:2:3", "--i-A", "0:1:3", "--workers", "1", "-q"]) == 1
    assert "control characters" in _one_line_error(capsys) and not bad.exists()
    bad.mkdir()
    _recording(bad / "r.csv")
    assert main(["pipeline", str(bad), "-o", str(tmp_path / "out")]) == 1
    assert "control characters" in _one_line_error(capsys) and not (tmp_path / "out").exists()


def test_ctrl_c_inside_a_sweep_worker_is_one_line(monkeypatch, tmp_path, capsys):
    from solenoid_fmu.field.geometry import load_geometry
    from solenoid_fmu.field.material import load_material
    from solenoid_fmu.maps import sweep as maps

    calls = []

    def interrupted(*args):
        calls.append(args[2])
        raise KeyboardInterrupt

    # a worker thread (as a process-pool worker) hands the interrupt back through its future
    with cf.ThreadPoolExecutor(1) as pool, pytest.raises(KeyboardInterrupt):
        maps.build_maps(load_geometry(None), load_material(None), x_m=np.array([0.5e-3, 1e-3, 2e-3]),
                        i_A=np.array([0.0, 0.5, 1.0]), executor=pool, sweep=interrupted, progress=False)
    calls.clear()
    monkeypatch.setattr(maps, "_default_sweep", lambda: interrupted)
    out = tmp_path / "m"
    assert main(["maps", "-o", str(out), "--x-mm", "0.5:2:3", "--i-A", "0:1:3", "--workers", "1", "-q"]) == 130
    assert capsys.readouterr().err == "interrupted\n"
    assert len(calls) == 1 and not (out / "maps.npz").exists()  # no map from an interrupted sweep
