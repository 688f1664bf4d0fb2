"""FMI 3.0 ``modelDescription.xml``: the FMI 2.0 description of :mod:`solenoid_fmu.fmu.model_description`
carried over element by element, so both versions have the same variables, value references, names,
units, descriptions, start values, ranges and dependencies.

What changes (FMI 3.0 schema): ``guid`` becomes ``instantiationToken``; ``ScalarVariable`` with a
``Real`` / ``Integer`` / ``Boolean`` child becomes one ``Float64`` / ``Int32`` / ``Boolean`` element;
``derivative`` and the ``ModelStructure`` dependencies name value references instead of 1-based
indices (``Output``, ``ContinuousStateDerivative``, ``InitialUnknown``); the independent variable
``time`` [s] is declared (value reference after the model-exchange locals, as ``VR_TIME`` in
``solenoid_fmi3.c``); capability flags take their FMI 3.0 names (``canGetAndSetFMUState`` ...; no
event mode, intermediate update or early return in co-simulation); ``SourceFiles`` move to
``sources/buildDescription.xml``; ``VendorAnnotations`` become ``Annotations``.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

from lxml import etree

from ..errors import FmuBuildError
from ..realtime import MapTables
from .interface import interface_for, me_variables
from .model_description import rewrite_fmu

__all__ = ["FMI3_TYPES", "time_value_reference", "to_fmi3"]

#: FMI 2.0 type element -> FMI 3.0 variable element.
FMI3_TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}
_CS3 = (("needsExecutionTool", "false"), ("canBeInstantiatedOnlyOncePerProcess", "false"),
        ("canGetAndSetFMUState", "true"), ("canSerializeFMUState", "true"),
        ("providesDirectionalDerivative", "false"), ("providesAdjointDerivatives", "false"),
        ("providesPerElementDependencies", "false"), ("canHandleVariableCommunicationStepSize", "true"),
        ("maxOutputDerivativeOrder", "0"), ("providesIntermediateUpdate", "false"),
        ("mightReturnEarlyFromDoStep", "false"), ("canReturnEarlyAfterIntermediateUpdate", "false"),
        ("hasEventMode", "false"), ("providesEvaluateDiscreteStates", "false"))
_ME3 = (("needsExecutionTool", "false"), ("canBeInstantiatedOnlyOncePerProcess", "false"),
        ("canGetAndSetFMUState", "true"), ("canSerializeFMUState", "true"),
        ("providesDirectionalDerivative", "false"), ("providesAdjointDerivatives", "false"),
        ("providesPerElementDependencies", "false"), ("needsCompletedIntegratorStep", "true"),
        ("providesEvaluateDiscreteStates", "false"))
_STRUCTURE = {"Outputs": "Output", "Derivatives": "ContinuousStateDerivative", "InitialUnknowns": "InitialUnknown"}


def time_value_reference(tables: MapTables) -> int:
    """Value reference of ``time``: after the interface and the model-exchange locals (``VR_TIME`` in C)."""
    return len(interface_for(tables)) + len(me_variables(tables))


def to_fmi3(fmu_path, tables: MapTables) -> None:
    """Rewrite the FMU ``fmu_path`` (its FMI 2.0 description final) into an FMI 3.0 description, in place.

    Raises
    ------
    FmuBuildError
        The FMI 2.0 description has an element this conversion does not know (a bug to fix here).
    """
    fmu_path = Path(fmu_path)
    with zipfile.ZipFile(fmu_path) as zf:
        root2 = etree.fromstring(zf.read("modelDescription.xml"), etree.XMLParser(remove_blank_text=True))
        doc = zf.read("documentation/index.html").decode("utf-8")
    root = etree.Element("fmiModelDescription", fmiVersion="3.0")
    for key, value in root2.attrib.items():
        if key == "guid":
            root.set("instantiationToken", value)
        elif key not in ("fmiVersion", "numberOfEventIndicators"):
            root.set(key, value)
    children = {child.tag: child for child in root2}
    scalars = list(children["ModelVariables"])
    vr_of_index = {k + 1: sv.get("valueReference") for k, sv in enumerate(scalars)}
    for tag, flags in (("ModelExchange", _ME3), ("CoSimulation", _CS3)):
        if tag in children:
            etree.SubElement(root, tag, modelIdentifier=children[tag].get("modelIdentifier"), **dict(flags))
    root.append(children["UnitDefinitions"])
    cats = children["LogCategories"]
    for cat in cats:
        cat.set("description", cat.get("description", "").replace("fmi2", "fmi3"))
    root.append(cats)
    root.append(children["DefaultExperiment"])
    variables = etree.SubElement(root, "ModelVariables")
    for sv in scalars:
        variables.append(_variable(sv, vr_of_index))
    etree.SubElement(variables, "Float64", name="time", valueReference=str(time_value_reference(tables)),
                     causality="independent", variability="continuous", unit="s",
                     description="simulation time [s] (the independent variable)")
    structure = etree.SubElement(root, "ModelStructure")
    for group in children["ModelStructure"]:
        if group.tag not in _STRUCTURE:
            raise FmuBuildError(f"{fmu_path}: ModelStructure/{group.tag} has no FMI 3.0 counterpart here")
        for unknown in group:
            el = etree.SubElement(structure, _STRUCTURE[group.tag],
                                  valueReference=vr_of_index[int(unknown.get("index"))])
            deps = unknown.get("dependencies")
            if deps is not None:
                el.set("dependencies", " ".join(vr_of_index[int(d)] for d in deps.split()))
            if unknown.get("dependenciesKind") is not None:
                el.set("dependenciesKind", unknown.get("dependenciesKind"))
    annotations = etree.SubElement(root, "Annotations")
    for tool in children.get("VendorAnnotations", ()):
        ann = etree.SubElement(annotations, "Annotation", type=f"org.{tool.get('name')}")
        for child in tool:
            ann.append(child)
    xml = etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)
    doc = doc.replace("fmi2", "fmi3").replace("FMI 2.0", "FMI 3.0")
    rewrite_fmu(fmu_path, {"modelDescription.xml": xml, "documentation/index.html": doc.encode("utf-8")})


def _variable(sv, vr_of_index: dict):
    """One FMI 2.0 ScalarVariable as its FMI 3.0 element (the type child's attributes merged in)."""
    if len(sv) != 1 or sv[0].tag not in FMI3_TYPES:
        raise FmuBuildError(f"variable {sv.get('name')!r}: no FMI 3.0 type for {[c.tag for c in sv]}")
    typed = sv[0]
    el = etree.Element(FMI3_TYPES[typed.tag], **dict(sv.attrib))
    for key, value in typed.attrib.items():
        el.set(key, vr_of_index[int(value)] if key == "derivative" else value)
    return el
