"""Per-step cost of the hysteresis models, for the benchmark table.

``python -m solenoid_fmu.realtime.hysteresis_cost`` prints it.
"""

from __future__ import annotations

import time

import numpy as np

from .hysteresis import PlayHysteresis
from .preisach import PreisachHysteresis

__all__ = ["step_cost_s"]


def step_cost_s(n_plays: int = 24, n_steps: int = 20000) -> dict:
    """Measured wall time per ``step`` call of each model (seconds), for the benchmark table.

    Drives each model with a triangular input of ``n_steps`` samples and returns
    ``{"play": s_per_step, "preisach": s_per_step}``.
    """
    b = 1.5 * np.sin(np.linspace(0.0, 12.0 * np.pi, n_steps))
    play = PlayHysteresis(np.linspace(0.05, 1.5, n_plays), np.full(n_plays, 10.0))
    pre = PreisachHysteresis()
    out = {}
    for name, model in (("play", play), ("preisach", pre)):
        step = model.step
        t0 = time.perf_counter()
        for v in b.tolist():
            step(v)
        out[name] = (time.perf_counter() - t0) / n_steps
    return out


if __name__ == "__main__":
    cost = step_cost_s()
    print(f"PlayHysteresis.step (24 plays):      {cost['play'] * 1e6:7.2f} us per step")
    print(f"PreisachHysteresis.step (Everett):  {cost['preisach'] * 1e6:7.2f} us per step")
