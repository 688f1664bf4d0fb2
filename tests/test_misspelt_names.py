"""Header keys and column names that look like misspelt ones of recordings.md (stop 53).

An optional key with a typo (``coil_resistance_Ohm``) used to vanish without a word: kept as an unknown key, the
recording was taken as one without a header resistance. A required one (``Kind``, ``Current_A``) was reported as
missing with no hint of the name that was there. Now both say which name was found.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from truthsteels import truth_dir

from solenoid_fmu.identification.campaign import _flux_recordings
from solenoid_fmu.measure import misspelt_in, read_recording, validate_recording
from solenoid_fmu.measure.format import FILL_KEY, KNOWN_COLUMNS, KNOWN_HEADER, SHIFT_KEY, near_miss
from solenoid_fmu.realtime import load_tables
from solenoid_fmu.rig.protocols import random_campaign

DATA = "0.0,0.00,0.000\n" + "".join(f"{0.001 * k:.3f},{0.5 - 0.001 * k:.3f},{0.01 * k:.3f}\n" for k in range(1, 400))


def write(path: Path, header: dict, columns: str = "time_s,voltage_V,current_A", data: str = DATA) -> Path:
    head = {"recording": "1", "kind": "flux", "solenoid": "PS45", "position_mm": "1.0", **header}
    path.write_text("".join(f"# {k}: {v}\n" for k, v in head.items() if v is not None) + columns + "\n" + data)
    return path


@pytest.mark.parametrize(("name", "known"), [("coil_resistance_Ohm", "coil_resistance_ohm"),
                                             ("coil_resistence_ohm", "coil_resistance_ohm"),
                                             ("coil_resistance_ohms", "coil_resistance_ohm"),
                                             ("Position_MM", "position_mm"), ("Kind", "kind"),
                                             ("coil_temperature_c", "coil_temperature_C")])
def test_a_misspelt_header_key_is_taken_for_its_known_key(name, known):
    assert near_miss(name, KNOWN_HEADER) == known


@pytest.mark.parametrize("name", ["operator", "temperature_C", "serial", "coil_temp_C", "ambient_C", SHIFT_KEY,
                                  FILL_KEY])
def test_other_header_keys_are_not_misspellings(name, tmp_path):
    assert not misspelt_in([read_recording(write(tmp_path / "r.csv", {name: "1.0"}))])


def test_a_misspelt_column_is_taken_for_its_known_column():
    assert near_miss("Current_A", KNOWN_COLUMNS) == "current_A"
    assert near_miss("force_n", KNOWN_COLUMNS) == "force_N"
    assert near_miss("current_mA", KNOWN_COLUMNS) == "current_A"  # another unit: not what the format reads
    assert near_miss("temperature_C", KNOWN_COLUMNS) is None


def test_a_missing_required_name_is_reported_with_the_misspelt_one_found(tmp_path):
    bad = write(tmp_path / "a.csv", {"kind": None, "Kind": "flux"})
    assert any("missing header key 'kind'" in p and "'Kind' found" in p for p in validate_recording(bad))
    bad = write(tmp_path / "b.csv", {}, columns="time_s,voltage_V,Current_A")
    assert any("current_A" in p and "'Current_A' found" in p for p in validate_recording(bad))
    bad = write(tmp_path / "c.csv", {"position_mm": None, "Position_MM": "1.0"})
    assert any("stroke is missing" in p and "'Position_MM' found" in p for p in validate_recording(bad))


def test_identify_names_a_misspelt_header_resistance_and_takes_the_recording_as_without_one(tmp_path):
    random_campaign(load_tables(truth_dir("X6Cr17")), tmp_path, "", seed=5, max_samples=2000)
    paths = sorted((tmp_path / "recordings").glob("*.csv"))
    flux = [p for p in paths if read_recording(p).kind == "flux"]
    assert len(flux) >= 2
    typo = flux[0]
    typo.write_text(typo.read_text().replace("# coil_resistance_ohm:", "# coil_resistance_Ohm:", 1))
    recs, used, _, notes = _flux_recordings(paths)
    by_name = {r.path.name: r for r in recs}
    assert "coil_resistance_ohm" not in by_name[typo.name].header
    assert all("coil_resistance_ohm" in by_name[p.name].header for p in flux[1:])
    assert typo.name in {r.path.name for r in used}  # used as a recording without a header R (stop 52)
    assert [n for n in notes if "coil_resistance" in n] == [
        f"{typo.name}: header 'coil_resistance_Ohm' is not read (recordings.md has 'coil_resistance_ohm')"]


def _misspelt_copy(paths, tmp_path, kind):
    """A copy of the first recording of ``kind`` with its header resistance key misspelt."""
    src = next(Path(p) for p in paths if read_recording(p).kind == kind)
    dst = tmp_path / src.name
    dst.write_text(src.read_text().replace("# coil_resistance_ohm:", "# coil_resistance_Ohm:", 1))
    return dst


NOT_READ = "header 'coil_resistance_Ohm' is not read (recordings.md has 'coil_resistance_ohm')"


def test_flux_validate_diagnose_and_improve_name_a_misspelt_header_resistance(rig_maps, rig_campaign, tmp_path, capsys):
    """Stops 54-55: the commands that read recordings themselves say it too (stop 53: identify and the pipeline)."""
    import json

    from solenoid_fmu import cli
    from solenoid_fmu.loop import improve

    _, _, fmu, _ = rig_maps
    paths = rig_campaign("")
    flux = _misspelt_copy(paths, tmp_path, "flux")
    assert cli.main(["flux", str(flux), "--json"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["names_not_read"] == [f"{flux.name}: {NOT_READ}"]
    assert f"note: {flux.name}: {NOT_READ}" in err
    assert cli.main(["validate", str(fmu), str(flux), "--json"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["names_not_read"] == [f"{flux.name}: {NOT_READ}"] and NOT_READ in err
    others = [p for p in paths if Path(p).name != flux.name][:3]
    assert cli.main(["diagnose", str(fmu), *others, str(flux), "--json"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["names_not_read"] == [f"{flux.name}: {NOT_READ}"] and f"note: {flux.name}" in err
    said = []
    improve(fmu, [flux, *others], progress=said.append, max_effects=0)
    assert f"{flux.name}: {NOT_READ}" in said
    said.clear()  # recordings handed over already read (the pipeline, which said it at its step 1): not again
    improve(fmu, [read_recording(p) for p in (flux, *others)], progress=said.append, max_effects=0)
    assert not any(NOT_READ in line for line in said)
