"""Triangular mesh of the (r, z) half-plane that follows the armature without remeshing.

Choice: **one fixed-topology mesh, morphed**. The mesh is built once (Shewchuk's Triangle, quality
30 degrees) with the armature at a reference gap ``x_ref`` (the middle of the stroke), graded
towards the moving region's boundary, where the working and parasitic air gaps are. For any other
gap x every vertex moves by ``(x - x_ref) * (dr_dx, dz_dx)``:

- z follows one piecewise-linear map whose knots are the heights of all polygon vertices: the
  heights of fixed parts stay, the heights of the armature move with it. Horizontal lines stay
  horizontal and every vertex at a given height moves alike, so the thin parasitic gap between
  armature and pole tube is not sheared at all; the working gap is stretched uniformly. The
  armature's boundary moves rigidly, its interior is stretched piecewise (harmless: one material).
- r changes only next to slanted edges (PS45's control cone): each vertex keeps its relative
  position between the nearest non-horizontal edges left and right of it on its horizontal line.

The vertex positions are affine in x with a fixed connectivity: Psi and the force are smooth
functions of x with no remeshing noise, and the co-energy can be differentiated with respect to x
exactly on the discrete level (see :mod:`solenoid_fmu.field.fem`). The knots must keep their order over
the stroke (checked, MeshError otherwise), and elements never invert: signed areas are quadratic
in x, checked at both ends of the stroke and at their minimum.

The mesh-size knob ``mesh_size`` scales every target size: 1.0 (the default) gives ~0.2 mm at the
armature's boundary, growing by 0.3 per unit distance, at most 3 mm in steel and 12 mm in the far air
(with second-order elements; on PS45 the default is within 0.02 % in Psi and 0.05 % in F of a
mesh refined twice, i.e. mesh_size = 0.25).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import MeshError
from .geometry import Geometry

#: Finest mesh-size factor accepted. Each halving of it quadruples the unknowns (mesh_size 1: ~39 000, 2: 9 785);
#: below 0.2 a mesh passes a million unknowns and the direct solver's factor several GB of memory (at 1e-3 the
#: mesher alone grew to 10 GB): refused before meshing.
MIN_MESH_SIZE = 0.2
#: Base target sizes [m] for mesh_size = 1.
H_GAP_M = 0.20e-3
GROWTH = 0.30
H_STEEL_M = 3.0e-3
H_COIL_M = 4.0e-3
H_AIR_M = 12.0e-3

# segment markers
_VERTICAL_FIXED, _PINNED_FIXED, _MOVING, _BOX_PINNED, _BOX_SLIDING = 2, 3, 4, 5, 6


@dataclass(frozen=True, eq=False)
class MorphMesh:
    """A triangle mesh with a vertex velocity field for the armature position.

    Attributes
    ----------
    p_ref : ndarray, shape (2, nv)
        Vertex (r, z) coordinates [m] at the reference gap ``x_ref_m``.
    t : ndarray, shape (3, nt)
        Triangles (counter-clockwise vertex indices).
    dr_dx, dz_dx : ndarray, shape (nv,)
        Vertex velocity per unit armature displacement (dz_dx = 1 on the armature, 0 on fixed
        corners; dr_dx non-zero only next to slanted edges).
    region : ndarray, shape (nt,)
        Region index per triangle into ``region_names``; -1 for the air outside all polygons.
    region_names : tuple of str
    x_ref_m : float
    mesh_size : float
    """

    p_ref: np.ndarray
    t: np.ndarray
    dr_dx: np.ndarray
    dz_dx: np.ndarray
    region: np.ndarray
    region_names: tuple[str, ...]
    x_ref_m: float
    mesh_size: float

    def points_at(self, x_m: float) -> np.ndarray:
        """Vertex coordinates (2, nv) [m] for working gap ``x_m``."""
        p = self.p_ref.copy()
        p[0] += (x_m - self.x_ref_m) * self.dr_dx
        p[1] += (x_m - self.x_ref_m) * self.dz_dx
        return p

    def elements_of(self, *names: str) -> np.ndarray:
        """Boolean mask (nt,) of the triangles in the named regions (``"air"`` = outside all polygons)."""
        mask = np.zeros(self.t.shape[1], dtype=bool)
        for name in names:
            if name == "air":
                mask |= self.region < 0
            else:
                mask |= self.region == self.region_names.index(name)
        return mask

    @property
    def n_vertices(self) -> int:
        return self.p_ref.shape[1]

    @property
    def n_triangles(self) -> int:
        return self.t.shape[1]


def _pslg(geom: Geometry, x_ref: float):
    """Vertices, segments (with markers) and region seeds of the planar straight-line graph."""
    from shapely.geometry import Polygon  # loaded when a mesh is built, not on import

    d = geom.domain
    polys = []
    box = np.array([[0.0, d.z_min_m], [d.r_max_m, d.z_min_m], [d.r_max_m, d.z_max_m], [0.0, d.z_max_m]])
    polys.append((box, None))
    for reg in geom.regions:
        polys.append((reg.polygon_at(x_ref), reg))
    scale = 1e9  # snap to 1 nm to merge shared vertices
    key_to_idx: dict[tuple[int, int], int] = {}
    verts: list[np.ndarray] = []

    def vid(pt):
        key = (round(pt[0] * scale), round(pt[1] * scale))
        if key not in key_to_idx:
            key_to_idx[key] = len(verts)
            verts.append(np.array(pt, dtype=float))
        return key_to_idx[key]

    raw_segments = []
    for poly, reg in polys:
        ids = [vid(pt) for pt in poly]
        for a, b in zip(ids, ids[1:] + ids[:1], strict=True):
            if a == b:
                continue
            pa, pb = verts[a], verts[b]
            if reg is None:
                vertical = abs(pa[0] - pb[0]) < 1e-12
                mark = _BOX_SLIDING if vertical else _BOX_PINNED
            elif reg.moves:
                mark = _MOVING
            else:
                vertical = abs(pa[0] - pb[0]) < 1e-12
                fixed_src = reg.name == geom.coil.region or reg.ampere_turns != 0
                mark = _VERTICAL_FIXED if (vertical and not fixed_src) else _PINNED_FIXED
            raw_segments.append((a, b, mark))
    V = np.array(verts)
    # split segments at vertices lying on them (T-junctions between regions sharing part of an edge)
    segs: dict[tuple[int, int], int] = {}
    for a, b, mark in raw_segments:
        pa, pb = V[a], V[b]
        dvec = pb - pa
        L2 = dvec @ dvec
        rel = V - pa
        tpar = rel @ dvec / L2
        cross = rel[:, 0] * dvec[1] - rel[:, 1] * dvec[0]
        on = (np.abs(cross) / np.sqrt(L2) < 1e-10) & (tpar > 1e-9) & (tpar < 1 - 1e-9)
        inner = np.flatnonzero(on)
        chain = [a] + list(inner[np.argsort(tpar[inner])]) + [b]
        for u, v in zip(chain[:-1], chain[1:], strict=True):
            k = (min(u, v), max(u, v))
            # moving and pinned markers win over sliding ones when edges coincide
            segs[k] = max(segs.get(k, 0), mark) if mark != _VERTICAL_FIXED else segs.get(k, mark)
    S = np.array(list(segs.keys()), dtype=np.int32)
    M = np.array(list(segs.values()), dtype=np.int32)
    seeds = []
    for k, reg in enumerate(geom.regions):
        pt = Polygon(reg.polygon_at(x_ref)).representative_point()
        seeds.append([pt.x, pt.y, k + 1, 0.0])
    return V, S, M, np.array(seeds)


def _distance_to_polygon(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance (n,) from points (n, 2) to the boundary of a polygon (m, 2)."""
    a = poly
    b = np.roll(poly, -1, axis=0)
    ab = b - a
    ap = points[:, None, :] - a[None, :, :]
    t = np.clip(np.einsum("nmk,mk->nm", ap, ab) / np.einsum("mk,mk->m", ab, ab), 0, 1)
    proj = a[None] + t[..., None] * ab[None]
    return np.sqrt(((points[:, None, :] - proj) ** 2).sum(-1)).min(axis=1)


