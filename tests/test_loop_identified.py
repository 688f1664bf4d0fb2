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
from steelcampaigns import CAMPAIGNS, campaign_id, identified, once_per_session
from truthsteels import truth_dir

from solenoid_fmu.field import load_geometry, load_material
from solenoid_fmu.loop import improve_tables, split_recordings, with_effects
from solenoid_fmu.loop.gates import noise_floor
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
    ("9SMn28K", 12): "heating found, error 0.29 % -> 0.26 % (0.89), the rig's own C_th, R_th on the same maps 0.25 %; "
                     "the cut asks for 0.097 %, below the exact model (truth maps + the rig's heating: 0.19 % -> "
                     "0.13 %, 0.69) and near the sensors' white noise alone (0.09 %): no model reaches it "
                     "(test_heating_alone_...)",
    ("random-0", 18): "heating found, error 0.22 % -> 0.14 % (0.65), as good as the rig's own C_th, R_th on the same "
                      "maps (0.14 %); the exact model (truth maps + the rig's heating) 0.20 % -> 0.12 % (0.58) misses "
                      "the cut too. Stop 42 had 0.46 -> 0.16 % (0.35), the exact model 0.46 -> 0.12 % (stop 39): "
                      "the eq.-4 offset from the rests (stop 43; the exact model does not depend on the "
                      "identification) took 0.26 points out of the bare models' error, and what heating changes is "
                      "now near the noise (0.11 %)",
}


def _param(name, effects, seed):
    marks = ()
    if (name, seed) in SHORT_OF_GOAL:
        marks = pytest.mark.xfail(reason=f"issue 20 open: {SHORT_OF_GOAL[(name, seed)]}", strict=False)
    return pytest.param(name, effects, seed, marks=marks, id=campaign_id(name, effects, seed))


def _heating_section(heating: dict, alpha_per_K: float) -> dict:
    """The model's heating section for the rig's coil heating (``truth.json`` ``effects.heating``)."""
    return {"heating": {"C_th_J_per_K": heating["C_th_J_per_K"], "R_th_K_per_W": heating["R_th_K_per_W"],
                        "alpha_per_K": alpha_per_K}}


def loop_on_identified_recordings(folder, curve, work, truth_tables=None, *, preset: str = "medium",
                                  executor=None) -> dict:
    """The pipeline's maps + G_eddy -> loop on a campaign folder and an identified curve, in memory
    (``work``: a folder for the maps the loop reads); what it found and the pooled held-out error of the
    bare identified model (no effect, no eddy term) and of the final one, and the final residuals' white noise
    alone (``noise_floor``, :func:`solenoid_fmu.loop.gates.noise_floor`: what no model can go below). ``preset``:
    the maps' (:data:`solenoid_fmu.pipeline.PRESETS`; the test's ``medium``, the pipeline's default ``full``),
    their FEM sweep run by ``executor`` (default: in this process).

    Where the rig's only effect is coil heating and ``truth_tables`` (the truth's maps) are given, also the
    reference a perfect loop is judged by: ``true_heating``, the identified maps with the rig's own C_th and
    R_th (``truth.json``) instead of the fitted ones; ``perfect_before`` and ``perfect_after``, the truth's
    maps without and with the rig's heating (nothing identified, nothing fitted): what the sensors' noise,
    offsets and channel delays and eq. 4 leave of the error when the model is exact."""
    recs = [read_recording(p) for p in sorted((folder / "recordings").glob("*.csv"))]
    maps, eddy = campaign_maps(load_geometry(), curve, recs, preset=preset, name="identified", executor=executor)
    save_maps(maps.with_eddy(None, source="bare"), work / "bare")
    save_maps(maps, work / "maps")
    flux_of = FluxCache()
    tables = load_tables(work / "maps")
    res = improve_tables(tables, recs, flux_of=flux_of, eddy_measured=eddy is not None and eddy.measurable)
    _, val = split_recordings(recs)
    names = {recording_name(r) for r in val}
    # maps without an eddy term (step 4 measured none: G_model_S 0) are the bare model: the loop's first simulation
    bare = res.cases_before if not tables.G_eddy_S else _cases(load_tables(work / "bare"), recs, flux_of=flux_of)
    out = {"found": effects_found([s.effect for s in res.steps if s.accepted], eddy),
           "tried": [(s.effect, s.accepted) for s in res.steps],
           "eddy_r2": None if eddy is None else eddy.r2,
           "before": math.sqrt(_error(bare, names)), "after": math.sqrt(_error(res.cases_after, names)),
           "noise_floor": math.sqrt(noise_floor(res.cases_after, names))}
    effects = json.loads((folder / "truth.json").read_text())["effects"]
    if truth_tables is not None and [k for k, v in effects.items() if v and k != "noise"] == ["heating"]:
        def err(tables):
            return math.sqrt(_error(_cases(tables, recs, flux_of=flux_of), names))

        out["true_heating"] = err(with_effects(tables, _heating_section(effects["heating"], tables.coil.alpha_per_K)))
        out["perfect_before"] = err(truth_tables)
        out["perfect_after"] = err(with_effects(truth_tables, _heating_section(effects["heating"],
                                                                               truth_tables.coil.alpha_per_K)))
    return out


