"""Shared fixtures: small rig campaigns with undeclared effects (cached across test modules and workers)."""

import os
import shutil
import uuid

import pytest


def small_campaign():
    """A short campaign of every kind (a few seconds of rig time per recording)."""
    from solenoid_fmu.rig import CampaignConfig

    return CampaignConfig(
        flux_peaks_A=(0.5, 1.0, 1.5), flux_cycles=1, flux_rate_A_per_s=2.0, flux_sample_rate_Hz=200.0,
        stroke_currents_A=(0.5, 1.0, 1.5), stroke_from_m=2.5e-3, stroke_to_m=0.6e-3, stroke_speed_m_per_s=1e-3,
        stroke_sample_rate_Hz=50.0, ramp_sample_rate_Hz=1000.0, ramp_hold_s=0.1,
        eddy_rates_A_per_s=(25.0, 100.0), eddy_cycles=1, eddy_sample_rate_Hz=4000.0,
        step_hold_s=0.3, step_sample_rate_Hz=1000.0, pause_s=5.0)


def session_shared(tmp_path_factory, name: str):
    """A folder ``name`` shared by this session's xdist workers (the parent of their base temporary directories), or
    in the session's own base temporary directory when pytest runs without xdist: there the parent is
    ``pytest-of-<user>``, which every later session shares too, and a test run alone would read what an earlier
    session computed with other code (a loop's result cached at 13:08 served a run at 14:01 of stop 46)."""
    base = tmp_path_factory.getbasetemp()
    shared = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / name
    shared.mkdir(exist_ok=True)
    return shared


@pytest.fixture(scope="session")
def rig_maps(tmp_path_factory):
    """(tables, maps_dir, plain FMU, shared dir): synthetic maps with a single eddy term and their FMU."""
    import mapsfixture

    from solenoid_fmu.fmu.export import build_fmu
    from solenoid_fmu.realtime.model import load_tables

    base = tmp_path_factory.mktemp("rig")
    maps_dir = mapsfixture.write_maps(base / "maps")
    shared = session_shared(tmp_path_factory, "campaigns")
    return load_tables(maps_dir), maps_dir, build_fmu(maps_dir, base / "plain.fmu"), shared


@pytest.fixture(scope="session")
def rig_campaign(rig_maps):
    """Factory: effects string -> sorted recording paths of the small campaign with those effects."""
    from solenoid_fmu.rig import Effects, run_campaign

    tables, maps_dir, _, shared = rig_maps

    def make(effects: str):
        final = shared / f"camp-{effects.replace(',', '+') or 'none'}"
        if not final.is_dir():
            tmp = shared / f".tmp-{uuid.uuid4().hex}"
            run_campaign(tables, tmp, effects=Effects.from_names(effects), campaign=small_campaign(), seed=3,
                         maps_dir=maps_dir)
            try:
                os.rename(tmp, final)  # atomic: another worker may have made the same campaign meanwhile
            except OSError:
                shutil.rmtree(tmp, ignore_errors=True)
        return sorted(str(p) for p in (final / "recordings").glob("*.csv"))

    return make


@pytest.fixture(scope="session")
def shared_campaigns(tmp_path_factory):
    """The folder where :mod:`steelcampaigns` draws and identifies the truth-steel campaigns once per session
    (shared by the xdist workers: the parent of their base temporary directories)."""
    return session_shared(tmp_path_factory, "steel-campaigns")


def _campaign_of(item):
    """The truth-steel campaign (name, effects, seed) a test works on, or None."""
    cs = getattr(item, "callspec", None)
    if cs is None or "shared_campaigns" not in getattr(item, "fixturenames", ()):
        return None
    return cs.params.get("name"), cs.params.get("effects"), cs.params.get("seed")


def pytest_collection_modifyitems(config, items):
    """Test modules with a slow-marked test first, each module's tests kept together (module fixtures, such as
    the pipeline's demo run, are set up once), the original order otherwise: the two xdist workers then start
    on the minute-long tests and the short ones fill the gaps at the end, instead of one worker finishing a
    three-minute fixture alone.

    The truth-steel campaign tests come first of all, ordered by campaign: a campaign's identification test
    and the loop test that reads the same identification sit side by side, so one worker runs them one after
    the other. Module by module, one worker identified while the other worker's loop test waited on the same
    campaign's file lock (230 worker-s of waiting in one CI run)."""
    slow_modules = {item.module.__name__ for item in items if item.get_closest_marker("slow") is not None}
    order = {id(item): k for k, item in enumerate(items)}
    campaigns: dict = {}
    for item in items:
        c = _campaign_of(item)
        if c is not None:
            campaigns.setdefault(c, len(campaigns))

    def key(item):
        c = _campaign_of(item)
        if c is not None:
            return (0, campaigns[c], order[id(item)])
        return (1 if item.module.__name__ in slow_modules else 2, 0, order[id(item)])

    items.sort(key=key)
