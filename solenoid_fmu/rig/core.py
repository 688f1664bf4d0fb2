r"""Virtual test rig: a known truth model runs the paper's test campaign and writes recordings.

The truth is richer than the real-time model, so that identification and the residual analysis
can be tested against a known answer. It is the characteristic maps from the FEM with a given
(true) B(H) curve, ``i_f(Psi, x)`` and ``F(Psi, x)`` (paper eqs. 2-3), plus any of these effects
(each with physically sensible defaults, all settable):

``hysteresis`` (:class:`HysteresisEffect`)
    Rate-independent magnetic hysteresis acting on the flux-current relation: a Preisach
    operator (:class:`~solenoid_fmu.hysteresis.PreisachHysteresis`, deliberately not the play
    model the real-time FMU fits) adds ``i_hyst[Psi]`` to the field-generating current, so
    ``Psi(i)`` shows loops and the force follows through ``Psi``. Default major-loop half-width
    at ``Psi = 0``: 3 % of the coil's maximum current (a solid-steel solenoid).
``eddy-ladder`` (:class:`EddyLadder`)
    (Without it the truth carries the maps' single linear term ``G_eddy`` of paper eq. (2), if the
    maps have one, as the real-time model does.)
    Frequency-dependent eddy currents: instead of the single conductance ``G_eddy`` of paper
    eq. (2) (``i_eddy = G dPsi/dt``) the induced voltage ``e = dPsi/dt`` drives two or more
    conductance-inductance sections in parallel (the Foster form of an RL ladder),
    ``tau_k di_k/dt = G_k e - i_k``, ``i_eddy = sum_k i_k``. At low rates this is
    ``G = sum G_k``; at higher rates the slow sections cannot follow, so the effective
    conductance falls, which is what the paper's fig. 14 shows at 125 A/s.
``heating`` (:class:`Heating`)
    ``R(T) = R20 (1 + alpha (T - 20 degC))`` with a first-order thermal model
    ``C_th dT/dt = i^2 R(T) - (T - T_amb) / R_th`` (time constant ``R_th C_th`` of a few
    minutes; default 300 s). The temperature carries over from one recording to the next, with cooling in the
    pauses between them.
``friction`` (:class:`Friction`)
    Friction in the force measurement of the force-stroke sweeps: a Dahl model in the position
    (force ``F_c`` = 2.5 N while sliding, sign set by the direction of motion, smooth over a
    pre-sliding distance, held when the carriage stops). The load cell reads
    ``F_mag + F_fric``: with the gap opening (x rising) friction acts with the magnetic force,
    closing against it, as in the paper's fig. 8 (1-5 N).
``noise`` (:class:`DataAcquisition`)
    The data acquisition: Gaussian sensor noise on every channel, a voltage offset (5 mV),
    a current offset, and quantization of each channel to its ADC resolution.

Drive: the amplifier is a voltage source with a current loop (PI controller with anti-windup
and an output limit). The ``flux``, ``force_stroke``, ``ramp`` and ``eddy`` tests are
current-controlled; ``voltage_step`` is voltage-controlled. The model equations (SI)::

    U = R(T) i + dPsi/dt                                            (paper eq. 1)
    i = i_f(Psi, x) + i_hyst[Psi] + sum_k i_k                        (paper eq. 2, extended)
    tau_k di_k/dt = G_k dPsi/dt - i_k
    F = F(Psi, x)  (+ friction in the measured force)                (paper eq. 3)

integrated with the two-stage L-stable Rosenbrock method ROS2 (as :mod:`solenoid_fmu.model`)
on sub-steps of at most ``h_sub_max_s``; the hysteresis operator and the temperature are
advanced after each sub-step (explicit splitting; both change slowly on a sub-step).

Before each recording the rig demagnetizes the armature (decaying alternating current, not
recorded), as a real rig does before a flux measurement, and measures the coil resistance
(4-wire, written as ``coil_resistance_ohm`` with the temperature ``coil_temperature_C``).
Nothing in the recordings names the effects or the true material: a separate ``truth.json``
holds them (:func:`read_truth`), for tests only; the pipeline never reads it.

Command line: ``solenoid-fmu rig --geometry G --material TRUE.csv --effects hysteresis,friction
-o DIR [--maps MAPSDIR] [--seed N]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import math
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SolenoidError
from ..measure import make_recording, write_recording
from ..realtime import (
    COPPER_ALPHA_PER_K,
    ROS2_GAMMA,
    HysteresisError,
    MapTables,
    ModelError,
    PreisachHysteresis,
    load_tables,
)

__all__ = [
    "EFFECT_NAMES",
    "TRUTH_SCHEMA",
    "CampaignConfig",
    "DataAcquisition",
    "EddyLadder",
    "Effects",
    "Excitation",
    "Friction",
    "Heating",
    "HysteresisEffect",
    "RigError",
    "RigTruth",
    "TruthModel",
    "TruthResult",
    "add_cli",
    "campaign_excitations",
    "measure",
    "read_truth",
    "run_campaign",
    "run_excitations",
]

#: Names of the switchable effects (CLI ``--effects``).
EFFECT_NAMES = ("hysteresis", "eddy-ladder", "heating", "friction", "noise")
#: Schema name and version of ``truth.json``.
TRUTH_SCHEMA = "solenoid-fmu-rig-truth"
TRUTH_SCHEMA_VERSION = 1
#: Significant digits of the numbers in the recording files.
FILE_DIGITS = 7


class RigError(SolenoidError):
    """Bad rig configuration: unknown effect, unphysical parameter, unusable maps or truth file."""


def _positive(name: str, value, allow_zero: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise RigError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v) or v < 0.0 or (v == 0.0 and not allow_zero):
        raise RigError(f"{name} must be a finite number {'>=' if allow_zero else '>'} 0, got {value!r}")
    return v


# --------------------------------------------------------------------------------------------
# Effects
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class HysteresisEffect:
    """Magnetic hysteresis of the truth: a Preisach term added to the field-generating current.

    Parameters
    ----------
    half_width_A : float, optional
        Half-width of the saturated major loop at ``Psi = 0``, as a current [A]; default 3 % of
        the coil's maximum current (maps.json ``coil.max_current_A``).
    b_c_rel, spread_rel : float
        Peak position and width of the Preisach density as fractions of the saturation flux
        (see :meth:`PreisachHysteresis.with_coercive`).
    saturation_Wb : float, optional
        Flux linkage [Wb] beyond which every hysteron is switched; default the maps' largest
        flux ``psi_Wb[-1]``.
    """

    half_width_A: float | None = None
    b_c_rel: float = 0.15
    spread_rel: float = 0.2
    saturation_Wb: float | None = None


@dataclass(frozen=True)
class EddyLadder:
    """Eddy currents as parallel conductance-inductance sections driven by ``e = dPsi/dt``.

    Parameters
    ----------
    G_S : tuple of float
        Conductance of each section [S] (A per V of induced voltage); the low-rate limit of the
        lumped ``G_eddy`` of paper eq. (2) is their sum. Default (3 mS, 2 mS).
    tau_s : tuple of float
        Time constant ``L_k G_k`` of each section [s], > 0. Default (0.3 ms, 3 ms).
    """

    G_S: tuple = (3.0e-3, 2.0e-3)
    tau_s: tuple = (3.0e-4, 3.0e-3)

    def __post_init__(self):
        G = tuple(_positive(f"eddy G_S[{k}]", v) for k, v in enumerate(self.G_S))
        tau = tuple(_positive(f"eddy tau_s[{k}]", v) for k, v in enumerate(self.tau_s))
        if len(G) != len(tau) or len(G) < 1:
            raise RigError(f"eddy ladder needs as many G_S as tau_s (>= 1), got {len(G)} and {len(tau)}")
        object.__setattr__(self, "G_S", G)
        object.__setattr__(self, "tau_s", tau)

    def effective_G_S(self, omega_rad_per_s: float) -> float:
        """Real part of the ladder's admittance at angular frequency ``omega`` [S]."""
        return float(sum(g / (1.0 + (omega_rad_per_s * t) ** 2) for g, t in zip(self.G_S, self.tau_s,
                                                                                 strict=True)))


