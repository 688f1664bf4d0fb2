"""``modelDescription.xml`` and ``documentation/index.html`` of an FMU, written from the interface table.

A backend writes an FMU whose variables follow :func:`solenoid_fmu.fmu.interface.interface_for`
(pythonfmu's own description, or the native backend's minimal one);
:func:`finalize_model_description` then rewrites it with lxml into what a strict importer
expects: SI unit definitions and a unit on every real variable, descriptions, start values,
explicit variabilities, ``drive_mode`` as an Integer 1..2, ``ModelStructure`` with ``Outputs``
and ``InitialUnknowns`` and their dependencies, a ``DefaultExperiment``, generation tool and
date, and the maps' provenance (in the description and as a vendor annotation). What differs per
backend (model exchange with its locals and derivatives, source files, documentation notes) is a
:class:`BackendDescription`.
"""

from __future__ import annotations

import datetime
import hashlib
import html
import json
import os
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

from lxml import etree

from .._version import __version__
from ..errors import FmuBuildError
from ..realtime import MapTables
from .interface import (
    DEFAULT_EXPERIMENT,
    DISPLAY_UNITS,
    DRIVE_MODE_RANGE,
    ME_UNIT_DEFINITIONS,
    MODEL_IDENTIFIER,
    UNIT_DEFINITIONS,
    interface_for,
    me_dependencies,
    me_variables,
)

__all__ = ["BackendDescription", "finalize_model_description", "rewrite_fmu"]


@dataclass(frozen=True)
class BackendDescription:
    """What a backend adds to the shared model description and documentation page.

    Attributes
    ----------
    model_exchange : bool
        Declare ``ModelExchange`` too: the locals of :func:`~solenoid_fmu.fmu.interface.me_variables`,
        ``Derivatives`` and the outputs' model-exchange dependencies on the inputs and states.
    source_files : tuple of str
        ``SourceFiles`` of each interface (a source FMU).
    cs_attributes : dict
        Further ``CoSimulation`` attributes.
    doc_note : str
        The documentation page's ``<li>`` on the backend.
    step_error : str
        What ``fmi2DoStep`` returns for an invalid input (documentation).
    """

    model_exchange: bool = False
    source_files: tuple = ()
    cs_attributes: dict = field(default_factory=dict)
    doc_note: str = ""
    step_error: str = "fmi2Discard"


#: The maps.json keys the modelDescription's vendor annotation repeats (``<Maps>``, sorted JSON).
_SIDECAR_KEYS = ("name", "force_method", "coil", "eddy", "effects", "provenance")
#: CoSimulation capability flags of every export.
_CS_FLAGS = (("needsExecutionTool", "false"), ("canHandleVariableCommunicationStepSize", "true"),
             ("canInterpolateInputs", "false"), ("canBeInstantiatedOnlyOncePerProcess", "false"),
             ("canGetAndSetFMUstate", "true"), ("canSerializeFMUstate", "true"),
             ("providesDirectionalDerivative", "false"))
#: ModelExchange attributes of a native FMU.
_ME_FLAGS = (("needsExecutionTool", "false"), ("completedIntegratorStepNotNeeded", "false"),
             ("canBeInstantiatedOnlyOncePerProcess", "false"), ("canNotUseMemoryManagementFunctions", "false"),
             ("canGetAndSetFMUstate", "true"), ("canSerializeFMUstate", "true"),
             ("providesDirectionalDerivative", "false"))


def _fmt(value: float) -> str:
    return repr(float(value))


def _sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def rewrite_fmu(fmu_path, replace: dict) -> None:
    """Rewrite the FMU zip ``fmu_path`` in place with the members of ``replace`` (name -> bytes)
    replaced or added; an interrupted rewrite leaves the old file."""
    fmu_path = Path(fmu_path)
    with zipfile.ZipFile(fmu_path) as zf:
        entries = [(info, zf.read(info.filename)) for info in zf.infolist()]
    fd, tmp_name = tempfile.mkstemp(prefix=".md.", suffix=".fmu", dir=fmu_path.parent)
    os.close(fd)
    try:
        with zipfile.ZipFile(tmp_name, "w", zipfile.ZIP_DEFLATED) as out:
            for info, data in entries:
                if info.filename not in replace:
                    out.writestr(info, data)
            for name, data in replace.items():
                out.writestr(name, data)
        os.replace(tmp_name, fmu_path)
    finally:
        if os.path.exists(tmp_name):
            os.unlink(tmp_name)


