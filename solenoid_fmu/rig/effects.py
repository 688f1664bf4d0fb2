r"""The effects the rig's truth can have, switchable by name, with physically sensible defaults.

Each effect is a frozen dataclass of parameters; :class:`Effects` holds the ones switched on
(None = off). What each does in the truth (:mod:`solenoid_fmu.rig.truth`):

``hysteresis`` (:class:`HysteresisEffect`)
    Rate-independent magnetic hysteresis acting on the flux-current relation: a Preisach
    operator (:class:`~solenoid_fmu.realtime.PreisachHysteresis`, deliberately not the play
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
``noise`` (:class:`~solenoid_fmu.rig.DataAcquisition`)
    The data acquisition: Gaussian sensor noise on every channel, a voltage offset (5 mV),
    a current offset, and quantization of each channel to its ADC resolution
    (:mod:`solenoid_fmu.rig.daq`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from .daq import DataAcquisition
from .errors import RigError, positive

__all__ = ["EFFECT_NAMES", "EddyLadder", "Effects", "Friction", "Heating", "HysteresisEffect"]

#: Names of the switchable effects (CLI ``--effects``).
EFFECT_NAMES = ("hysteresis", "eddy-ladder", "heating", "friction", "noise")


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
        (see :meth:`~solenoid_fmu.realtime.PreisachHysteresis.with_coercive`).
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
        G = tuple(positive(f"eddy G_S[{k}]", v) for k, v in enumerate(self.G_S))
        tau = tuple(positive(f"eddy tau_s[{k}]", v) for k, v in enumerate(self.tau_s))
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
        positive("C_th_J_per_K", self.C_th_J_per_K)
        positive("R_th_K_per_W", self.R_th_K_per_W)

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
        positive("friction force_N", self.force_N, allow_zero=True)
        positive("friction presliding_m", self.presliding_m)




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