@dataclass(frozen=True)
class Heating:
    """Coil heating: first-order thermal model driven by ``i^2 R(T)``.

    Parameters
    ----------
    C_th_J_per_K : float
        Heat capacity of coil and housing [J/K]. Default 300 (about 0.6 kg of steel and
        0.1 kg of copper).
    R_th_K_per_W : float
        Thermal resistance to ambient [K/W]. Default 1.0 (time constant 300 s; 48 W at 2 A
        would heat the coil by 48 K in steady state).

    Notes
    -----
    Even a slow rise matters for the flux linkage from voltage (paper eq. 4): at 2 A the
    resistive voltage is 24 V, so a 0.1 % rise of R during a slow triangle integrates to an
    error of the order of 0.1 Wb. Recordings with this effect test the resistance handling.
    """

    C_th_J_per_K: float = 300.0
    R_th_K_per_W: float = 1.0

    def __post_init__(self):
        _positive("C_th_J_per_K", self.C_th_J_per_K)
        _positive("R_th_K_per_W", self.R_th_K_per_W)

    @property
    def time_constant_s(self) -> float:
        """``R_th C_th`` [s]."""
        return self.C_th_J_per_K * self.R_th_K_per_W


@dataclass(frozen=True)
class Friction:
    """Friction in the force measurement (Dahl model in the armature position).

    Parameters
    ----------
    force_N : float
        Sliding friction force [N] (the paper: force hysteresis 1-5 N, i.e. +-F_c). Default 2.5.
    presliding_m : float
        Position change over which the friction force builds up after a reversal [m]
        (Dahl stiffness ``F_c / presliding_m``). Default 20 um.
    """

    force_N: float = 2.5
    presliding_m: float = 20e-6

    def __post_init__(self):
        _positive("friction force_N", self.force_N, allow_zero=True)
        _positive("friction presliding_m", self.presliding_m)


@dataclass(frozen=True)
class DataAcquisition:
    """Sensor noise, offsets and quantization of the data acquisition.

    Parameters
    ----------
    voltage_noise_V, current_noise_A, force_noise_N, position_noise_m : float
        Standard deviation of white Gaussian sensor noise per channel [V], [A], [N], [m].
    voltage_offset_V, current_offset_A : float
        Constant offsets of the voltage and current channels [V], [A].
    adc_bits : int
        ADC resolution; a channel with full-scale range ``+-FS`` has the step ``2 FS / 2**bits``.
    voltage_range_V, current_range_A, force_range_N : float
        Full-scale ranges (+-) [V], [A], [N].
    position_resolution_m : float
        Resolution of the position encoder [m].
    force_gain, force_offset_N : float
        Calibration error of the force sensor: measured = gain * true + offset [1], [N]
        (a sensor fault; 1 and 0 for a calibrated sensor).
    """

    voltage_noise_V: float = 3e-3
    current_noise_A: float = 0.5e-3
    force_noise_N: float = 0.05
    position_noise_m: float = 0.5e-6
    voltage_offset_V: float = 5e-3
    current_offset_A: float = 0.0
    adc_bits: int = 16
    voltage_range_V: float = 100.0
    current_range_A: float = 5.0
    force_range_N: float = 100.0
    position_resolution_m: float = 1e-6
    force_gain: float = 1.0
    force_offset_N: float = 0.0

    def __post_init__(self):
        for name in ("voltage_noise_V", "current_noise_A", "force_noise_N", "position_noise_m"):
            _positive(name, getattr(self, name), allow_zero=True)
        for name in ("voltage_range_V", "current_range_A", "force_range_N", "position_resolution_m"):
            _positive(name, getattr(self, name))
        _positive("force_gain", self.force_gain)
        for name in ("voltage_offset_V", "current_offset_A", "force_offset_N"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v)):
                raise RigError(f"{name} must be a finite number, got {v!r}")
        if not (isinstance(self.adc_bits, int) and 4 <= self.adc_bits <= 32):
            raise RigError(f"adc_bits must be an integer in 4..32, got {self.adc_bits!r}")