def finalize_model_description(fmu_path, *, tables: MapTables, maps_files: dict, maps_name: str, generation_tool: str,
                               model_name: str | None = None, backend: BackendDescription | None = None) -> None:
    """Rewrite ``modelDescription.xml`` inside ``fmu_path`` (in place) for strict importers.

    Parameters
    ----------
    fmu_path : path-like
        FMU whose variables follow :func:`~solenoid_fmu.fmu.interface.interface_for` (any backend).
    tables : solenoid_fmu.realtime.MapTables
        The maps packed into the FMU (their ranges and sidecar go into the description).
    maps_files : dict
        The maps' files packed into the FMU, ``{"maps.npz": bytes, "maps.json": bytes}`` (their hashes go
        into the provenance).
    maps_name : str
        The maps' name when their sidecar has none.
    generation_tool : str
        ``generationTool`` attribute.
    model_name : str, optional
        ``modelName``; default ``"solenoid <maps name>"``.
    backend : BackendDescription, optional
        What the backend adds; default a co-simulation FMU without extras.

    Notes
    -----
    Adds or replaces: root attributes (description with provenance, generation tool and UTC
    date, version), CoSimulation capability flags (and ModelExchange if the backend has it),
    ``UnitDefinitions`` (SI base-unit exponents), ``DefaultExperiment`` (with a tolerance),
    ``VendorAnnotations`` (maps provenance as JSON), a unit, description, variability and start
    value on every variable, and ``ModelStructure`` (co-simulation: Outputs without direct
    feedthrough; model exchange: Outputs and Derivatives with their dependencies; InitialUnknowns
    depending on the inputs and parameters). Also writes ``documentation/index.html``.
    """
    backend = backend or BackendDescription()
    fmu_path = Path(fmu_path)
    with zipfile.ZipFile(fmu_path) as zf:
        md_bytes = zf.read("modelDescription.xml") if "modelDescription.xml" in zf.namelist() else None
    if md_bytes is None:
        raise FmuBuildError(f"{fmu_path}: no modelDescription.xml in the FMU")
    root = etree.fromstring(md_bytes, etree.XMLParser(remove_blank_text=True))
    maps_name = str(tables.name or maps_name)
    sha_npz = hashlib.sha256(maps_files["maps.npz"]).hexdigest()
    sha_json = hashlib.sha256(maps_files["maps.json"]).hexdigest()
    _set_root_attributes(root, tables, maps_name, sha_npz, model_name, generation_tool)
    children = {child.tag: child for child in root}
    me, cs = _capabilities(fmu_path, children.get("CoSimulation"), backend)
    locals_ = me_variables(tables) if backend.model_exchange else ()
    units = _unit_definitions(locals_)
    log_categories = children.get("LogCategories")
    experiment = etree.Element("DefaultExperiment", **DEFAULT_EXPERIMENT)
    vendor = _vendor_annotations(tables, maps_name, sha_npz, sha_json)

    variables = children.get("ModelVariables")
    interface = interface_for(tables)
    _write_variables(fmu_path, variables, interface)
    _write_locals(variables, len(interface), locals_)
    structure = _model_structure(tables, interface, len(locals_) // 2, backend.model_exchange)

    # -- reassemble in schema order ---------------------------------------------------------
    for child in list(root):
        root.remove(child)
    for el in (me, cs, units, log_categories, experiment, vendor, variables, structure):
        if el is not None:
            root.append(el)
    xml = etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)
    doc = documentation_html(root.get("modelName"), root.get("description"), tables, backend)
    rewrite_fmu(fmu_path, {"modelDescription.xml": xml, "documentation/index.html": doc.encode("utf-8")})


def _set_root_attributes(root, tables: MapTables, maps_name: str, sha_npz: str, model_name: str | None,
                         generation_tool: str) -> None:
    """The root's attributes: model name, the description with the maps' provenance, tool, UTC date, version."""
    prov = tables.provenance
    geo = prov.get("geometry") or {}
    now = datetime.datetime.now(datetime.UTC).replace(microsecond=0)
    root.set("modelName", model_name or f"solenoid {maps_name}")
    root.set("description",
             f"Valve solenoid real-time lumped model (paper eqs. 1-3: U = R i + dPsi/dt, "
             f"i = i_f(Psi, x) + G_eddy dPsi/dt, F = F(Psi, x)) from the characteristic maps "
             f"'{maps_name}' (maps.npz sha256 {sha_npz}; geometry {geo.get('name', '?')} "
             f"sha256 {geo.get('sha256', '?')}; maps created {prov.get('created_utc', '?')}, "
             f"code {prov.get('code_version', '?')}). Gap range {tables.x_min_m:.6g} .. "
             f"{tables.x_max_m:.6g} m, |Psi| <= {tables.psi_max_Wb:.6g} Wb.")
    root.set("generationTool", generation_tool)
    root.set("generationDateAndTime", now.strftime("%Y-%m-%dT%H:%M:%SZ"))
    root.set("version", __version__)
    root.set("author", "solenoid-fmu")
    root.set("variableNamingConvention", "structured")


