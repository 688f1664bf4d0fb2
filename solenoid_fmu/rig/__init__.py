"""rig: the virtual test rig (a known truth runs the test campaign and writes recordings).

Modules: :mod:`.effects` (the truth's effects), :mod:`.excitation` (what the rig drives, the
campaign), :mod:`.truth` (the truth model), :mod:`.daq` (sensors and converters),
:mod:`.campaign` (running a campaign, ``truth.json``), :mod:`.protocols` (randomized campaigns
of other rigs, for tests), :mod:`.steels` (randomized steels, for tests), :mod:`.lot` (a production lot:
units around a nominal steel, some out of spec), :mod:`.cli` (``solenoid-fmu rig``).
"""

from .campaign import TRUTH_SCHEMA, RigTruth, read_truth, run_campaign, run_excitations
from .daq import DataAcquisition, TruthResult, measure
from .effects import EFFECT_NAMES, EddyLadder, Effects, Friction, Heating, HysteresisEffect
from .errors import RigError
from .excitation import CampaignConfig, Excitation, campaign_excitations
from .lot import EOL_CAMPAIGN, LotUnit, draw_lot, plan_lot, scale_turns
from .protocols import random_campaign, random_protocol
from .steels import random_steel, random_steel_parameters
from .truth import TruthModel

__all__ = [
    "EFFECT_NAMES",
    "EOL_CAMPAIGN",
    "TRUTH_SCHEMA",
    "CampaignConfig",
    "DataAcquisition",
    "EddyLadder",
    "Effects",
    "Excitation",
    "Friction",
    "Heating",
    "HysteresisEffect",
    "LotUnit",
    "RigError",
    "RigTruth",
    "TruthModel",
    "TruthResult",
    "campaign_excitations",
    "draw_lot",
    "measure",
    "plan_lot",
    "random_campaign",
    "random_protocol",
    "read_truth",
    "run_campaign",
    "random_steel",
    "random_steel_parameters",
    "scale_turns",
    "run_excitations",
]
