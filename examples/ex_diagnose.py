r"""Trace an FMU's residual against recordings to the effect the model lacks (``sf.diagnose``).

Each candidate effect (hysteresis, frequency-dependent eddy currents, coil heating, friction,
sensor offset, the steel's B(H) itself) is a set of features of the measured signals; the
diagnosis ranks them by the residual share they explain on held-out recordings. Run::

    python examples/ex_diagnose.py FMU RECORDING.csv ...
"""

from __future__ import annotations

import sys

import solenoid_fmu as sf


def run(fmu, recordings) -> dict:
    """``verdict`` (an effect or ``"unexplained"``) and ``ranking`` [(effect, score)], best first."""
    d = sf.diagnose(fmu, recordings)
    return {"verdict": d.verdict, "ranking": [(c.effect, c.score) for c in d.ranking]}


if __name__ == "__main__":
    r = run(sys.argv[1], sys.argv[2:])
    for effect, score in r["ranking"]:
        print(f"{effect:<12} {score:.3f}")
    print(f"verdict: {r['verdict']}")
