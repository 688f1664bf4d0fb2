"""One unit on a worker: the campaign's files in, the pipeline in a temporary folder, the unit's outputs out.

:func:`run_unit` is the task the executor (a local process pool or a Dask worker) runs. It needs no
filesystem shared with the client: the campaign arrives as ``{relative path: bytes}`` and the outputs leave the
same way (a unit's outputs are a few MB). It never raises for a unit's own failure: a failing pipeline gives
``status: failed`` and the one-line error, so the lot goes on.

Determinism: BLAS and OpenMP run single-threaded for the whole unit (``threadpoolctl``; the FEM already pins
them per solve), and the pipeline's maps sweep runs in the worker's process (``workers=1``), so a unit gives
the same numbers in a local process pool and on a Dask worker.
"""

from __future__ import annotations

import json
import os
import socket
import tempfile
import time
import uuid
from pathlib import Path

from ..field import single_threaded
from ..fileio import write_files
from ..pipeline import run_pipeline
from .features import unit_features

__all__ = ["TEXT_SUFFIXES", "one_line", "run_unit"]

#: Output files whose worker-side paths are rewritten (to paths relative to the unit's folder).
TEXT_SUFFIXES = (".json", ".html", ".csv", ".bh", ".tab", ".txt")


def one_line(exc: BaseException) -> str:
    """The error as one line: ``Type: message`` with newlines folded."""
    text = " ".join(str(exc).split()) or repr(exc)
    return text if isinstance(exc, Exception) and type(exc).__module__.startswith("solenoid_fmu") \
        else f"{type(exc).__name__}: {text}"


def _collect(out: Path, campaign: Path, campaign_label: str) -> dict[str, bytes]:
    files = {}
    label = json.dumps(campaign_label)[1:-1]
    for path in sorted(out.rglob("*")):
        if not path.is_file():
            continue
        data = path.read_bytes()
        if path.suffix in TEXT_SUFFIXES:
            text = data.decode("utf-8", errors="surrogateescape")
            text = text.replace(str(campaign), label).replace(str(out) + "/", "").replace(str(out), ".")
            data = text.encode("utf-8", errors="surrogateescape")
        files[path.relative_to(out).as_posix()] = data
    return files


def run_unit(name: str, files: dict, *, preset: str = "quick", geometry_text: str | None = None,
             start_material_text: str | None = None, campaign_label: str = "", input_sha256: str = "") -> dict:
    """Run the pipeline on one unit's campaign and return its outputs.

    Parameters
    ----------
    name : str
        The unit's name (the campaign folder's name, so the maps and FMUs are named after it).
    files : dict of str to bytes
        The campaign's files by relative path (:func:`solenoid_fmu.lot.units.campaign_files`).
    preset : str
        The pipeline's preset (:data:`solenoid_fmu.pipeline.PRESETS`).
    geometry_text : str, optional
        The geometry TOML's content (default: the packaged PS45).
    start_material_text : str, optional
        The B(H) CSV the identification starts from (the lot's nominal steel; default the literature curve).
    campaign_label : str
        The campaign folder as the client knows it (written into the outputs where the worker's path was).
    input_sha256 : str
        The inputs' hash (:func:`solenoid_fmu.lot.units.input_sha256`), recorded in the unit's record.

    Returns
    -------
    dict
        ``unit`` (the record for ``unit.json``: ``unit``, ``status`` ("ok" or "failed"), ``error`` (one line or
        None), ``features``, ``run_id``, ``input_sha256``, ``preset``, ``wall_s`` [s], ``worker``) and ``files``
        (the pipeline's outputs, ``{relative path: bytes}``; empty for a failed unit).
    """
    t0 = time.perf_counter()
    record = {"unit": name, "status": "failed", "error": None, "features": {}, "run_id": uuid.uuid4().hex,
              "input_sha256": input_sha256, "preset": preset, "campaign": campaign_label,
              "worker": f"{socket.gethostname()}:{os.getpid()}", "wall_s": None}
    out_files: dict = {}
    with tempfile.TemporaryDirectory(prefix="solenoid-lot-") as tmp, single_threaded():
        camp, out = Path(tmp) / "in" / name, Path(tmp) / "out" / name
        try:
            write_files(camp, files, "campaign file")
            camp.mkdir(parents=True, exist_ok=True)
            geometry = None
            if geometry_text is not None:
                geometry = Path(tmp) / "geometry.toml"
                geometry.write_text(geometry_text, encoding="utf-8")
            start = None
            if start_material_text is not None:
                start = Path(tmp) / "start-material.csv"
                start.write_text(start_material_text, encoding="utf-8")
            summary = run_pipeline(camp, out, geometry=geometry, preset=preset, workers=1, progress=None,
                                   start_material=start)
            record["features"] = unit_features(summary["recordings"], out, geometry)
            record["status"] = "ok"
            out_files = _collect(out, camp, campaign_label or name)
        except Exception as exc:  # the unit fails, the lot goes on: its one-line error is its result
            record["error"] = one_line(exc).replace(str(camp), campaign_label or name)  # the client's path
    record["wall_s"] = time.perf_counter() - t0
    return {"unit": record, "files": out_files}
