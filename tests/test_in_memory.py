"""``improve`` and the pipeline pass their data in memory: nothing they write is read back (issue 24, item 3).

Every file opened for reading during a run is recorded (``open``/``io.open``, which ``pathlib``, ``np.load``
and ``zipfile`` go through, and ``os.open``); the run's output folder is empty before it, so a file there
at the end that was read is an output the run read back. (The FMU builder's private staging file, which it
completes and checks with fmpy before renaming it to the FMU, is gone by then: it is the builder's work on
one output, not data passed between steps; so is :func:`solenoid_fmu.maps.save_maps`'s check of a pair it
replaces, whole or not, before keeping it aside until the new pair is in place: the pipeline's second round
writes its maps over the first round's, and those reads are logged apart, :attr:`ReadLog.replaced`.) The maps go
from the sweep to the FMU builder, to the loop and to the improved FMU in memory: no ``maps.npz``, ``maps.json``
or FMU is read anywhere.
"""

from __future__ import annotations

import builtins
import io
import os
import sys
from pathlib import Path

from solenoid_fmu.fmu import simulate_model
from solenoid_fmu.maps import load_maps
from solenoid_fmu.measure import read_recording

READ_FLAGS = os.O_WRONLY | os.O_RDWR
#: Prefixes of the temporary folders the FMU backends (and pythonfmu) pack an FMU in.
BUILDER_TMP = ("solenoid_fmu_build_", "solenoid_fmu_c_", "pythonfmu_")


def _replacing_maps() -> bool:
    """True when called (at any depth) from save_maps' replacement of a maps pair (its check of the old pair)."""
    frame = sys._getframe(2)
    while frame is not None:
        if frame.f_code.co_name == "_commit_pair" and frame.f_globals.get("__name__") == "solenoid_fmu.maps.io":
            return True
        frame = frame.f_back
    return False


class ReadLog:
    """The files opened for reading while installed (resolved paths, in order); ``replaced``: those save_maps
    read to check the pair it replaces."""

    def __init__(self, monkeypatch):
        self.paths: list[Path] = []
        self.replaced: list[Path] = []
        real_open, real_os_open = builtins.open, os.open

        def note(file, reading: bool):
            if reading and isinstance(file, str | bytes | os.PathLike):
                path = Path(os.fsdecode(file)).resolve()
                if not path.is_dir():
                    (self.replaced if _replacing_maps() else self.paths).append(path)

        def logged_open(file, mode="r", *args, **kwargs):
            fh = real_open(file, mode, *args, **kwargs)  # a file that is not there is not read
            note(file, not any(c in mode for c in "wax+"))
            return fh

        def logged_os_open(path, flags, *args, **kwargs):
            fd = real_os_open(path, flags, *args, **kwargs)
            note(path, not flags & READ_FLAGS)
            return fd

        monkeypatch.setattr(builtins, "open", logged_open)
        monkeypatch.setattr(io, "open", logged_open)
        monkeypatch.setattr(os, "open", logged_os_open)

    def outputs_read(self, folder) -> list[Path]:
        """The files under ``folder`` (empty before the run) that were read: outputs the run read back."""
        written = {p.resolve() for p in Path(folder).rglob("*") if p.is_file()}
        return [p for p in self.paths if p in written]

    def maps_or_fmus(self) -> list[Path]:
        """Maps files or FMUs read, but for the FMU builder's own (its temporary folders and staging file)."""
        def builders(p: Path) -> bool:
            return p.name.startswith(".") or any(part.startswith(BUILDER_TMP) for part in p.parts)

        return [p for p in self.paths
                if (p.suffix == ".fmu" or p.name in ("maps.npz", "maps.json")) and not builders(p)]


