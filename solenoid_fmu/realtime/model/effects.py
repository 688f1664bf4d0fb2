"""The ``effects`` section of maps.json, checked and prepared for the step.

Part of the FMU payload (:mod:`solenoid_fmu.realtime.model`): numpy and the standard library only.
"""

from __future__ import annotations

import math

from .definitions import ModelMapsError
from .tables import MapTables


def effects_data(tables: MapTables) -> dict:
    """The ``effects`` section of maps.json, checked and prepared for the step (SI units).

    Keys (each optional): ``hysteresis`` {thresholds [Wb], weights [A/Wb], shape {b_nodes [Wb],
    g_nodes [-]} or null}, ``eddy_ladder`` {G_S [S], tau_s [s]}, ``heating`` {C_th_J_per_K,
    R_th_K_per_W, alpha_per_K}, ``friction`` {force_N, presliding_m}.
    """
    where = f"{tables.where}: maps.json effects"
    out = {}
    for name, data in tables.effects.items():  # the record: an object of known effects, each an object or null
        if data is None:
            continue
        try:
            if name == "hysteresis":
                r = [float(v) for v in data["thresholds"]]
                wts = [float(v) for v in data["weights"]]
                shape = data.get("shape") or {}
                gb = [float(v) for v in shape.get("b_nodes", ())]
                gg = [float(v) for v in shape.get("g_nodes", ())]
                ok = (len(r) == len(wts) >= 1 and all(v > 0 for v in r) and all(v >= 0 for v in wts)
                      and len(gb) == len(gg) and all(gb[k + 1] > gb[k] for k in range(len(gb) - 1))
                      and all(math.isfinite(v) for v in r + wts + gb + gg))
                if not ok:
                    raise ValueError("finite thresholds > 0 and weights >= 0 of equal length, finite increasing "
                                     "shape nodes and factors")
                out[name] = {"r": r, "w": wts, "gb": gb, "gg": gg, "thresholds": r}
            elif name == "eddy_ladder":
                G = [float(v) for v in data["G_S"]]
                tau = [float(v) for v in data["tau_s"]]
                if not (len(G) == len(tau) >= 1 and all(0 <= v < math.inf for v in G)
                        and all(0 < v < math.inf for v in tau)):
                    raise ValueError("finite G_S >= 0 and tau_s > 0 of equal length")
                out[name] = {"G_S": G, "tau_s": tau}
            else:
                vals = {k: float(v) for k, v in data.items()}
                if any(not math.isfinite(v) or v < 0 for v in vals.values()):
                    raise ValueError("values must be finite and >= 0")
                out[name] = vals
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelMapsError(f"{where}.{name}: {exc}") from None
    return out

