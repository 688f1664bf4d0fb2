"""``improve`` and the pipeline pass their data in memory: nothing they write is read back (issue 24, item 3).

Every file opened for reading during a run is recorded (``open``/``io.open``, which ``pathlib``, ``np.load``
and ``zipfile`` go through, and ``os.open``); the run's output folder is empty before it, so a file there
at the end that was read is an output the run read back. (The FMU builder's private staging file, which it
completes and checks with fmpy before renaming it to the FMU, is gone by then: it is the builder's work on
one output, not data passed between steps.) The maps go from the sweep to the FMU builder, to the loop and
to the improved FMU in memory: no ``maps.npz``, ``maps.json`` or FMU is read anywhere.
"""

from __future__ import annotations

import builtins
import io
import os
from pathlib import Path

from solenoid_fmu.maps import load_maps
from solenoid_fmu.measure import read_recording

READ_FLAGS = os.O_WRONLY | os.O_RDWR
#: Prefixes of the temporary folders the FMU backends (and pythonfmu) pack an FMU in.
BUILDER_TMP = ("solenoid_fmu_build_", "solenoid_fmu_c_", "pythonfmu_")


class ReadLog:
    """The files opened for reading while installed (resolved paths, in order)."""

    def __init__(self, monkeypatch):
        self.paths: list[Path] = []
        real_open, real_os_open = builtins.open, os.open

        def note(file, reading: bool):
            if reading and isinstance(file, str | bytes | os.PathLike):
                path = Path(os.fsdecode(file)).resolve()
                if not path.is_dir():
                    self.paths.append(path)

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
    log = ReadLog(monkeypatch)
    res = improve(maps, recs, out / "improved.fmu", report_dir=out / "report")
    monkeypatch.undo()
    assert isinstance(res, ImproveResult) and res.effects_added == ["friction"]
    assert res.improved_fmu.is_file() and (res.maps_dir / "maps.npz").is_file()
    assert log.outputs_read(out) == [], "improve read back files it wrote"
    assert log.maps_or_fmus() == [], "improve read maps or an FMU from a file"
    # the record's dict form is improve.json's
    assert set(res.as_dict()) == {"fmu", "improved_fmu", "maps", "effects_added", "steps", "not_identifiable",
                                  "diagnoses", "recordings", "before", "after"}
    # the improved maps in memory are those written
    assert load_maps(res.maps_dir).metadata == res.maps.metadata


def test_pipeline_reads_back_nothing_it_wrote(tmp_path, monkeypatch):
    """The smoke preset (with figures) on one unit of the test lot (~20 s)."""
    import lotdata

    from solenoid_fmu.pipeline import PRESETS, run_pipeline

    unit = lotdata.plan()[0]
    folder = lotdata.draw(tmp_path / "campaigns", units=[unit])[0]
    out = tmp_path / "out"
    monkeypatch.setitem(PRESETS, "smoke", dict(PRESETS["smoke"], figures=True))  # the report embeds figures
    log = ReadLog(monkeypatch)
    summary = run_pipeline(folder, out, preset="smoke", workers=1, progress=None,
                           start_material=lotdata.NOMINAL_STEEL_CSV)
    monkeypatch.undo()
    assert Path(summary["improved_fmu"]).is_file() and Path(summary["maps"], "maps.npz").is_file()
    assert list((out / "validate").glob("*.png")) and list((out / "improved").glob("*.png"))
    assert list((out / "identify").glob("*.png"))  # the identification's figures, embedded from memory
    assert log.outputs_read(out) == [], "the pipeline read back files it wrote"
    assert log.maps_or_fmus() == [], "the pipeline read maps or an FMU from a file"
    assert any(Path(p).resolve() in log.paths for p in summary["recordings"])  # the log sees the inputs read