def test_improve_on_maps_in_memory_reads_nothing_it_wrote(rig_maps, rig_campaign, tmp_path, monkeypatch):
    from solenoid_fmu.loop import ImproveResult, improve

    maps = load_maps(rig_maps[1])
    recs = [read_recording(p) for p in rig_campaign("friction")]
    out = tmp_path / "out"
    out.mkdir()
    import solenoid_fmu.loop.validation as validation

    validated = []  # the validations' own simulations (the loop's run through loop.gates)
    monkeypatch.setattr(validation, "simulate_model", lambda *a, **k: validated.append(1) or simulate_model(*a, **k))
    log = ReadLog(monkeypatch)
    res = improve(maps, recs, out / "improved.fmu", report_dir=out / "report")
    monkeypatch.undo()
    assert isinstance(res, ImproveResult) and res.effects_added == ["friction"]
    # the validations before and after are the loop's first and last simulations, not simulated again
    assert validated == [] and len(res.after["recordings"]) == len(recs)
    assert res.improved_fmu.is_file() and (res.maps_dir / "maps.npz").is_file()
    assert log.outputs_read(out) == [], "improve read back files it wrote"
    assert log.maps_or_fmus() == [], "improve read maps or an FMU from a file"
    # the record's dict form is improve.json's
    assert set(res.as_dict()) == {"fmu", "improved_fmu", "maps", "effects_added", "steps", "not_identifiable",
                                  "diagnoses", "recordings", "before", "after", "force_timing"}
    # the improved maps in memory are those written
    assert load_maps(res.maps_dir).metadata == res.maps.metadata


def test_pipeline_reads_back_nothing_it_wrote(tmp_path, monkeypatch):
    """The smoke preset (with figures, one evaluation per identification stage: what is checked is where the data
    goes, not the fit) on one unit of the test lot, both rounds: the second round is forced (the smoke preset's
    loop adds no heating), its heating-corrected recordings are written for the user and passed to the
    identification in memory (~30 s)."""
    import lotdata

    from solenoid_fmu import pipeline
    from solenoid_fmu.pipeline import PRESETS, run_pipeline

    unit = lotdata.plan()[0]
    folder = lotdata.draw(tmp_path / "campaigns", units=[unit])[0]
    out = tmp_path / "out"
    # the report embeds figures: the identification's own ones too
    monkeypatch.setitem(PRESETS, "smoke", dict(PRESETS["smoke"], figures=True, identify_max_nfev=1))
    heating = {"C_th_J_per_K": 5.0, "R_th_K_per_W": 20.0, "alpha_per_K": 0.00393}
    monkeypatch.setattr(pipeline, "_second_round_heating", lambda res, ident: heating)
    log = ReadLog(monkeypatch)
    summary = run_pipeline(folder, out, preset="smoke", workers=1, progress=None,
                           start_material=lotdata.NOMINAL_STEEL_CSV)
    monkeypatch.undo()
    assert Path(summary["improved_fmu"]).is_file() and Path(summary["maps"], "maps.npz").is_file()
    assert list((out / "validate").glob("*.png")) and list((out / "improved").glob("*.png"))
    # the second round ran on the heating-corrected recordings (those it identified from are named so)
    corrected = sorted((out / "heating-corrected").glob("*.csv"))
    assert summary["first_round"] is not None and corrected
    assert {Path(p).resolve() for p in summary["identification"]["recordings"]} <= {p.resolve() for p in corrected}
    assert list((out / "identify").glob("*.png"))  # the identification's figures, embedded from memory
    assert log.outputs_read(out) == [], "the pipeline read back files it wrote"
    # save_maps checked the first round's maps it replaced (maps/ and the improved maps), and nothing else
    assert {(p.parent.name, p.name) for p in log.replaced} == {
        (d, f) for d in ("maps", Path(summary["improved_maps"]).name) for f in ("maps.json", "maps.npz")}
    assert log.maps_or_fmus() == [], "the pipeline read maps or an FMU from a file"
    assert any(Path(p).resolve() in log.paths for p in summary["recordings"])  # the log sees the inputs read