_EFFECT_CLASSES = {"hysteresis": HysteresisEffect, "eddy-ladder": EddyLadder, "heating": Heating,
                   "friction": Friction, "noise": DataAcquisition}
_EFFECT_FIELDS = {"hysteresis": "hysteresis", "eddy-ladder": "eddy", "heating": "heating",
                  "friction": "friction", "noise": "daq"}


@dataclass(frozen=True)
class Effects:
    """Which effects the truth has (None = off) and their parameters."""

    hysteresis: HysteresisEffect | None = None
    eddy: EddyLadder | None = None
    heating: Heating | None = None
    friction: Friction | None = None
    daq: DataAcquisition | None = None

    @classmethod
    def from_names(cls, names, **overrides) -> Effects:
        """Effects switched on by name (:data:`EFFECT_NAMES`), with default parameters.

        Parameters
        ----------
        names : str or iterable of str
            Comma-separated string or names; "" or "none" for no effect.
        **overrides
            Effect objects by field name (``hysteresis=HysteresisEffect(...)``) replacing defaults.
        """
        if isinstance(names, str):
            names = [] if names.strip().lower() in ("", "none") else names.split(",")
        chosen = {}
        for raw in names:
            name = raw.strip().lower()
            if name not in _EFFECT_CLASSES:
                raise RigError(f"unknown effect {raw.strip()!r}; known: {', '.join(EFFECT_NAMES)}")
            chosen[_EFFECT_FIELDS[name]] = _EFFECT_CLASSES[name]()
        chosen.update(overrides)
        return cls(**chosen)

    def names(self) -> list[str]:
        """Names of the effects switched on."""
        return [n for n in EFFECT_NAMES if getattr(self, _EFFECT_FIELDS[n]) is not None]

    def to_dict(self) -> dict:
        """JSON-able ``{effect name: parameters or None}``."""
        out = {}
        for n in EFFECT_NAMES:
            obj = getattr(self, _EFFECT_FIELDS[n])
            out[n] = None if obj is None else {k: (list(v) if isinstance(v, tuple) else v)
                                               for k, v in dataclasses.asdict(obj).items()}
        return out

    @classmethod
    def from_dict(cls, data: dict) -> Effects:
        """Inverse of :meth:`to_dict`."""
        if not isinstance(data, dict):
            raise RigError(f"effects must be a JSON object, got {type(data).__name__}")
        kwargs = {}
        for name, params in data.items():
            if name not in _EFFECT_CLASSES:
                raise RigError(f"unknown effect {name!r} in truth data; known: {', '.join(EFFECT_NAMES)}")
            if params is None:
                continue
            klass = _EFFECT_CLASSES[name]
            known = {f.name for f in dataclasses.fields(klass)}
            bad = sorted(set(params) - known)
            if bad:
                raise RigError(f"effect {name!r}: unknown parameter(s) {bad}; known: {sorted(known)}")
            vals = {k: (tuple(v) if isinstance(v, list) else v) for k, v in params.items()}
            kwargs[_EFFECT_FIELDS[name]] = klass(**vals)
        return cls(**kwargs)


# --------------------------------------------------------------------------------------------
# Excitations and the campaign
# --------------------------------------------------------------------------------------------


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


# --------------------------------------------------------------------------------------------
# The truth model
# --------------------------------------------------------------------------------------------


@dataclass
class TruthResult:
    """True (noise-free) signals of one excitation at the sample times, SI units.

    Attributes
    ----------
    time_s, voltage_V, current_A, psi_Wb, force_N, position_m : numpy.ndarray, shape (n,)
        Sample times [s]; coil voltage [V] and coil current [A] as means over the sample
        interval ending at each sample (integrating converters; sample 0: instantaneous), so
        ``sum`` of the trapezoid of ``U - R i`` reproduces ``psi_Wb`` (paper eq. 4) up to half a
        sample; flux linkage [Wb], measured force (magnetic force plus friction) [N] and
        working gap [m] at the sample times.
    force_magnetic_N, i_hyst_A, i_eddy_A, temperature_C : numpy.ndarray, shape (n,)
        Magnetic force alone [N], hysteresis current [A], eddy current [A], coil temperature [degC].
    resistance_start_ohm, temperature_start_C, temperature_end_C : float
        Coil resistance [ohm] and temperature [degC] at the start, temperature at the end.
    """

    time_s: np.ndarray
    voltage_V: np.ndarray
    current_A: np.ndarray
    psi_Wb: np.ndarray
    force_N: np.ndarray
    position_m: np.ndarray
    force_magnetic_N: np.ndarray
    i_hyst_A: np.ndarray
    i_eddy_A: np.ndarray
    temperature_C: np.ndarray
    resistance_start_ohm: float
    temperature_start_C: float
    temperature_end_C: float


