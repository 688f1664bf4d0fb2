"""What the lot compares between units: named features of one unit's pipeline outputs and recordings (SI).

:func:`unit_features` reads a finished unit (its campaign folder and pipeline output folder) and returns
``{feature name: float}``; :data:`FEATURES` names and describes them. They are the quantities the steel,
the coil and the mechanics show themselves in, each measured or identified per unit:

* ``B_T_at_<H>``: the identified B(H) [T] at H = 1, 3, 10 kA/m (``material/material.csv``'s table, interpolated);
* ``R20_ohm``: the coil resistance at 20 degC [ohm]: the recordings' header ``coil_resistance_ohm``, corrected
  from the header's ``coil_temperature_C`` with copper's coefficient, median over the recordings; where headers
  have none, R at the start as the recordings' own data pin it (:func:`~solenoid_fmu.measure.headers_from_data`),
  taken at 20 degC without a ``coil_temperature_C``;
* ``psi_Wb_rated_<x>``, ``F_N_rated_<x>``: flux linkage [Wb] and force [N] of the identified maps at the rated
  current (the geometry's ``max_current_A``) at strokes 0.6 and 2.5 mm;
* ``friction_N``: half the force gap [N] between the closing and the opening pass of the ``force_stroke``
  recordings at equal position (model-free: Coulomb friction adds to the force one way, takes away the other).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..field import load_geometry, read_bh_csv
from ..maps import force_at, load_maps, psi_at
from ..measure import headers_from_data, read_unipolar
from ..realtime import COPPER_ALPHA_PER_K

__all__ = ["FEATURES", "FEATURE_H_A_PER_M", "FEATURE_STROKES_M", "friction_estimate_N", "unit_features"]

#: Field strengths [A/m] at which the identified B(H) is compared.
FEATURE_H_A_PER_M = (1e3, 3e3, 1e4)
#: Strokes [m] at which Psi and F at the rated current are compared.
FEATURE_STROKES_M = (0.6e-3, 2.5e-3)


def _h_label(H: float) -> str:
    return f"{H / 1e3:g}kA_per_m"


def _x_label(x: float) -> str:
    return f"{x * 1e3:g}mm".replace(".", "p")


#: Feature name -> description with unit (the columns of lot.csv, in order).
FEATURES = {
    **{f"B_T_at_{_h_label(H)}": f"identified B [T] at H = {H:g} A/m" for H in FEATURE_H_A_PER_M},
    "R20_ohm": "coil resistance at 20 degC [ohm] (recording headers)",
    **{f"psi_Wb_rated_{_x_label(x)}": f"Psi [Wb] at the rated current, x = {x * 1e3:g} mm" for x in FEATURE_STROKES_M},
    **{f"F_N_rated_{_x_label(x)}": f"F [N] at the rated current, x = {x * 1e3:g} mm" for x in FEATURE_STROKES_M},
    "friction_N": "half the closing/opening force gap of the force strokes [N]",
}


def friction_estimate_N(recordings) -> float:
    """Half the median force gap [N] between the closing and the opening pass at equal position.

    Only samples where the armature moves at over half its peak speed count; the gap is taken on a common
    position grid over the overlap of both passes (its outer 10 % left out). NaN when no ``force_stroke``
    recording passes both ways.
    """
    gaps = []
    for r in recordings:
        if r.kind != "force_stroke" or r.position_m is None or r.force_N is None:
            continue
        x, f, t = (np.asarray(a, dtype=float) for a in (r.position_m, r.force_N, r.time_s))
        v = np.gradient(x, t)
        moving = np.abs(v) > 0.5 * np.max(np.abs(v), initial=0.0)
        close, open_ = moving & (v < 0), moving & (v > 0)
        if close.sum() < 4 or open_.sum() < 4:
            continue
        lo = max(x[close].min(), x[open_].min())
        hi = min(x[close].max(), x[open_].max())
        if hi <= lo:
            continue
        grid = np.linspace(lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo), 25)
        oc, oo = np.argsort(x[close]), np.argsort(x[open_])
        fc = np.interp(grid, x[close][oc], f[close][oc])
        fo = np.interp(grid, x[open_][oo], f[open_][oo])
        gaps.append(float(np.median(np.abs(fc - fo))) / 2.0)
    return float(np.median(gaps)) if gaps else math.nan


def _r20_ohm(recordings) -> float:
    values = []
    for r in recordings:
        try:
            R = float(r.header["coil_resistance_ohm"])
        except (KeyError, ValueError):
            continue
        try:
            T = float(r.header.get("coil_temperature_C", 20.0))
        except ValueError:
            T = 20.0
        values.append(R / (1.0 + COPPER_ALPHA_PER_K * (T - 20.0)))
    return float(np.median(values)) if values else math.nan


def unit_features(recording_paths, out_dir, geometry=None) -> dict:
    """The features (:data:`FEATURES`) of one unit from its recordings and its pipeline output folder.

    Parameters
    ----------
    recording_paths : list of path-like
        The unit's recordings (those the pipeline read: ``summary.json["recordings"]``).
    out_dir : path-like
        The unit's pipeline output (``material/material.csv``, ``maps/``).
    geometry : Geometry or path, optional
        The solenoid (default: the packaged PS45): its rated current.

    Returns
    -------
    dict
        Feature name -> float (SI; NaN where the unit does not give it).
    """
    out = Path(out_dir)
    recs = read_unipolar(recording_paths)[0]  # a rig's negative current mirrored, bipolar ones left out
    if any(r.voltage_V is not None and r.coil_resistance_ohm is None for r in recs):  # optional in recordings.md
        recs = headers_from_data(recs).recordings
    H_tab, B_tab = read_bh_csv(out / "material" / "material.csv")  # the table as written, interpolated
    geom = geometry if hasattr(geometry, "coil") else load_geometry(geometry)
    maps = load_maps(out / "maps")
    i_rated = float(geom.coil.max_current_A)
    feats = {f"B_T_at_{_h_label(H)}": float(np.interp(H, H_tab, B_tab)) for H in FEATURE_H_A_PER_M}
    feats["R20_ohm"] = _r20_ohm(recs)
    for x in FEATURE_STROKES_M:
        feats[f"psi_Wb_rated_{_x_label(x)}"] = float(np.asarray(psi_at(maps, i_rated, x)).ravel()[0])
    for x in FEATURE_STROKES_M:
        feats[f"F_N_rated_{_x_label(x)}"] = float(np.asarray(force_at(maps, i_rated, x)).ravel()[0])
    feats["friction_N"] = friction_estimate_N(recs)
    return feats
