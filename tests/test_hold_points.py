"""Static points from current holds (``ramp`` and ``voltage_step`` recordings) for the B(H) identification.

A synthetic ramp through a coil with a known flux linkage (Psi = L_sat(i) i, eq. 4 exact) and a known
force law: the hold gives Psi and F at the held current; a header resistance 2 % off (the coil warmed
since it was measured) is corrected from the hold itself, where U = R i.
"""

import numpy as np
import pytest

from solenoid_fmu.identification.campaign_data import FORCE_FLOOR_REL, hold_points
from solenoid_fmu.measure import make_recording

R_TRUE = 12.0
X_M = 1.2e-3


def _psi(i):
    """A saturating flux linkage [Wb] of the current [A]."""
    return 0.25 * np.tanh(i / 1.2) * 1.2


def _ramp(R_header, peak_A=1.6, fs=5000.0, noise=0.0, seed=0, kind="ramp"):
    t = np.arange(0.0, 1.0, 1.0 / fs)
    i = np.interp(t, [0.0, 0.1, 0.2, 0.6, 0.7, 1.0], [0.0, 0.0, peak_A, peak_A, 0.0, 0.0])
    u = R_TRUE * i + np.gradient(_psi(i), t)
    rng = np.random.default_rng(seed)
    u = u + 0.02 + noise * rng.standard_normal(t.size)  # a voltage offset, measured in the rests
    return make_recording(kind, "PS45", t, i, voltage_V=u, force_N=3.0 * i**2, position_m=X_M,
                          coil_resistance_ohm=R_header)


@pytest.mark.parametrize("R_header", [R_TRUE, 1.02 * R_TRUE])
def test_hold_gives_the_static_flux_and_force_even_with_a_header_resistance_off(R_header):
    pts, notes = hold_points([_ramp(R_header)])
    assert not notes
    psi = [p for p in pts if p.kind == "psi"]
    force = [p for p in pts if p.kind == "force"]
    assert len(psi) == 1 and len(force) == 1
    assert psi[0].i_A == pytest.approx(1.6, rel=1e-6) and psi[0].x_m == pytest.approx(X_M)
    # eq. 4 with the trapezoid rule at 5 kHz: 1e-4 relative; a 2 % resistance error uncorrected would
    # leave 0.24 ohm x 0.16 A s = 0.04 Wb, 10 % of Psi
    assert psi[0].value == pytest.approx(_psi(1.6), rel=1e-3)
    assert force[0].value == pytest.approx(3.0 * 1.6**2, rel=1e-9)
    assert force[0].sigma == pytest.approx(FORCE_FLOOR_REL * force[0].value)
    assert all(p.group.startswith("hold:") for p in pts)


def test_hold_sigma_grows_with_the_remanence_and_noise():
    quiet = [p for p in hold_points([_ramp(R_TRUE)])[0] if p.kind == "psi"][0]
    loose = [p for p in hold_points([_ramp(R_TRUE)], remanence_Wb=0.01)[0] if p.kind == "psi"][0]
    noisy = [p for p in hold_points([_ramp(R_TRUE, noise=0.5)])[0] if p.kind == "psi"][0]
    assert loose.sigma > 0.01 > quiet.sigma
    assert noisy.sigma > quiet.sigma
    assert abs(noisy.value - _psi(1.6)) < 3 * noisy.sigma


def test_a_recording_without_rest_or_hold_is_left_out_with_a_note():
    t = np.arange(0.0, 0.5, 2e-4)
    i = 1.0 + 0.5 * np.sin(2 * np.pi * 4 * t)  # energized throughout, no hold
    rec = make_recording("ramp", "PS45", t, i, voltage_V=R_TRUE * i, force_N=0 * i, position_m=X_M,
                         coil_resistance_ohm=R_TRUE)
    pts, notes = hold_points([rec])
    assert pts == [] and len(notes) == 1 and "left out" in notes[0]
