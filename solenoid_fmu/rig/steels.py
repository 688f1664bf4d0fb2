"""Randomized soft-magnetic steels for tests: Roschke parameter sets drawn around the published ones.

:func:`random_steel` draws the five parameters of Roschke's mu_r(B) approximation (the form of the
Modelica FluxTubes material records, :mod:`solenoid_fmu.field.steels`) from one seeded generator:

* ``mu_i`` (initial relative permeability): log-uniform in [100, 2000];
* ``B_myMax`` (flux density of the peak permeability): uniform in [1.0, 1.8] T;
* ``c_a``: log-uniform in [900, 2e5] (published: 970 for X6Cr17 ... 187000 for VACOFER S2);
* ``c_b``: log-uniform in [1, 40] (published: 1.2 ... 35.8);
* ``n``: uniform in [6, 20] (published: 6.4 ... 19).

A draw is tabulated and checked exactly like a published record (:func:`solenoid_fmu.field.roschke_curve`:
B(H) rising, one inflection of the permeability, slopes between mu0 and ``MU_R_MAX`` mu0, a table
that ends in saturation so that the Newton-safe curve follows it); draws refused there are
rejected and drawn again, so every returned curve is one the FEM accepts. Same generator state,
same steel.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import MaterialError
from ..field import BHCurve, RoschkeParameters, roschke_curve
from .errors import RigError

__all__ = ["MAX_DRAWS", "ROSCHKE_RANGES", "random_steel", "random_steel_parameters"]

#: Ranges of the drawn parameters: (low, high, "log" or "lin").
ROSCHKE_RANGES = {
    "mu_i": (100.0, 2000.0, "log"),
    "B_myMax_T": (1.0, 1.8, "lin"),
    "c_a": (900.0, 2.0e5, "log"),
    "c_b": (1.0, 40.0, "log"),
    "n": (6.0, 20.0, "lin"),
}
#: Draws tried before giving up (a healthy generator needs a handful).
MAX_DRAWS = 1000


def _draw(rng: np.random.Generator, lo: float, hi: float, scale: str) -> float:
    if scale == "log":
        return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
    return float(rng.uniform(lo, hi))


def random_steel_parameters(rng: np.random.Generator, name: str = "random steel") -> RoschkeParameters:
    """Draw Roschke parameters (in :data:`ROSCHKE_RANGES`) until their curve passes the material checks.

    Parameters
    ----------
    rng : numpy.random.Generator
        The generator (``numpy.random.default_rng(seed)``); advanced by the draws.
    name : str
        Label of the parameter set.

    Returns
    -------
    RoschkeParameters
        With ``record = "random"``.

    Raises
    ------
    RigError
        No acceptable draw in :data:`MAX_DRAWS` tries, or ``rng`` is not a numpy Generator.
    """
    if not isinstance(rng, np.random.Generator):
        raise RigError(f"rng must be a numpy.random.Generator (numpy.random.default_rng(seed)), got {rng!r}")
    last = ""
    for _ in range(MAX_DRAWS):
        values = {key: _draw(rng, *spec) for key, spec in ROSCHKE_RANGES.items()}
        p = RoschkeParameters(**values, label=name, record="random")
        try:
            roschke_curve(p, name)
        except MaterialError as exc:
            last = str(exc)
            continue
        return p
    raise RigError(f"no random steel passed the material checks in {MAX_DRAWS} draws; last refusal: {last}")


def random_steel(rng: np.random.Generator, name: str = "random steel") -> BHCurve:
    """A random, physically plausible steel's B(H) curve (see the module docstring).

    Parameters
    ----------
    rng : numpy.random.Generator
        The generator; the same state gives the same steel.
    name : str
        Name of the curve.

    Returns
    -------
    BHCurve
        The checked, Newton-safe curve of :func:`random_steel_parameters`' draw.
    """
    return roschke_curve(random_steel_parameters(rng, name), name)
