r"""Published soft-magnetic steels: Roschke's mu_r(B) parameter sets of the Modelica Standard Library.

Every soft-magnetic material record of the Modelica Standard Library's
``Modelica.Magnetic.FluxTubes.Material.SoftMagnetic`` package carries the five parameters of
Roschke's approximation ([Ro00] in the library's user's guide; the function ``mu_rApprox``)

.. math:: \mu_r(B) = 1 + \frac{\mu_i - 1 + c_a B_N}{1 + c_b B_N + B_N^n}, \qquad B_N = |B| / B_{\mu,max}

Source: modelica/ModelicaStandardLibrary, files
``Modelica/Magnetic/FluxTubes/Material/SoftMagnetic/{Steel,PureIron,CobaltIron,NickelIron}/*.mo``
(records ``Steel_9SMnPb28``, ``Steel_9SMn28K``, ``AISI_1008``, ``DC03``, ``X6Cr17``, ``VacoferS2``,
``Permenorm3601K3``; left out below: ``AISI_12L14``, ``DC01``, ``RFe80``, ``Vacoflux50``, ``MuMetall``) and
``.../SoftMagnetic/mu_rApprox.mo`` for the formula. The parameters below are copied from those
records (``mu_i``, ``B_myMax`` [T], ``c_a``, ``c_b``, ``n``).

Tabulation (:func:`roschke_table`), as for the shipped literature curve of 9SMnPb28: H = B / (mu0
mu_r(B)) at B = 0.05, 0.10, ... 2.30 T, with (0, 0) first; B(H) must rise (checked). The curve beyond
the table continues with slope mu0 (:mod:`solenoid_fmu.field.material`).

**Saturation cut.** The Roschke formula is a fit to data that end near 1.6-2 T; beyond them, for
several records, mu_r(B) falls so fast towards 1 that the differential permeability dB/dH drops
below mu0, i.e. the magnetization M = B/mu0 - H *decreases* with H, which no ferromagnet does
(and which :func:`~solenoid_fmu.field.material.check_bh_table` refuses: "saturation tends to mu0
from above"). The table therefore ends at the last grid point before the first chord whose
relative permeability is below 1; beyond it the curve continues with slope mu0 (constant
magnetization, the physical completion). Records cut this way (grid, 0.05 T): 9SMn28K at 1.95 T,
X6Cr17 at 2.25 T, VacoferS2 at 1.95 T, Permenorm3601K3 at 1.95 T (see :func:`roschke_table`; the
tests recompute it). 9SMnPb28 is not cut (its last chord, 2.25-2.30 T, has mu_r = 1.03), so
``steel_curve("9SMnPb28")`` is the shipped literature curve.

**Reproduced.** The table goes through the project's Newton-safe curve
(:func:`~solenoid_fmu.field.material.bh_curve_from_table`), whose slope is mu0 from the last table
point on; :func:`roschke_curve` refuses a table that curve misses by more than
:data:`MAX_TABLE_MISFIT` in H at any point.

**Left out** (the reason is checked by the tests):

- ``AISI_12L14``, ``DC01``, ``RFe80``, ``Vacoflux50``: the fit still has mu_r = 46 ... 300 at 2.30 T
  (chord permeability 7 ... 24 over the last step: it does not saturate within the grid, the formula
  is used far beyond its data), so the table
  ends on a steep slope that the Newton-safe curve, bound to slope mu0 after the last point, cannot
  follow: its knot permeabilities hit ``MU_R_MAX`` and it misses H by 20-250 % near 2.3 T (the
  curve's own table then fails the material checks when reloaded). Cutting them at some lower B
  would invent a saturation the records do not state.
- ``MuMetall`` (77 % NiFe, mu_i = 27300, B_myMax = 0.46 T): its permeability exceeds
the solver's bound ``MU_R_MAX`` = 1e5 from the first table point on (mu_r(0.05 T) = 1.0e5,
peak 2.1e5), so the material checks refuse it; it is a shielding alloy, not a solenoid steel.
The electric sheets (``ElectricSheet``, ``SSEE``, ``Macfadyen``, ``RawData``) are laminations for
AC machines, not solid solenoid parts, and are not included.

Note: DC03's record has mu_i = 0, so its formula gives mu_r(0) = 0; the table starts at 0.05 T
(mu_r = 751), so the curve's initial permeability is that chord's.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import MaterialError
from .material import MU_0, BHCurve, bh_curve_from_table

__all__ = [
    "EXCLUDED_STEELS",
    "MAX_TABLE_MISFIT",
    "STEELS",
    "RoschkeParameters",
    "roschke_curve",
    "roschke_mu_r",
    "roschke_table",
    "steel_curve",
    "steel_names",
]

#: Grid of the tabulation [T]: 0.05 T steps up to 2.30 T (the shipped literature table's grid).
B_STEP_T = 0.05
B_LAST_T = 2.30
#: Largest relative misfit in H between a table and its Newton-safe curve that :func:`roschke_curve` accepts.
MAX_TABLE_MISFIT = 0.03


@dataclasses.dataclass(frozen=True)
class RoschkeParameters:
    """One parameter set of Roschke's mu_r(B) approximation (a Modelica ``SoftMagnetic`` record).

    Attributes
    ----------
    mu_i : float
        Initial relative permeability at B = 0 (of the formula; 1 + (mu_i - 1) at B = 0).
    B_myMax_T : float
        Flux density at the maximum relative permeability [T] (normalizes B).
    c_a, c_b : float
        Coefficients of the approximation.
    n : float
        Exponent of the approximation.
    label : str
        Human-readable name (the record's description).
    record : str
        Where the parameters come from (Modelica class path, or "random" for drawn sets).
    """

    mu_i: float
    B_myMax_T: float
    c_a: float
    c_b: float
    n: float
    label: str = ""
    record: str = ""

    def __post_init__(self):
        for key in ("mu_i", "B_myMax_T", "c_a", "c_b", "n"):
            v = getattr(self, key)
            if not (isinstance(v, int | float) and np.isfinite(v)) or v < 0 or (key in ("B_myMax_T", "n") and v == 0):
                raise MaterialError(f"Roschke parameter {key} must be a finite number "
                                    f"{'> 0' if key in ('B_myMax_T', 'n') else '>= 0'}, got {v!r}")


_MSL = "Modelica.Magnetic.FluxTubes.Material.SoftMagnetic"

#: The published parameter sets that pass the material checks (after the saturation cut), by name.
STEELS: dict[str, RoschkeParameters] = {
    "9SMnPb28": RoschkeParameters(400, 1.488, 1200, 3, 12.5, "9SMnPb28 (1.0718)", f"{_MSL}.Steel.Steel_9SMnPb28"),
    "9SMn28K": RoschkeParameters(500, 1.036, 43414, 35.8, 14, "9SMn28K (1.0715)", f"{_MSL}.Steel.Steel_9SMn28K"),
    "AISI_1008": RoschkeParameters(200, 1.17, 8100, 2.59, 10, "AISI 1008 (1.0204)", f"{_MSL}.Steel.AISI_1008"),
    "DC03": RoschkeParameters(0, 1.05, 27790, 16, 10.4, "DC03 (1.0347, previously St3)", f"{_MSL}.Steel.DC03"),
    "X6Cr17": RoschkeParameters(274, 1.1, 970, 1.2, 8.3, "X6Cr17 (1.4016)", f"{_MSL}.Steel.X6Cr17"),
    "VacoferS2": RoschkeParameters(2666, 1.15, 187000, 4.24, 19, "VACOFER S2 (99.95% Fe)",
                                   f"{_MSL}.PureIron.VacoferS2"),
    "Permenorm3601K3": RoschkeParameters(3000, 0.67, 50000, 2.39, 9.3, "PERMENORM 3601 K3 (36% NiFe)",
                                         f"{_MSL}.NickelIron.Permenorm3601K3"),
}

_NOT_SATURATED = ("the Roschke fit does not saturate within 2.30 T (mu_r >> 1 at the last point), so the "
                  "Newton-safe curve (slope mu0 after the table) misses the table's H by far more than "
                  "MAX_TABLE_MISFIT near 2.3 T")

#: Published parameter sets left out, with the parameters and why (see the module docstring).
EXCLUDED_STEELS: dict[str, tuple[RoschkeParameters, str]] = {
    "AISI_12L14": (RoschkeParameters(10, 0.94, 5900, 4.19, 6.4, "AISI 12L14 (1.0718)", f"{_MSL}.Steel.AISI_12L14"),
                   _NOT_SATURATED),
    "DC01": (RoschkeParameters(5, 1.1, 6450, 3.65, 7.7, "DC01 (1.0330, previously St2)", f"{_MSL}.Steel.DC01"),
             _NOT_SATURATED),
    "RFe80": (RoschkeParameters(123, 1.27, 44410, 6.4, 10, "Hyperm 0 (RFe80)", f"{_MSL}.PureIron.RFe80"),
              _NOT_SATURATED),
    "Vacoflux50": (RoschkeParameters(3850, 1.75, 11790, 2.63, 15.02, "VACOFLUX 50 (50% CoFe)",
                                     f"{_MSL}.CobaltIron.Vacoflux50"), _NOT_SATURATED),
    "MuMetall": (
        RoschkeParameters(27300, 0.46, 1037500, 3.67, 10, "MUMETALL (77% NiFe)", f"{_MSL}.NickelIron.MuMetall"),
        "permeability above the solver's bound MU_R_MAX = 1e5 from 0.05 T on (a shielding alloy, not a "
        "solenoid steel)",
    ),
}


def roschke_mu_r(B_T, p: RoschkeParameters) -> np.ndarray:
    """Relative permeability mu_r(B) of Roschke's approximation (Modelica ``mu_rApprox``).

    Parameters
    ----------
    B_T : array-like
        Flux density [T] (the sign is ignored).
    p : RoschkeParameters

    Returns
    -------
    ndarray
        mu_r = 1 + (mu_i - 1 + c_a B_N) / (1 + c_b B_N + B_N^n), B_N = |B| / B_myMax.
    """
    BN = np.abs(np.asarray(B_T, dtype=float)) / p.B_myMax_T
    return 1.0 + (p.mu_i - 1.0 + p.c_a * BN) / (1.0 + p.c_b * BN + BN**p.n)


def roschke_table(p: RoschkeParameters, name: str = "material") -> tuple[np.ndarray, np.ndarray]:
    """The (H, B) table of a parameter set on the 0.05 T grid, with the saturation cut.

    Parameters
    ----------
    p : RoschkeParameters
    name : str
        Used in error messages.

    Returns
    -------
    H_A_per_m, B_T : ndarray, shape (n,)
        Starting at (0, 0); H = B / (mu0 mu_r(B)) at B = 0.05 ... 2.30 T, ending at the last grid
        point before the first chord whose relative permeability (dB/dH)/mu0 is below 1 (see the
        module docstring).

    Raises
    ------
    MaterialError
        Non-positive mu_r, or H not rising with B (naming B), or fewer than 3 points left by the cut.
    """
    B = B_STEP_T * np.arange(1, round(B_LAST_T / B_STEP_T) + 1)
    mu_r = roschke_mu_r(B, p)
    if np.any(mu_r <= 0):
        k = int(np.argmax(mu_r <= 0))
        raise MaterialError(f"{name}: Roschke mu_r = {mu_r[k]:.4g} <= 0 at B = {B[k]:.2f} T")
    H = np.concatenate([[0.0], B / (MU_0 * mu_r)])
    B = np.concatenate([[0.0], B])
    dH = np.diff(H)
    if np.any(dH <= 0):
        k = int(np.argmax(dH <= 0))
        raise MaterialError(f"{name}: H = B / (mu0 mu_r(B)) does not rise between B = {B[k]:.2f} and "
                            f"{B[k + 1]:.2f} T (B(H) would fall)")
    chord_mu_r = np.diff(B) / dH / MU_0
    below = np.flatnonzero(chord_mu_r < 1.0)
    end = int(below[0]) + 1 if below.size else len(B)
    if end < 3:
        raise MaterialError(f"{name}: the Roschke curve falls below mu0 already at B = {B[end]:.2f} T")
    return H[:end], B[:end]


def roschke_curve(p: RoschkeParameters, name: str | None = None) -> BHCurve:
    """The project's checked :class:`~solenoid_fmu.field.BHCurve` of a Roschke parameter set.

    Parameters
    ----------
    p : RoschkeParameters
    name : str, optional
        Curve name (default ``p.label``).

    Raises
    ------
    MaterialError
        When the table fails :func:`roschke_table` or the material checks (one inflection of the
        permeability, slopes between mu0 and ``MU_R_MAX`` mu0), or its curve misses it by more than
        :data:`MAX_TABLE_MISFIT` in H, naming the point.
    """
    name = name or p.label or "Roschke curve"
    H, B = roschke_table(p, name)
    curve = bh_curve_from_table(H, B, name=name)
    misfit = np.abs(curve.H_of_B(B[1:]) - H[1:]) / H[1:]
    k = int(np.argmax(misfit))
    if misfit[k] > MAX_TABLE_MISFIT:
        raise MaterialError(
            f"{name}: the Newton-safe curve misses the Roschke table by {misfit[k] * 100:.3g} % in H at "
            f"B = {B[k + 1]:.2f} T (H = {H[k + 1]:.6g} A/m; at most {MAX_TABLE_MISFIT * 100:g} % accepted): "
            f"the table does not end in saturation (chord mu_r = {(B[-1] - B[-2]) / (H[-1] - H[-2]) / MU_0:.3g} "
            "at its last point)"
        )
    return curve


def steel_names() -> list[str]:
    """Names of the published steels :func:`steel_curve` knows (keys of :data:`STEELS`)."""
    return list(STEELS)


def steel_curve(name: str) -> BHCurve:
    """The B(H) curve of a published steel (see :data:`STEELS` and the module docstring).

    Parameters
    ----------
    name : str
        A key of :data:`STEELS`, e.g. ``"9SMnPb28"``, ``"DC01"``, ``"X6Cr17"``.

    Raises
    ------
    MaterialError
        Unknown name (listing the known ones, and the reason for a left-out record).
    """
    if name in EXCLUDED_STEELS:
        raise MaterialError(f"steel {name!r} is left out: {EXCLUDED_STEELS[name][1]}")
    if name not in STEELS:
        raise MaterialError(f"unknown steel {name!r}; known: {', '.join(STEELS)}")
    return roschke_curve(STEELS[name], name=name)
