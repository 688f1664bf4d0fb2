"""The identified B(H) holds on campaigns from other rigs, other steels and with undeclared effects.

Twelve campaigns: seven published steels (Modelica FluxTubes records) and five random ones
(``tests/data/truth-steels``, FEM at a finer, per-stroke mesh at 32 strokes: no inverse crime), each on a
randomized protocol (:func:`solenoid_fmu.rig.random_campaign`: other sample rates, shapes, cycles,
rests, strokes, energized force strokes, voltage offsets) with none, heating, an eddy ladder,
hysteresis or heating + hysteresis at the rig's realistic sizes (heating: the coil's C_th drawn per
campaign in 30-100 J/K, R_th in 1-3 K/W, :func:`solenoid_fmu.rig.protocols.random_heating`: 0.5-1.6 K/s at
2 A, 1.3-8.4 K over these campaigns; hysteresis: 3 % of the rated current; ladder 3 + 2 mS). The identified curve is
judged by what a user gets from it: Psi and F by the FEM at 4 strokes x 5 currents against the
truth, within 1 % and 2 %.

A failing campaign reproduces with ``random_campaign(load_tables(truth_dir(NAME)), DIR, EFFECTS,
seed=SEED, max_samples=SAMPLES)`` (``tests/steelcampaigns.py``) and
``solenoid-fmu identify DIR/recordings/*.csv -o m.csv``.
"""

import json

import numpy as np
import pytest
from steelcampaigns import CAMPAIGNS, campaign_id, identified, once_per_session
from truthsteels import is_published, prediction_errors

PSI_TOL, F_TOL = 0.01, 0.02
#: Campaigns where the identified curve misses the issue's goal today (the issue stays open): the
#: largest error measured (Psi %, F %) at the commit that added this list, 2-core machine.
SHORT_OF_GOAL: dict = {}  # none since stop 37 (Permenorm 0.57 / 2.06 % and random-3 0.84 / 2.50 % before)
#: Campaigns where even the halving guard fails today (none since the branch mean of the first ascent and
#: the highest peak's descent; random-4 failed it before).
NOT_HALVED: set = set()


def _strict(name, effects, seed):
    marks = ()
    if (name, seed) in SHORT_OF_GOAL:
        psi, F = SHORT_OF_GOAL[(name, seed)]
        marks = pytest.mark.xfail(reason=f"issue 20 open: measured Psi {psi} %, F {F} % (goal 1 %, 2 %)",
                                  strict=False)
    return pytest.param(name, effects, seed, marks=marks, id=campaign_id(name, effects, seed))


def test_the_campaigns_cover_published_and_random_steels_and_every_effect():
    published = {n for n, _, _ in CAMPAIGNS if is_published(n)}
    assert len(CAMPAIGNS) >= 12 and len(published) >= 6
    assert {fx for _, fx, _ in CAMPAIGNS} == {"", "heating", "eddy-ladder", "hysteresis", "heating,hysteresis"}


@pytest.mark.slow
def test_the_heated_campaigns_warm_the_coil_by_a_few_kelvin(shared_campaigns):
    """Issue 20's size of the heating: a few kelvin over a campaign (the coil's temperature in truth.json),
    more than 1 K in every heated campaign and 3 K or more in half of them; none without heating."""
    from steelcampaigns import campaign_dir

    spans = {}
    for name, effects, seed in CAMPAIGNS:
        truth = json.loads((campaign_dir(shared_campaigns, name, effects, seed) / "truth.json").read_text())
        T = [t for r in truth["recordings"] for t in (r["temperature_start_C"], r["temperature_end_C"])]
        spans[(name, effects)] = max(T) - min(T)
    heated = [v for (_, fx), v in spans.items() if "heating" in fx]
    assert len(heated) >= 4 and min(heated) > 1.0 and np.median(heated) >= 3.0, spans
    assert all(v < 1e-9 for (_, fx), v in spans.items() if "heating" not in fx), spans


def _errors(shared, name, effects, seed):
    """The identified curve's prediction errors (once per session: both tests of a campaign read them), their
    table and the identification's summary."""
    from solenoid_fmu.field import load_material

    folder, csv = identified(shared, name, effects, seed)

    def compute(_work):
        e = prediction_errors(load_material(csv), name)
        return {k: v.tolist() if isinstance(v, np.ndarray) else v for k, v in e.items()}

    err = {k: np.asarray(v) if isinstance(v, list) else v
           for k, v in once_per_session(shared, f"{folder.name}-errors", compute).items()}
    table = f"Psi %:\n{np.round(err['psi_rel'] * 100, 2)}\nF %:\n{np.round(err['F_rel'] * 100, 2)}"
    return err, table, json.loads((csv.parent / "identification.json").read_text())


@pytest.mark.slow
@pytest.mark.parametrize(("name", "effects", "seed"), [_strict(*c) for c in CAMPAIGNS])
def test_identified_curve_predicts_flux_and_force_of_the_truth(shared_campaigns, name, effects, seed):
    err, table, _ = _errors(shared_campaigns, name, effects, seed)
    assert err["psi_max_rel"] <= PSI_TOL, table
    assert err["F_max_rel"] <= F_TOL, table


def _guard(name, effects, seed):
    marks = ()
    if (name, seed) in NOT_HALVED:
        psi, F = SHORT_OF_GOAL[(name, seed)]
        marks = pytest.mark.xfail(reason=f"issue 20 open: measured Psi {psi} %, F {F} %, not half the literature "
                                         "curve's F error", strict=False)
    return pytest.param(name, effects, seed, marks=marks, id=campaign_id(name, effects, seed))


@pytest.mark.slow
@pytest.mark.parametrize(("name", "effects", "seed"), [_guard(*c) for c in CAMPAIGNS])
def test_identification_at_least_halves_the_error_of_the_literature_curve(shared_campaigns, name, effects, seed):
    """Every campaign, including those short of the goal: the identified curve errs at most half as much
    as the literature curve (not identifying at all), in Psi and in F; the literature steel itself (the
    control) stays within the goal. Heating is named exactly where the truth has it."""
    from solenoid_fmu.field import load_material

    err, table, summary = _errors(shared_campaigns, name, effects, seed)
    lit = prediction_errors(load_material(), name)
    if name == "9SMnPb28":
        assert err["psi_max_rel"] <= PSI_TOL and err["F_max_rel"] <= F_TOL, table
    else:
        assert err["psi_max_rel"] <= 0.5 * lit["psi_max_rel"], (table, lit["psi_max_rel"])
        assert err["F_max_rel"] <= 0.5 * lit["F_max_rel"], (table, lit["F_max_rel"])
    # the coil's heating is named where the truth has it, and not invented where it has none
    assert any("coil heats" in n for n in summary["notes"]) == ("heating" in effects), summary["notes"]
    # the held-out table covers every group of points, with finite errors
    assert summary["held_out"] and all(np.isfinite(r["rms_held_out_pct"]) for r in summary["held_out"])
    # a curve that misses the goal is not handed over without a word: its prediction band says the campaign does
    # not pin that quantity down (twice the 1-sigma above the goal somewhere on the working range)
    for miss, what in ((err["psi_max_rel"] > PSI_TOL, "pin the flux linkage"), (err["F_max_rel"] > F_TOL,
                                                                                 "pin the force")):
        assert not miss or any(what in w for w in summary["warnings"]), (table, summary["warnings"])
