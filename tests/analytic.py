"""Analytic reference solutions and test geometries for the FEM checks (SI units)."""

from __future__ import annotations

import numpy as np
from scipy.special import ellipe, ellipk

from solenoid_fmu.field.geometry import geometry_from_dict

MU_0 = 4e-7 * np.pi


def rect(r0, r1, z0, z1):
    """A rectangle polygon in mm."""
    return [[r0, z0], [r1, z0], [r1, z1], [r0, z1]]


def long_solenoid_geometry(rc=5.0, r1=6.0, r2=9.0, length=2.0, turns=20.0):
    """Axial slice of an infinitely long coil with a steel core (mm); natural top/bottom/outer."""
    return geometry_from_dict(
        {
            "name": "long-solenoid",
            "units": "mm",
            "stroke": {"min_mm": 0.0, "max_mm": 1.0},
            "coil": {"region": "coil", "turns": turns, "resistance_ohm_20C": 1.0, "max_current_A": 1.0},
            "domain": {"r_max_mm": r2 + 2.0, "z_min_mm": 0.0, "z_max_mm": length,
                       "natural": ["outer", "top", "bottom"]},
            "region": [
                {"name": "core", "material": "steel", "polygon": rect(0.0, rc, 0.0, length)},
                {"name": "coil", "material": "copper", "polygon": rect(r1, r2, 0.0, length)},
            ],
        }
    )


def long_solenoid_psi(curve, i_A, rc, r1, r2, length, turns):
    """Exact flux linkage [Wb] of the infinitely long coil slice (all lengths in m).

    H = H0 = (turns/length) i inside r1, falling linearly to 0 across the winding; the core carries
    B(H0) from the curve, the air mu0 H0.
    """
    H0 = turns / length * i_A
    phi_r1 = np.pi * rc**2 * float(curve.B_of_H(H0)) + np.pi * (r1**2 - rc**2) * MU_0 * H0
    # in the winding: Phi(r) = Phi(r1) + 2 pi mu0 int_r1^r r' H0 (r2 - r')/(r2 - r1) dr'
    x, w = np.polynomial.legendre.leggauss(40)
    r = 0.5 * (r2 - r1) * x + 0.5 * (r1 + r2)

    def phi(rr):
        s = 0.5 * (rr - r1) * x + 0.5 * (rr + r1)
        return phi_r1 + 2 * np.pi * MU_0 * H0 * 0.5 * (rr - r1) * np.sum(w * s * (r2 - s) / (r2 - r1))

    mean_phi = 0.5 * np.sum(w * np.array([phi(ri) for ri in r]))
    return turns * mean_phi, phi_r1


def air_coil_geometry(a=10.0, length=20.0, thickness=0.04, turns=100.0, box=300.0):
    """A thin single-layer air-core coil of mean radius a and given length (mm)."""
    return geometry_from_dict(
        {
            "name": "air-coil",
            "units": "mm",
            "stroke": {"min_mm": 0.0, "max_mm": 1.0},
            "coil": {"region": "coil", "turns": turns, "resistance_ohm_20C": 1.0, "max_current_A": 1.0},
            "domain": {"r_max_mm": box, "z_min_mm": -box, "z_max_mm": box},
            "region": [
                {"name": "coil", "material": "copper",
                 "polygon": rect(a - thickness / 2, a + thickness / 2, -length / 2, length / 2)},
            ],
        }
    )


def nagaoka_inductance(a_m, length_m, turns, k_nagaoka):
    """L = K_N mu0 pi a^2 N^2 / l of a single-layer coil [H]."""
    return k_nagaoka * MU_0 * np.pi * a_m**2 * turns**2 / length_m


def filament_mutual(a, b, d):
    """Mutual inductance [H] of two coaxial circular filaments, radii a, b, axial distance d [m]."""
    m = 4 * a * b / ((a + b) ** 2 + d**2)
    k = np.sqrt(m)
    return MU_0 * np.sqrt(a * b) * ((2 / k - k) * ellipk(m) - 2 / k * ellipe(m))


def coil_coil_force(c1, c2, at1, at2, n=16):
    """Axial force [N] on coil 2 (+z) between two coaxial rectangular coils in air.

    c1, c2 = (r0, r1, z0, z1) in m; at1, at2 their ampere-turns [A]. The filament force
    I1 I2 dM/dz is integrated over both cross-sections with Gauss-Legendre points; dM/dz by a
    central difference of the elliptic-integral mutual inductance.
    """
    x, w = np.polynomial.legendre.leggauss(n)

    def pts(c):
        r = 0.5 * (c[1] - c[0]) * x + 0.5 * (c[0] + c[1])
        z = 0.5 * (c[3] - c[2]) * x + 0.5 * (c[2] + c[3])
        R, Z = np.meshgrid(r, z, indexing="ij")
        W = np.outer(w, w) * 0.25  # weights for the mean over the rectangle
        return R.ravel(), Z.ravel(), W.ravel()

    r1, z1, w1 = pts(c1)
    r2, z2, w2 = pts(c2)
    A = r1[:, None]
    B = r2[None, :]
    D = z2[None, :] - z1[:, None]
    h = 1e-7
    dM = (filament_mutual(A, B, D + h) - filament_mutual(A, B, D - h)) / (2 * h)
    return at1 * at2 * np.sum(w1[:, None] * w2[None, :] * dM)


def two_coil_geometry(c1_mm, c2_mm, turns1, at2, box=150.0):
    """Fixed coil 1 (the excitation coil) and moving coil 2 with fixed ampere-turns (mm)."""
    return geometry_from_dict(
        {
            "name": "two-coils",
            "units": "mm",
            "stroke": {"min_mm": 0.0, "max_mm": 2.0},
            "coil": {"region": "coil", "turns": turns1, "resistance_ohm_20C": 1.0, "max_current_A": 1.0},
            "domain": {"r_max_mm": box, "z_min_mm": -box, "z_max_mm": box},
            "region": [
                {"name": "coil", "material": "copper", "polygon": rect(*c1_mm)},
                {"name": "coil2", "material": "copper", "polygon": rect(*c2_mm), "moves": True,
                 "ampere_turns": at2},
            ],
        }
    )
