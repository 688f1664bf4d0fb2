"""FMI 2.0 (native also FMI 3.0) FMU of the real-time solenoid model: :func:`build_fmu` (CLI ``solenoid-fmu export``).

``build_fmu(maps_dir, dest_fmu)`` reads the maps, has a backend (:data:`BACKENDS`) write the FMU,
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
from ..maps import load_maps
from ..realtime import MapTables, ModelMapsError, load_tables
from .model_description import BackendDescription, finalize_model_description
from .model_description3 import to_fmi3
from .native import NATIVE_CS_DESCRIPTION, NATIVE_DESCRIPTION, build_c_fmu
from .python_backend import PYTHON_DESCRIPTION, build_python_fmu

__all__ = ["BACKENDS", "Backend", "build_fmu", "load_maps_tables"]


@dataclass(frozen=True)
class Backend:
    """An export backend: ``build(maps_dir, dest_fmu, tables) -> generationTool`` writes an FMU with the
    interface variables; ``descriptions`` maps each interface it offers (the first is the default) to what
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


def build_fmu(maps_dir, dest_fmu, *, backend: str = "python", interface: str | None = None,
              model_name: str | None = None, validate: bool = True, fmi_version: int = 2) -> Path:
    """Export the real-time model with the given maps as an FMI 2.0 (or, native, FMI 3.0) FMU.

    Parameters
    ----------
    maps_dir : str or path-like
        Maps directory (``maps.npz`` + ``maps.json``, shared format).
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
    maps_dir = Path(maps_dir)
    dest = check_output_name(dest_fmu)
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
    tables = load_maps_tables(maps_dir)
    try:
        dest.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(prefix=f".{dest.stem}.", suffix=".fmu", dir=dest.parent)
    except (FileExistsError, NotADirectoryError):
        raise
    except OSError as exc:  # a read-only or full folder: name the FMU, not the hidden temporary file
        raise write_failure(dest, exc) from None
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        tool = spec.build(maps_dir, tmp, tables, **({"fmi_version": 3} if fmi_version == 3 else {}))
        finalize_model_description(tmp, tables=tables, maps_dir=maps_dir, generation_tool=tool,
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