class TruthModel:
    """The rig's truth: FEM maps plus the chosen effects, integrated with their own states.

    Parameters
    ----------
    tables : MapTables
        The true characteristic maps ``i_f(Psi, x)``, ``F(Psi, x)`` (FEM with the true B(H)).
    effects : Effects
        Effects switched on.
    R20_ohm : float, optional
        Coil resistance at 20 degC [ohm]; default from the maps (coil.resistance_ohm_20C).
    alpha_per_K : float, optional
        Temperature coefficient of the resistance [1/K]; default from the maps, else copper.
    max_current_A : float, optional
        Coil's maximum current [A] (sets the default hysteresis width); default from the maps.
    h_sub_max_s : float
        Largest integration sub-step [s].
    """

    def __init__(self, tables: MapTables, effects: Effects | None = None, R20_ohm: float | None = None,
                 alpha_per_K: float | None = None, max_current_A: float | None = None,
                 h_sub_max_s: float = 5e-4):
        self.tables = tables
        self.effects = effects or Effects()
        coil = tables.meta.get("coil") or {}
        R20 = R20_ohm if R20_ohm is not None else coil.get("resistance_ohm_20C")
        if R20 is None:
            raise RigError("no coil resistance: give R20_ohm or maps with coil.resistance_ohm_20C")
        self.R20_ohm = _positive("R20_ohm", R20)
        if alpha_per_K is None:
            alpha_per_K = coil.get("temperature_coefficient_per_K", COPPER_ALPHA_PER_K)
        alpha = alpha_per_K
        self.alpha_per_K = _positive("alpha_per_K", alpha, allow_zero=True)
        imax = max_current_A if max_current_A is not None else coil.get("max_current_A")
        if imax is None:
            raise RigError("no maximum current: give max_current_A or maps with coil.max_current_A")
        self.max_current_A = _positive("max_current_A", imax)
        self.h_sub_max_s = _positive("h_sub_max_s", h_sub_max_s)
        self.preisach = None
        hy = self.effects.hysteresis
        if hy is not None:
            width = hy.half_width_A if hy.half_width_A is not None else 0.03 * self.max_current_A
            sat = hy.saturation_Wb if hy.saturation_Wb is not None else tables.psi_max_Wb
            try:
                self.preisach = PreisachHysteresis.with_coercive(_positive("hysteresis saturation_Wb", sat),
                                                                 _positive("hysteresis half_width_A", width),
                                                                 b_c_rel=hy.b_c_rel, spread_rel=hy.spread_rel)
            except HysteresisError as exc:
                raise RigError(f"hysteresis: {exc}") from None
            slope_min = float(np.min(tables.tables()["i_f_slope_A"][1:])) * tables.inv_dpsi
            neg = self.preisach.max_negative_slope()
            if neg >= slope_min:
                raise RigError(f"hysteresis half-width {width:g} A is too large for these maps: the branches "
                               f"of Psi(i) would fold back (Preisach slope -{neg:.3g} A/Wb against the maps' "
                               f"smallest di_f/dPsi {slope_min:.3g} A/Wb); choose a smaller half_width_A")
        self.hysteresis_half_width_A = None if self.preisach is None else (
            hy.half_width_A if hy.half_width_A is not None else 0.03 * self.max_current_A)

    def resistance_ohm(self, T_C: float) -> float:
        """Coil resistance [ohm] at ``T_C`` [degC]: ``R20 (1 + alpha (T - 20))``."""
        return self.R20_ohm * (1.0 + self.alpha_per_K * (T_C - 20.0))

    def cool(self, T_C: float, pause_s: float, ambient_C: float) -> float:
        """Coil temperature [degC] after ``pause_s`` [s] without current (exponential cooling)."""
        he = self.effects.heating
        if he is None:
            return ambient_C
        return ambient_C + (T_C - ambient_C) * math.exp(-pause_s / he.time_constant_s)

    def simulate(self, exc: Excitation, cfg: CampaignConfig | None = None, T_start_C: float | None = None,
                 demagnetize: bool = True) -> TruthResult:
        """Run one excitation on the truth and return the true signals at the sample times.

        With ``exc.preroll_s > 0`` the unrecorded lead-in (see :class:`Excitation`) is simulated
        first and its samples are dropped: the result starts energized at time 0.

        Parameters
        ----------
        exc : Excitation
            What the rig drives.
        cfg : CampaignConfig, optional
            Amplifier gains and limit, ambient temperature (default :class:`CampaignConfig`).
        T_start_C : float, optional
            Coil temperature at the start [degC]; default the ambient.
        demagnetize : bool
            Reset the hysteresis to the AC-demagnetized state first (the rig does this before
            every recording).

        Returns
        -------
        TruthResult
        """
        if exc.preroll_s > 0.0:
            return self._simulate_with_preroll(exc, cfg, T_start_C, demagnetize)
        cfg = cfg or CampaignConfig()
        tab = self.tables
        T = cfg.ambient_C if T_start_C is None else float(T_start_C)
        heating = self.effects.heating
        ambient = cfg.ambient_C
        ladder = self.effects.eddy
        Gk = np.array(ladder.G_S) if ladder else np.zeros(0)
        tk = np.array(ladder.tau_s) if ladder else np.zeros(0)
        if not ladder and (tab.G_eddy_S or 0.0) > 0.0:
            # without the ladder the truth has the paper's single linear term of the maps (eq. 2),
            # i_eddy = G dPsi/dt, as one section fast enough to be instantaneous (ROS2 is L-stable)
            Gk, tk = np.array([float(tab.G_eddy_S)]), np.array([1e-6])
        nk = Gk.size
        current_mode = exc.mode == "current"
        if exc.mode not in ("current", "voltage"):
            raise RigError(f"excitation {exc.name}: mode must be 'current' or 'voltage', got {exc.mode!r}")
        kp, ki, umax = cfg.amplifier_kp_V_per_A, cfg.amplifier_ki_V_per_As, cfg.amplifier_max_V
        pre = self.preisach
        if pre is not None and demagnetize:
            pre.reset(0.0)
        fr = self.effects.friction
        t_samp = exc.times_s()
        ns = t_samp.size
        x_samp = exc.position_m(t_samp)
        # state y = [Psi, z (PI integrator), i_1 .. i_n]
        y = np.zeros(2 + nk)
        h_hyst = 0.0 if pre is None else pre.step(0.0)
        f_fric = 0.0
        out = {k: np.empty(ns) for k in ("U", "i", "psi", "F", "ih", "ie", "T")}
        eye = np.eye(2 + nk)
        R_start = self.resistance_ohm(T)
        T0 = T
        dt = 1.0 / exc.sample_rate_Hz
        n_sub = max(1, math.ceil(dt / self.h_sub_max_s - 1e-9))
        hs = dt / n_sub
        g = ROS2_GAMMA

        n_y = 2 + nk
        di_base = np.zeros(n_y)
        di_base[2:] = 1.0
        inv_tk = 1.0 / tk if nk else tk
        G_over_tk = Gk * inv_tk if nk else Gk
        ladder_diag = np.diag(inv_tk) if nk else None

        def rhs(ref, yv, cell, R):
            """f(y), Jacobian, U [V], i [A] for reference ``ref`` (A or V) in x cell ``cell``."""
            i_f, s = tab.i_f_and_slope(yv[0], cell[0], cell[1])
            i = i_f + h_hyst + (float(yv[2:].sum()) if nk else 0.0)
            J = np.zeros((n_y, n_y))
            di = di_base.copy()
            di[0] = s
            f = np.empty(n_y)
            if current_mode:
                err = ref - i
                u_raw = kp * err + yv[1]
                if -umax <= u_raw <= umax:
                    U = u_raw
                    dU = -kp * di
                    dU[1] = 1.0
                    f[1] = ki * err
                    J[1] = -ki * di
                else:
                    U = umax if u_raw > umax else -umax
                    dU = np.zeros(n_y)
                    f[1] = 0.0
            else:
                U = ref
                dU = np.zeros(n_y)
                f[1] = 0.0
            e = U - R * i
            de = dU - R * di
            f[0] = e
            J[0] = de
            if nk:
                f[2:] = G_over_tk * e - yv[2:] * inv_tk
                J[2:] = G_over_tk[:, None] * de[None, :]
                J[2:, 2:] -= ladder_diag
            return f, J, U, i

        def record(k, t, U, i):
            x_m = x_samp[k]
            out["U"][k] = U
            out["i"][k] = i
            out["psi"][k] = y[0]
            out["F"][k] = tab.force_N(y[0], x_m)
            out["ih"][k] = h_hyst
            out["ie"][k] = float(np.sum(y[2:]))
            out["T"][k] = T

        R = self.resistance_ohm(T)
        # The amplifier is digital: its reference (and the carriage position) is held over each
        # sub-step at the value of the sub-step's midpoint (precomputed, vectorized). A step in
        # the reference then acts exactly at its time when that is a sub-step boundary.
        t_mid = t_samp[:-1, None] + hs * (np.arange(n_sub)[None, :] + 0.5)
        ref_sub = exc.reference(t_mid)
        moving = len(exc.pos_m) > 1
        fixed_cell = tab.x_cell(float(x_samp[0]))
        x_sub = exc.position_m(t_mid) if moving else None
        ref0 = float(exc.reference(0.0))
        _, _, U0, i0 = rhs(ref0, y, tab.x_cell(float(x_samp[0])), R)
        record(0, 0.0, U0, i0)
        fric = np.zeros(ns)
        i_prev = i0
        for k in range(1, ns):
            psi_start = y[0]
            ri_int = 0.0  # integral of R i over the sample interval [V s]
            i_int = 0.0  # integral of i over the sample interval [A s]
            for m in range(n_sub):
                cell = tab.x_cell(float(x_sub[k - 1, m])) if moving else fixed_cell
                R = self.resistance_ohm(T)
                f1, J, _, i_a = rhs(ref_sub[k - 1, m], y, cell, R)
                if m:
                    ri_int += 0.5 * hs * R * (i_prev + i_a)
                    i_int += 0.5 * hs * (i_prev + i_a)
                i_prev = i_a
                W = eye - (g * hs) * J
                k1 = np.linalg.solve(W, f1)
                f2 = rhs(ref_sub[k - 1, m], y + hs * k1, cell, R)[0]
                k2 = np.linalg.solve(W, f2 - 2.0 * k1)
                y = y + 1.5 * hs * k1 + 0.5 * hs * k2
                if pre is not None:
                    h_hyst = pre.step(y[0])
                if heating is not None:
                    P = i_a * i_a * R
                    T += hs * (P - (T - ambient) / heating.R_th_K_per_W) / heating.C_th_J_per_K
            R = self.resistance_ohm(T)
            _, _, _, i = rhs(ref_sub[k - 1, n_sub - 1], y, tab.x_cell(float(x_samp[k])), R)
            ri_int += 0.5 * hs * R * (i_prev + i)
            i_int += 0.5 * hs * (i_prev + i)
            i_prev = i
            # Voltage and current channels are means over the sample interval (integrating
            # converters, the same anti-aliasing on both), so paper eq. 4 holds exactly for the
            # samples: U_mean - mean(R i) = (Psi_k - Psi_k-1) / dt.
            U = (y[0] - psi_start + ri_int) / dt
            record(k, t_samp[k], U, i_int / dt)
            if fr is not None and fr.force_N > 0.0:
                dx = x_samp[k] - x_samp[k - 1]
                if dx != 0.0:
                    target = fr.force_N if dx > 0.0 else -fr.force_N
                    f_fric = target + (f_fric - target) * math.exp(-abs(dx) / fr.presliding_m)
            fric[k] = f_fric
        return TruthResult(time_s=t_samp, voltage_V=out["U"], current_A=out["i"], psi_Wb=out["psi"],
                           force_N=out["F"] + fric, position_m=x_samp, force_magnetic_N=out["F"],
                           i_hyst_A=out["ih"], i_eddy_A=out["ie"], temperature_C=out["T"],
                           resistance_start_ohm=R_start, temperature_start_C=T0, temperature_end_C=T)

    def _simulate_with_preroll(self, exc: Excitation, cfg, T_start_C, demagnetize) -> TruthResult:
        """:meth:`simulate` of an excitation with a lead-in: simulate it, then drop its samples."""
        fs = exc.sample_rate_Hz
        n_pre = max(1, math.ceil(exc.preroll_s * fs - 1e-9))
        pre = n_pre / fs
        shift = tuple(float(t) + pre for t in exc.ref_t_s)
        moving = len(exc.pos_m) > 1
        ext = dataclasses.replace(
            exc, ref_t_s=(0.0, 0.5 * pre, *shift), ref_values=(0.0, exc.ref_values[0], *exc.ref_values),
            pos_t_s=(0.0, *(float(t) + pre for t in exc.pos_t_s)) if moving else exc.pos_t_s,
            pos_m=(exc.pos_m[0], *exc.pos_m) if moving else exc.pos_m, preroll_s=0.0)
        res = self.simulate(ext, cfg, T_start_C, demagnetize)
        n = exc.times_s().size
        cut = {f.name: getattr(res, f.name)[n_pre:n_pre + n] for f in dataclasses.fields(res)
               if isinstance(getattr(res, f.name), np.ndarray)}
        cut["time_s"] = exc.times_s()[:cut["current_A"].size]
        return dataclasses.replace(res, **cut)


