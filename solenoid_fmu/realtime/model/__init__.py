r"""The real-time lumped solenoid model, paper eqs. (1)-(3) with the eddy-current term.

This package imports only numpy and the standard library: it is copied verbatim into every FMU
(as the package ``solenoid_model_<hash>/``) and must not import anything from ``solenoid_fmu`` (its
modules import each other relatively). The equations (SI units throughout)::

    U = R i + dPsi/dt                          paper eq. (1)
    i = i_f(Psi, x) + i_eddy,  i_eddy = G dPsi/dt   paper eq. (2), G = G_eddy [S] (the paper's L_eddy)
    F = F(Psi, x)                              paper eq. (3)

The state is the flux linkage ``Psi`` [Wb]; ``x`` [m] is the armature working gap (an input);
``F`` [N] is positive when it pulls the armature towards the pole (closing the gap).

Drive modes
-----------
``voltage`` (1): input ``U`` [V]. Eliminating ``i`` gives the ODE
``(1 + R G) dPsi/dt = U - R i_f(Psi, x)``. Outputs ``i``, ``dPsi/dt``, ``i_eddy``, ``F`` are
the instantaneous values at the communication point.

``current`` (2): input ``i`` [A]. With ``G > 0`` the ODE is ``G dPsi/dt = i - i_f(Psi, x)``;
with ``G = 0`` the relation is algebraic, ``i_f(Psi, x) = i``, solved by a safeguarded Newton
iteration. The outputs ``dPsi/dt``, ``U = R i + dPsi/dt`` and ``i_eddy = G dPsi/dt`` are the
exact means over the last communication step, ``dPsi/dt = (Psi(t+h) - Psi(t)) / h``: with a
held input current an instantaneous value would miss the flux jump at each communication point
(and would be zero in the algebraic case), while the mean is the voltage whose integral gives
the flux (the same relation the test rig uses, paper eq. 4). ``Psi`` and ``F`` are
instantaneous. Before the first step the instantaneous values are reported.

Inputs are held constant over a communication step (zero-order hold, FMI 2.0 co-simulation
without input interpolation). Outputs after a step are computed with the inputs of that step:
no output depends directly on an input set at the same communication point.

Map lookup (reproduce exactly in generated code)
------------------------------------------------
The maps are ``i_f(Psi, x)`` and ``F(Psi, x)`` on a regular flux grid ``psi_k = k dpsi``
(``k = 0 .. n_psi - 1``) times a strictly increasing gap grid ``x_j``. Along ``Psi`` the tables
are interpolated by a monotone piecewise cubic Hermite (PCHIP, C1 in ``Psi``; monotone data give
a monotone ``i_f``, so the inverse is unique); along ``x`` linearly. When the maps are loaded,
the node slopes (scaled by ``dpsi``, :func:`pchip_scaled_slopes`) are turned into the cubic
coefficients ``c0..c3`` of every cell and their differences ``e0..e3`` to the next x column
(:func:`cell_coefficients`); generated C embeds these arrays (:meth:`MapTables.tables`) rather
than recomputing them.

For ``Psi < 0`` the solenoid's symmetry is used (no remanence in the lumped map):
``i_f(-Psi, x) = -i_f(Psi, x)`` and ``F(-Psi, x) = F(Psi, x)``. Then, with ``a = |Psi|``
clamped to ``[0, psi_max]`` and ``x`` clamped to ``[x_0, x_last]``::

    s = a * inv_dpsi;  k = min(int(s), n_psi - 2);  t = s - k
    j = index of the x cell (bisect, clamped to 0 .. n_x - 2);  w = (x - x_j) * inv_dx_j
    (q0..q3, e0..e3) = coefficients of cell (k, j);  c_i = q_i + w * e_i
    value = c0 + t (c1 + t (c2 + t c3))
    d value / d Psi = (c1 + t (2 c2 + 3 t c3)) * inv_dpsi

Integrator
----------
Per communication step ``h`` the model takes ``n = max(1, ceil(h / h_sub_max - 1e-9))`` equal
sub-steps. An ODE sub-step is the two-stage, second-order, L-stable Rosenbrock method ROS2
(Verwer, Spee, Blom and Hundsdorfer 1999, gamma = 1 + 1/sqrt(2)) applied to
``m dPsi/dt = f(Psi) = b - c i_f(Psi, x)`` (voltage mode ``m = 1 + R G, b = U, c = R``;
current mode ``m = G, b = i, c = 1``)::

    W  = m + gamma * hs * c * di_f/dPsi(Psi_n)
    k1 = f(Psi_n) / W
    k2 = (f(Psi_n + hs k1) - 2 m k1) / W
    Psi_{n+1} = Psi_n + 1.5 hs k1 + 0.5 hs k2

It is linearly implicit, so its work is fixed (two map lookups per sub-step, no iteration; the
first lookup of a step reuses the output evaluation that ended the previous step when Psi and
the x cell are unchanged, which gives bit-identical values), it stays stable for any sub-step
(L-stable) and remains well defined for ``m -> 0``. The algebraic
case (current mode, ``G = 0``) solves ``i_f(Psi, x) = i`` once per communication step with a
Newton iteration safeguarded by bisection on ``[0, psi_max]`` (at most ``NEWTON_MAX_ITER``
iterations, stop when the update is below ``NEWTON_TOL_REL * psi_max``). Both paths have a
bounded amount of work per communication step, a requirement of real-time execution.

Out-of-map operation
--------------------
``x`` outside ``[x_0, x_last]`` and ``|Psi|`` beyond ``psi_max`` are clamped (the flux state
itself is held at ``+-psi_max``, so it does not wind up). Each excursion is reported once, when
it begins, as an event in :attr:`SolenoidModel.events` (the FMU turns each into one FMI log
message); it is reported again only after the value has returned into the map. Entering the
part of the map that lies beyond the FEM data (``|i_f|`` above the sweep's largest current
``i_A[-1]``, where the maps are linearly extrapolated) is reported the same way. A NaN or
infinite input, ``R <= 0`` or ``G < 0`` raises :class:`ModelInputError` and leaves the state
untouched.

State and parameters
--------------------
The full internal state is a flat list of floats (:meth:`SolenoidModel.get_state`,
:meth:`SolenoidModel.set_state`, names in :data:`STATE_NAMES`), so that a rollback is exact.
Parameters are a dict (:data:`DEFAULT_PARAMS`). The effect sub-models (hysteresis play operators,
eddy-current ladder, coil heating, friction) keep their states after the base ones (``FX_*`` indices) and
have switchable parameters whose defaults follow maps.json's ``effects`` section.

Modules (each by job; the package is the FMU payload: numpy and the standard library only, relative
imports among its own modules, copied whole into every pythonfmu FMU)
------------------------------------------------------------------------------------------------
``definitions`` constants, state layout (named indices ``ST_*``, ``FX_*``), parameters, errors;
``maps_io`` the maps file format and its checks, :func:`load_tables`; ``records`` the typed records of
maps.json's metadata (:class:`CoilRecord`, :class:`EddyRecord`, :class:`EffectsRecord`); ``tables``
:class:`MapTables` and the one cell lookup :func:`~.tables.cell_cubic`; ``effects`` the effects section of maps.json;
``play`` the play operator; ``params`` the parameter checks; ``integrate`` the ROS2 sub-steps;
``solenoid`` :class:`SolenoidModel`.
"""

