"""Geometry reading and validation: every problem is reported by name."""

import copy
import tomllib

import pytest

from solenoid_fmu.errors import GeometryError
from solenoid_fmu.field.geometry import default_geometry_path, geometry_from_dict, load_geometry


@pytest.fixture
def ps45_dict():
    return tomllib.loads(default_geometry_path().read_text())


def test_ps45_loads_in_si():
    g = load_geometry()
    assert g.name == "PS45"
    assert g.coil.turns == 1500 and g.coil.max_current_A == 2.0
    assert g.stroke.min_m == pytest.approx(0.2e-3) and g.stroke.max_m == pytest.approx(3.5e-3)
    arm = g.region("armature")
    assert arm.moves and arm.polygon_at(1e-3)[0, 1] == pytest.approx(13e-3)
    assert g.coil_region.area_m2 == pytest.approx(10.5e-3 * 39e-3)
    assert len(g.sha256) == 64 and g.validate() == []


def _problems(d):
    with pytest.raises(GeometryError) as exc:
        geometry_from_dict(d, "case.toml")
    return exc.value.problems


def test_self_intersecting_polygon(ps45_dict):
    d = copy.deepcopy(ps45_dict)
    d["region"][2]["polygon"] = [[6.3, 20.0], [8.0, 44.0], [8.0, 20.0], [6.3, 44.0]]  # bow tie
    assert any("tube" in p and "self-intersecting" in p for p in _problems(d))


def test_open_polygon(ps45_dict):
    d = copy.deepcopy(ps45_dict)
    d["region"][2]["polygon"] = [[6.3, 20.0], [8.0, 20.0]]
    assert any("tube" in p and "open polygon" in p for p in _problems(d))


def test_overlapping_regions(ps45_dict):
    d = copy.deepcopy(ps45_dict)
    d["region"][4]["polygon"] = [[7.5, 2.5], [19.0, 2.5], [19.0, 41.5], [7.5, 41.5]]  # coil into the tube
    probs = _problems(d)
    assert any("'coil'" in p and "overlap" in p for p in probs)


def test_region_outside_air_box(ps45_dict):
    d = copy.deepcopy(ps45_dict)
    d["domain"]["r_max_mm"] = 20.0
    assert any("yoke" in p and "outside the air box" in p for p in _problems(d))


def test_moving_region_collides_within_stroke(ps45_dict):
    d = copy.deepcopy(ps45_dict)
    arm = next(r for r in d["region"] if r["name"] == "armature")
    arm["polygon"] = [[r, z - 0.5] for r, z in arm["polygon"]]  # at x = 0.2 mm it enters the pole
    probs = _problems(d)
    assert any("armature" in p and "collides with 'pole'" in p for p in probs)


def test_no_coil_and_bad_turns_reported_together(ps45_dict):
    d = copy.deepcopy(ps45_dict)
    d["coil"]["turns"] = 0
    d["coil"]["region"] = "winding"
    probs = _problems(d)
    assert any("turns must be > 0" in p for p in probs)
    assert any("'winding' is not defined" in p for p in probs)
    d.pop("coil")
    assert any("no [coil] table" in p for p in _problems(d))


def test_unknown_material_and_bad_file(tmp_path):
    f = tmp_path / "g.toml"
    f.write_text("this is = = not toml")
    with pytest.raises(GeometryError, match="not valid TOML"):
        load_geometry(f)
