"""A production lot on the rig: N units around one nominal steel, a few with an undeclared effect, a few out of spec.

The valve maker measures every solenoid at end of line. :func:`plan_lot` draws what each unit of a lot
*is* (pure, seeded, cheap); :func:`draw_lot` runs the end-of-line campaign (:data:`EOL_CAMPAIGN`, the
same short protocol for every unit) on each unit's truth and writes one campaign folder per unit plus
``lot-truth.json`` (for tests: which units are out of spec and why). The truth maps of a unit's steel
are the caller's (an FEM per steel is minutes; ``tests/data/make_lot_truths.py`` computes them with a
discretization other than the identification's, so there is no inverse crime).

A unit (:class:`LotUnit`) is one of

* ``nominal``: the nominal steel with batch variation: Roschke's ``B_myMax`` (the flux density of peak
  permeability, which sets B at the knee and above) drawn with a relative sigma :data:`BATCH_SIGMA_B` (1 %),
  ``c_a`` (the rise of the permeability) log-normal with :data:`BATCH_SIGMA_CA` (3 %); the coil resistance
  at 20 degC with :data:`BATCH_SIGMA_R` (0.3 %); the friction force around :data:`NOMINAL_FRICTION_N`
  with 5 %;
* ``effect``: a nominal unit whose truth has an undeclared, in-spec effect (coil heating, eddy ladder):
  the model must take it on, the lot must not flag it;
* ``out-of-spec``: ``steel`` (another published steel, B 10-25 % lower than the nominal's over the
  working range), ``friction`` (:data:`HIGH_FRICTION_FACTOR` x the nominal friction), ``turns`` (a
  coil with :data:`FEW_TURNS_FACTOR` x the turns: resistance and flux both 15 % off).

Fewer turns scale the truth's maps exactly: with k = N'/N the same field needs k times the current's
ampere-turns, so Psi'(i) = k Psi(k i) and F'(i) = F(k i); on the flux grid, ``i_f'(k Psi) = i_f(Psi) / k``
and ``F'(k Psi) = F(Psi)`` (:func:`scale_turns`). The resistance of the same wire scales with k.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from ..field import STEELS, RoschkeParameters
from ..fileio import atomic_write_text
from ..realtime import MapTables, replace_meta
from .campaign import run_campaign
from .effects import Effects, Friction
from .errors import RigError
from .excitation import CampaignConfig

__all__ = ["BATCH_SIGMA_B", "BATCH_SIGMA_CA", "BATCH_SIGMA_R", "EOL_CAMPAIGN", "FEW_TURNS_FACTOR",
           "HIGH_FRICTION_FACTOR", "LOT_TRUTH", "NOMINAL_FRICTION_N", "LotUnit", "draw_lot", "plan_lot",
           "scale_turns", "unit_steel"]

#: Relative 1-sigma batch spread of Roschke's B_myMax (B at the knee and above).
BATCH_SIGMA_B = 0.01
#: Relative 1-sigma (log-normal) batch spread of Roschke's c_a.
BATCH_SIGMA_CA = 0.03
#: Relative 1-sigma spread of the coil resistance at 20 degC.
BATCH_SIGMA_R = 0.003
#: Sliding friction of a nominal unit [N] (relative spread 5 %).
NOMINAL_FRICTION_N = 1.0
#: The out-of-spec ``friction`` unit's friction, in nominal frictions.
HIGH_FRICTION_FACTOR = 4.0
#: The out-of-spec ``turns`` unit's turns, in nominal turns.
FEW_TURNS_FACTOR = 0.85
#: The lot's truth file (beside the unit folders).
LOT_TRUTH = "lot-truth.json"

#: The end-of-line campaign: one flux triangle to 2 A at mid-stroke, one force stroke there and back at
#: 1.5 A, two eddy triangles; ~15 s of rig time, every kind the pipeline reads the steel, friction and eddy
#: currents from.
EOL_CAMPAIGN = CampaignConfig(
    tests=("flux", "force_stroke", "eddy"), flux_peaks_A=(2.0,), flux_cycles=1, flux_rate_A_per_s=4.0,
    flux_sample_rate_Hz=200.0, stroke_currents_A=(1.5,), stroke_from_m=2.5e-3, stroke_to_m=0.6e-3,
    stroke_speed_m_per_s=2e-3, stroke_sample_rate_Hz=50.0, eddy_rates_A_per_s=(25.0, 100.0), eddy_cycles=1,
    eddy_peak_A=1.0, eddy_sample_rate_Hz=2000.0, pause_s=5.0)


@dataclasses.dataclass(frozen=True)
class LotUnit:
    """What one unit of a lot is (SI).

    Attributes
    ----------
    name : str
        Folder name of the unit's campaign.
    kind : {"nominal", "effect", "out-of-spec"}
    steel : RoschkeParameters
        The unit's true steel (a batch draw around the nominal, or another published steel).
    steel_name : str
        ``nominal`` for batch draws, else the published steel's name (the key of :data:`~solenoid_fmu.field.STEELS`).
    R20_factor : float
        Coil resistance at 20 degC in nominal resistances.
    turns_factor : float
        Coil turns in nominal turns.
    friction_N : float
        Sliding friction force [N].
    effects : str
        Undeclared effects (``solenoid-fmu rig --effects`` names) besides friction.
    reason : str
        Why the unit is out of spec (empty otherwise).
    """

    name: str
    kind: str
    steel: RoschkeParameters
    steel_name: str = "nominal"
    R20_factor: float = 1.0
    turns_factor: float = 1.0
    friction_N: float = NOMINAL_FRICTION_N
    effects: str = ""
    reason: str = ""

    def to_dict(self) -> dict:
        """JSON-able content."""
        d = dataclasses.asdict(self)
        d["steel"] = dataclasses.asdict(self.steel)
        return d


def unit_steel(nominal: RoschkeParameters, rng: np.random.Generator, name: str) -> RoschkeParameters:
    """A batch draw of the nominal steel: ``B_myMax`` x (1 + N(0, 1 %)), ``c_a`` x exp(N(0, 3 %))."""
    B = float(nominal.B_myMax_T * (1.0 + BATCH_SIGMA_B * rng.standard_normal()))
    return dataclasses.replace(nominal, B_myMax_T=B,
                               c_a=float(nominal.c_a * np.exp(BATCH_SIGMA_CA * rng.standard_normal())),
                               label=f"{nominal.label}, batch draw {name}", record="lot batch draw")


def plan_lot(n: int = 10, seed: int = 0, *, nominal: str = "DC03", effects=("heating", "eddy-ladder"),
             out_of_spec=("steel", "friction", "turns"), other_steel: str = "9SMn28K") -> list[LotUnit]:
    """Draw what each unit of a lot is (module docstring): ``n`` units, the last ``len(out_of_spec)`` out of
    spec, the ``len(effects)`` before them with one undeclared effect each, the rest nominal.

    Parameters
    ----------
    n : int
        Units in the lot.
    seed : int
        Seeds every draw (same seed, same lot).
    nominal, other_steel : str
        Published steels (:data:`solenoid_fmu.field.STEELS`): the lot's and the ``steel`` unit's.
    effects : sequence of str
        One undeclared effect per ``effect`` unit.
    out_of_spec : sequence of {"steel", "friction", "turns"}

    Returns
    -------
    list of LotUnit
        Named ``u01``, ``u02``, ...
    """
    for s in (nominal, other_steel):
        if s not in STEELS:
            raise RigError(f"unknown steel {s!r}; known: {', '.join(STEELS)}")
    bad = sorted(set(out_of_spec) - {"steel", "friction", "turns"})
    if bad:
        raise RigError(f"unknown out-of-spec kind(s) {bad}; known: steel, friction, turns")
    n_nominal = n - len(effects) - len(out_of_spec)
    if n_nominal < 3:
        raise RigError(f"a lot of {n} units leaves {n_nominal} nominal ones; the median needs at least 3")
    rng = np.random.default_rng([seed, 0x107])
    units = []
    for k in range(n):
        name = f"u{k + 1:02d}"
        steel = unit_steel(STEELS[nominal], rng, name)
        common = {"R20_factor": float(1.0 + BATCH_SIGMA_R * rng.standard_normal()),
                  "friction_N": float(NOMINAL_FRICTION_N * (1.0 + 0.05 * rng.standard_normal()))}
        if k < n_nominal:
            units.append(LotUnit(name, "nominal", steel, **common))
        elif k < n_nominal + len(effects):
            units.append(LotUnit(name, "effect", steel, effects=effects[k - n_nominal], **common))
        else:
            what = out_of_spec[k - n_nominal - len(effects)]
            if what == "steel":
                units.append(LotUnit(name, "out-of-spec", STEELS[other_steel], steel_name=other_steel,
                                     reason=f"another steel ({other_steel})", **common))
            elif what == "friction":
                common["friction_N"] *= HIGH_FRICTION_FACTOR
                units.append(LotUnit(name, "out-of-spec", steel, reason=f"friction x {HIGH_FRICTION_FACTOR:g}",
                                     **common))
            else:
                common["R20_factor"] *= FEW_TURNS_FACTOR
                units.append(LotUnit(name, "out-of-spec", steel, turns_factor=FEW_TURNS_FACTOR,
                                     reason=f"coil with {FEW_TURNS_FACTOR:g} x the turns", **common))
    return units


def scale_turns(tables: MapTables, k: float, R20_factor: float = 1.0) -> MapTables:
    """The truth maps of a coil with ``k`` x the turns (module docstring), resistance x ``R20_factor``."""
    t = tables.tables()
    n_psi = len(t["i_f_A"])
    psi = np.arange(n_psi) * t["dpsi_Wb"]
    coil = tables.coil
    if coil.resistance_ohm_20C is not None:
        coil = dataclasses.replace(coil, resistance_ohm_20C=float(coil.resistance_ohm_20C) * R20_factor)
    meta = replace_meta(tables.meta, coil=coil)
    return MapTables(k * psi, t["x_m"], np.asarray(t["i_f_A"]) / k, t["force_N"], meta=meta,
                     where=f"{tables.where} (turns x {k:g})", i_fem_max_A=t["i_fem_max_A"] / k)


def draw_lot(units, tables_of, out_dir, seed: int = 0, campaign: CampaignConfig = EOL_CAMPAIGN) -> list[Path]:
    """Run the end-of-line campaign on every unit's truth: ``out_dir/<unit>/`` (recordings, ``truth.json``)
    and ``out_dir/lot-truth.json`` (the plan, :meth:`LotUnit.to_dict`).

    Parameters
    ----------
    units : list of LotUnit
        :func:`plan_lot`'s plan.
    tables_of : callable(LotUnit) -> MapTables
        The truth maps of the unit's steel with the nominal coil (turns and resistance are applied here).
    out_dir : path-like
    seed : int
        Seeds the sensor noise (unit k gets ``seed * 1000 + k``).
    campaign : CampaignConfig

    Returns
    -------
    list of Path
        The units' campaign folders, in order.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    folders = []
    for k, u in enumerate(units):
        tables = scale_turns(tables_of(u), u.turns_factor, u.R20_factor)
        fx = Effects.from_names(",".join(["noise", *filter(None, [u.effects])]))
        fx = dataclasses.replace(fx, friction=Friction(force_N=u.friction_N))
        run_campaign(tables, out / u.name, effects=fx, campaign=campaign, seed=seed * 1000 + k)
        folders.append(out / u.name)
    atomic_write_text(out / LOT_TRUTH, json.dumps({"units": [u.to_dict() for u in units]}, indent=1) + "\n")
    return folders
