r"""The virtual test rig: a campaign of recordings of a known solenoid (``sf.run_rig``).

The rig simulates the solenoid the maps describe, plus effects the model does not have
(``effects``: e.g. friction, hysteresis, heating, an eddy ladder, noise), through the test
protocols of the recording format (flux triangles, force strokes, ramps, eddy triangles, voltage
steps) and writes them as a campaign folder: ``recordings/*.csv`` and ``truth.json``. Run::

    python examples/ex_run_rig.py [MAPS_DIR] [OUT_DIR] [EFFECTS]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import solenoid_fmu as sf
from solenoid_fmu.rig import CampaignConfig

#: A short campaign: every kind of recording, a few seconds of rig time each.
SHORT = CampaignConfig(
    flux_peaks_A=(0.5, 1.0, 1.5), flux_cycles=1, flux_rate_A_per_s=2.0, flux_sample_rate_Hz=200.0,
    stroke_currents_A=(0.5, 1.0, 1.5), stroke_from_m=2.5e-3, stroke_to_m=0.6e-3, stroke_speed_m_per_s=1e-3,
    stroke_sample_rate_Hz=50.0, ramp_sample_rate_Hz=1000.0, ramp_hold_s=0.1, eddy_rates_A_per_s=(25.0, 100.0),
    eddy_cycles=1, eddy_sample_rate_Hz=4000.0, step_hold_s=0.3, step_sample_rate_Hz=1000.0, pause_s=5.0)


def run(maps_dir="maps/ps45-literature", out_dir="build/ex_run_rig", effects: str = "friction,noise",
        seed: int = 1) -> dict:
    """Run the short campaign; returns the folder, the recordings by kind and the truth's effects."""
    folder = sf.run_rig(maps_dir, out_dir, effects=effects, seed=seed, campaign=SHORT)
    by_kind: dict = {}
    for p in sorted((folder / "recordings").glob("*.csv")):
        by_kind.setdefault(sf.read_recording(p).kind, []).append(p)
    truth = json.loads((Path(folder) / "truth.json").read_text())
    return {"folder": folder, "by_kind": by_kind, "truth_effects": truth["effects"], "kinds": SHORT.tests}


if __name__ == "__main__":
    r = run(*sys.argv[1:4])
    for kind, paths in r["by_kind"].items():
        print(f"{kind}: {len(paths)} recordings")
