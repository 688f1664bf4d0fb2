"""Native FMU backend: generated C, no Python at run time, FMI 2.0 co-simulation and model exchange.

``solenoid-fmu export maps/NAME -o build/NAME.fmu --backend c`` (or
``build_fmu(maps_dir, dest, backend="c")``) writes the C sources of
:mod:`solenoid_fmu.fmu.c_sources` (the model source ``fmu/c/solenoid_fmu.c``, the generated
``solenoid_model.h`` and ``solenoid_maps.h``, the FMI 2.0 headers shipped with fmpy) into the FMU's
``sources/`` and compiles ``binaries/linux64/SolenoidFmu.so`` with the machine's C compiler
(``$CC``, else ``gcc``, else ``cc``) using :data:`CFLAGS` (``-std=c99 -O2 -Wall -Wextra -Werror
-ffp-contract=off``: no fused multiply-add, so the arithmetic is the one of
:mod:`solenoid_fmu.realtime.model`). ``sources/`` also holds a ``CMakeLists.txt``, so a source FMU
importer (fmpy, Simulink) or a Windows user builds the binary for another platform.
``resources/`` carries ``maps.npz`` and ``maps.json`` (read by
:func:`solenoid_fmu.fmu.simulate_recording`, not by the binary).

The C code reproduces :class:`solenoid_fmu.realtime.model.SolenoidModel` step for step
(co-simulation: ROS2 sub-steps of at most ``h_sub_max_s``, the safeguarded Newton iteration in
current mode with ``G_eddy = 0``, the same excursion flags and messages); ``fmi2DoStep`` allocates
nothing. A NaN or infinite input, ``R_ohm <= 0`` or ``G_eddy_S < 0`` is logged and returns
``fmi2Error`` with the state unchanged.

Effect sub-models (maps.json ``effects``; :data:`solenoid_fmu.fmu.interface.EFFECT_VARIABLES`): the
effect data become constant arrays in ``solenoid_maps.h``; switches and scalars are FMU parameters
with the defaults of :class:`~solenoid_fmu.realtime.model.SolenoidModel`; the outputs ``i_hyst_A``
and ``T_rise_K`` exist. Co-simulation reproduces ``SolenoidModel._step_fx`` step for step (1e-9, in
practice bit for bit); the effect states are part of the FMU state.

Model exchange (same binary, same variables; interface ``cs+me``, the default): the continuous
state is the local ``psi_state_Wb`` [Wb] with derivative ``der(psi_state_Wb)`` [V] (paper eqs. 1-2
solved for dPsi/dt: voltage mode ``(U - R i_f) / (1 + R G)``, current mode ``(i - i_f) / G``);
with effects also one ``ladder_state_<k>_A`` per eddy-ladder section and ``T_state_K``
(:func:`solenoid_fmu.fmu.interface.me_variables`). Current mode with ``G_eddy = 0`` is algebraic:
the state is frozen (derivative 0), ``Psi`` is solved from the input at each evaluation (no
events), ``dpsi_dt_V = i_eddy_A = 0`` and ``U_out_V = R i`` (an ME FMU gets no di/dt). The
outputs are instantaneous in model exchange, so ``ModelStructure/Outputs`` lists their
dependencies on the inputs. Hysteresis and friction are rate independent: ME evaluates them from
the memory committed at the last accepted step (``fmi2CompletedIntegratorStep``,
``fmi2NewDiscreteStates``) moved to the current Psi and x. Current mode with ``G_eddy_S = 0`` and
the ladder on is a differential-algebraic system and is refused in model exchange (error at
initialization); co-simulation supports it.

FMI 2.0 has one ``ModelStructure`` for both interfaces. In co-simulation the outputs change only in
``fmi2DoStep`` (no direct feedthrough), so the model-exchange dependencies make co-simulation
masters that read them (OMSimulator) see algebraic loops that do not exist. Interface ``cs``
(``export --backend c --interface cs``) declares co-simulation only, with outputs that depend on no
input (as the pythonfmu FMU): the same binary, for co-simulation masters with feedback loops.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

from lxml import etree

from .. import __version__
from ..errors import FmuBuildError
from ..realtime import MapTables
from .c_sources import default_params, generate_sources
from .interface import LOG_CATEGORIES, MODEL_IDENTIFIER, interface_for, start_values
from .model_description import BackendDescription

__all__ = [
    "CFLAGS",
    "NATIVE_CS_DESCRIPTION",
    "NATIVE_DESCRIPTION",
    "build_c_fmu",
    "compile_shared_library",
    "find_compiler",
]

#: Compiler flags of the binary (gcc/clang syntax).
CFLAGS = ("-std=c99", "-O2", "-fPIC", "-shared", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror")

_DOC_C = ("<li>Native FMU (generated C, no Python at run time): co-simulation and model exchange in one "
          "binary; <code>sources/</code> builds it for other platforms (CMakeLists.txt). Model exchange: "
          "state psi_state_Wb (with effects also the eddy-ladder currents and the temperature rise); "
          "instantaneous outputs; current mode with G_eddy_S = 0 is algebraic (no continuous state, "
          "dpsi_dt_V = 0, U_out_V = R i); with effects, current mode with G_eddy_S = 0 and the eddy "
          "ladder on is co-simulation only.</li>")
_DOC_C_CS = ("<li>Native FMU (generated C, no Python at run time), declared for co-simulation only: the "
             "outputs depend on no input at the same communication point (no algebraic loops in a "
             "co-simulation master); <code>sources/</code> builds it for other platforms (CMakeLists.txt). "
             "Export without <code>--interface cs</code> for model exchange too.</li>")

_NATIVE_CS = {"canNotUseMemoryManagementFunctions": "false"}
#: The native FMU's description: co-simulation and model exchange (interface ``cs+me``).
NATIVE_DESCRIPTION = BackendDescription(model_exchange=True, source_files=("solenoid_fmu.c",),
                                        cs_attributes=_NATIVE_CS, doc_note=_DOC_C, step_error="fmi2Error")
#: The native FMU declared for co-simulation only (interface ``cs``): outputs without direct feedthrough.
NATIVE_CS_DESCRIPTION = BackendDescription(model_exchange=False, source_files=("solenoid_fmu.c",),
                                           cs_attributes=_NATIVE_CS, doc_note=_DOC_C_CS, step_error="fmi2Error")


def find_compiler() -> str:
    """Path of the C compiler: ``$CC``, else ``gcc``, else ``cc``."""
    for name in (os.environ.get("CC"), "gcc", "cc"):
        if name:
            path = shutil.which(name)
            if path:
                return path
    raise FmuBuildError("no C compiler found (set CC or install gcc); the native FMU backend compiles C")


def _platform() -> tuple[str, str]:
    if sys.platform.startswith("linux") and sys.maxsize > 2**32:
        return "linux64", ".so"
    if sys.platform == "darwin":
        return "darwin64", ".dylib"
    raise FmuBuildError(f"the native backend compiles on linux64 and darwin64, not {sys.platform}; build the "
                        "binary from the FMU's sources/ with CMake on this platform")


def compile_shared_library(src_dir, out_path, *, extra_flags=()) -> Path:
    """Compile ``src_dir/solenoid_fmu.c`` into the shared library ``out_path`` with :data:`CFLAGS`.

    Raises
    ------
    FmuBuildError
        No compiler, or the compiler failed (its output is in the message).
    """
    cc = find_compiler()
    src_dir = Path(src_dir)
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    cmd = [cc, *CFLAGS, *extra_flags, f"-I{src_dir}", "-o", str(out_path), str(src_dir / "solenoid_fmu.c"), "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    if proc.returncode != 0:
        raise FmuBuildError(f"compiling the native FMU failed ({' '.join(cmd)}):\n{proc.stderr.strip()}")
    return out_path


def _raw_model_description(guid: str, params: dict, tables: MapTables) -> bytes:
    """A minimal co-simulation description with the interface variables (interface_for) and their start values.

    :func:`solenoid_fmu.fmu.model_description.finalize_model_description` completes it (with
    :data:`NATIVE_DESCRIPTION`: model exchange too).
    """
    root = etree.Element("fmiModelDescription", fmiVersion="2.0", modelName="solenoid", guid=guid,
                         numberOfEventIndicators="0")
    etree.SubElement(root, "CoSimulation", modelIdentifier=MODEL_IDENTIFIER)
    cats = etree.SubElement(root, "LogCategories")
    for name, desc in LOG_CATEGORIES:
        etree.SubElement(cats, "Category", name=name, description=desc)
    starts = start_values(tables, params)
    mv = etree.SubElement(root, "ModelVariables")
    for k, v in enumerate(interface_for(tables)):
        sv = etree.SubElement(mv, "ScalarVariable", name=v.name, valueReference=str(k))
        el = etree.SubElement(sv, "Integer" if v.type == "Enumeration" else v.type)
        if v.name in starts:
            start = starts[v.name]
            el.set("start", repr(float(start)) if v.type == "Real" else ("true" if start else "false")
                   if v.type == "Boolean" else str(int(start)))
    etree.SubElement(root, "ModelStructure")
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8")


def build_c_fmu(maps_dir, dest, tables: MapTables) -> str:
    """Generate, compile and pack the native FMU into ``dest`` (description not yet final).

    Returns the ``generationTool`` string. :func:`solenoid_fmu.fmu.build_fmu` then runs
    :func:`solenoid_fmu.fmu.model_description.finalize_model_description`.
    """
    maps_dir = Path(maps_dir)
    platform, ext = _platform()
    params = default_params(tables)
    with tempfile.TemporaryDirectory(prefix="solenoid_fmu_c_") as tmp:
        tmp = Path(tmp)
        src = tmp / "sources"
        guid = generate_sources(tables, src)
        lib = compile_shared_library(src, tmp / "binaries" / platform / f"{MODEL_IDENTIFIER}{ext}")
        with zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.writestr("modelDescription.xml", _raw_model_description(guid, params, tables))
            zf.write(lib, f"binaries/{platform}/{lib.name}")
            for p in sorted(src.iterdir()):
                zf.write(p, f"sources/{p.name}")
            for name in ("maps.npz", "maps.json"):
                zf.write(maps_dir / name, f"resources/{name}")
    cc = Path(find_compiler()).name
    return f"solenoid-fmu {__version__} (c backend: generated C99, compiled with {cc})"