def _capabilities(fmu_path: Path, cs, backend: BackendDescription) -> tuple:
    """(ModelExchange or None, CoSimulation): the capability flags and the backend's source files."""
    if cs is None:
        raise FmuBuildError(f"{fmu_path}: modelDescription.xml has no CoSimulation element")
    for key, value in (*_CS_FLAGS, *backend.cs_attributes.items()):
        cs.set(key, value)
    me = None
    if backend.model_exchange:
        me = etree.Element("ModelExchange", modelIdentifier=MODEL_IDENTIFIER, **dict(_ME_FLAGS))
    for el in (me, cs):
        if el is not None and backend.source_files:
            for child in el.findall("SourceFiles"):
                el.remove(child)
            files = etree.SubElement(el, "SourceFiles")
            for name in backend.source_files:
                etree.SubElement(files, "File", name=name)
    return me, cs


def _unit_definitions(locals_) -> etree._Element:
    """``UnitDefinitions``: the interface's units and those of the model-exchange locals, with display units."""
    units = etree.Element("UnitDefinitions")
    for name, exps in (*UNIT_DEFINITIONS.items(),
                       *((n, e) for n, e in ME_UNIT_DEFINITIONS.items() if any(u == n for _, u, _ in locals_))):
        u = etree.SubElement(units, "Unit", name=name)
        etree.SubElement(u, "BaseUnit", **{k: str(v) for k, v in exps.items()})
        for dname, factor in DISPLAY_UNITS.get(name, ()):
            etree.SubElement(u, "DisplayUnit", name=dname, factor=_fmt(factor))
    return units


def _vendor_annotations(tables: MapTables, maps_name: str, sha_npz: str, sha_json: str) -> etree._Element:
    """``VendorAnnotations``: the maps' name, hashes, ranges and their sidecar (sorted JSON)."""
    vendor = etree.Element("VendorAnnotations")
    tool = etree.SubElement(vendor, "Tool", name="solenoid-fmu")
    maps_el = etree.SubElement(tool, "Maps", name=maps_name, npz_sha256=sha_npz, json_sha256=sha_json,
                               psi_max_Wb=_fmt(tables.psi_max_Wb), x_min_m=_fmt(tables.x_min_m),
                               x_max_m=_fmt(tables.x_max_m), n_psi=str(tables.n_psi), n_x=str(tables.n_x))
    sidecar = {k: v for k, v in tables.meta.items() if k in _SIDECAR_KEYS}
    maps_el.text = json.dumps(sidecar, sort_keys=True)
    return vendor


def _write_variables(fmu_path: Path, variables, interface: tuple) -> None:
    """Complete the ScalarVariables of the interface (in place): attributes, unit, start value."""
    scalars = list(variables) if variables is not None else []
    by_name = {sv.get("name"): sv for sv in scalars}
    if [sv.get("name") for sv in scalars] != [v.name for v in interface]:
        raise FmuBuildError(f"{fmu_path}: model variables {[sv.get('name') for sv in scalars]} do not "
                            f"match the interface {[v.name for v in interface]}")
    for k, spec in enumerate(interface):
        sv = by_name[spec.name]
        sv.set("valueReference", str(k))
        sv.set("description", spec.description)
        sv.set("causality", spec.causality)
        sv.set("variability", spec.variability)
        if spec.causality == "parameter":
            sv.set("initial", "exact")
        elif spec.causality == "output":
            sv.set("initial", "calculated")
        elif "initial" in sv.attrib:
            del sv.attrib["initial"]
        old = sv[0] if len(sv) else None
        start = old.get("start") if old is not None else None
        for child in list(sv):
            sv.remove(child)
        el = etree.SubElement(sv, spec.type)
        if spec.name == "drive_mode":
            el.set("min", str(DRIVE_MODE_RANGE[0]))
            el.set("max", str(DRIVE_MODE_RANGE[1]))
        if spec.unit is not None:
            el.set("unit", spec.unit)
            if spec.unit in DISPLAY_UNITS:
                el.set("displayUnit", DISPLAY_UNITS[spec.unit][0][0])
        if spec.causality in ("input", "parameter"):
            if start is None:
                raise FmuBuildError(f"{fmu_path}: variable {spec.name} has no start value")
            if spec.type == "Real":
                start = _fmt(float(start))
            elif spec.type == "Boolean":
                start = "true" if start.lower() in ("true", "1") else "false"
            else:
                start = str(int(start))
            el.set("start", start)


