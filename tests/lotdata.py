"""The test lot: :func:`solenoid_fmu.rig.lot.plan_lot` drawn on truth maps shipped in ``tests/data/``.

``tests/data/lot-truths/<unit>/`` holds the maps of every unit whose steel is a batch draw of the nominal one
(made by ``tests/data/make_lot_truths.py``); the ``steel`` out-of-spec unit reads the published steel's truth
in ``tests/data/truth-steels/``. :func:`draw` writes the lot's campaigns (a second or two).
"""

from __future__ import annotations

from pathlib import Path

from solenoid_fmu.realtime import load_tables
from solenoid_fmu.rig import draw_lot, plan_lot

DATA = Path(__file__).resolve().parent / "data"
LOT_TRUTHS_DIR = DATA / "lot-truths"
#: The lot's nominal steel (DC03's published Roschke table): where every unit's identification starts
#: (``solenoid-fmu batch --start-material``), as a valve maker starts from the steel's datasheet.
NOMINAL_STEEL_CSV = DATA / "truth-steels" / "DC03" / "steel.csv"
#: Units and seed of the test lot (3 nominal, 2 with an undeclared effect, 3 out of spec).
N_UNITS = 8
SEED = 23


def plan():
    """The test lot's plan (list of :class:`solenoid_fmu.rig.lot.LotUnit`)."""
    return plan_lot(N_UNITS, SEED)


def truth_tables(unit):
    """The truth maps of a unit's steel (nominal coil)."""
    if unit.steel_name == "nominal":
        return load_tables(LOT_TRUTHS_DIR / unit.name)
    return load_tables(DATA / "truth-steels" / unit.steel_name)


def draw(out_dir, units=None):
    """Write the lot's campaigns to ``out_dir/<unit>/`` (and ``lot-truth.json``); returns the folders."""
    return draw_lot(plan() if units is None else units, truth_tables, out_dir, seed=SEED)
