r"""Close the loop (``sf.improve``): add the effects the residual asks for, fit them, re-export.

Diagnose, add the best effect to the model, fit its parameters on the larger excitations, keep
it only if the error on the held-out recordings falls; repeat. Writes the improved FMU and returns
the errors before and after per recording and signal. Run::

    python examples/ex_improve.py FMU OUT_FMU RECORDING.csv ...
"""

from __future__ import annotations

import sys

import solenoid_fmu as sf


def run(fmu, recordings, out_fmu) -> dict:
    """``effects_added``, ``improved_fmu`` and, per signal, the summed RMS error ``before``/``after``."""
    res = sf.improve(fmu, recordings, out_fmu)
    totals: dict = {}
    for rec in res.recordings:
        for signal, e in rec["signals"].items():
            t = totals.setdefault(signal, {"before": 0.0, "after": 0.0})
            t["before"] += e["before"]
            t["after"] += e["after"]
    return {"effects_added": res.effects_added, "improved_fmu": str(res.improved_fmu), "totals": totals}


if __name__ == "__main__":
    r = run(sys.argv[1], sys.argv[3:], sys.argv[2])
    print(f"effects added: {', '.join(r['effects_added']) or 'none'}")
    for signal, t in r["totals"].items():
        print(f"{signal}: RMS error {t['before']:.4g} -> {t['after']:.4g}")