# --------------------------------------------------------------------------------------------
# Data acquisition and files
# --------------------------------------------------------------------------------------------


def _quantize(v: np.ndarray, step: float) -> np.ndarray:
    return np.round(v / step) * step


def measure(truth: TruthResult, exc: Excitation, daq: DataAcquisition | None, rng: np.random.Generator,
            solenoid: str = "PS45"):
    """Turn true signals into a :class:`~solenoid_fmu.recordings.Recording` as the rig's DAQ sees them.

    Parameters
    ----------
    truth : TruthResult
        Output of :meth:`TruthModel.simulate`.
    exc : Excitation
        The excitation (kind, channels, notes).
    daq : DataAcquisition or None
        Noise, offsets and quantization; None: ideal sensors.
    rng : numpy.random.Generator
        Random numbers for the noise.
    solenoid : str
        Header ``solenoid``.

    Returns
    -------
    Recording
        With header ``coil_resistance_ohm`` (4-wire, before the run) and ``coil_temperature_C``.
    """
    n = truth.time_s.size
    u, i, f, x = truth.voltage_V.copy(), truth.current_A.copy(), truth.force_N.copy(), truth.position_m.copy()
    if exc.current_delay_s:
        i = np.interp(truth.time_s - exc.current_delay_s, truth.time_s, i)
    u = u + exc.voltage_offset_V
    if daq is not None:
        u = u + daq.voltage_offset_V + rng.normal(0.0, daq.voltage_noise_V, n)
        i = i + daq.current_offset_A + rng.normal(0.0, daq.current_noise_A, n)
        f = daq.force_gain * f + daq.force_offset_N + rng.normal(0.0, daq.force_noise_N, n)
        x = x + rng.normal(0.0, daq.position_noise_m, n)
        levels = 2.0 ** daq.adc_bits
        u = _quantize(np.clip(u, -daq.voltage_range_V, daq.voltage_range_V), 2 * daq.voltage_range_V / levels)
        i = _quantize(np.clip(i, -daq.current_range_A, daq.current_range_A), 2 * daq.current_range_A / levels)
        f = _quantize(np.clip(f, -daq.force_range_N, daq.force_range_N), 2 * daq.force_range_N / levels)
        x = _quantize(x, daq.position_resolution_m)
    header = {"coil_resistance_ohm": round(truth.resistance_start_ohm, 4),
              "coil_temperature_C": round(truth.temperature_start_C, 1),
              "sample_rate_Hz": exc.sample_rate_Hz, "notes": exc.notes}
    if exc.header_keys is not None:
        header = {k: (v if k in exc.header_keys else None) for k, v in header.items()}
    return make_recording(
        exc.kind, solenoid, truth.time_s, i,
        voltage_V=u if exc.with_voltage else None,
        force_N=f if exc.with_force else None,
        position_m=x if exc.position_column else float(exc.pos_m[0]), **header)


