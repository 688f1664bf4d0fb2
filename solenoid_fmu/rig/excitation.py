"""What the rig drives and samples: one :class:`Excitation` per recording, and the paper's campaign.

:class:`CampaignConfig` holds every number of the test campaign (paper section 3);
:func:`campaign_excitations` turns it into the excitations, in order: flux triangles, force-stroke
sweeps, a current ramp, eddy triangles and a voltage step.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .errors import RigError

__all__ = ["CampaignConfig", "Excitation", "campaign_excitations"]


@dataclass(frozen=True)
class Excitation:
    """One test of the campaign: what the rig drives and samples.

    Parameters
    ----------
    name : str
        File stem of the recording.
    kind : str
        Recording kind (``flux``, ``force_stroke``, ``ramp``, ``eddy``, ``voltage_step``).
    mode : {"current", "voltage"}
        Amplifier mode: the reference is a current [A] or a voltage [V].
    sample_rate_Hz : float
        Sample rate of the data acquisition [Hz].
    ref_t_s, ref_values : tuple of float
        Piecewise-linear reference: knots in time [s] and values [A] or [V].
    pos_t_s, pos_m : tuple of float
        Piecewise-linear armature position (working gap) [s], [m]; one knot for a fixed stroke.
    with_voltage, with_force, position_column : bool
        Which channels the file holds (``position_column``: a ``position_mm`` column instead of
        the header value).
    notes : str
        The recording's ``notes`` header.
    preroll_s : float
        Unrecorded lead-in [s]: the truth ramps the reference from zero to its first value over the
        first half of ``preroll_s`` and holds it, and recording starts after it, so the file begins
        energized (a force-stroke bench at constant current before the carriage moves). Rounded to
        whole sample periods.
    voltage_offset_V : float
        Offset of this recording's voltage channel [V] on top of the DAQ's.
    current_delay_s : float
        Delay of the current channel against the voltage channel [s] (the current samples are
        the true current at ``t - current_delay_s``).
    columns : tuple of str
        Column order of the file (a permutation of the columns it holds); empty: the default order.
    header_keys : tuple of str, optional
        Optional header keys written (``coil_resistance_ohm``, ``coil_temperature_C``,
        ``sample_rate_Hz``, ``notes``); None: all.
    """

    name: str
    kind: str
    mode: str
    sample_rate_Hz: float
    ref_t_s: tuple
    ref_values: tuple
    pos_t_s: tuple
    pos_m: tuple
    with_voltage: bool = True
    with_force: bool = False
    position_column: bool = False
    notes: str = ""
    preroll_s: float = 0.0
    voltage_offset_V: float = 0.0
    current_delay_s: float = 0.0
    columns: tuple = ()
    header_keys: tuple | None = None

    @property
    def duration_s(self) -> float:
        """Length of the recording [s]."""
        return float(self.ref_t_s[-1])

    def times_s(self) -> np.ndarray:
        """Sample times [s], ``k / f_s`` up to the duration."""
        n = int(math.floor(self.duration_s * self.sample_rate_Hz + 1e-9)) + 1
        return np.arange(n) / self.sample_rate_Hz

    def reference(self, t_s):
        """Reference current [A] or voltage [V] at ``t_s``."""
        return np.interp(t_s, self.ref_t_s, self.ref_values)

    def position_m(self, t_s):
        """Armature working gap [m] at ``t_s``."""
        return np.interp(t_s, self.pos_t_s, self.pos_m) if len(self.pos_m) > 1 else \
            np.full(np.shape(t_s), self.pos_m[0])


@dataclass(frozen=True)
class CampaignConfig:
    """The test campaign (paper section 3); every number can be changed.

    Times [s], currents [A], rates [A/s], positions [m], sample rates [Hz]. ``tests`` selects
    the kinds to run, in order.
    """

    solenoid: str = "PS45"
    tests: tuple = ("flux", "force_stroke", "ramp", "eddy", "voltage_step")
    rest_start_s: float = 0.3
    rest_end_s: float = 0.5
    pause_s: float = 60.0
    # flux triangles
    flux_peaks_A: tuple = (0.5, 1.0, 1.5, 2.0)
    flux_rate_A_per_s: float = 1.0
    flux_cycles: int = 2
    flux_position_m: float = 1.5e-3
    flux_sample_rate_Hz: float = 1000.0
    # force-stroke sweeps
    stroke_currents_A: tuple = (0.5, 1.0, 1.5, 2.0)
    stroke_from_m: float = 2.8e-3
    stroke_to_m: float = 0.5e-3
    stroke_speed_m_per_s: float = 0.5e-3
    stroke_dwell_s: float = 0.5
    stroke_current_rate_A_per_s: float = 10.0
    stroke_sample_rate_Hz: float = 200.0
    # current ramp with force
    ramp_peak_A: float = 2.0
    ramp_rate_A_per_s: float = 10.0
    ramp_hold_s: float = 0.5
    ramp_position_m: float = 1.5e-3
    ramp_sample_rate_Hz: float = 5000.0
    # eddy triangles
    eddy_rates_A_per_s: tuple = (12.5, 25.0, 62.5, 125.0)
    eddy_peak_A: float = 1.0
    eddy_cycles: int = 3
    eddy_position_m: float = 1.5e-3
    eddy_sample_rate_Hz: float = 10000.0
    # voltage step
    step_voltage_V: float = 24.0
    step_hold_s: float = 0.6
    step_position_m: float = 1.5e-3
    step_sample_rate_Hz: float = 10000.0
    # amplifier (current loop) and ambient
    amplifier_kp_V_per_A: float = 1000.0
    amplifier_ki_V_per_As: float = 5.0e4
    amplifier_max_V: float = 100.0
    ambient_C: float = 22.0

    def to_dict(self) -> dict:
        """JSON-able parameters."""
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(self).items()}

    @classmethod
    def from_dict(cls, data: dict) -> CampaignConfig:
        """Inverse of :meth:`to_dict` (unknown keys refused)."""
        known = {f.name for f in dataclasses.fields(cls)}
        bad = sorted(set(data) - known)
        if bad:
            raise RigError(f"campaign: unknown key(s) {bad}")
        return cls(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in data.items()})


def _fmt(v: float) -> str:
    return f"{v:g}"


def _triangles(peak: float, rate: float, cycles: int, t0: float) -> tuple[list, list]:
    """Knots of ``cycles`` unipolar triangles 0 -> peak -> 0 starting at ``t0``."""
    half = peak / rate
    t, v = [], []
    for c in range(cycles):
        base = t0 + 2.0 * half * c
        t += [base + half, base + 2.0 * half]
        v += [peak, 0.0]
    return t, v


def campaign_excitations(cfg: CampaignConfig) -> list[Excitation]:
    """The excitations of the campaign, in order (see :class:`CampaignConfig`).

    Returns
    -------
    list of Excitation
        Flux triangles (one recording per peak), force-stroke sweeps (one per current: current
        up at the far stop, slow move to the near stop and back, current down), a current ramp,
        eddy triangles (one recording per rate) and a voltage step.
    """
    if cfg.flux_cycles < 1 or cfg.eddy_cycles < 1:
        raise RigError("flux_cycles and eddy_cycles must be >= 1")
    out: list[Excitation] = []
    r0, r1 = cfg.rest_start_s, cfg.rest_end_s
    for kind in cfg.tests:
        if kind == "flux":
            for peak in cfg.flux_peaks_A:
                t, v = _triangles(peak, cfg.flux_rate_A_per_s, cfg.flux_cycles, r0)
                end = t[-1] + r1
                out.append(Excitation(
                    f"flux_{peak:.2f}A".replace(".", "p"), "flux", "current", cfg.flux_sample_rate_Hz,
                    (0.0, r0, *t, end), (0.0, 0.0, *v, 0.0), (0.0,), (cfg.flux_position_m,),
                    notes=f"triangular current, peak {_fmt(peak)} A, {_fmt(cfg.flux_rate_A_per_s)} A/s, "
                          f"{cfg.flux_cycles} cycle(s)"))
        elif kind == "force_stroke":
            a, b = cfg.stroke_from_m, cfg.stroke_to_m
            move = abs(a - b) / cfg.stroke_speed_m_per_s
            d = cfg.stroke_dwell_s
            for cur in cfg.stroke_currents_A:
                up = cur / cfg.stroke_current_rate_A_per_s
                t1 = r0 + up + d  # current settled at the far stop
                t2 = t1 + move  # at the near stop
                t3 = t2 + d
                t4 = t3 + move  # back at the far stop
                t5 = t4 + d
                t6 = t5 + up
                end = t6 + r1
                out.append(Excitation(
                    f"force_stroke_{cur:.2f}A".replace(".", "p"), "force_stroke", "current",
                    cfg.stroke_sample_rate_Hz, (0.0, r0, r0 + up, t5, t6, end), (0.0, 0.0, cur, cur, 0.0, 0.0),
                    (0.0, t1, t2, t3, t4, end), (a, a, b, b, a, a), with_force=True, position_column=True,
                    notes=f"constant current {_fmt(cur)} A; armature moved {_fmt(a * 1e3)} -> {_fmt(b * 1e3)} -> "
                          f"{_fmt(a * 1e3)} mm at {_fmt(cfg.stroke_speed_m_per_s * 1e3)} mm/s"))
        elif kind == "ramp":
            up = cfg.ramp_peak_A / cfg.ramp_rate_A_per_s
            t = (0.0, r0, r0 + up, r0 + up + cfg.ramp_hold_s, r0 + 2 * up + cfg.ramp_hold_s,
                 r0 + 2 * up + cfg.ramp_hold_s + r1)
            out.append(Excitation(
                "ramp", "ramp", "current", cfg.ramp_sample_rate_Hz, t,
                (0.0, 0.0, cfg.ramp_peak_A, cfg.ramp_peak_A, 0.0, 0.0), (0.0,), (cfg.ramp_position_m,),
                with_force=True, notes=f"current ramp {_fmt(cfg.ramp_rate_A_per_s)} A/s to {_fmt(cfg.ramp_peak_A)} A, "
                                       f"hold {_fmt(cfg.ramp_hold_s)} s, ramp down"))
        elif kind == "eddy":
            for rate in cfg.eddy_rates_A_per_s:
                t, v = _triangles(cfg.eddy_peak_A, rate, cfg.eddy_cycles, r0)
                end = t[-1] + r1
                out.append(Excitation(
                    f"eddy_{rate:g}Aps".replace(".", "p"), "eddy", "current", cfg.eddy_sample_rate_Hz,
                    (0.0, r0, *t, end), (0.0, 0.0, *v, 0.0), (0.0,), (cfg.eddy_position_m,),
                    notes=f"triangular current, peak {_fmt(cfg.eddy_peak_A)} A, {_fmt(rate)} A/s, "
                          f"{cfg.eddy_cycles} cycle(s)"))
        elif kind == "voltage_step":
            t1 = r0 + cfg.step_hold_s
            out.append(Excitation(
                "voltage_step", "voltage_step", "voltage", cfg.step_sample_rate_Hz,
                (0.0, r0, r0, t1, t1, t1 + r1), (0.0, 0.0, cfg.step_voltage_V, cfg.step_voltage_V, 0.0, 0.0),
                (0.0,), (cfg.step_position_m,), with_force=True,
                notes=f"voltage step 0 -> {_fmt(cfg.step_voltage_V)} V, hold {_fmt(cfg.step_hold_s)} s, back to 0"))
        else:
            raise RigError(f"unknown test {kind!r} in the campaign; known: flux, force_stroke, ramp, eddy, "
                           "voltage_step")
    return out
