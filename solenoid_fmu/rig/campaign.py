"""A campaign on the truth: run the excitations in order, write the recordings and ``truth.json``.

The coil cools between recordings; ``truth.json`` (:class:`RigTruth`, :func:`read_truth`) holds
what the recordings do not say (effects, true material and maps, temperatures), for tests only.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..measure import write_recording
from ..realtime import MapTables
from .daq import measure
from .effects import Effects
from .errors import RigError
from .excitation import CampaignConfig, campaign_excitations
from .truth import TruthModel

__all__ = ["FILE_DIGITS", "TRUTH_SCHEMA", "TRUTH_SCHEMA_VERSION", "RigTruth", "read_truth", "run_campaign",
           "run_excitations"]

#: Schema name and version of ``truth.json``.
TRUTH_SCHEMA = "solenoid-fmu-rig-truth"
TRUTH_SCHEMA_VERSION = 1
#: Significant digits of the numbers in the recording files.
FILE_DIGITS = 7


@dataclass
class RigTruth:
    """Content of ``truth.json``: what the recordings do not say (for tests only).

    Attributes
    ----------
    solenoid : str
        Solenoid name.
    effects : Effects
        The effects and their parameters.
    campaign : CampaignConfig
        The campaign.
    seed : int or None
        Seed of the noise.
    material : dict
        ``{"path": relative to the directory or absolute, "sha256": ...}`` of the true B(H) CSV, or {}.
    maps : str or None
        Directory of the true maps (relative to the truth file's directory when inside it).
    coil : dict
        ``R20_ohm`` (the truth's resistance_ohm_20C), ``alpha_per_K``, ``max_current_A`` of the truth.
    recordings : list of dict
        Per file: ``file``, ``kind``, ``temperature_start_C``, ``temperature_end_C``,
        ``resistance_start_ohm``, ``psi_end_Wb``.
    derived : dict
        Derived true numbers: hysteresis half-width [A], ladder low-rate conductance [S].
    """

    solenoid: str
    effects: Effects
    campaign: CampaignConfig
    seed: int | None
    material: dict = field(default_factory=dict)
    maps: str | None = None
    coil: dict = field(default_factory=dict)
    recordings: list = field(default_factory=list)
    derived: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """JSON-able content with schema name and version."""
        return {"schema": TRUTH_SCHEMA, "schema_version": TRUTH_SCHEMA_VERSION, "solenoid": self.solenoid,
                "effects": self.effects.to_dict(), "campaign": self.campaign.to_dict(), "seed": self.seed,
                "material": dict(self.material), "maps": self.maps, "coil": dict(self.coil),
                "recordings": [dict(r) for r in self.recordings], "derived": dict(self.derived)}

    @classmethod
    def from_dict(cls, data: dict, where: str = "truth") -> RigTruth:
        """Inverse of :meth:`to_dict` (checks schema and version)."""
        if not isinstance(data, dict) or data.get("schema") != TRUTH_SCHEMA:
            raise RigError(f"{where}: not a rig truth file (schema must be {TRUTH_SCHEMA!r})")
        if data.get("schema_version") != TRUTH_SCHEMA_VERSION:
            raise RigError(f"{where}: schema_version {data.get('schema_version')!r} is not supported "
                           f"(this reader reads {TRUTH_SCHEMA_VERSION})")
        try:
            return cls(solenoid=str(data["solenoid"]), effects=Effects.from_dict(data["effects"]),
                       campaign=CampaignConfig.from_dict(data["campaign"]), seed=data.get("seed"),
                       material=dict(data.get("material") or {}), maps=data.get("maps"),
                       coil=dict(data.get("coil") or {}), recordings=list(data.get("recordings") or []),
                       derived=dict(data.get("derived") or {}))
        except KeyError as exc:
            raise RigError(f"{where}: missing key {exc.args[0]!r}") from None
        except TypeError as exc:
            raise RigError(f"{where}: bad value: {exc}") from None

    def __eq__(self, other):
        if not isinstance(other, RigTruth):
            return NotImplemented
        return self.to_dict() == other.to_dict()


def read_truth(path) -> RigTruth:
    """Read ``truth.json`` (a file or the campaign directory holding it)."""
    path = Path(path)
    if path.is_dir():
        path = path / "truth.json"
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise RigError(f"{path}: no such truth file") from None
    except json.JSONDecodeError as exc:
        raise RigError(f"{path}:{exc.lineno}: not valid JSON: {exc.msg}") from None
    return RigTruth.from_dict(data, where=str(path))


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _rel(path: Path, base: Path) -> str:
    try:
        return Path(path).resolve().relative_to(base.resolve()).as_posix()
    except ValueError:
        return str(Path(path).resolve())


def run_campaign(tables: MapTables, output_dir, effects: Effects | None = None,
                 campaign: CampaignConfig | None = None, seed: int | None = 0, material_path=None,
                 maps_dir=None, progress: bool = False) -> RigTruth:
    """Run the campaign on the truth and write one recording per test plus ``truth.json``.

    Parameters
    ----------
    tables : MapTables
        The true maps.
    output_dir : path-like
        Campaign directory: recordings go to ``output_dir/recordings/NN_<name>.csv``,
        the truth to ``output_dir/truth.json``.
    effects : Effects, optional
        Effects of the truth (default none).
    campaign : CampaignConfig, optional
        The tests (default :class:`~solenoid_fmu.rig.CampaignConfig`).
    seed : int or None
        Seed of the sensor noise.
    material_path, maps_dir : path-like, optional
        The true B(H) CSV and maps directory, referenced from ``truth.json``.
    progress : bool
        Print one line per recording.

    Returns
    -------
    RigTruth
        What was written to ``truth.json``.
    """
    cfg = campaign or CampaignConfig()
    return run_excitations(tables, output_dir, campaign_excitations(cfg), effects=effects, campaign=cfg, seed=seed,
                           material_path=material_path, maps_dir=maps_dir, progress=progress)


def run_excitations(tables: MapTables, output_dir, excitations, *, effects: Effects | None = None,
                    campaign: CampaignConfig | None = None, seed: int | None = 0, file_names=None,
                    material_path=None, maps_dir=None, progress: bool = False, derived: dict | None = None
                    ) -> RigTruth:
    """Run the given excitations on the truth, in order, and write the recordings and ``truth.json``.

    The coil cools for ``campaign.pause_s`` between recordings. ``file_names`` (one per
    excitation) default to ``NN_<name>.csv``; ``derived`` adds entries to the truth's ``derived``.
    Column order and optional header keys come from each :class:`~solenoid_fmu.rig.Excitation`. See
    :func:`run_campaign` for the other parameters.
    """
    out = Path(output_dir)
    rec_dir = out / "recordings"
    rec_dir.mkdir(parents=True, exist_ok=True)
    effects = effects or Effects()
    cfg = campaign or CampaignConfig()
    excitations = list(excitations)
    if file_names is None:
        file_names = [f"{n:02d}_{exc.name}.csv" for n, exc in enumerate(excitations, start=1)]
    if len(file_names) != len(excitations) or len(set(file_names)) != len(file_names):
        raise RigError("file_names must be one distinct name per excitation")
    model = TruthModel(tables, effects)
    rng = np.random.default_rng(seed)
    T = cfg.ambient_C
    entries = []
    for n, (exc, name) in enumerate(zip(excitations, file_names, strict=True), start=1):
        if n > 1:
            T = model.cool(T, cfg.pause_s, cfg.ambient_C)
        res = model.simulate(exc, cfg, T_start_C=T)
        T = res.temperature_end_C
        rec = measure(res, exc, effects.daq, rng, solenoid=cfg.solenoid)
        write_recording(rec_dir / name, rec, digits=FILE_DIGITS, columns=exc.columns or None)
        entries.append({"file": f"recordings/{name}", "kind": exc.kind,
                        "temperature_start_C": res.temperature_start_C, "temperature_end_C": res.temperature_end_C,
                        "resistance_start_ohm": res.resistance_start_ohm, "psi_end_Wb": float(res.psi_Wb[-1])})
        if progress:
            print(f"  {name}: {len(rec)} samples, {exc.duration_s:.3g} s", flush=True)
    material = {}
    if material_path is not None:
        material = {"path": _rel(Path(material_path), out), "sha256": _sha256(Path(material_path))}
    derived = {"hysteresis_half_width_A": model.hysteresis_half_width_A,
               "eddy_G_low_rate_S": float(sum(effects.eddy.G_S)) if effects.eddy else None,
               "resistance_20C_ohm": model.resistance_ohm_20C, **(derived or {})}
    truth = RigTruth(solenoid=cfg.solenoid, effects=effects, campaign=cfg, seed=seed, material=material,
                     maps=None if maps_dir is None else _rel(Path(maps_dir), out),
                     coil={"R20_ohm": model.resistance_ohm_20C, "alpha_per_K": model.alpha_per_K,
                           "max_current_A": model.max_current_A},
                     recordings=entries, derived=derived)
    (out / "truth.json").write_text(json.dumps(truth.to_dict(), indent=2) + "\n", encoding="utf-8")
    return truth
