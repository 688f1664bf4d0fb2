"""The twelve campaigns on truth steels (issue 20's must-show): drawn and identified once per test session.

Shared by ``test_identify_campaigns.py`` (the identified curve against the truth) and
``test_loop_identified.py`` (the loop started from what the pipeline identifies). Each campaign is
drawn by :func:`solenoid_fmu.rig.protocols.random_campaign` from the truth's maps
(``tests/data/truth-steels``) and identified by :func:`solenoid_fmu.identification.identify_from_recordings`
as the pipeline's quick preset does; both results live in a folder shared by the xdist workers, guarded
by a file lock so that a second worker waits for the first instead of redoing the work.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import shutil
import uuid
from pathlib import Path

from truthsteels import truth_dir

from solenoid_fmu.identification import identify_from_recordings
from solenoid_fmu.pipeline import PRESETS
from solenoid_fmu.realtime import load_tables
from solenoid_fmu.rig.protocols import random_campaign

#: Samples per recording (the protocol runs faster where it would exceed them).
SAMPLES = 8000
#: Currents per stroke: the pipeline's quick preset (bounds the test time).
N_CURRENTS = PRESETS["quick"]["n_currents"]
#: (truth steel, effects, protocol seed): >= 6 published steels, the rest random; every effect.
CAMPAIGNS = [
    ("9SMnPb28", "", 11), ("9SMn28K", "heating", 12), ("AISI_1008", "eddy-ladder", 13),
    ("DC03", "hysteresis", 14), ("X6Cr17", "heating,hysteresis", 15), ("VacoferS2", "", 16),
    ("Permenorm3601K3", "hysteresis", 17), ("random-0", "heating", 18), ("random-1", "eddy-ladder", 19),
    ("random-2", "", 20), ("random-3", "heating,hysteresis", 21), ("random-4", "hysteresis", 22),
]


def campaign_id(name: str, effects: str, seed: int) -> str:
    """The pytest id of a campaign: ``NAME-EFFECTS-SEED``."""
    return f"{name}-{effects or 'none'}-{seed}"


@contextlib.contextmanager
def _locked(path: Path):
    with open(path, "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _publish(tmp: Path, final: Path) -> None:
    try:
        os.rename(tmp, final)
    except OSError:
        shutil.rmtree(tmp, ignore_errors=True)


def campaign_dir(shared: Path, name: str, effects: str, seed: int) -> Path:
    """The campaign's folder (``recordings/``, ``truth.json``), drawn once per session."""
    final = shared / f"steel-{name}-{effects.replace(',', '+') or 'none'}-{seed}"
    with _locked(shared / f"{final.name}.lock"):
        if not final.is_dir():
            tmp = shared / f".tmp-{uuid.uuid4().hex}"
            random_campaign(load_tables(truth_dir(name)), tmp, effects, seed=seed, max_samples=SAMPLES)
            _publish(tmp, final)
    return final


def identified(shared: Path, name: str, effects: str, seed: int) -> tuple[Path, Path]:
    """(campaign folder, identified ``material.csv``; ``identification.json`` beside it), once per session."""
    folder = campaign_dir(shared, name, effects, seed)
    out = folder.parent / f"{folder.name}-identified"
    with _locked(shared / f"{out.name}.lock"):
        if not (out / "material.csv").is_file():
            tmp = folder.parent / f".tmp-{uuid.uuid4().hex}"
            res = identify_from_recordings(sorted((folder / "recordings").glob("*.csv")),
                                           out_csv=tmp / "material.csv", progress=False, n_currents=N_CURRENTS)
            (tmp / "identification.json").write_text(json.dumps(res.summary()))
            _publish(tmp, out)
    return folder, out / "material.csv"


def once_per_session(shared: Path, key: str, compute) -> dict:
    """``compute(work)`` (a JSON-able dict; ``work`` an empty folder it may write into) computed once per session
    and kept as ``<shared>/<key>.json``: a second worker asking for it waits on the lock and reads the file."""
    final = shared / f"{key}.json"
    with _locked(shared / f"{key}.lock"):
        if not final.is_file():
            work = shared / f".tmp-{uuid.uuid4().hex}"
            work.mkdir()
            try:
                text = json.dumps(compute(work))
                (work / "out.json").write_text(text)
                os.replace(work / "out.json", final)
            finally:
                shutil.rmtree(work, ignore_errors=True)
    return json.loads(final.read_text())
