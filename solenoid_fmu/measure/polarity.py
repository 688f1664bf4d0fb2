"""The coil current's polarity: a rig wired the other way round records the same campaign with i < 0.

A solenoid without a permanent magnet does not care which way its current flows: the flux linkage is odd in the
current (``Psi(-i) = -Psi(i)``, and so the eq.-4 voltage ``U = R i + dPsi/dt`` is odd too), the force even. A
recording whose current is negative throughout (a shunt or a driver connected the other way round, a rig that
energizes with a negative supply) is therefore the same measurement as its mirror image ``i -> -i``, ``U -> -U``
(force, position and time as recorded), exactly: :func:`unipolar` takes it mirrored. The analyses of the
campaign (branches and commutation curve, holds, eddy triangles, resistance tracks) read excursions from zero
current up to a peak, so a **bipolar** recording (current of both signs: symmetric triangles, an AC
demagnetization recorded with it) is left out of them, with its file and the time of its first sign change said;
the real-time model itself is odd in the current and simulates such a recording as it is (``validate``).

The force has a sign of its own: ``recordings.md`` counts it positive when it pulls the armature towards the pole,
and a solenoid's magnetic force does nothing else. A force column that is negative while the coil is energized
(:func:`force_reversed`) was recorded with the opposite sign convention (a load cell mounted or wired the other way
round) and is taken negated, said like a mirrored current: left as it is, the identification fitted a curve 140 %
off the force points and flagged every recording as disagreeing.

Units: SI (A, V, N, s).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .conditioning import noise_std
from .format import Recording
from .reader import read_recording

__all__ = ["POLARITY_NOISE_SHARE", "current_sign", "force_reversed", "mirrored", "polarity_problem", "read_unipolar",
           "unipolar"]

#: An excursion of the current's other sign counts where it exceeds this share of the recording's largest one,
#: both taken as the 0.5 % / 99.5 % percentiles of the current (:data:`POLARITY_PERCENTILE`): below it, it is the
#: current sensor's offset and noise or a controller's undershoot at a return to zero. A bipolar protocol's
#: excursions are of one size (symmetric triangles, an AC demagnetization); a fast eddy triangle's undershoot
#: reached 5.7 % of its 2.1 A peak (``tests/test_robust_fem_maps.py``), white noise of 5 % of the peak 12 %.
POLARITY_NOISE_SHARE = 0.25
#: The percentile [%] (and 100 less it) the excursions of :data:`POLARITY_NOISE_SHARE` are read at: an undershoot
#: of a few samples does not count, an excursion over half a per cent of the recording does.
POLARITY_PERCENTILE = 0.5
#: Nor does an excursion within this many standard deviations of the current's white noise (a recording with no
#: current to speak of is positive).
NOISE_SIGMAS = 5.0
#: The header key a mirrored recording carries (its value says what was done).
MIRRORED_KEY = "polarity"
#: Samples whose |current| exceeds this share of the recording's largest are energized (:func:`force_reversed`).
ENERGIZED_SHARE = 0.1
#: A force column counts as reversed where its median over the energized samples lies below zero by more than this
#: many standard deviations of its white noise (friction and noise move single samples, not the median of a run
#: whose magnetic force pulls).
FORCE_NOISE_SIGMAS = 5.0
#: The header key a recording whose force was taken negated carries.
FORCE_SIGN_KEY = "force_sign"


def current_sign(rec: Recording) -> tuple[int, int]:
    """(+1 or -1: the sign of the recording's current, 0: bipolar or no current at all; the index of the first
    sample of the minority sign where bipolar, else -1). See :data:`POLARITY_NOISE_SHARE`, :data:`NOISE_SIGMAS`."""
    i = np.asarray(rec.current_A, dtype=float)
    lo, hi = np.percentile(i, [POLARITY_PERCENTILE, 100.0 - POLARITY_PERCENTILE])
    hi, lo = max(float(hi), 0.0), max(-float(lo), 0.0)
    big = max(hi, lo)
    if big <= 0.0:
        return 0, -1
    floor = max(POLARITY_NOISE_SHARE * big, NOISE_SIGMAS * noise_std(i))
    if lo <= floor:
        return 1, -1
    if hi <= floor:
        return -1, -1
    minority = -i if hi >= lo else i  # samples of the sign with the smaller excursion
    return 0, int(np.argmax(minority > floor))


def mirrored(rec: Recording) -> Recording:
    """``rec`` with its current and voltage negated (force, position, time and extra columns as recorded), and the
    header key ``polarity`` saying so."""
    header = dict(rec.header)
    header[MIRRORED_KEY] = "mirrored: recorded with negative current; current and voltage negated"
    return dataclasses.replace(rec, header=header, current_A=-np.asarray(rec.current_A),
                               voltage_V=None if rec.voltage_V is None else -np.asarray(rec.voltage_V))


def force_reversed(rec: Recording) -> float | None:
    """The median force [N] over the energized samples (:data:`ENERGIZED_SHARE`) where it is negative beyond the
    force's noise (:data:`FORCE_NOISE_SIGMAS`): the column was recorded with the opposite sign; else None (no force
    column, no energized sample, a force that pulls)."""
    if rec.force_N is None:
        return None
    i = np.abs(np.asarray(rec.current_A, dtype=float))
    on = i > ENERGIZED_SHARE * float(np.max(i, initial=0.0))
    if not on.any():
        return None
    f = np.asarray(rec.force_N, dtype=float)
    med = float(np.median(f[on]))
    return med if med < -FORCE_NOISE_SIGMAS * noise_std(f) and med < 0.0 else None


def polarity_problem(rec: Recording) -> str | None:
    """Why the analyses of one-signed excursions (eq.-4 branches, holds, tracks) cannot take ``rec`` as recorded, or
    None: bipolar (the time of its first sign change said), or negative throughout (take it :func:`mirrored`)."""
    sign, k = current_sign(rec)
    i = np.asarray(rec.current_A)
    if sign < 0:
        return (f"current negative throughout (down to {np.min(i):.4g} A): recorded with the opposite polarity; "
                "the commands that read a campaign take it mirrored (i -> -i, U -> -U)")
    if sign == 0 and k >= 0:
        return (f"bipolar current ({np.min(i):.4g} .. {np.max(i):.4g} A, the sign changes at t = "
                f"{float(rec.time_s[k]):.6g} s): the campaign's analyses take excursions of one sign from zero; "
                "record each sign as its own recording")
    return None


def unipolar(recs: list) -> tuple[list, list[str], list[str]]:
    """(the recordings with a positive current: those recorded with a negative one mirrored, :func:`mirrored`, and
    a reversed force column negated, :func:`force_reversed`; what was mirrored or negated, one line each; what was
    left out, bipolar recordings, one reason each). The order of ``recs`` is kept; a recording without current (all
    zero) is kept as it is. Idempotent."""
    keep, turned, left = [], [], []
    for rec in recs:
        sign, _ = current_sign(rec)
        if sign < 0:
            turned.append(f"{rec.label()}: current negative throughout (down to {np.min(rec.current_A):.4g} A): "
                          "taken mirrored (i -> -i, U -> -U; flux odd, force even in the current)")
            rec = mirrored(rec)
        elif (why := polarity_problem(rec)) is not None:
            left.append(f"{rec.label()}: {why}")
            continue
        if (med := force_reversed(rec)) is not None:
            turned.append(f"{rec.label()}: force negative while the coil is energized (median {med:.4g} N; the "
                          "format counts a pull towards the pole positive): taken negated")
            header = {**rec.header, FORCE_SIGN_KEY: "negated: recorded with the opposite sign convention"}
            rec = dataclasses.replace(rec, header=header, force_N=-np.asarray(rec.force_N))
        keep.append(rec)
    return keep, turned, left


def read_unipolar(items) -> tuple[list, list[str], list[str]]:
    """:func:`unipolar` of recordings given as paths (read, :func:`~.reader.read_recording`) or :class:`Recording`."""
    return unipolar([r if isinstance(r, Recording) else read_recording(r) for r in items])
