"""Native FMU backend: generated C, no Python at run time, FMI 2.0 co-simulation and model exchange.

``solenoid-fmu export maps/NAME -o build/NAME.fmu --backend c`` (or
``build_fmu(maps_dir, dest, backend="c")``) writes the C sources of
:mod:`solenoid_fmu.fmu.c_sources` (the model source ``fmu/c/solenoid_fmu.c`` and the parts it includes,
``sol_core.h``, ``sol_lookup.c``, ``sol_params.c``, ``sol_step.c``, ``sol_effects.c``, ``sol_me.c``; the generated
``solenoid_model.h`` and ``solenoid_maps.h``, the FMI 2.0 headers shipped with fmpy) into the FMU's
``sources/`` and compiles ``binaries/linux64/SolenoidFmu.so`` with the machine's C compiler
(``$CC``, else ``gcc``, else ``cc``) and ``binaries/win64/SolenoidFmu.dll`` with Debian's mingw-w64
cross compiler (``x86_64-w64-mingw32-gcc``, or ``$CC_WIN64``; where it is missing the export leaves
win64 out and says so: :func:`skipped_platforms`), both using :data:`CFLAGS` (``-std=c99 -O2 -Wall
-Wextra -Werror -ffp-contract=off``: no fused multiply-add, so the arithmetic is the one of
:mod:`solenoid_fmu.realtime.model`, and the two binaries agree bit for bit). ``generationTool``
names the compiler of each binary. ``sources/`` also holds a ``CMakeLists.txt``, so a source FMU
importer (fmpy, Dymola, OMSimulator) or a user on macOS or aarch64 builds the binary for another
platform.
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
import platform
import shutil
import subprocess
import sys
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

from lxml import etree

from .._version import __version__
from ..errors import FmuBuildError
from ..realtime import MapTables
from .c_sources import default_params, generate_sources
from .interface import LOG_CATEGORIES, MODEL_IDENTIFIER, interface_for, start_values
from .model_description import BackendDescription

__all__ = [
    "CFLAGS",
    "NATIVE_CS_DESCRIPTION",
    "NATIVE_DESCRIPTION",
    "CROSS_TARGETS",
    "WIN64",
    "Target",
    "build_c_fmu",
    "compile_binaries",
    "compile_shared_library",
    "compiler_version",
    "cross_compiler",
    "find_compiler",
    "generation_tool",
    "host_target",
    "skipped_platforms",
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


@dataclass(frozen=True)
class Target:
    """A platform the native FMU carries a binary for.

    Attributes
    ----------
    fmi2, fmi3 : str
        Folder under ``binaries/`` in an FMI 2.0 / FMI 3.0 FMU (``linux64`` / ``x86_64-linux``).
    ext : str
        File extension of the shared library.
    compilers : tuple of str
        Cross compilers tried in order (``$CC_<FMI2 NAME>`` first); empty for the machine's own platform.
    package : str
        The Debian package that brings the cross compiler (named in the skip note).
    """

    fmi2: str
    fmi3: str
    ext: str
    compilers: tuple = ()
    package: str = ""

    def folder(self, fmi_version: int) -> str:
        return self.fmi3 if fmi_version == 3 else self.fmi2


#: win64, cross-compiled with Debian's mingw-w64 (``x86_64-w64-mingw32-gcc``; the DLL imports only
#: KERNEL32 and msvcrt). ``$CC_WIN64`` names another compiler for the same target.
WIN64 = Target("win64", "x86_64-windows", ".dll", ("x86_64-w64-mingw32-gcc", "x86_64-w64-mingw32-gcc-win32"),
               "gcc-mingw-w64-x86-64-win32")
#: Platforms cross-compiled besides the machine's own, where their compiler is installed.
CROSS_TARGETS = (WIN64,)


def host_target() -> Target:
    """The platform of this machine (compiled with :func:`find_compiler`)."""
    if sys.platform.startswith("linux") and sys.maxsize > 2**32 and _machine() in ("x86_64", "amd64"):
        return Target("linux64", "x86_64-linux", ".so")
    if sys.platform == "darwin":
        return Target("darwin64", "aarch64-darwin" if _machine() == "arm64" else "x86_64-darwin", ".dylib")
    raise FmuBuildError(f"the native backend compiles on x86_64 Linux and macOS, not {sys.platform} "
                        f"{_machine()}; build the binary from the FMU's sources/ with CMake on this platform")


def _machine() -> str:
    return platform.machine().lower()


def cross_compiler(target: Target) -> str | None:
    """Path of the cross compiler for ``target`` (``$CC_<NAME>``, then its usual names), or None."""
    for name in (os.environ.get(f"CC_{target.fmi2.upper()}"), *target.compilers):
        if name:
            path = shutil.which(name)
            if path:
                return path
    return None


def skipped_platforms() -> dict:
    """Cross platforms the native export leaves out on this machine: name -> what is missing."""
    return {t.fmi2: f"no {t.compilers[0]} (Debian package {t.package}; as root: make setup-system)"
            for t in CROSS_TARGETS if cross_compiler(t) is None}


def compiler_version(cc: str) -> str:
    """``NAME VERSION`` of a gcc-compatible compiler (``gcc 12.2.0``), for ``generationTool``."""
    try:
        proc = subprocess.run([cc, "-dumpfullversion", "-dumpversion"], capture_output=True, text=True, timeout=30)
        version = proc.stdout.strip().splitlines()[0] if proc.returncode == 0 and proc.stdout.strip() else ""
    except (OSError, subprocess.SubprocessError):
        version = ""
    return f"{Path(cc).name} {version}".strip()


def compile_shared_library(src_dir, out_path, *, extra_flags=(), cc: str | None = None,
                           source: str = "solenoid_fmu.c") -> Path:
    """Compile ``src_dir/source`` into the shared library ``out_path`` with :data:`CFLAGS`.

    ``cc``: the compiler (default :func:`find_compiler`; a cross compiler for another platform).

    Raises
    ------
    FmuBuildError
        No compiler, or the compiler failed (its output is in the message).
    """
    cc = cc or find_compiler()
    src_dir = Path(src_dir)
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    cmd = [cc, *CFLAGS, *extra_flags, f"-I{src_dir}", "-o", str(out_path), str(src_dir / source), "-lm"]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    except (OSError, subprocess.SubprocessError) as exc:
        raise FmuBuildError(f"compiling the native FMU failed ({' '.join(cmd)}): {exc}") from None
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


def build_c_fmu(maps_files: dict, dest, tables: MapTables, *, fmi_version: int = 2) -> str:
    """Generate, compile and pack the native FMU into ``dest`` (description not yet final), with the maps'
    files ``maps_files`` (``{"maps.npz": bytes, "maps.json": bytes}``) under ``resources/``.

    Binaries: the machine's platform (:func:`host_target`, with :func:`find_compiler`) and every
    :data:`CROSS_TARGETS` platform whose cross compiler is installed (:func:`skipped_platforms` names
    the others). FMI 3.0 (``fmi_version=3``): the binaries of ``solenoid_fmi3.c`` (which includes
    ``solenoid_fmu.c``) under the FMI 3.0 platform folders (``x86_64-linux``, ``x86_64-windows``),
    exporting only the fmi3 functions. Returns the ``generationTool`` string, which names the compiler
    of each binary.
    :func:`solenoid_fmu.fmu.build_fmu` then runs
    :func:`solenoid_fmu.fmu.model_description.finalize_model_description`.
    """
    params = default_params(tables)
    with tempfile.TemporaryDirectory(prefix="solenoid_fmu_c_") as tmp:
        tmp = Path(tmp)
        src = tmp / "sources"
        guid = generate_sources(tables, src, fmi_version=fmi_version)
        if fmi_version == 3:
            libs, compiled = compile_binaries(src, tmp / "binaries", fmi_version=3, source="solenoid_fmi3.c",
                                              extra_flags=("-fvisibility=hidden",))
        else:
            libs, compiled = compile_binaries(src, tmp / "binaries", fmi_version=2)
        with zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.writestr("modelDescription.xml", _raw_model_description(guid, params, tables))
            for lib in libs:
                zf.write(lib, lib.relative_to(tmp).as_posix())
            for p in sorted(src.iterdir()):
                zf.write(p, f"sources/{p.name}")
            for name, data in maps_files.items():
                zf.writestr(f"resources/{name}", data)
    return generation_tool(compiled)


def compile_binaries(src, binaries_dir, *, fmi_version: int = 2, source: str = "solenoid_fmu.c",
                     extra_flags=()) -> tuple[list, dict]:
    """Compile ``src/source`` for this machine and every cross platform with a compiler.

    Returns the library paths (under ``binaries_dir/<platform folder>/``) and platform -> compiler
    (``NAME VERSION``).
    """
    host = host_target()
    libs, compiled = [], {}
    for target, cc in ((host, find_compiler()), *((t, cross_compiler(t)) for t in CROSS_TARGETS)):
        if cc is None:
            continue
        out = Path(binaries_dir) / target.folder(fmi_version) / f"{MODEL_IDENTIFIER}{target.ext}"
        libs.append(compile_shared_library(src, out, cc=cc, source=source, extra_flags=extra_flags))
        compiled[target.folder(fmi_version)] = compiler_version(cc)
    return libs, compiled


def generation_tool(compiled: dict) -> str:
    """``generationTool``: the exporter and the compiler of each binary."""
    each = ", ".join(f"{name}: {cc}" for name, cc in compiled.items())
    return f"solenoid-fmu {__version__} (c backend: generated C99; binaries {each})"
