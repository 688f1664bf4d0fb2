"""The lot's outlier rule: robust z-scores by median and MAD, per named feature.

For a feature v over the units that finished, z = 0.6745 (v - median) / MAD' with
MAD' = max(MAD, floor), MAD the median absolute deviation from the median (Iglewicz & Hoaglin 1993; 0.6745 makes
z a standard normal score for normal data). A unit stands out when |z| > :data:`Z_THRESHOLD` for any feature.

The threshold is 5, not Iglewicz & Hoaglin's 3.5 for normal data: a lot's in-spec units are not only spread
by the batch (~1 % in B) but shifted by effects the identification does not fully separate (coil heating moves
the identified B(H) and the maps by up to ~2.5 %, measured on the test lot), while the faults worth a look are
10 % and more off. The floor (:data:`MAD_FLOOR_REL` of |median|, at least :data:`MAD_FLOOR_ABS` for the
friction) keeps a lot whose units agree closer than the identification resolves from flagging noise: with
it, a unit must be more than 5 / 0.6745 x 0.5 % = 3.7 % off the median to stand out, whatever the lot's spread.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["MAD_FLOOR_ABS", "MAD_FLOOR_REL", "RULE", "Z_THRESHOLD", "robust_z", "stand_out"]

#: |z| above this stands out (module docstring: why 5).
Z_THRESHOLD = 5.0
#: Floor of the MAD relative to |median| (the resolution of an identified or measured quantity).
MAD_FLOOR_REL = 0.005
#: Absolute floors of the MAD per feature (features near zero), in the feature's unit.
MAD_FLOOR_ABS = {"friction_N": 0.1}
#: The rule in words (lot.html, README).
RULE = (f"robust z = 0.6745 (v - median) / max(MAD, floor) per feature over the units that finished, MAD the "
        f"median absolute deviation, floor {MAD_FLOOR_REL * 100:g} % of |median| (friction: "
        f"{MAD_FLOOR_ABS['friction_N']:g} N); a unit stands out when |z| > {Z_THRESHOLD:g} for any feature")


def robust_z(values, floor: float = 0.0) -> np.ndarray:
    """Robust z-scores of ``values`` (NaN stays NaN); ``floor`` bounds the MAD from below."""
    v = np.asarray(values, dtype=float)
    ok = np.isfinite(v)
    z = np.full(v.shape, math.nan)
    if not ok.any():
        return z
    med = float(np.median(v[ok]))
    mad = max(float(np.median(np.abs(v[ok] - med))), floor, MAD_FLOOR_REL * abs(med), 1e-300)
    z[ok] = 0.6745 * (v[ok] - med) / mad
    return z


def stand_out(rows: list[dict], features) -> dict:
    """Robust z of every feature for every row, and which rows stand out.

    Parameters
    ----------
    rows : list of dict
        One per unit: ``unit`` and the features (float or missing).
    features : iterable of str

    Returns
    -------
    dict
        unit -> ``{"z": {feature: z}, "flagged_by": [features with |z| > threshold]}``.
    """
    out = {r["unit"]: {"z": {}, "flagged_by": []} for r in rows}
    for f in features:
        z = robust_z([r.get(f, math.nan) for r in rows], MAD_FLOOR_ABS.get(f, 0.0))
        for r, zk in zip(rows, z, strict=True):
            out[r["unit"]]["z"][f] = float(zk)
            if math.isfinite(zk) and abs(zk) > Z_THRESHOLD:
                out[r["unit"]]["flagged_by"].append(f)
    return out