from __future__ import annotations

from .definitions import (
    COPPER_ALPHA_PER_K,
    DEFAULT_PARAMS,
    DRIVE_CURRENT,
    DRIVE_VOLTAGE,
    EFFECT_NAMES,
    EFFECT_STATE_NAMES,
    MAX_SUBSTEPS,
    NEWTON_MAX_ITER,
    NEWTON_TOL_REL,
    ROS2_GAMMA,
    STATE_LAYOUT,
    STATE_NAMES,
    T_START_EXCESS_RANGE_K,
    ModelError,
    ModelInputError,
    ModelMapsError,
    heating_alpha,
)
from .effects import effects_data
from .maps_io import (
    MAPS_JSON,
    MAPS_MAX_ARRAY_ELEMENTS,
    MAPS_NPZ,
    MAPS_PREVIOUS,
    MAPS_SCHEMA,
    MAPS_SCHEMA_VERSION,
    load_tables,
    maps_pair_consistent,
    read_maps_dir,
)
from .play import play_step
from .records import CoilRecord, EddyRecord, EffectsRecord, coil_problems, eddy_problems, replace_meta
from .solenoid import SolenoidModel
from .tables import MapTables, cell_coefficients, pchip_scaled_slopes

__all__ = [
    "COPPER_ALPHA_PER_K",
    "DEFAULT_PARAMS",
    "DRIVE_CURRENT",
    "DRIVE_VOLTAGE",
    "EFFECT_NAMES",
    "EFFECT_STATE_NAMES",
    "MAPS_SCHEMA",
    "MAPS_SCHEMA_VERSION",
    "MAX_SUBSTEPS",
    "CoilRecord",
    "EddyRecord",
    "EffectsRecord",
    "MapTables",
    "ModelError",
    "ModelInputError",
    "ModelMapsError",
    "NEWTON_MAX_ITER",
    "NEWTON_TOL_REL",
    "ROS2_GAMMA",
    "SolenoidModel",
    "STATE_LAYOUT",
    "STATE_NAMES",
    "T_START_EXCESS_RANGE_K",
    "cell_coefficients",
    "coil_problems",
    "eddy_problems",
    "effects_data",
    "heating_alpha",
    "load_tables",
    "pchip_scaled_slopes",
    "MAPS_JSON",
    "MAPS_NPZ",
    "MAPS_MAX_ARRAY_ELEMENTS",
    "MAPS_PREVIOUS",
    "maps_pair_consistent",
    "play_step",
    "read_maps_dir",
    "replace_meta",
]