# --------------------------------------------------------------------------------------------
# Campaign and truth.json
# --------------------------------------------------------------------------------------------


@dataclass
class RigTruth:
    """Content of ``truth.json``: what the recordings do not say (for tests only).

    Attributes
    ----------
    solenoid : str
        Solenoid name.
    effects : Effects
        The effects and their parameters.
    campaign : CampaignConfig
        The campaign.
    seed : int or None
        Seed of the noise.
    material : dict
        ``{"path": relative to the directory or absolute, "sha256": ...}`` of the true B(H) CSV, or {}.
    maps : str or None
        Directory of the true maps (relative to the truth file's directory when inside it).
    coil : dict
        ``R20_ohm``, ``alpha_per_K``, ``max_current_A`` of the truth.
    recordings : list of dict
        Per file: ``file``, ``kind``, ``temperature_start_C``, ``temperature_end_C``,
        ``resistance_start_ohm``, ``psi_end_Wb``.
    derived : dict
        Derived true numbers: hysteresis half-width [A], ladder low-rate conductance [S].
    """

    solenoid: str
    effects: Effects
    campaign: CampaignConfig
    seed: int | None
    material: dict = field(default_factory=dict)
    maps: str | None = None
    coil: dict = field(default_factory=dict)
    recordings: list = field(default_factory=list)
    derived: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """JSON-able content with schema name and version."""
        return {"schema": TRUTH_SCHEMA, "schema_version": TRUTH_SCHEMA_VERSION, "solenoid": self.solenoid,
                "effects": self.effects.to_dict(), "campaign": self.campaign.to_dict(), "seed": self.seed,
                "material": dict(self.material), "maps": self.maps, "coil": dict(self.coil),
                "recordings": [dict(r) for r in self.recordings], "derived": dict(self.derived)}

    @classmethod
    def from_dict(cls, data: dict, where: str = "truth") -> RigTruth:
        """Inverse of :meth:`to_dict` (checks schema and version)."""
        if not isinstance(data, dict) or data.get("schema") != TRUTH_SCHEMA:
            raise RigError(f"{where}: not a rig truth file (schema must be {TRUTH_SCHEMA!r})")
        if data.get("schema_version") != TRUTH_SCHEMA_VERSION:
            raise RigError(f"{where}: schema_version {data.get('schema_version')!r} is not supported "
                           f"(this reader reads {TRUTH_SCHEMA_VERSION})")
        try:
            return cls(solenoid=str(data["solenoid"]), effects=Effects.from_dict(data["effects"]),
                       campaign=CampaignConfig.from_dict(data["campaign"]), seed=data.get("seed"),
                       material=dict(data.get("material") or {}), maps=data.get("maps"),
                       coil=dict(data.get("coil") or {}), recordings=list(data.get("recordings") or []),
                       derived=dict(data.get("derived") or {}))
        except KeyError as exc:
            raise RigError(f"{where}: missing key {exc.args[0]!r}") from None
        except TypeError as exc:
            raise RigError(f"{where}: bad value: {exc}") from None

    def __eq__(self, other):
        if not isinstance(other, RigTruth):
            return NotImplemented
        return self.to_dict() == other.to_dict()


