"""Coil heating from the campaign's resistance tracks: evidence the flux residual alone cannot give.

Within one recording a coil at realistic size warms by a tenth of a kelvin or so (C_th of a few hundred
J/K, tens of joules per slow triangle): its eq.-4 drift is far below what a B(H) error of one per cent
leaves in the flux residual, so :func:`solenoid_fmu.loop.effects.fit_heating` on that residual cannot
tell it, and its gate cannot see it pay. The resistance itself can: the campaign's resistance tracks
(:func:`solenoid_fmu.measure.campaign_resistance`: current plateaus, cycle closure, rests and the
headers, one heating rate ``kappa = alpha / C_th`` [1/J] for the coil) measure it with its uncertainty.

:func:`heating_from_resistance` turns a ``kappa`` above the identification's ``KAPPA_SIGNIFICANT`` sigmas into the
heating section of the model: ``C_th = alpha / kappa`` [J/K], ``R_th`` at the default of the residual
fit (1 K/W: cooling is not identifiable from recordings of seconds), ``alpha`` the maps' coil value or
copper's. The same recordings and threshold as the B(H) identification's choice of eq.-4 resistance
(:func:`solenoid_fmu.identification.campaign_data.resistance_choice`): the current-driven recordings at a
fixed stroke with a voltage (``flux``, ``ramp``, ``eddy``; a ramp's current hold pins R(t)).

Where they measure the heating (:func:`heats`), the same tracks also give the flux the loop fits hysteresis and
the eddy ladder on (:meth:`solenoid_fmu.loop.residuals.FluxCache.note_tracks`).
"""

from __future__ import annotations

from ..errors import RecordingError
from ..identification import KAPPA_SIGNIFICANT
from ..measure import CampaignResistance, campaign_resistance
from .heating_fit import R_TH_DEFAULT_K_PER_W
from .residuals import recording_name

#: Kinds of recording the heating rate is measured on (as the identification does).
KINDS = ("flux", "ramp", "eddy")


def campaign_tracks(recordings) -> CampaignResistance | None:
    """The campaign's resistance tracks (:func:`solenoid_fmu.measure.campaign_resistance`) over its ``flux``,
    ``ramp`` and ``eddy`` recordings with a voltage column (:data:`KINDS`; those whose armature moves are left
    out by the tracks themselves), or None: no ``flux`` recording among them, or the tracks cannot be fitted."""
    flux = [r for r in recordings if r.kind in KINDS and r.voltage_V is not None]
    if not any(r.kind == "flux" for r in flux):
        return None
    try:
        return campaign_resistance(flux)
    except RecordingError:
        return None


def heats(camp: CampaignResistance | None) -> bool:
    """True when the tracks measure the coil heating: ``kappa`` above ``KAPPA_SIGNIFICANT`` of its sigmas."""
    if camp is None:
        return False
    kappa, sigma = float(camp.kappa_per_J), float(camp.kappa_sigma_per_J)
    return sigma > 0.0 and kappa > KAPPA_SIGNIFICANT * sigma


def heating_from_resistance(recordings, tables, camp: CampaignResistance | None = None) -> tuple[dict, dict] | None:
    """The heating section from the campaign's resistance tracks, or None.

    Parameters
    ----------
    recordings : list of Recording
        The campaign (:func:`campaign_tracks` says which of its recordings take part).
    tables : MapTables
        The model's maps (``coil.temperature_coefficient_per_K``, else copper's 0.00393 /K).
    camp : CampaignResistance, optional
        The campaign's tracks when already computed (:func:`campaign_tracks` of ``recordings``).

    Returns
    -------
    (section, note) or None
        ``section``: ``C_th_J_per_K``, ``R_th_K_per_W``, ``alpha_per_K``; ``note``: ``kappa_per_J``,
        ``kappa_sigma_per_J``, ``sigmas``, ``recordings``. None when there is no such recording, the
        tracks cannot be fitted, or ``kappa`` is not significant.
    """
    camp = campaign_tracks(recordings) if camp is None else camp
    if not heats(camp):
        return None
    kappa, sigma = float(camp.kappa_per_J), float(camp.kappa_sigma_per_J)
    flux = [member for member, _ in camp.members]
    alpha = tables.coil.alpha_per_K
    section = {"C_th_J_per_K": alpha / kappa, "R_th_K_per_W": R_TH_DEFAULT_K_PER_W, "alpha_per_K": alpha}
    note = {"from": "resistance tracks", "kappa_per_J": kappa, "kappa_sigma_per_J": sigma,
            "sigmas": kappa / sigma, "recordings": [recording_name(r) for r in flux]}
    return section, note
