"""A lot's units on disk: the campaign folders (inputs, as bytes for the workers), the output folders
``OUT/<unit>/`` (written whole or not at all) and the test of a unit that is done.

A unit's output folder is complete when it holds ``summary.json``, no ``pipeline.incomplete`` marker and a
``unit.json`` with ``status: ok`` whose ``input_sha256`` is that of the unit's present inputs (its recordings,
the preset, the geometry): changed inputs are redone. The client writes a unit's files into
``OUT/.tmp-<unit>-<id>/`` and renames that folder to ``OUT/<unit>`` (:func:`publish_unit`), so a batch killed at
any moment leaves every unit folder either whole or absent.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import uuid
from pathlib import Path

from ..errors import SolenoidError
from ..fileio import atomic_write_text, write_files
from ..pipeline import INCOMPLETE_MARKER

__all__ = ["UNIT_JSON", "LotError", "campaign_files", "input_sha256", "publish_unit", "read_unit_json",
           "remove_leftovers", "unit_complete", "unit_names"]

#: The unit's record in its output folder (status, error, features, run id, input hash).
UNIT_JSON = "unit.json"
_TMP, _OLD = ".tmp-", ".old-"


class LotError(SolenoidError):
    """The lot cannot be run as asked (a campaign folder missing, two units of one name, a scheduler out of reach)."""


def unit_names(campaign_dirs) -> list[tuple[str, Path]]:
    """``(unit name, folder)`` per campaign folder: the name is the folder's; refuses a missing folder and
    two folders of one name (their outputs would share ``OUT/<name>``)."""
    units, seen = [], {}
    for d in campaign_dirs:
        p = Path(d)
        if not p.is_dir():
            raise LotError(f"{d}: campaign folder not found")
        name = p.resolve().name
        if name in seen:
            raise LotError(f"two campaign folders give the unit name {name!r}: {seen[name]} and {d}; rename one")
        seen[name] = d
        units.append((name, p))
    if not units:
        raise LotError("no campaign folder given")
    return units


def campaign_files(folder) -> dict[str, bytes]:
    """The campaign's CSV files as ``{relative path: bytes}`` (as the pipeline finds them: never inside
    ``truth`` or hidden folders); what a worker needs, since it may share no filesystem with the client."""
    folder = Path(folder)
    out = {}
    for path in sorted(folder.rglob("*.csv")):
        rel = path.relative_to(folder)
        if any(part == "truth" or part.startswith(".") for part in rel.parts[:-1]):
            continue
        out[rel.as_posix()] = path.read_bytes()
    return out


def input_sha256(files: dict[str, bytes], preset: str, geometry_text: str | None,
                 start_material_text: str | None = None) -> str:
    """sha256 over the unit's inputs: file names and contents, the preset, the geometry TOML (None: packaged)
    and the start material's CSV (None: the literature curve)."""
    h = hashlib.sha256()
    for rel in sorted(files):
        h.update(rel.encode() + b"\0" + hashlib.sha256(files[rel]).digest())
    h.update(f"\0preset={preset}\0geometry=".encode() + (geometry_text or "<packaged>").encode())
    h.update(b"\0start=" + (start_material_text or "<literature>").encode())
    return h.hexdigest()


def read_unit_json(unit_dir) -> dict | None:
    """The unit's ``unit.json`` (None when missing or unreadable)."""
    try:
        return json.loads((Path(unit_dir) / UNIT_JSON).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def unit_complete(unit_dir, sha256: str) -> bool:
    """True when ``unit_dir`` holds one complete, successful run on the inputs whose hash is ``sha256``."""
    d = Path(unit_dir)
    rec = read_unit_json(d)
    return (rec is not None and rec.get("status") == "ok" and rec.get("input_sha256") == sha256
            and (d / "summary.json").is_file() and not (d / INCOMPLETE_MARKER).exists())


def publish_unit(out_dir, name: str, files: dict[str, bytes], unit_record: dict) -> Path:
    """Write a unit's files and ``unit.json`` into ``OUT/<name>`` whole: into a temporary folder beside it,
    then renamed (the earlier folder, if any, is moved aside first and removed after)."""
    out = Path(out_dir)
    tmp = out / f"{_TMP}{name}-{uuid.uuid4().hex[:8]}"
    tmp.mkdir(parents=True)
    try:
        try:
            write_files(tmp, files, f"unit {name}: output path")
        except ValueError as exc:
            raise LotError(str(exc)) from None
        atomic_write_text(tmp / UNIT_JSON, json.dumps(unit_record, indent=1, allow_nan=True) + "\n")
        final = out / name
        old = None
        if final.exists():
            old = out / f"{_OLD}{name}-{uuid.uuid4().hex[:8]}"
            final.rename(old)
        tmp.rename(final)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return final


def remove_leftovers(out_dir) -> None:
    """Remove temporary and moved-aside unit folders a killed batch left in ``out_dir``."""
    for p in Path(out_dir).glob(".*"):
        if p.is_dir() and (p.name.startswith(_TMP) or p.name.startswith(_OLD)):
            shutil.rmtree(p, ignore_errors=True)