def read_truth(path) -> RigTruth:
    """Read ``truth.json`` (a file or the campaign directory holding it)."""
    path = Path(path)
    if path.is_dir():
        path = path / "truth.json"
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise RigError(f"{path}: no such truth file") from None
    except json.JSONDecodeError as exc:
        raise RigError(f"{path}:{exc.lineno}: not valid JSON: {exc.msg}") from None
    return RigTruth.from_dict(data, where=str(path))


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _rel(path: Path, base: Path) -> str:
    try:
        return Path(path).resolve().relative_to(base.resolve()).as_posix()
    except ValueError:
        return str(Path(path).resolve())


def run_campaign(tables: MapTables, output_dir, effects: Effects | None = None,
                 campaign: CampaignConfig | None = None, seed: int | None = 0, material_path=None,
                 maps_dir=None, progress: bool = False) -> RigTruth:
    """Run the campaign on the truth and write one recording per test plus ``truth.json``.

    Parameters
    ----------
    tables : MapTables
        The true maps.
    output_dir : path-like
        Campaign directory: recordings go to ``output_dir/recordings/NN_<name>.csv``,
        the truth to ``output_dir/truth.json``.
    effects : Effects, optional
        Effects of the truth (default none).
    campaign : CampaignConfig, optional
        The tests (default :class:`CampaignConfig`).
    seed : int or None
        Seed of the sensor noise.
    material_path, maps_dir : path-like, optional
        The true B(H) CSV and maps directory, referenced from ``truth.json``.
    progress : bool
        Print one line per recording.

    Returns
    -------
    RigTruth
        What was written to ``truth.json``.
    """
    cfg = campaign or CampaignConfig()
    return run_excitations(tables, output_dir, campaign_excitations(cfg), effects=effects, campaign=cfg, seed=seed,
                           material_path=material_path, maps_dir=maps_dir, progress=progress)


def run_excitations(tables: MapTables, output_dir, excitations, *, effects: Effects | None = None,
                    campaign: CampaignConfig | None = None, seed: int | None = 0, file_names=None,
                    material_path=None, maps_dir=None, progress: bool = False, derived: dict | None = None
                    ) -> RigTruth:
    """Run the given excitations on the truth, in order, and write the recordings and ``truth.json``.

    The coil cools for ``campaign.pause_s`` between recordings. ``file_names`` (one per
    excitation) default to ``NN_<name>.csv``; ``derived`` adds entries to the truth's ``derived``.
    Column order and optional header keys come from each :class:`Excitation`. See
    :func:`run_campaign` for the other parameters.
    """
    out = Path(output_dir)
    rec_dir = out / "recordings"
    rec_dir.mkdir(parents=True, exist_ok=True)
    effects = effects or Effects()
    cfg = campaign or CampaignConfig()
    excitations = list(excitations)
    if file_names is None:
        file_names = [f"{n:02d}_{exc.name}.csv" for n, exc in enumerate(excitations, start=1)]
    if len(file_names) != len(excitations) or len(set(file_names)) != len(file_names):
        raise RigError("file_names must be one distinct name per excitation")
    model = TruthModel(tables, effects)
    rng = np.random.default_rng(seed)
    T = cfg.ambient_C
    entries = []
    for n, (exc, name) in enumerate(zip(excitations, file_names, strict=True), start=1):
        if n > 1:
            T = model.cool(T, cfg.pause_s, cfg.ambient_C)
        res = model.simulate(exc, cfg, T_start_C=T)
        T = res.temperature_end_C
        rec = measure(res, exc, effects.daq, rng, solenoid=cfg.solenoid)
        write_recording(rec_dir / name, rec, digits=FILE_DIGITS, columns=exc.columns or None)
        entries.append({"file": f"recordings/{name}", "kind": exc.kind,
                        "temperature_start_C": res.temperature_start_C, "temperature_end_C": res.temperature_end_C,
                        "resistance_start_ohm": res.resistance_start_ohm, "psi_end_Wb": float(res.psi_Wb[-1])})
        if progress:
            print(f"  {name}: {len(rec)} samples, {exc.duration_s:.3g} s", flush=True)
    material = {}
    if material_path is not None:
        material = {"path": _rel(Path(material_path), out), "sha256": _sha256(Path(material_path))}
    derived = {"hysteresis_half_width_A": model.hysteresis_half_width_A,
               "eddy_G_low_rate_S": float(sum(effects.eddy.G_S)) if effects.eddy else None,
               "resistance_20C_ohm": model.R20_ohm, **(derived or {})}
    truth = RigTruth(solenoid=cfg.solenoid, effects=effects, campaign=cfg, seed=seed, material=material,
                     maps=None if maps_dir is None else _rel(Path(maps_dir), out),
                     coil={"R20_ohm": model.R20_ohm, "alpha_per_K": model.alpha_per_K,
                           "max_current_A": model.max_current_A},
                     recordings=entries, derived=derived)
    (out / "truth.json").write_text(json.dumps(truth.to_dict(), indent=2) + "\n", encoding="utf-8")
    return truth


