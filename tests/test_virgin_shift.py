"""Force strokes and holds on a hysteretic steel sit on the virgin ascent, not on the branch mean
(:mod:`solenoid_fmu.identification.virgin_side`).

A force stroke and a hold are reached by a rising current from the rig's demagnetized state: the state's
magnetizing current is the measured one minus the hysteresis current of the virgin ascent. The flux loops
of the same campaign show how far the ascent lies from the branch mean the identification fits the FEM's
curve to; the shift takes the points there. The truth is the rig's Preisach hysteresis on an analytic
anhysteretic Psi(i) (the helpers of ``test_virgin_and_top``), densities the shift was not tuned on.
"""

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
from test_virgin_and_top import DENSITIES, i_curve, psi_curve, recording

from solenoid_fmu.identification.campaign_data import MeasuredPoint
from solenoid_fmu.identification.virgin_side import on_virgin_side, virgin_shift
from solenoid_fmu.realtime import PreisachHysteresis

PEAKS_A = (0.8, 1.6, 2.0)


def stroke(hyst, peaks_A=PEAKS_A, widen=None):
    """Per-stroke details as ``flux_points`` gives them (the commutation curve's recordings): unipolar loops
    to ``peaks_A``, the descents of the last one moved ``widen(i)`` [A] down (a drift that opens its loops)."""
    recs = [recording(hyst, [p]) for p in peaks_A]
    if widen is not None:
        last = recs[-1]
        last.branches = [dataclasses.replace(b, i_A=b.i_A - widen(b.i_A)) if b.direction == "descending" else b
                         for b in last.branches]
    return {"cc": SimpleNamespace(results=recs)}


def virgin_states(hyst, i_lo=0.4, i_hi=1.6, n=400):
    """Currents [A] and the anhysteretic currents of their flux on the virgin ascent from the demagnetized
    state (a force stroke energized, a ramp to its hold)."""
    hyst.reset()
    seg = np.linspace(0.0, float(psi_curve(i_hi + 0.2)), n)
    i = i_curve(seg) + np.array([hyst.step(p) for p in seg])
    sel = (i >= i_lo) & (i <= i_hi)
    return i[sel], i_curve(seg[sel])


def preisach(b_c_rel, spread_rel, density, half_width_A):
    return PreisachHysteresis.with_coercive(float(psi_curve(2.0)), half_width_A, b_c_rel=b_c_rel,
                                            spread_rel=spread_rel, density=density)


@pytest.mark.parametrize(("b_c_rel", "spread_rel", "density", "half_width_A"), DENSITIES)
def test_the_shift_takes_virgin_states_to_the_curve(b_c_rel, spread_rel, density, half_width_A):
    hyst = preisach(b_c_rel, spread_rel, density, half_width_A)
    i, i_true = virgin_states(hyst)
    h = virgin_shift({"s": stroke(hyst)}, i)
    before = np.sqrt(np.mean((i - i_true) ** 2))
    after = np.sqrt(np.mean((i - h - i_true) ** 2))
    assert before > 1e-3  # the virgin ascent is off the curve by more than a milliampere
    assert after < 0.25 * before  # 0.03-0.11 on these five


def test_without_hysteresis_nothing_moves():
    points = [MeasuredPoint("force", 0.7, 1e-3, 12.0, 0.05, "force:a", "a"),
              MeasuredPoint("psi", 1.6, 1e-3, 0.33, 0.001, "hold:b", "b")]
    got, note = on_virgin_side(points, {"s": stroke(None)})
    assert note is None
    assert [p.i_A for p in got] == pytest.approx([p.i_A for p in points], abs=1e-9)
    assert on_virgin_side(points, {}) == (points, None)  # no flux stroke: nothing to measure h on


def test_a_loop_widened_by_drift_is_left_out():
    """A drift (e.g. an unpinned heating track) keeps a loop open up to its tip; hysteresis closes there."""
    hyst = preisach(*DENSITIES[0])
    i = np.array([0.5, 1.0, 1.5])
    clean = virgin_shift({"s": stroke(hyst, (1.6, 2.0))}, i)
    drifted = virgin_shift({"s": stroke(hyst, (1.6, 2.0, 2.0), widen=lambda c: 0.02 * c)}, i)
    assert clean[0] > 1e-3  # (the loops close towards the peak: 0.14 mA at 1.5 A)
    assert drifted == pytest.approx(clean)
    assert np.all(virgin_shift({"s": stroke(hyst, (2.0,), widen=lambda c: 0.02 * c)}, i) == 0.0)


