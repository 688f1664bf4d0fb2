"""Randomized test protocols: campaigns as a rig other than ours would record them (for tests).

Our own rig (:func:`solenoid_fmu.rig.campaign_excitations`) always runs the same protocol. The
loop must work on campaigns from any rig that writes the recording format, so the tests draw the
protocol too. :func:`random_protocol` draws, from one seeded generator:

* sample rates from 500 Hz to 20 kHz (log-uniform, capped so that a recording holds at most
  ``max_samples`` samples; a protocol too long for that is run faster);
* flux recordings (2-4): triangles, raised-cosine sines or trapezoids, 1-5 cycles, peaks from
  30 % to 100 % of the coil's maximum current, rests before, between and after the cycles (at
  least one zero-current rest of 30 ms or more at the start or end, else the voltage offset of
  eq. 4 cannot be measured), one position or one per recording;
* eddy recordings (2-4 rates): the same shapes, fast (half-cycles of 4-80 ms);
* force-stroke recordings (2-3 currents): energized from the first sample (the coil at constant
  current before the carriage moves, an unrecorded lead-in, :attr:`Excitation.preroll_s`) or
  with the current ramped inside the recording; the carriage starts at one end, then the other, and moves
  there and back (the first recording always, so that friction shows a reversal) or one way;
  the voltage column is present or not;
* a current ramp and a voltage step, each present or not;
* per recording: a voltage-channel offset of up to +-20 mV, a current-channel delay of up to
  20 us, the columns in any order, optional header keys left out (``coil_resistance_ohm`` is
  always written: the coil heating can only be seen against the resistance measured before
  the run), file names that carry no order (random hex).

:func:`random_campaign` runs such a protocol on the truth (:class:`solenoid_fmu.rig.TruthModel`)
and writes it like ``solenoid-fmu rig`` does; ``truth.json`` holds the drawn protocol under
``derived.protocol``. Every draw comes from ``numpy.random.default_rng(seed)``, so a failing
seed reproduces.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from ..realtime import MapTables
from .campaign import RigTruth, run_excitations
from .daq import DataAcquisition
from .effects import Effects, Heating
from .errors import RigError
from .excitation import CampaignConfig, Excitation

__all__ = ["SHAPES", "random_campaign", "random_protocol"]

#: Waveform shapes of the cyclic excitations.
SHAPES = ("triangle", "sine", "trapezoid")
_OPTIONAL_HEADER = ("coil_temperature_C", "sample_rate_Hz", "notes")


def _loguniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _cycle(shape: str, peak: float, half_s: float, hold_s: float) -> tuple[list, list]:
    """Knots (times from the cycle start [s], values) of one unipolar cycle 0 -> peak -> 0."""
    if shape == "triangle":
        return [half_s, 2.0 * half_s], [peak, 0.0]
    if shape == "trapezoid":
        return [half_s, half_s + hold_s, 2.0 * half_s + hold_s], [peak, peak, 0.0]
    ph = np.linspace(0.0, 2.0 * math.pi, 25)[1:]  # raised cosine, 24 linear pieces per cycle
    return list(ph / (2.0 * math.pi) * 2.0 * half_s), list(0.5 * peak * (1.0 - np.cos(ph)))


def _cyclic(shape: str, peak: float, half_s: float, cycles: int, rest_before: float, rest_between: float,
            rest_after: float, hold_s: float) -> tuple[tuple, tuple]:
    """Reference knots of ``cycles`` cycles with rests; starts and ends at zero."""
    t, v = [0.0], [0.0]
    now = rest_before
    if rest_before > 0:
        t.append(now)
        v.append(0.0)
    for c in range(cycles):
        if c and rest_between > 0:
            now += rest_between
            t.append(now)
            v.append(0.0)
        dt, dv = _cycle(shape, peak, half_s, hold_s)
        t += [now + d for d in dt]
        v += dv
        now = t[-1]
    t.append(now + rest_after)
    v.append(0.0)
    return tuple(t), tuple(v)


def _rests(rng: np.random.Generator, lo: float, hi: float) -> tuple[float, float]:
    """Rest before and after [s]: each present or not, at least one of them >= 30 ms."""
    before = rng.uniform(lo, hi) if rng.random() < 0.8 else 0.0
    after = rng.uniform(lo, hi) if rng.random() < 0.8 else 0.0
    if max(before, after) < 0.03:
        before = rng.uniform(max(lo, 0.03), max(hi, 0.06))
    return before, after


def _sample_rate(rng: np.random.Generator, duration_s: float, max_samples: int, lo: float = 500.0,
                 hi: float = 20000.0) -> float:
    """A sample rate in [lo, hi] [Hz], lowered so that the recording holds <= ``max_samples``."""
    fs = _loguniform(rng, lo, hi)
    return float(round(max(min(fs, max_samples / duration_s), min(lo, 500.0))))


def _scaled(t: tuple, fs_min: float, max_samples: int) -> tuple[tuple, float]:
    """Knot times compressed so that the recording fits ``max_samples`` at ``fs_min``; the factor."""
    k = min(1.0, max_samples / (t[-1] * fs_min + 1.0))
    return tuple(x * k for x in t), k


def _channels(rng: np.random.Generator, voltage: bool, force: bool, position_column: bool) -> dict:
    """Per-recording channel details: offsets, delay, column order, header keys."""
    cols = ["time_s", "current_A"] + ["voltage_V"] * voltage + ["position_mm"] * position_column + \
        ["force_N"] * force
    order = tuple(cols[k] for k in rng.permutation(len(cols)))
    keys = ("coil_resistance_ohm",) + tuple(k for k in _OPTIONAL_HEADER if rng.random() < 0.6)
    return {"voltage_offset_V": float(rng.uniform(-0.02, 0.02)), "current_delay_s": float(rng.uniform(0.0, 20e-6)),
            "columns": order, "header_keys": keys, "with_voltage": voltage, "with_force": force,
            "position_column": position_column}


def _flux_like(rng, kind: str, n: int, x_fixed, i_max: float, max_samples: int, fast: bool) -> list[Excitation]:
    out = []
    shape = str(rng.choice(SHAPES))
    peaks = np.sort(rng.uniform(0.3, 1.0, n))[::-1] * i_max if not fast else \
        np.full(n, rng.uniform(0.3, 0.7) * i_max)
    halves = np.sort([_loguniform(rng, 0.004, 0.08) for _ in range(n)]) if fast else \
        [rng.uniform(0.15, 0.8) for _ in range(n)]
    for k in range(n):
        if rng.random() < 0.3:
            shape = str(rng.choice(SHAPES))
        cycles = int(rng.integers(1, 6))
        before, after = _rests(rng, 0.02, 0.4 if not fast else 0.3)
        between = rng.uniform(0.01, 0.2) if rng.random() < 0.3 else 0.0
        half = float(halves[k])
        hold = rng.uniform(0.1, 1.0) * half
        t, v = _cyclic(shape, float(peaks[k]), half, cycles, before, between, after, hold)
        t, scale = _scaled(t, 500.0, max_samples)
        half_s = half * scale
        fs = _sample_rate(rng, t[-1], max_samples, lo=max(500.0, 10.0 / half_s) if fast else 500.0)
        x = float(x_fixed[k])
        ch = _channels(rng, True, False, False)
        out.append(Excitation(
            f"{kind}_{k}", kind, "current", fs, t, v, (0.0,), (x,),
            notes=f"{shape}, peak {peaks[k]:.3g} A, {cycles} cycle(s), half-cycle {half * 1e3:.3g} ms", **ch))
    return out


def _force_strokes(rng, n: int, x_lo: float, x_hi: float, i_max: float, max_samples: int) -> list[Excitation]:
    out = []
    energized = rng.random() < 0.6
    first_high = rng.random() < 0.5
    for k in range(n):
        cur = float(rng.uniform(0.3, 1.0) * i_max)
        a, b = (x_hi, x_lo) if (k % 2 == 0) == first_high else (x_lo, x_hi)  # the carriage starts at both ends
        back = k == 0 or rng.random() < 0.75
        legs = [b, a] * int(rng.integers(1, 3)) if back else [b]
        speed = _loguniform(rng, 0.5e-3, 5e-3)
        dwell = float(rng.uniform(0.0, 0.3))
        move = abs(a - b) / speed
        total = len(legs) * (move + dwell) + 1.0
        if total * 500.0 > max_samples:  # faster carriage so that the stroke fits the sample budget
            speed *= total * 500.0 / max_samples
            move = abs(a - b) / speed
        if energized:
            start = float(rng.uniform(0.05, 0.3))
            pre = float(rng.uniform(0.05, 0.3))
        else:
            r0 = float(rng.uniform(0.05, 0.3))
            up = cur / rng.uniform(5.0, 20.0)
            start = r0 + up + float(rng.uniform(0.05, 0.3))
            pre = 0.0
        pos_t, pos = [0.0, start], [a, a]
        now = start
        for target in legs:
            now += move
            pos_t.append(now)
            pos.append(target)
            now += dwell
            if dwell > 0:
                pos_t.append(now)
                pos.append(target)
        end_motion = now + float(rng.uniform(0.05, 0.3))
        if energized:
            ref_t, ref_v = (0.0, end_motion), (cur, cur)
            end = end_motion
        else:
            down = end_motion + up
            end = down + float(rng.uniform(0.05, 0.3))
            ref_t, ref_v = (0.0, r0, r0 + up, end_motion, down, end), (0.0, 0.0, cur, cur, 0.0, 0.0)
        pos_t.append(end)
        pos.append(pos[-1])
        fs = _sample_rate(rng, end, max_samples, hi=5000.0)
        ch = _channels(rng, bool(rng.random() < 0.6), True, True)
        out.append(Excitation(
            f"force_stroke_{k}", "force_stroke", "current", fs, ref_t, ref_v, tuple(pos_t), tuple(pos),
            preroll_s=pre, notes=f"{cur:.3g} A {'throughout' if energized else 'ramped'}; "
                                 f"{a * 1e3:.3g} mm -> {b * 1e3:.3g} mm{' and back' if back else ''}", **ch))
    return out


def random_protocol(rng: np.random.Generator, *, x_range_m: tuple, max_current_A: float, R_ohm: float,
                    max_samples: int = 20000) -> list[Excitation]:
    """One randomized campaign protocol (see the module docstring), in a random order.

    Parameters
    ----------
    rng : numpy.random.Generator
        The only source of randomness.
    x_range_m : (float, float)
        Armature gaps the maps cover [m]; positions are drawn inside with 10 % margins.
    max_current_A : float
        The coil's maximum current [A]; peaks and holding currents are drawn up to it.
    R_ohm : float
        Coil resistance [ohm] (sets the voltage-step amplitude).
    max_samples : int
        Upper limit of samples per recording (bounds the test time).
    """
    if max_samples < 1000:
        raise RigError(f"max_samples must be >= 1000, got {max_samples}")
    x0, x1 = sorted(float(v) for v in x_range_m)
    span = x1 - x0
    if not span > 0:
        raise RigError(f"x_range_m must span a positive range, got {x_range_m}")
    x_lo, x_hi = x0 + 0.1 * span, x1 - 0.1 * span
    i_max = float(max_current_A)

    def positions(n):
        if rng.random() < 0.7:
            return np.full(n, rng.uniform(x0 + 0.2 * span, x1 - 0.2 * span))
        return rng.uniform(x0 + 0.2 * span, x1 - 0.2 * span, n)

    excs = _flux_like(rng, "flux", int(rng.integers(2, 5)), positions(4), i_max, max_samples, fast=False)
    excs += _flux_like(rng, "eddy", int(rng.integers(2, 5)), positions(4), i_max, max_samples, fast=True)
    excs += _force_strokes(rng, int(rng.integers(2, 4)), x_lo, x_hi, i_max, max_samples)
    if rng.random() < 0.7:
        peak = float(rng.uniform(0.5, 1.0) * i_max)
        up = peak / rng.uniform(5.0, 40.0)
        r0, r1 = _rests(rng, 0.02, 0.3)
        hold = float(rng.uniform(0.1, 0.5))
        t = (0.0, r0, r0 + up, r0 + up + hold, r0 + 2 * up + hold, r0 + 2 * up + hold + r1)
        v = (0.0, 0.0, peak, peak, 0.0, 0.0)
        if r0 == 0.0:  # no rest before: the ramp starts at t = 0
            t, v = t[1:], v[1:]
        if r1 == 0.0:
            t, v = t[:-1], v[:-1]
        excs.append(Excitation("ramp", "ramp", "current", _sample_rate(rng, t[-1], max_samples), t, v, (0.0,),
                               (float(positions(1)[0]),), notes=f"ramp to {peak:.3g} A",
                               **_channels(rng, True, True, False)))
    if rng.random() < 0.7:
        volts = float(rng.uniform(0.4, 1.0) * R_ohm * i_max)
        r0 = float(rng.uniform(0.02, 0.2))
        t1 = r0 + float(rng.uniform(0.15, 0.5))
        end = t1 + float(rng.uniform(0.1, 0.3))
        excs.append(Excitation("voltage_step", "voltage_step", "voltage",
                               _sample_rate(rng, end, max_samples, lo=1000.0),
                               (0.0, r0, r0, t1, t1, end), (0.0, 0.0, volts, volts, 0.0, 0.0), (0.0,),
                               (float(positions(1)[0]),), notes=f"voltage step to {volts:.3g} V",
                               **_channels(rng, True, True, False)))
    excs = [_within_budget(e, max_samples) for e in excs]
    return [excs[k] for k in rng.permutation(len(excs))]


def _within_budget(exc: Excitation, max_samples: int) -> Excitation:
    """``exc`` with at most ``max_samples`` samples: a lower sample rate (not below 500 Hz), then
    faster (all knot times scaled down)."""
    if exc.duration_s * exc.sample_rate_Hz + 1 <= max_samples:
        return exc
    fs = max(500.0, math.floor((max_samples - 2) / exc.duration_s))
    k = min(1.0, (max_samples - 2) / (fs * exc.duration_s))
    return dataclasses.replace(exc, sample_rate_Hz=float(fs), ref_t_s=tuple(t * k for t in exc.ref_t_s),
                               pos_t_s=tuple(t * k for t in exc.pos_t_s), preroll_s=exc.preroll_s * k)


#: Range of the coil's heat capacity [J/K] (log-uniform) the randomized campaigns draw when heating is named:
#: the winding (40-80 g of copper) and what of bobbin and iron follows it within seconds. With the
#: randomized protocols' recordings and pauses the coil then warms by a few kelvin over a campaign at rated
#: current and more at 2 A (issue 20; the 300 J/K default of :class:`~.effects.Heating`, coil and housing
#: together, gave 0.4-1.8 K).
RANDOM_C_TH_J_PER_K = (30.0, 100.0)
#: Range of the thermal resistance to ambient [K/W] (log-uniform): a 45 mm solenoid on a rig fixture.
RANDOM_R_TH_K_PER_W = (1.0, 3.0)


def random_heating(rng) -> Heating:
    """Coil heating of a randomized campaign: C_th and R_th log-uniform in :data:`RANDOM_C_TH_J_PER_K` and
    :data:`RANDOM_R_TH_K_PER_W` (time constant 30-300 s)."""
    c = float(np.exp(rng.uniform(*np.log(RANDOM_C_TH_J_PER_K))))
    r = float(np.exp(rng.uniform(*np.log(RANDOM_R_TH_K_PER_W))))
    return Heating(C_th_J_per_K=c, R_th_K_per_W=r)


def random_campaign(tables: MapTables, output_dir, effects: str | Effects = "", seed: int = 0, *,
                    max_samples: int = 20000, sensor_fault: bool = False, maps_dir=None) -> RigTruth:
    """Draw a protocol with ``seed``, run it on the truth and write the campaign to ``output_dir``.

    Parameters
    ----------
    tables : MapTables
        The true maps (positions, maximum current and resistance are taken from their metadata).
    output_dir : path-like
        Campaign directory (``recordings/<hex>.csv``, ``truth.json``).
    effects : str or Effects
        The truth's effects (names as for ``solenoid-fmu rig --effects``); sensor noise, offsets
        and quantization are always on. Named heating is drawn with the campaign (:func:`random_heating`,
        from ``seed``); an :class:`~.effects.Effects` object is taken as given.
    seed : int
        Seeds the protocol, the sensor noise and the fault.
    max_samples : int
        Upper limit of samples per recording.
    sensor_fault : bool
        A force-sensor calibration error (gain 1.04-1.08, offset +-0.3-1 N): a fault of the
        measurement, not an effect the model should take on.
    """
    rng = np.random.default_rng([seed, 0x5EED])
    if isinstance(effects, str):
        effects = Effects.from_names(effects)
        if effects.heating is not None:  # named, not given: the rig's coil draws its own (own stream)
            effects = dataclasses.replace(effects, heating=random_heating(np.random.default_rng([seed, 0x4EA7])))
    coil = tables.coil
    i_max = float(coil.max_current_A or 2.0)
    R = float(coil.resistance_ohm_20C or 10.0)
    x = tables.tables()["x_m"]
    excs = random_protocol(rng, x_range_m=(float(x[0]), float(x[-1])), max_current_A=i_max, R_ohm=R,
                           max_samples=max_samples)
    daq = effects.daq or DataAcquisition()
    f_max = float(np.max(np.abs(tables.tables()["force_N"])))
    # the channels' ranges as a careful operator sets them: 1.5 x what the solenoid can give
    fields = {f: getattr(daq, f) for f in daq.__dataclass_fields__}
    fields.update(force_range_N=max(daq.force_range_N, 1.5 * f_max), current_range_A=max(daq.current_range_A,
                                                                                          1.5 * i_max))
    if sensor_fault:
        fields.update(force_gain=float(rng.uniform(1.04, 1.08)),
                      force_offset_N=float(rng.choice([-1.0, 1.0]) * rng.uniform(0.3, 1.0)))
    daq = DataAcquisition(**fields)
    effects = Effects(hysteresis=effects.hysteresis, eddy=effects.eddy, heating=effects.heating,
                      friction=effects.friction, daq=daq)
    names = []
    for _ in excs:
        name = f"{rng.integers(0, 2**32):08x}.csv"
        while name in names:
            name = f"{rng.integers(0, 2**32):08x}.csv"
        names.append(name)
    cfg = CampaignConfig(tests=(), pause_s=float(rng.uniform(2.0, 60.0)))
    protocol = [{"file": f"recordings/{n}", "kind": e.kind, "sample_rate_Hz": e.sample_rate_Hz,
                 "preroll_s": e.preroll_s, "notes": e.notes, "columns": list(e.columns)}
                for n, e in zip(names, excs, strict=True)]
    return run_excitations(tables, Path(output_dir), excs, effects=effects, campaign=cfg, seed=seed,
                           file_names=names, maps_dir=maps_dir,
                           derived={"protocol": protocol, "sensor_fault": sensor_fault})
