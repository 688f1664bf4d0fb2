"""The loop started from what the pipeline identifies, on the twelve truth-steel campaigns (issue 20).

Each campaign of :mod:`steelcampaigns` (seven published and five random steels on randomized
protocols, with none, heating, an eddy ladder, hysteresis or heating + hysteresis) goes the pipeline's
way, in memory: B(H) identified from the recordings (quick preset), maps of that steel with the eddy
conductance (:func:`solenoid_fmu.pipeline.campaign_maps`, the ``medium`` preset: quick's 9 x 12 grid alone
left 1.3-1.5 % of full scale in the force by interpolation and decided random-1's verdict), then the loop
(:func:`solenoid_fmu.loop.improve_tables`). Never the true maps: the material error the identification
leaves is in the model the loop starts from, as it is for a user.

Asked: exactly the true effects found (nothing on the clean campaigns), and the pooled held-out error
(the RMS over the validation recordings and their signals of the full-scale NRMSE, the loop's own
validation measure) of the final model at 1/3 or less of the bare identified model's (no effect, no
eddy term) where there are effects. "Found" are the effects the loop added and ``eddy`` where the
pipeline's step 4 measured an eddy current (:func:`solenoid_fmu.pipeline.effects_found`): the eddy
ladder of the rig is the paper's eddy term (G_eddy in the maps) and the loop's ladder only refines it.
"""

from __future__ import annotations

import json
import math

import pytest
from steelcampaigns import CAMPAIGNS, campaign_id, identified

from solenoid_fmu.field import load_geometry, load_material
from solenoid_fmu.loop import improve_tables, split_recordings
from solenoid_fmu.loop.improvement import _cases, _error
from solenoid_fmu.loop.residuals import FluxCache, recording_name
from solenoid_fmu.maps import save_maps
from solenoid_fmu.measure import read_recording
from solenoid_fmu.pipeline import campaign_maps, effects_found
from solenoid_fmu.realtime import load_tables

#: What the loop must add for each truth effect (rig name -> model effect).
EXPECTED = {"hysteresis": "hysteresis", "eddy-ladder": "eddy", "heating": "heating"}
#: The pooled held-out error must fall to this fraction or less where the truth has effects.
CUT = 1.0 / 3.0
#: Campaigns where the loop misses today (issue 20 open): what it added and the pooled held-out
#: NRMSE before -> after [%], measured at the commit that added this list.
SHORT_OF_GOAL = {
    ("9SMn28K", 12): "heating found (resistance tracks), error 0.40 % -> 0.37 % (0.92): from the TRUE curve the loop "
                     "got 0.50 % -> 0.48 % on quick maps (0.47 % on maps at mesh 1.0): heating's share of the error "
                     "is too small",
    ("random-0", 18): "heating found, error 0.53 % -> 0.43 % (0.82); from the TRUE curve 0.82 % -> 0.75 % on quick "
                      "maps (as 9SMn28K)",
}


def _param(name, effects, seed):
    marks = ()
    if (name, seed) in SHORT_OF_GOAL:
        marks = pytest.mark.xfail(reason=f"issue 20 open: {SHORT_OF_GOAL[(name, seed)]}", strict=False)
    return pytest.param(name, effects, seed, marks=marks, id=campaign_id(name, effects, seed))


def loop_on_identified_recordings(folder, curve, work) -> dict:
    """The pipeline's maps + G_eddy -> loop on a campaign folder and an identified curve, in memory
    (``work``: a folder for the maps the loop reads); what it found and the pooled held-out error of the
    bare identified model (no effect, no eddy term) and of the final one."""
    recs = [read_recording(p) for p in sorted((folder / "recordings").glob("*.csv"))]
    maps, eddy = campaign_maps(load_geometry(), curve, recs, preset="medium", name="identified")
    save_maps(maps.with_eddy(None, source="bare"), work / "bare")
    save_maps(maps, work / "maps")
    flux_of = FluxCache()
    res = improve_tables(load_tables(work / "maps"), recs, flux_of=flux_of)
    _, val = split_recordings(recs)
    names = {recording_name(r) for r in val}
    bare = _cases(load_tables(work / "bare"), recs, flux_of=flux_of)
    return {"found": effects_found([s.effect for s in res.steps if s.accepted], eddy),
            "tried": [(s.effect, s.accepted) for s in res.steps],
            "eddy_r2": None if eddy is None else eddy.r2,
            "before": math.sqrt(_error(bare, names)), "after": math.sqrt(_error(res.cases_after, names))}


def loop_on_identified(shared, name, effects, seed, work) -> dict:
    """:func:`loop_on_identified_recordings` on a campaign of :mod:`steelcampaigns`."""
    folder, csv = identified(shared, name, effects, seed)
    return loop_on_identified_recordings(folder, load_material(csv), work)


@pytest.mark.slow
@pytest.mark.parametrize(("name", "effects", "seed"), [_param(*c) for c in CAMPAIGNS])
def test_loop_from_identified_maps_adds_exactly_the_true_effects(shared_campaigns, tmp_path, name, effects, seed):
    out = loop_on_identified(shared_campaigns, name, effects, seed, tmp_path)
    want = sorted(EXPECTED[e] for e in effects.split(",") if e)
    msg = json.dumps(out)
    assert out["found"] == want, msg
    if want:
        assert out["after"] <= CUT * out["before"], msg
    else:  # nothing added; an eddy term too small to count as measured does not make the model worse
        assert not any(ok for _, ok in out["tried"]) and out["after"] <= 1.001 * out["before"], msg
