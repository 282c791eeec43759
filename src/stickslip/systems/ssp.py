"""A system as an SSP file (System Structure and Parameterization 1.0): the chain wired from FMUs alone.

``<stem>.ssp`` is a zip archive of ``SystemStructure.ssd`` and ``resources/`` with the block's FMU
(``SpringBlockFriction.fmu``, FMI 2 co-simulation) and the coupling FMU (``ChainCoupling.fmu``,
:mod:`stickslip.fmu.coupling`). Block ``i`` (1-based) is the component ``b<i>``, its coupling springs the component
``c<i>``:

    b<i>.x -> c<i>.x,   b<i-1>.x -> c<i>.x_left,   b<i+1>.x -> c<i>.x_right,   c<i>.F -> b<i>.F_ext

with ``c<i>.kc_left = kc_(i-1)`` and ``c<i>.kc_right = kc_i`` (0 at the chain's ends), so that
``F_ext_i = kc_(i-1) (x_(i-1) - x_i) + kc_i (x_(i+1) - x_i)`` (N, +x; SPEC section 5). Every component's values
(the block's parameters, ``v_drive`` and the start value of ``F_ext``; the stiffnesses) are inline in the SSD,
one parameter set named :data:`PARAMETER_SET` (libcosim applies a component's first set; ecos applies the set
named at ``init``). The DefaultExperiment holds the stop time and, as an OSP annotation, the fixed step.
"""

import shutil
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

from ..fmu.coupling import COUPLING_FILE
from ..fmu.variables import VARIABLES

SSD = "SystemStructure.ssd"
PARAMETER_SET = "initialValues"
NAMESPACES = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
              "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
              "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
              "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations"}
BLOCK_FILE = "SpringBlockFriction.fmu"
_INTEGERS = {v.name for v in VARIABLES if v.kind == "integer"}


def _tag(prefix, name):
    return f"{{{NAMESPACES[prefix]}}}{name}"


def connections(n):
    """``[(start element, start connector, end element, end connector)]`` of a chain of ``n`` blocks."""
    wires = []
    for i in range(1, n + 1):
        wires.append((f"b{i}", "x", f"c{i}", "x"))
        if i > 1:
            wires.append((f"b{i - 1}", "x", f"c{i}", "x_left"))
        if i < n:
            wires.append((f"b{i + 1}", "x", f"c{i}", "x_right"))
        wires.append((f"c{i}", "F", f"b{i}", "F_ext"))
    return wires


def component_values(system):
    """``{component: {variable: value}}``: each block's parameters, ``v_drive`` and ``F_ext`` at the start
    positions (as the FMPy masters set them); each coupling's stiffnesses."""
    forces = system.forces([b["x_start"] for b in system.blocks])
    springs = (0.0, *system.coupling, 0.0)
    values = {}
    for i, (block, force) in enumerate(zip(system.blocks, forces), start=1):
        values[f"b{i}"] = {**block, "v_drive": system.v_drive, "F_ext": force}
        values[f"c{i}"] = {"kc_left": springs[i - 1], "kc_right": springs[i]}
    return values


def system_description(system, step):
    """The SSD of ``system`` (bytes) with the fixed step ``step`` (s)."""
    for prefix, uri in NAMESPACES.items():
        ET.register_namespace(prefix, uri)
    root = ET.Element(_tag("ssd", "SystemStructureDescription"), version="1.0", name=system.name)
    elements = ET.SubElement(ET.SubElement(root, _tag("ssd", "System"), name=system.name), _tag("ssd", "Elements"))
    wires = connections(system.n)
    for name, values in component_values(system).items():
        source = BLOCK_FILE if name.startswith("b") else COUPLING_FILE
        component = ET.SubElement(elements, _tag("ssd", "Component"), name=name, source=f"resources/{source}",
                                  type="application/x-fmu-sharedlibrary")
        _connectors(component, name, wires)
        _parameters(component, values)
    wiring = ET.SubElement(root.find(_tag("ssd", "System")), _tag("ssd", "Connections"))
    for start, out, end, into in wires:
        ET.SubElement(wiring, _tag("ssd", "Connection"), startElement=start, startConnector=out, endElement=end,
                      endConnector=into)
    experiment = ET.SubElement(root, _tag("ssd", "DefaultExperiment"), startTime="0.0",
                               stopTime=repr(system.stop_time))
    annotation = ET.SubElement(ET.SubElement(experiment, _tag("ssd", "Annotations")), _tag("ssc", "Annotation"),
                               type="com.opensimulationplatform")
    algorithm = ET.SubElement(annotation, _tag("osp", "Algorithm"))
    ET.SubElement(algorithm, _tag("osp", "FixedStepAlgorithm"), baseStepSize=repr(step))
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)


def _connectors(component, name, wires):
    """The component's connectors: the variables its connections use, with their kind."""
    node = ET.SubElement(component, _tag("ssd", "Connectors"))
    kinds = {}
    for start, out, end, into in wires:
        if start == name:
            kinds[out] = "output"
        if end == name:
            kinds[into] = "input"
    for connector, kind in kinds.items():
        ET.SubElement(ET.SubElement(node, _tag("ssd", "Connector"), name=connector, kind=kind), _tag("ssc", "Real"))


def _parameters(component, values):
    """The component's values as an inline parameter set (:data:`PARAMETER_SET`)."""
    binding = ET.SubElement(ET.SubElement(component, _tag("ssd", "ParameterBindings")), _tag("ssd", "ParameterBinding"))
    parameter_set = ET.SubElement(ET.SubElement(binding, _tag("ssd", "ParameterValues")), _tag("ssv", "ParameterSet"),
                                  version="1.0", name=PARAMETER_SET)
    parameters = ET.SubElement(parameter_set, _tag("ssv", "Parameters"))
    for name, value in values.items():
        parameter = ET.SubElement(parameters, _tag("ssv", "Parameter"), name=name)
        if name in _INTEGERS:
            ET.SubElement(parameter, _tag("ssv", "Integer"), value=str(int(value)))
        else:
            ET.SubElement(parameter, _tag("ssv", "Real"), value=repr(float(value)))


def write_ssp(system, step, block_fmu, coupling_fmu, dest):
    """Write ``system`` with the fixed step ``step`` (s) as the SSP archive ``dest`` holding ``block_fmu`` and
    ``coupling_fmu``; return its path."""
    dest = Path(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr(SSD, system_description(system, step))
        for source, name in ((block_fmu, BLOCK_FILE), (coupling_fmu, COUPLING_FILE)):
            with open(source, "rb") as stream, archive.open(f"resources/{name}", "w") as entry:
                shutil.copyfileobj(stream, entry)
    return dest
