"""The morphing mesh: conforming at every gap, no inversion, rigid armature, sliding along slants."""

import numpy as np
import pytest

from solenoid_fmu.field.geometry import load_geometry
from solenoid_fmu.field.mesh import build_mesh


@pytest.fixture(scope="module")
def ps45_mesh():
    g = load_geometry()
    return g, build_mesh(g)


def _areas(p, t):
    a, b, c = p[:, t[0]], p[:, t[1]], p[:, t[2]]
    return 0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))


@pytest.mark.parametrize("x_mm", [0.2, 0.5, 1.85, 2.8, 3.5])
def test_regions_conform_at_every_gap(ps45_mesh, x_mm):
    g, m = ps45_mesh
    p = m.points_at(x_mm * 1e-3)
    areas = _areas(p, m.t)
    assert areas.min() > 0
    for k, reg in enumerate(g.regions):
        assert areas[m.region == k].sum() == pytest.approx(reg.area_m2, rel=1e-9), reg.name
    box = g.domain.r_max_m * (g.domain.z_max_m - g.domain.z_min_m)
    assert areas.sum() == pytest.approx(box, rel=1e-12)


def test_armature_boundary_moves_and_fixed_corners_stay(ps45_mesh):
    g, m = ps45_mesh
    for reg in g.regions:
        for r, z in reg.polygon_at(m.x_ref_m):
            k = np.argmin((m.p_ref[0] - r) ** 2 + (m.p_ref[1] - z) ** 2)
            assert m.dz_dx[k] == pytest.approx(1.0 if reg.moves else 0.0, abs=1e-12) and m.dr_dx[k] == 0.0
    # vertices on the armature's front face (z = 12 mm + x) all move with it: the working gap
    front = np.abs(m.p_ref[1] - (12e-3 + m.x_ref_m)) < 1e-12
    assert front.sum() > 10 and np.allclose(m.dz_dx[front], 1.0, atol=1e-12)


def test_nodes_on_the_slanted_collar_stay_on_it(ps45_mesh):
    g, m = ps45_mesh
    (r0, z0), (r1, z1) = (8.0e-3, 12.0e-3), (6.6e-3, 16.0e-3)
    on = np.abs((m.p_ref[0] - r0) * (z1 - z0) - (m.p_ref[1] - z0) * (r1 - r0)) < 1e-12
    on &= (m.p_ref[1] > z0) & (m.p_ref[1] < z1)
    assert on.sum() >= 3
    for x in (0.2e-3, 3.5e-3):
        p = m.points_at(x)[:, on]
        cross = (p[0] - r0) * (z1 - z0) - (p[1] - z0) * (r1 - r0)
        assert np.abs(cross).max() < 1e-15


def test_mesh_size_knob_refines(ps45_mesh):
    g, m = ps45_mesh
    fine = build_mesh(g, mesh_size=0.5)
    assert fine.n_triangles > 1.7 * m.n_triangles
