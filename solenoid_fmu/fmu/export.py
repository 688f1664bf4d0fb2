"""FMI 2.0 (native also FMI 3.0) FMU of the real-time solenoid model: :func:`build_fmu` (CLI ``solenoid-fmu export``).

``build_fmu(maps, dest_fmu)`` takes the maps (a directory, or :class:`~solenoid_fmu.maps.CharacteristicMaps`
in memory), has a backend (:data:`BACKENDS`) write the FMU,
completes its ``modelDescription.xml`` and documentation from the interface table
(:mod:`solenoid_fmu.fmu.model_description`) and checks every FMU built with
``fmpy.validation.validate_fmu``, refusing it if that reports anything.

Backends: ``python`` packs the model for pythonfmu (:mod:`solenoid_fmu.fmu.python_backend`;
co-simulation, needs Python with numpy where it runs); ``c`` generates and compiles native C with
the same variables (:mod:`solenoid_fmu.fmu.native`), declared for co-simulation and model
exchange (interface ``cs+me``, the default) or for co-simulation only (``cs``); ``fmi_version=3``
(``export --backend c --fmi 3``) gives FMI 3.0 from the same C
(:mod:`solenoid_fmu.fmu.model_description3`).

Semantics (see :mod:`solenoid_fmu.realtime.model`): inputs are held over a communication step;
outputs are computed at the end of each step from the state and the inputs of that step.
Out-of-map inputs are clamped and logged once per excursion through the FMI logger (status warning).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..errors import FmuBuildError, MapsError
from ..fileio import WRITE_ERRNOS, check_output_name, umask, write_failure
from ..maps import CharacteristicMaps, encode_maps, load_maps, maps_tables
from ..realtime import MAPS_JSON, MAPS_NPZ, MapTables, ModelMapsError, load_tables
from .model_description import BackendDescription, finalize_model_description
from .model_description3 import to_fmi3
from .native import NATIVE_CS_DESCRIPTION, NATIVE_DESCRIPTION, build_c_fmu
from .python_backend import PYTHON_DESCRIPTION, build_python_fmu

__all__ = ["BACKENDS", "Backend", "build_fmu", "load_maps_tables", "maps_payload"]


@dataclass(frozen=True)
class Backend:
    """An export backend: ``build(maps_files, dest_fmu, tables) -> generationTool`` writes an FMU with the
    interface variables (``maps_files``: ``{"maps.npz": bytes, "maps.json": bytes}``, packed as they are);
    ``descriptions`` maps each interface it offers (the first is the default) to what
    :func:`~solenoid_fmu.fmu.model_description.finalize_model_description` adds for it."""

    build: Callable
    descriptions: dict
    fmi_versions: tuple = (2,)

    @property
    def default_interface(self) -> str:
        return next(iter(self.descriptions))


#: Export backends by name. ``python``: pythonfmu (co-simulation; needs Python with numpy where it
#: runs); ``c``: native C, co-simulation and model exchange (``cs+me``) or co-simulation only (``cs``).
BACKENDS = {
    "python": Backend(build_python_fmu, {"cs": PYTHON_DESCRIPTION}),
    "c": Backend(build_c_fmu, {"cs+me": NATIVE_DESCRIPTION, "cs": NATIVE_CS_DESCRIPTION}, (2, 3)),
}


def load_maps_tables(maps_dir) -> MapTables:
    """Read a maps directory for export; model-level problems become :class:`MapsError`.

    Parameters
    ----------
    maps_dir : str or path-like
        Directory with ``maps.npz`` and ``maps.json``.

    Returns
    -------
    solenoid_fmu.realtime.MapTables
    """
    maps_dir = Path(maps_dir)
    if not maps_dir.is_dir():
        raise MapsError(f"{maps_dir}: maps directory not found")
    load_maps(maps_dir)  # one rule for every reader: the checks of `solenoid-fmu maps --from` (schema, units,
    # name, arrays, npz and json written together) before the model's own
    try:
        return load_tables(maps_dir)
    except ModelMapsError as exc:
        raise MapsError(str(exc)) from None


def maps_payload(maps) -> tuple[dict, MapTables, str]:
    """What an FMU packs of ``maps``: the files' bytes by name, the model's tables and the maps' name.

    ``maps`` is a maps directory (read once, checked as :func:`load_maps_tables` does) or
    :class:`~solenoid_fmu.maps.CharacteristicMaps` (encoded in memory as :func:`solenoid_fmu.maps.save_maps`
    would write them; nothing is written or read).
    """
    if isinstance(maps, CharacteristicMaps):
        npz, sidecar = encode_maps(maps)
        tables = maps_tables(maps)
        return {MAPS_NPZ: npz, MAPS_JSON: sidecar}, tables, str(tables.name or "maps")
    maps_dir = Path(maps)
    tables = load_maps_tables(maps_dir)
    try:
        files = {name: (maps_dir / name).read_bytes() for name in (MAPS_NPZ, MAPS_JSON)}
    except OSError as exc:
        raise MapsError(f"{maps_dir}: cannot be read: {exc.strerror}") from None
    return files, tables, str(tables.name or maps_dir.name)


def build_fmu(maps, dest_fmu, *, backend: str = "python", interface: str | None = None,
              model_name: str | None = None, validate: bool = True, fmi_version: int = 2) -> Path:
    """Export the real-time model with the given maps as an FMI 2.0 (or, native, FMI 3.0) FMU.

    Parameters
    ----------
    maps : str, path-like or CharacteristicMaps
        Maps directory (``maps.npz`` + ``maps.json``, shared format), or the maps in memory
        (:func:`maps_payload`).
    dest_fmu : str or path-like
        FMU file to write (parent directories are created; an existing file is replaced).
    backend : str
        Key of :data:`BACKENDS`: ``"python"`` (pythonfmu co-simulation; the FMU needs Python with
        numpy) or ``"c"`` (native binary from generated C).
    interface : str, optional
        FMI interfaces the FMU declares: ``"cs"`` (co-simulation only, outputs without direct
        feedthrough) or ``"cs+me"`` (co-simulation and model exchange; native only). Default: the
        backend's first (python ``cs``, c ``cs+me``).
    model_name : str, optional
        ``modelName`` in the model description; default ``"solenoid <maps name>"``.
    validate : bool
        Check the result with ``fmpy.validation.validate_fmu``; any problem is an error.
    fmi_version : int
        2 (default), or 3 (``c`` backend only): an FMI 3.0 FMU from the same generated C, with the
        same variables (Float64 / Int32 / Boolean) and the independent variable ``time``
        (:mod:`solenoid_fmu.fmu.model_description3`).

    Returns
    -------
    pathlib.Path
        The FMU written.

    Raises
    ------
    MapsError
        The maps directory is missing or unusable.
    FmuBuildError
        Unknown backend or interface, exporter failure, or validation problems (all listed).
    """
    dest = check_output_name(dest_fmu)
    spec, description = _backend_for(backend, interface, fmi_version, dest)
    files, tables, maps_name = maps_payload(maps)
    tmp = _temporary_beside(dest)
    try:
        tool = spec.build(files, tmp, tables, **({"fmi_version": 3} if fmi_version == 3 else {}))
        finalize_model_description(tmp, tables=tables, maps_files=files, maps_name=maps_name, generation_tool=tool,
                                   model_name=model_name, backend=description)
        if fmi_version == 3:
            to_fmi3(tmp, tables)
        if validate:
            from fmpy.validation import validate_fmu  # third-party, slow to import: only when validating

            problems = validate_fmu(str(tmp))
            if problems:
                raise FmuBuildError(f"{dest}: fmpy validation found {len(problems)} problem(s):\n"
                                    + "\n".join(f"  - {p}" for p in problems))
        os.chmod(tmp, 0o666 & ~umask())  # the mode open() would give, not mkstemp's private 0600
        os.replace(tmp, dest)
    except OSError as exc:
        if exc.errno not in WRITE_ERRNOS:
            raise
        raise write_failure(dest, exc) from None
    finally:
        if tmp.exists():
            tmp.unlink()
    return dest


def _backend_for(backend: str, interface: str | None, fmi_version: int, dest: Path):
    """The backend of :func:`build_fmu` and its model description for ``interface``, checked with the FMI
    version and the output name (else :class:`FmuBuildError`)."""
    if backend not in BACKENDS:
        raise FmuBuildError(f"unknown FMU backend {backend!r}; available: {', '.join(BACKENDS)}")
    spec = BACKENDS[backend]
    interface = interface or spec.default_interface
    if interface not in spec.descriptions:
        raise FmuBuildError(f"the {backend} backend offers interface {' or '.join(spec.descriptions)}, "
                            f"not {interface!r}")
    description: BackendDescription = spec.descriptions[interface]
    if fmi_version not in spec.fmi_versions:
        raise FmuBuildError(f"the {backend} backend writes FMI {' or '.join(map(str, spec.fmi_versions))}, "
                            f"not {fmi_version!r}" + ("; export --backend c for FMI 3" if backend != "c" else ""))
    if dest.suffix.lower() != ".fmu":
        raise FmuBuildError(f"{dest}: the output file must end in .fmu")
    return spec, description


def _temporary_beside(dest: Path) -> Path:
    """An empty temporary file beside ``dest`` (created with its folder) to build the FMU in."""
    try:
        dest.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(prefix=f".{dest.stem}.", suffix=".fmu", dir=dest.parent)
    except (FileExistsError, NotADirectoryError):
        raise
    except OSError as exc:  # a read-only or full folder: name the FMU, not the hidden temporary file
        raise write_failure(dest, exc) from None
    os.close(fd)
    return Path(tmp_name)
