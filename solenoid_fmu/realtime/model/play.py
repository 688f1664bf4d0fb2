"""The play operator of the hysteresis effect, scalar form (no numpy in the step).

Part of the FMU payload (:mod:`solenoid_fmu.realtime.model`): the standard library only.
"""

from __future__ import annotations

import bisect


def play_step(plays: list, r: list, wts: list, gb: list, gg: list, b: float) -> float:
    """Advance the play operators to input ``b`` (in place) and return ``g(b) sum w (b - p)``.

    The inverse Prandtl-Ishlinskii operator of ``solenoid_fmu.realtime.hysteresis.PlayHysteresis``
    (same arithmetic, scalar form, no numpy).
    """
    acc = 0.0
    for k in range(len(r)):
        lo = b - r[k]
        hi = b + r[k]
        q = plays[k]
        if q < lo:
            q = lo
        elif q > hi:
            q = hi
        plays[k] = q
        acc += wts[k] * (b - q)
    if not gb:
        return acc
    if b <= gb[0]:
        g = gg[0]
    elif b >= gb[-1]:
        g = gg[-1]
    else:
        jj = bisect.bisect_right(gb, b) - 1
        g = gg[jj] + (b - gb[jj]) / (gb[jj + 1] - gb[jj]) * (gg[jj + 1] - gg[jj])
    return g * acc

