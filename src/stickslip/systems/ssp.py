"""A system as an SSP file (System Structure and Parameterization 1.0): the chain wired from FMUs alone.

``<stem>.ssp`` is a zip archive of ``SystemStructure.ssd`` and ``resources/`` with the block's FMU
(``SpringBlockFriction.fmu``, FMI 2 co-simulation), the coupling FMU (``ChainCoupling.fmu``,
:mod:`stickslip.fmu.coupling`) and one parameter set per component (``<component>.ssv``). Block ``i`` (1-based) is
the component ``b<i>``, its coupling springs the component ``c<i>`` (:func:`component`: ``i`` zero-padded to the
width of the largest, ``b01`` .. ``b10``, so that no component's name begins another's):

    b<i>.x -> c<i>.x,   b<i-1>.x -> c<i>.x_left,   b<i+1>.x -> c<i>.x_right,   c<i>.F -> b<i>.F_ext

with ``c<i>.kc_left = kc_(i-1)`` and ``c<i>.kc_right = kc_i`` (0 at the chain's ends), so that
``F_ext_i = kc_(i-1) (x_(i-1) - x_i) + kc_i (x_(i+1) - x_i)`` (N, +x; SPEC section 5). Every component's values
(the block's parameters, ``v_drive`` and the start value of ``F_ext``; the stiffnesses) are a parameter set named
:data:`PARAMETER_SET` in its own file ``resources/<component>.ssv``, which the component's ParameterBinding
references (libcosim applies a component's first set; ecos applies the set named at ``init``; FMPy's SSP reader
reads it, and its simulator applies the sets handed to it with the components' names in front). A block's
connectors are its wired ``x`` and ``F_ext`` and the outputs an engine's run is read by (:data:`BLOCK_OUTPUTS`).
The DefaultExperiment holds the stop time and, as an OSP annotation, the fixed step.
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
#: the block's outputs besides ``x`` that are connectors of each block: an engine's run is read by them
BLOCK_OUTPUTS = ("v", "t_last_event", "mode", "n_events")
_INTEGERS = {v.name for v in VARIABLES if v.kind == "integer"}


def component(kind, i, n):
    """The name of block (``kind`` "b") or coupling (``kind`` "c") ``i`` (1-based) of a chain of ``n`` blocks:
    ``i`` zero-padded to the width of ``n``."""
    return f"{kind}{i:0{len(str(n))}d}"


def parameter_file(name):
    """The path, in the SSP, of the component ``name``'s parameter set."""
    return f"resources/{name}.ssv"


def _register_namespaces():
    """Write the SSP's namespaces with their usual prefixes."""
    for prefix, uri in NAMESPACES.items():
        ET.register_namespace(prefix, uri)


def _tag(prefix, name):
    return f"{{{NAMESPACES[prefix]}}}{name}"


def connections(n):
    """``[(start element, start connector, end element, end connector)]`` of a chain of ``n`` blocks."""
    wires = []
    for i in range(1, n + 1):
        block, coupling = component("b", i, n), component("c", i, n)
        wires.append((block, "x", coupling, "x"))
        if i > 1:
            wires.append((component("b", i - 1, n), "x", coupling, "x_left"))
        if i < n:
            wires.append((component("b", i + 1, n), "x", coupling, "x_right"))
        wires.append((coupling, "F", block, "F_ext"))
    return wires


def component_values(system):
    """``{component: {variable: value}}``: each block's parameters, ``v_drive`` and ``F_ext`` at the start
    positions (as the FMPy masters set them); each coupling's stiffnesses."""
    forces = system.forces([b["x_start"] for b in system.blocks])
    springs = (0.0, *system.coupling, 0.0)
    values = {}
    for i, (block, force) in enumerate(zip(system.blocks, forces), start=1):
        values[component("b", i, system.n)] = {**block, "v_drive": system.v_drive, "F_ext": force}
        values[component("c", i, system.n)] = {"kc_left": springs[i - 1], "kc_right": springs[i]}
    return values


def system_description(system, step):
    """The SSD of ``system`` (bytes) with the fixed step ``step`` (s)."""
    _register_namespaces()
    root = ET.Element(_tag("ssd", "SystemStructureDescription"), version="1.0", name=system.name)
    elements = ET.SubElement(ET.SubElement(root, _tag("ssd", "System"), name=system.name), _tag("ssd", "Elements"))
    wires = connections(system.n)
    for name in component_values(system):
        source = BLOCK_FILE if name.startswith("b") else COUPLING_FILE
        element = ET.SubElement(elements, _tag("ssd", "Component"), name=name, source=f"resources/{source}",
                                type="application/x-fmu-sharedlibrary")
        _connectors(element, name, wires)
        ET.SubElement(ET.SubElement(element, _tag("ssd", "ParameterBindings")), _tag("ssd", "ParameterBinding"),
                      source=parameter_file(name))
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


def _connectors(element, name, wires):
    """The component's connectors: the variables its connections use, with their kind, and a block's
    :data:`BLOCK_OUTPUTS`."""
    node = ET.SubElement(element, _tag("ssd", "Connectors"))
    kinds = {}
    for start, out, end, into in wires:
        if start == name:
            kinds[out] = "output"
        if end == name:
            kinds[into] = "input"
    if name.startswith("b"):
        kinds.update(dict.fromkeys(BLOCK_OUTPUTS, "output"))
    for connector, kind in kinds.items():
        ET.SubElement(ET.SubElement(node, _tag("ssd", "Connector"), name=connector, kind=kind),
                      _tag("ssc", "Integer" if connector in _INTEGERS else "Real"))


def parameter_set(values):
    """The parameter set :data:`PARAMETER_SET` (an SSV file's bytes) of one component's ``values``."""
    _register_namespaces()
    root = ET.Element(_tag("ssv", "ParameterSet"), version="1.0", name=PARAMETER_SET)
    parameters = ET.SubElement(root, _tag("ssv", "Parameters"))
    for name, value in values.items():
        parameter = ET.SubElement(parameters, _tag("ssv", "Parameter"), name=name)
        if name in _INTEGERS:
            ET.SubElement(parameter, _tag("ssv", "Integer"), value=str(int(value)))
        else:
            ET.SubElement(parameter, _tag("ssv", "Real"), value=repr(float(value)))
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)


def write_ssp(system, step, block_fmu, coupling_fmu, dest):
    """Write ``system`` with the fixed step ``step`` (s) as the SSP archive ``dest`` holding ``block_fmu`` and
    ``coupling_fmu``; return its path."""
    dest = Path(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr(SSD, system_description(system, step))
        for name, values in component_values(system).items():
            archive.writestr(parameter_file(name), parameter_set(values))
        for source, name in ((block_fmu, BLOCK_FILE), (coupling_fmu, COUPLING_FILE)):
            with open(source, "rb") as stream, archive.open(f"resources/{name}", "w") as entry:
                shutil.copyfileobj(stream, entry)
    return dest