def build_mesh(geom: Geometry, mesh_size: float = 1.0, x_ref_m: float | None = None) -> MorphMesh:
    """Mesh a geometry for the whole stroke.

    Parameters
    ----------
    geom : Geometry
    mesh_size : float
        Scale of all target element sizes (1 = default accuracy, 0.5 = twice finer).
    x_ref_m : float, optional
        Reference gap of the mesh [m]; default the middle of the stroke.

    Returns
    -------
    MorphMesh
    """
    import triangle  # loaded when a mesh is built, not on import

    if not (isinstance(mesh_size, int | float) and math.isfinite(mesh_size) and mesh_size >= MIN_MESH_SIZE):
        raise MeshError(f"mesh_size must be a finite number >= {MIN_MESH_SIZE} (each halving quadruples the "
                        f"unknowns; below {MIN_MESH_SIZE} the mesh and its solver need several GB), got {mesh_size!r}")
    if x_ref_m is None:
        x_ref_m = 0.5 * (geom.stroke.min_m + geom.stroke.max_m)
    V, S, M, seeds = _pslg(geom, x_ref_m)
    s = mesh_size
    region_h = []
    for reg in geom.regions:
        if reg.material == "steel":
            region_h.append(H_STEEL_M * s)
        elif reg.name == geom.coil.region or reg.ampere_turns:
            region_h.append(H_COIL_M * s)
        else:
            region_h.append(H_AIR_M * s)
    seeds[:, 3] = 0.5 * np.array(region_h) ** 2  # area constraint per region (Triangle's 'a' per region)
    pslg = dict(vertices=V, segments=S, segment_markers=M, regions=seeds)
    mesh = triangle.triangulate(pslg, f"pq30Aa{0.5 * (H_AIR_M * s) ** 2:.6e}")
    moving_polys = [reg.polygon_at(x_ref_m) for reg in geom.moving]
    region_h_arr = np.array(region_h + [H_AIR_M * s])
    # graded refinement towards the moving boundary: two passes of per-triangle area constraints
    for _ in range(3):
        P, T = mesh["vertices"], mesh["triangles"]
        cen = P[T].mean(axis=1)
        dist = np.full(len(cen), np.inf)
        for poly in moving_polys:
            dist = np.minimum(dist, _distance_to_polygon(cen, poly))
        att = mesh["triangle_attributes"][:, 0].astype(int)
        hmax = region_h_arr[np.where(att > 0, att - 1, len(region_h))]
        h = np.minimum(H_GAP_M * s + GROWTH * dist, hmax)
        area_target = 0.5 * h**2
        e1 = P[T[:, 1]] - P[T[:, 0]]
        e2 = P[T[:, 2]] - P[T[:, 0]]
        area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
        if np.all(area <= 1.3 * area_target):
            break
        mesh["triangle_max_area"] = area_target
        mesh = triangle.triangulate(mesh, "rpq30Aa")
    P = mesh["vertices"].T.copy()
    T = mesh["triangles"].T.astype(np.int64).copy()
    region = mesh["triangle_attributes"][:, 0].astype(int) - 1
    dr_dx, dz_dx = _morph_velocity(geom, P, x_ref_m)
    mm = MorphMesh(
        p_ref=P,
        t=T,
        dr_dx=dr_dx,
        dz_dx=dz_dx,
        region=region,
        region_names=tuple(r.name for r in geom.regions),
        x_ref_m=float(x_ref_m),
        mesh_size=float(mesh_size),
    )
    _check_no_inversion(mm, geom.stroke.min_m, geom.stroke.max_m)
    return mm