# --------------------------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------------------------


def add_cli(subparsers) -> None:
    """Register ``solenoid-fmu rig``."""
    p = subparsers.add_parser(
        "rig", help="virtual test rig: run the test campaign on a known truth and write recordings",
        description=("Run the paper's test campaign (flux triangles, force-stroke sweeps, current ramp, eddy "
                     "triangles, voltage step) on a truth model = FEM maps with the given true B(H) plus "
                     "effects, and write one recording per test into DIR/recordings and the truth into "
                     "DIR/truth.json (for tests only)."),
        epilog=("examples:\n"
                "  solenoid-fmu rig --material true.csv --effects hysteresis,friction -o build/campaign\n"
                "  solenoid-fmu rig --maps maps/ps45-true --effects all --seed 3 -o build/campaign\n"),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--geometry", metavar="G.toml", help="solenoid geometry (default: packaged PS45)")
    p.add_argument("--material", metavar="TRUE.csv", help="true B(H) curve (copied into DIR/truth/)")
    p.add_argument("--maps", metavar="MAPSDIR", help="use these true maps instead of running the FEM")
    p.add_argument("--effects", default="", metavar="LIST",
                   help=f"comma-separated effects: {','.join(EFFECT_NAMES)}, or 'all' (default: none)")
    p.add_argument("--seed", type=int, default=0, help="seed of the sensor noise (default 0)")
    p.add_argument("--mesh-size", type=float, default=1.0, help="FEM mesh-size factor when building maps")
    p.add_argument("--campaign", metavar="JSON", help="campaign parameters (keys of CampaignConfig) as JSON file")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="campaign directory to write")
    p.set_defaults(func=_cli)


def _cli(args) -> int:
    from ..fileio import refuse_overwriting_inputs, require_directory

    out = require_directory(args.output, "-o")
    written = [out / "recordings", out / "truth.json"] + ([] if args.maps else [out / "truth" / "maps"])
    refuse_overwriting_inputs(out, [args.geometry, args.material, args.maps, args.campaign], written=written)
    names = ",".join(EFFECT_NAMES) if args.effects.strip().lower() == "all" else args.effects
    effects = Effects.from_names(names)
    cfg = CampaignConfig()
    if args.campaign:
        try:
            cfg = CampaignConfig.from_dict(json.loads(Path(args.campaign).read_text(encoding="utf-8")))
        except json.JSONDecodeError as exc:
            raise RigError(f"{args.campaign}:{exc.lineno}: not valid JSON: {exc.msg}") from None
    truth_dir = out / "truth"
    material_path = None
    if args.material:
        src = Path(args.material)
        if not src.is_file():
            raise RigError(f"{src}: no such material file")
        truth_dir.mkdir(parents=True, exist_ok=True)
        material_path = truth_dir / src.name
        if src.resolve() != material_path.resolve():
            shutil.copyfile(src, material_path)
    if args.maps:
        maps_dir = Path(args.maps)
    else:
        if material_path is None:
            raise RigError("give --material TRUE.csv (the FEM builds the true maps) or --maps MAPSDIR")
        from ..field import load_geometry, load_material
        from ..maps import build_maps, default_currents, default_positions, save_maps

        geometry = load_geometry(args.geometry)
        material = load_material(material_path)
        st = geometry.stroke
        maps = build_maps(geometry, material, x_m=default_positions(st.min_m, st.max_m, 12),
                          i_A=default_currents(1.25 * geometry.coil.max_current_A, 16),
                          mesh_size=args.mesh_size, name="truth")
        maps_dir = truth_dir / "maps"
        save_maps(maps, maps_dir)
    try:
        tables = load_tables(maps_dir)
    except ModelError as exc:
        raise RigError(f"cannot use the maps: {exc}") from None
    geometry_name = ((tables.meta.get("provenance") or {}).get("geometry") or {}).get("name")
    if not args.campaign and isinstance(geometry_name, str) and geometry_name.strip():
        cfg = dataclasses.replace(cfg, solenoid=geometry_name.strip())
    print(f"rig: {cfg.solenoid}, effects: {', '.join(effects.names()) or 'none'}, maps: {maps_dir}")
    truth = run_campaign(tables, out, effects=effects, campaign=cfg, seed=args.seed,
                         material_path=material_path, maps_dir=maps_dir, progress=True)
    print(f"wrote {len(truth.recordings)} recordings to {out / 'recordings'} and {out / 'truth.json'}")
    return 0
