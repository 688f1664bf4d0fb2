"""The typed records of maps.json's metadata (coil, eddy, effects): they read every shipped sidecar and
write it back unchanged, refuse a value of the wrong type naming the file and key, and change maps only
through a new MapTables."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import mapsfixture as mf
import pytest

from solenoid_fmu.errors import MapsError
from solenoid_fmu.maps import load_maps
from solenoid_fmu.realtime import (
    COPPER_ALPHA_PER_K,
    CoilRecord,
    EddyRecord,
    EffectsRecord,
    ModelMapsError,
    load_tables,
    replace_meta,
)

ROOT = Path(__file__).resolve().parents[1]
SIDECARS = sorted(p for pattern in ("maps/*/maps.json", "tests/data/**/maps.json", "fitting/**/maps.json")
                  for p in ROOT.glob(pattern))
RECORDS = {"coil": CoilRecord, "eddy": EddyRecord, "effects": EffectsRecord}


@pytest.mark.parametrize("path", SIDECARS, ids=lambda p: str(p.parent.relative_to(ROOT)))
def test_every_shipped_sidecar_round_trips(path):
    """maps.json -> records -> dict: the same sections, keys in the same order, the same values."""
    meta = json.loads(path.read_text(encoding="utf-8"))
    records = {key: cls.from_dict(meta[key], str(path.parent)) for key, cls in RECORDS.items() if key in meta}
    assert {"coil", "eddy"} <= set(records)
    for key, rec in records.items():
        assert rec.as_dict() == meta[key] and list(rec.as_dict()) == list(meta[key])
    again = replace_meta(meta, **records)
    assert again == meta and json.dumps(again) == json.dumps(meta)


def test_records_keep_unknown_keys_nulls_and_order():
    coil = {"max_current_A": 2, "wire": {"d_mm": 0.3}, "turns": 1500, "resistance_ohm_20C": None}
    rec = CoilRecord.from_dict(coil)
    assert (rec.turns, rec.max_current_A, rec.resistance_ohm_20C) == (1500, 2, None)
    assert rec.as_dict() == coil and list(rec.as_dict()) == list(coil)
    assert rec.alpha_per_K == COPPER_ALPHA_PER_K  # the default, stated once
    assert CoilRecord.from_dict({"temperature_coefficient_per_K": 0.0}).alpha_per_K == 0.0
    # a field set since it was read follows the file's keys
    more = dataclasses.replace(rec, temperature_coefficient_per_K=0.004)
    assert list(more.as_dict()) == [*coil, "temperature_coefficient_per_K"]
    assert EddyRecord.from_dict(None).as_dict() == {"G_eddy_S": None}  # the key the format requires
    eddy = {"source": "fit", "G_eddy_S": None, "rates": [1, 2]}
    assert EddyRecord.from_dict(eddy).as_dict() == eddy
    fx = {"heating": None, "friction": {"force_N": 1.0, "presliding_m": 2e-5}}
    rec = EffectsRecord.from_dict(fx)
    assert rec.as_dict() == fx and rec.friction == fx["friction"] and rec.heating is None
    assert rec.named and rec.active and rec.items() == list(fx.items())
    nulls = EffectsRecord.from_dict({"heating": None})
    assert nulls.named and not nulls.active
    assert not EffectsRecord.from_dict(None).named and EffectsRecord.from_dict(None).as_dict() == {}


@pytest.mark.parametrize(("section", "value", "message"), [
    ("coil", {"resistance_ohm_20C": "12"}, "coil.resistance_ohm_20C must be a finite number, got '12'"),
    ("coil", {"max_current_A": True}, "coil.max_current_A must be a finite number, got True"),
    ("coil", {"turns": -3}, "coil.turns must be > 0, got -3"),
    ("coil", ["not", "an", "object"], "'coil' must be an object"),
    ("eddy", {"G_eddy_S": "0.01"}, "eddy.G_eddy_S must be null or a finite number >= 0 S, got '0.01'"),
    ("effects", {"bogus": {}}, "unknown effect 'bogus'"),
    ("effects", {"heating": 3.0}, "effects.heating: must be an object"),
])
def test_a_wrong_type_is_refused_naming_the_file_and_key(tmp_path, section, value, message):
    d = mf.write_maps(tmp_path / "maps")
    meta = json.loads((d / "maps.json").read_text())
    meta[section] = dict(meta.get(section) or {}, **value) if isinstance(value, dict) and section != "effects" \
        else value
    (d / "maps.json").write_text(json.dumps(meta))
    tables = None
    with pytest.raises(ModelMapsError) as info:  # the model's reader (inside every FMU)
        tables = load_tables(d)
        tables.effects  # noqa: B018  (the effects section is read when used)
    assert str(d) in str(info.value) and "maps.json" in str(info.value) and message in str(info.value)
    if section != "effects":
        with pytest.raises(MapsError) as info:  # the package's reader: the same rule, every key required
            load_maps(d)
        assert str(d / "maps.json") in str(info.value) and message in str(info.value)


def test_maps_change_only_through_a_new_table(tmp_path):
    tables = load_tables(mf.write_maps(tmp_path / "maps", G_eddy_S=0.02))
    before = json.dumps(tables.meta)
    eddy = dataclasses.replace(tables.eddy, G_eddy_S=0.03, source="refit")
    new = tables.with_meta(eddy=eddy, effects={"heating": {"C_th_J_per_K": 5.0}})
    assert json.dumps(tables.meta) == before  # the original is untouched
    assert new.G_eddy_S == 0.03 and new.eddy.source == "refit" and new.effects.heating == {"C_th_J_per_K": 5.0}
    assert tables.G_eddy_S == 0.02 and not tables.effects.named
    assert new.coil == tables.coil and new.tables().keys() == tables.tables().keys()
    assert new.i_f_A(0.1, 1e-3) == tables.i_f_A(0.1, 1e-3) and new.hot is tables.hot  # the same lookups
    with pytest.raises(ModelMapsError, match=r"maps\.json coil\.turns must be a finite number, got 'x'"):
        tables.with_meta(coil=dict(tables.coil.as_dict(), turns="x"))
