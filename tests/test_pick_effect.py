"""The loop's choice of the next effect to try (:func:`solenoid_fmu.loop.gates.pick_effect`): the try threshold, and
the lower one for an effect the recordings show by other means (the eddy current the maps' fit measured)."""

from __future__ import annotations

import pytest

from solenoid_fmu.loop import gates
from solenoid_fmu.loop.diagnosis import DEFAULT_MIN_NRMS, Candidate, Diagnosis


def _diagnosis(scores: dict, nrms: float = 10 * DEFAULT_MIN_NRMS) -> Diagnosis:
    ranking = [Candidate(effect, score=s, explained=s, per_signal={"force_N": s})
               for effect, s in sorted(scores.items(), key=lambda kv: -kv[1])]
    return Diagnosis(ranking, "unexplained", 0.25, residual_nrms={"force_N": nrms})


@pytest.mark.parametrize(("eddy_score", "evidence", "picked"), [
    (0.07, frozenset(), None),          # below TRY_THRESHOLD: not tried on the residual alone
    (0.07, {"eddy"}, "eddy"),           # the maps measured an eddy current: tried from the lower threshold
    (0.04, {"eddy"}, None),             # below that too
    (0.12, frozenset(), "eddy"),        # above TRY_THRESHOLD: tried either way
])
def test_an_effect_with_evidence_of_its_own_is_tried_from_the_lower_threshold(monkeypatch, eddy_score, evidence,
                                                                              picked):
    assert gates.TRY_THRESHOLD_WITH_EVIDENCE < 0.07 < gates.TRY_THRESHOLD < 0.12
    seen = []

    def fake(cases, threshold, balanced=False):
        seen.append(balanced)
        return _diagnosis({"eddy": eddy_score, "friction": 0.06})

    monkeypatch.setattr(gates, "diagnose", fake)
    diagnoses = []
    pick, _ = gates.pick_effect([], 0.25, set(), diagnoses, evidence)
    assert pick == picked
    # the evidence lowers the threshold of its own effect only: friction (0.06) is never tried here
    assert len(diagnoses) == len(seen) == (1 if picked else 2)  # no pick: the balanced diagnosis is asked too


def test_an_effect_already_tried_is_not_picked_again_even_with_evidence(monkeypatch):
    monkeypatch.setattr(gates, "diagnose", lambda cases, threshold, balanced=False: _diagnosis({"eddy": 0.3}))
    pick, _ = gates.pick_effect([], 0.25, {"eddy"}, [], {"eddy"})
    assert pick is None


def test_the_progress_line_says_why_an_eddy_ladder_under_the_try_threshold_is_tried():
    from solenoid_fmu.loop.improvement import _adding

    low = Candidate("eddy", score=0.056, explained=0.056, per_signal={"psi_Wb": 0.075})
    assert _adding(low, frozenset({"eddy"})) == ("adding eddy (diagnosis score 0.056; psi_Wb 0.075; tried from 0.05: "
                                                 "the maps' eddy fit measured an eddy current)")
    assert _adding(low, frozenset()) == "adding eddy (diagnosis score 0.056; psi_Wb 0.075)"
    # above the try threshold, or another effect: no reason to give
    assert "tried from" not in _adding(Candidate("eddy", 0.3, 0.3, {"psi_Wb": 0.3}), frozenset({"eddy"}))
    assert "tried from" not in _adding(Candidate("friction", 0.06, 0.06, {"force_N": 0.2}), frozenset({"eddy"}))


@pytest.mark.parametrize(("in_maps", "given", "evidence"), [
    (True, None, {"eddy"}),    # the maps' eddy fit measured an eddy current (an FMU the pipeline built)
    (False, None, set()),      # it measured none
    (None, None, set()),       # the maps do not say (older maps, a G_eddy set by hand)
    (None, True, {"eddy"}),    # the caller's verdict (the pipeline's step 4) wins over the maps'
    (True, False, set()),
])
def test_the_eddy_evidence_comes_from_the_maps_unless_the_caller_gives_it(in_maps, given, evidence):
    from types import SimpleNamespace

    from solenoid_fmu.realtime import EddyRecord

    tables = SimpleNamespace(eddy=EddyRecord(G_eddy_S=4e-3, source="fit", measured=in_maps))
    assert gates.evidence_of(tables, given) == evidence