def loop_on_identified(shared, name, effects, seed) -> dict:
    """:func:`loop_on_identified_recordings` on a campaign of :mod:`steelcampaigns` (with its truth's maps),
    computed once per session (a JSON file beside the campaign, shared by the xdist workers)."""
    folder, csv = identified(shared, name, effects, seed)

    def compute(work):
        return loop_on_identified_recordings(folder, load_material(csv), work, load_tables(truth_dir(name)))

    return once_per_session(shared, f"{folder.name}-loop", compute)


@pytest.mark.slow
@pytest.mark.parametrize(("name", "effects", "seed"), [_param(*c) for c in CAMPAIGNS])
def test_loop_from_identified_maps_adds_exactly_the_true_effects(shared_campaigns, name, effects, seed):
    out = loop_on_identified(shared_campaigns, name, effects, seed)
    want = sorted(EXPECTED[e] for e in effects.split(",") if e)
    msg = json.dumps(out)
    assert out["found"] == want, msg
    if want:
        assert out["after"] <= CUT * out["before"], msg
    else:  # nothing added; an eddy term too small to count as measured does not make the model worse
        assert not any(ok for _, ok in out["tried"]) and out["after"] <= 1.001 * out["before"], msg


#: The campaigns whose rig had coil heating alone (two of SHORT_OF_GOAL).
HEATING_ONLY = [c for c in CAMPAIGNS if c[1] == "heating"]


@pytest.mark.slow
@pytest.mark.parametrize(("name", "effects", "seed"), [pytest.param(*c, id=campaign_id(*c)) for c in HEATING_ONLY])
def test_heating_alone_is_fitted_as_well_as_the_rigs_own_and_no_heating_makes_the_cut(shared_campaigns, name,
                                                                                     effects, seed):
    """Why the heating-only campaigns are SHORT_OF_GOAL, checked rather than said: the loop's heating (C_th and R_th
    fitted from the resistance tracks and the flux residual, each run started at its temperature above ambient)
    leaves no more error than the rig's own C_th and R_th would on the same identified maps, and that one misses
    the cut too: no heating can make it on these maps. The exact model (the truth's maps with the rig's heating,
    nothing identified or fitted) still leaves more than the sensors' white noise, and more than a third of the bare
    identified model's error: not even the exact model, were the loop to reach it, would make the cut. When this
    test fails on one of its last two assertions, the cut has come within reach and SHORT_OF_GOAL must be looked at
    again."""
    out = loop_on_identified(shared_campaigns, name, effects, seed)
    msg = json.dumps(out)
    assert out["found"] == ["heating"], msg
    assert out["after"] < out["before"], msg
    assert out["after"] <= 1.05 * out["true_heating"], msg
    assert out["perfect_after"] < out["perfect_before"], msg
    assert out["noise_floor"] < out["perfect_after"], msg  # the exact model's error is more than noise
    assert out["true_heating"] > CUT * out["before"], msg
    assert out["perfect_after"] > CUT * out["before"], msg  # no model in the loop's reach makes the cut