def _morph_velocity(geom: Geometry, P: np.ndarray, x_ref: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertex velocity (dr/dx, dz/dx) per unit armature displacement (see the module docstring).

    z: piecewise-linear map through the knots = every vertex height of the fixed polygons and the
    air box (velocity 0) and of the moving polygons (velocity 1). r: each vertex keeps its relative
    position between the nearest non-horizontal edges left and right of it on its horizontal line
    (vertical edges do not move in r; slanted edges do, as their crossing height changes).
    """
    d = geom.domain
    fixed_z = {d.z_min_m, d.z_max_m}
    moving_z = set()
    edges = []  # (r0, z0, r1, z1, moves)
    box = [(0.0, d.z_min_m), (d.r_max_m, d.z_min_m), (d.r_max_m, d.z_max_m), (0.0, d.z_max_m)]
    polys = [(np.array(box), False)] + [(reg.polygon_at(x_ref), reg.moves) for reg in geom.regions]
    for poly, moves in polys:
        (moving_z if moves else fixed_z).update(np.round(poly[:, 1], 12).tolist())
        for a, b in zip(poly, np.roll(poly, -1, axis=0), strict=True):
            if abs(a[1] - b[1]) > 1e-12:
                edges.append((a[0], a[1], b[0], b[1], moves))
    both = fixed_z & moving_z
    if both:
        raise MeshError(
            f"a moving vertex shares the height z = {min(both) * 1e3:g} mm with a fixed one at the "
            "reference gap; the morph needs distinct heights"
        )
    knots = np.array(sorted(fixed_z | moving_z))
    vel = np.array([1.0 if k in moving_z else 0.0 for k in knots])
    # knots must keep their order over the whole stroke
    for lo_hi in (geom.stroke.min_m, geom.stroke.max_m):
        moved = knots + (lo_hi - x_ref) * vel
        if np.any(np.diff(moved) <= 0):
            k = int(np.argmax(np.diff(moved) <= 0))
            raise MeshError(
                f"at x = {lo_hi * 1e3:g} mm a moving edge height passes a fixed one near "
                f"z = {knots[k] * 1e3:g} mm; the morph cannot follow (split the stroke or the geometry)"
            )
    r, z = P
    dz_dx = np.interp(z, knots, vel)
    E = np.array(edges)
    r0, z0, r1, z1, mv = E.T
    zlo, zhi = np.minimum(z0, z1), np.maximum(z0, z1)
    slope = (r1 - r0) / (z1 - z0)  # dr/dz along each edge
    cross = (z[:, None] >= zlo[None] - 1e-12) & (z[:, None] <= zhi[None] + 1e-12)
    re = r0[None] + slope[None] * (z[:, None] - z0[None])  # edge radius at the vertex height
    # velocity of the edge crossing radius: fixed edge r_e(z'), moving edge r_e(z' - dx)
    dre = slope[None] * (dz_dx[:, None] - mv[None])
    big = 1e9
    left = np.where(cross & (re <= r[:, None] + 1e-12), re, -big)
    right = np.where(cross & (re >= r[:, None] - 1e-12), re, big)
    iL = np.argmax(left, axis=1)
    iR = np.argmin(right, axis=1)
    rows = np.arange(len(r))
    rL, rR = left[rows, iL], right[rows, iR]
    vL, vR = dre[rows, iL], dre[rows, iR]
    ok = (rL > -big / 2) & (rR < big / 2)
    span = np.where(ok & (rR - rL > 1e-12), rR - rL, 1.0)
    frac = np.where(ok & (rR - rL > 1e-12), (r - rL) / span, 0.0)
    dr_dx = np.where(ok, vL + frac * (vR - vL), 0.0)
    return dr_dx, dz_dx


def _signed_area(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    a, b, c = p[:, t[0]], p[:, t[1]], p[:, t[2]]
    return 0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))


def _check_no_inversion(mm: MorphMesh, x_lo: float, x_hi: float) -> None:
    """Raise MeshError if any triangle inverts (or degenerates) for a gap in [x_lo, x_hi]."""
    a_ref = _signed_area(mm.p_ref, mm.t)
    # signed area is quadratic in s = x - x_ref: check both ends and the vertex of the parabola
    s = np.array([x_lo, x_hi]) - mm.x_ref_m
    areas = [_signed_area(mm.points_at(mm.x_ref_m + si), mm.t) for si in s]
    a0 = a_ref
    a1 = _signed_area(mm.points_at(mm.x_ref_m + 1e-6), mm.t)
    am = _signed_area(mm.points_at(mm.x_ref_m - 1e-6), mm.t)
    c2 = (a1 + am - 2 * a0) / 2e-12
    c1 = (a1 - am) / 2e-6
    with np.errstate(divide="ignore", invalid="ignore"):
        s_star = np.where(c2 > 0, -c1 / (2 * c2), np.nan)
    inside = (s_star > s[0]) & (s_star < s[1])
    amin = np.minimum.reduce(areas)
    amin = np.where(inside, np.minimum(amin, a0 + c1 * s_star + c2 * s_star**2), amin)
    bad = amin <= 1e-3 * np.abs(a_ref)
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        c = mm.p_ref[:, mm.t[:, k]].mean(axis=1) * 1e3
        raise MeshError(
            f"the morphed mesh inverts {int(bad.sum())} triangle(s) within the stroke "
            f"(first near r = {c[0]:.3f} mm, z = {c[1]:.3f} mm); give the moving region more room "
            "or a different reference gap"
        )