def _write_locals(variables, n0: int, locals_: tuple) -> None:
    """Append the model-exchange locals (continuous states, then their derivatives) after the interface."""
    nx = len(locals_) // 2
    for k, (name, unit, desc) in enumerate(locals_):
        sv = etree.SubElement(variables, "ScalarVariable", name=name, valueReference=str(n0 + k), description=desc,
                              causality="local", variability="continuous", initial="calculated")
        real = etree.SubElement(sv, "Real", unit=unit)
        if k == 0:
            real.set("displayUnit", DISPLAY_UNITS["Wb"][0][0])
        elif k >= nx:
            real.set("derivative", str(n0 + 1 + k - nx))


def _model_structure(tables: MapTables, interface: tuple, nx: int, model_exchange: bool):
    """``ModelStructure``: Outputs (no direct feedthrough in co-simulation; the model-exchange
    dependencies otherwise), Derivatives, InitialUnknowns (outputs and ME locals on every known)."""
    index = {v.name: k + 1 for k, v in enumerate(interface)}
    knowns = " ".join(str(index[v.name]) for v in interface if v.causality in ("input", "parameter"))
    out_deps, der_deps = me_dependencies(tables) if model_exchange else ({}, ())
    structure = etree.Element("ModelStructure")
    outputs = etree.SubElement(structure, "Outputs")
    for v in interface:
        if v.causality == "output":
            etree.SubElement(outputs, "Unknown", index=str(index[v.name]),
                             dependencies=" ".join(str(d) for d in out_deps.get(v.name, ())))
    n0 = len(interface)
    if model_exchange:
        derivs = etree.SubElement(structure, "Derivatives")
        for idx in range(n0 + 1 + nx, n0 + 1 + 2 * nx):
            etree.SubElement(derivs, "Unknown", index=str(idx), dependencies=" ".join(str(d) for d in der_deps))
    initial = etree.SubElement(structure, "InitialUnknowns")
    unknowns = [index[v.name] for v in interface if v.causality == "output"]
    for idx in unknowns + list(range(n0 + 1, n0 + 1 + 2 * nx)):
        etree.SubElement(initial, "Unknown", index=str(idx), dependencies=knowns)
    return structure


def documentation_html(model_name: str, description: str, tables: MapTables, backend: BackendDescription) -> str:
    """``documentation/index.html``: the interface table and the semantics of the FMU."""
    rows = "\n".join(
        f"<tr><td><code>{html.escape(v.name)}</code></td><td>{v.causality}</td><td>{v.variability}</td>"
        f"<td>{html.escape(v.unit or '')}</td><td>{html.escape(v.description)}</td></tr>"
        for v in interface_for(tables))
    return f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>{html.escape(model_name)}</title></head>
<body>
<h1>{html.escape(model_name)}</h1>
<p>{html.escape(description)}</p>
<h2>Interface</h2>
<table border="1" cellspacing="0" cellpadding="3">
<tr><th>name</th><th>causality</th><th>variability</th><th>unit</th><th>meaning</th></tr>
{rows}
</table>
<h2>Semantics</h2>
<ul>
<li>Inputs are held constant over each communication step; the outputs after a step are computed
from the state and the inputs of that step (no direct feedthrough).</li>
<li>Voltage mode: outputs are instantaneous values. Current mode: U_out_V, dpsi_dt_V and i_eddy_A are
exact means over the last step (dPsi/dt = (Psi(t+h) - Psi(t)) / h).</li>
<li>Integrator: ROS2 (2nd order, L-stable, linearly implicit) with sub-steps of at most h_sub_max_s;
current mode with G_eddy_S = 0 solves i_f(Psi, x) = i by a safeguarded Newton iteration.</li>
<li>x outside [{tables.x_min_m:.6g}, {tables.x_max_m:.6g}] m and |Psi| above {tables.psi_max_Wb:.6g} Wb are
clamped and logged once per excursion (turn FMU logging on to see the messages); the output
out_of_map is true meanwhile.</li>
<li>A NaN or infinite input, R_ohm &lt;= 0 or G_eddy_S &lt; 0 is logged with status error and
fmi2DoStep returns {backend.step_error}; the state is left unchanged.</li>
{backend.doc_note}
</ul>
</body></html>
"""