def test_points_move_by_the_shift_and_the_note_says_how_far():
    hyst = preisach(*DENSITIES[2])
    strokes = {"s": stroke(hyst)}
    points = [MeasuredPoint("force", 0.6, 1e-3, 12.0, 0.05, "force:a", "a"),
              MeasuredPoint("force", 1.2, 2e-3, 25.0, 0.1, "force:a", "a")]
    got, note = on_virgin_side(points, strokes)
    h = virgin_shift(strokes, [0.6, 1.2])
    assert [p.i_A for p in got] == pytest.approx([0.6 - h[0], 1.2 - h[1]])
    assert [dataclasses.replace(p, i_A=0.0) for p in got] == [dataclasses.replace(p, i_A=0.0) for p in points]
    assert f"{max(h) * 1e3:.3g} mA" in note


def test_eddy_dominated_loops_move_nothing():
    """Where the eddy current G dPsi/dt is as wide as what is left of a loop, the rest may be the single G's
    error (an eddy ladder's slow loops are wider than one G says): no shift."""
    hyst = preisach(*DENSITIES[0])
    strokes = {"s": stroke(hyst)}
    i = np.array([0.5, 1.0])
    assert np.all(virgin_shift(strokes, i) > 1e-3)
    rate = np.median(np.abs(np.gradient(strokes["s"]["cc"].results[-1].psi_Wb)))  # Wb per sample (t = index)
    assert np.all(virgin_shift(strokes, i, G_S=0.1 / rate) == 0.0)  # 100 mA of eddy current


@pytest.mark.parametrize("density", range(len(DENSITIES)))
def test_the_shift_is_the_highest_loops_half_width_not_a_lower_loops_closing_at_its_tip(density):
    """A unipolar loop closes towards its own peak: at 1.3-1.45 A a loop to 1.6 A is 20-60 % narrower than the
    one to 2.0 A. The branch mean is the mean of the first ascent and the descent from the *highest* peak, so
    ``h`` is that loop's half-width: it meets the virgin ascent's true offset from the anhysteretic curve
    (Preisach truth) within 4 %. The smallest ``h`` over the loops (the rule until stop 44) took the lower loop's
    near its tip (fresh random-2 #136: 0.25 mA where the highest loop had 4.4 mA, F 5 % off the truth)."""
    hyst = preisach(*DENSITIES[density])
    i = np.array([1.0, 1.3, 1.45])
    both = virgin_shift({"s": stroke(hyst, (1.6, 2.0))}, i)
    top = virgin_shift({"s": stroke(hyst, (2.0,))}, i)
    iv, i_an = virgin_states(hyst, 0.4, 1.6)
    true = np.interp(i, iv, iv - i_an)
    assert both == pytest.approx(top, abs=1e-9)
    assert np.all(np.abs(both - true) <= 0.04 * true + 2e-5), (both, true)


#: The densities whose drifted top loop the tip gate rejects (on (0.25, 0.15, gaussian) it passes as hysteresis).
DRIFT_REJECTED = [d for d in DENSITIES if d != (0.25, 0.15, "gaussian", 0.07)]


@pytest.mark.parametrize(("b_c_rel", "spread_rel", "density", "half_width_A"), DRIFT_REJECTED)
def test_below_a_drifting_top_loop_the_highest_closed_loop_gives_the_shift(b_c_rel, spread_rel, density,
                                                                            half_width_A):
    """The demo campaign's case: the 2 A loop stays open at its tip (a coil heating with an unpinned resistance
    track), the lower loops close. The highest loop that counts gives h (before stop 50: none, the points stayed
    on the virgin ascent). Measured: 0.04-0.10 of the error left; the lowest loops' smallest h would leave
    0.1-0.5 of it (they close towards their own peaks)."""
    hyst = preisach(b_c_rel, spread_rel, density, half_width_A)
    i, i_true = virgin_states(hyst, i_hi=1.2)
    drift = dict(widen=lambda c: 0.02 * c)
    assert np.all(virgin_shift({"s": stroke(hyst, (2.0,), **drift)}, i) == 0.0)  # the drifted loop alone: none
    for peaks in ((1.0, 1.6, 2.0), (0.8, 1.2, 1.6, 2.0), (1.6, 2.0)):
        got = virgin_shift({"s": stroke(hyst, peaks, **drift)}, i)
        assert got == pytest.approx(virgin_shift({"s": stroke(hyst, (1.6,))}, i))  # the 1.6 A loop's
        before = np.sqrt(np.mean((i - i_true) ** 2))
        assert np.sqrt(np.mean((i - got - i_true) ** 2)) < 0.15 * before
