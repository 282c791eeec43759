"""Complete the model description that PythonFMU (FMI 2) or pythonfmu3 (FMI 3) writes.

The libraries write names, causalities and start values. :func:`complete` adds what an importer needs: units
and declared types, the enumeration types of the law selectors (their codes as items, so that a tool offers the
laws by name), the bounds the slave checks (``min``/``max``), a DefaultExperiment and, for FMI 2, the
ModelStructure's Outputs, Derivatives and InitialUnknowns and the ModelExchange element's capabilities; and it
replaces the libraries' random GUID and the time of the build by values that depend on the sources alone
(:func:`stickslip.fmu.archive.identity`).
"""

from xml.etree import ElementTree as ET

DEFAULT_EXPERIMENT = {"startTime": "0.0", "stopTime": "100.0", "tolerance": "1e-10"}

# unit as the slave states it -> (FMI unit name, declared type, exponents of the SI base units)
UNITS = {
    "kg": ("kg", "Mass", {"kg": 1}),
    "m": ("m", "Position", {"m": 1}),
    "m/s": ("m/s", "Velocity", {"m": 1, "s": -1}),
    "s": ("s", "Time", {"s": 1}),
    "N": ("N", "Force", {"kg": 1, "m": 1, "s": -2}),
    "N/m": ("N/m", "TranslationalSpringConstant", {"kg": 1, "s": -2}),
    "N s/m": ("N.s/m", "TranslationalDampingConstant", {"kg": 1, "s": -1}),
    "m/s2": ("m/s2", "Acceleration", {"m": 1, "s": -2}),
    "s/m": ("s/m", "InverseVelocity", {"m": -1, "s": 1}),
    "N/s": ("N/s", "ForceRate", {"kg": 1, "m": 1, "s": -3}),
}
DIMENSIONLESS = ("", "1")


class ModelDescriptionError(RuntimeError):
    """The slave declares something the model description cannot state."""


#: FMI version: the attribute that names one build of the model (the importer passes it back at instantiation)
GUID_ATTRIBUTES = {2: "guid", 3: "instantiationToken"}


def complete(xml, units, bounds, fmi_version, guid, generated=None, dependencies=None, enumerations=None):
    """``xml`` (the library's model description, bytes) completed; ``units``/``bounds``: {variable name: unit
    as the slave states it / (min, max) with None for an open end}; ``guid``: the GUID (FMI 3: instantiation
    token); ``generated``: generationDateAndTime (ISO 8601 text), or None to leave it out; ``dependencies``
    (FMI 2): {output name: the inputs it depends on directly}, for the outputs that depend on fewer than all;
    ``enumerations``: {variable name: its enumeration type, ``(name, items)`` with items ``(code, item name,
    description)``}, for the integer variables that hold a code (FMI 2 declares them Enumeration, FMI 3 too)."""
    root = ET.fromstring(xml)
    root.set(GUID_ATTRIBUTES[fmi_version], guid)
    root.attrib.pop("generationDateAndTime", None)
    if generated is not None:
        root.set("generationDateAndTime", generated)
    variables = root.find("ModelVariables")
    enumerations = enumerations or {}
    if fmi_version == 2:
        used = _annotate(variables, units, bounds, enumerations, lambda variable: variable[0])
        _insert_definitions(root, used, enumerations, _add_simple_type, _add_fmi2_enumeration)
        _fmi2_structure(root.find("ModelStructure"), variables, dependencies or {})
        _fmi2_exchange_capabilities(root)
    else:
        used = _annotate(variables, units, bounds, enumerations, lambda variable: variable)
        for old in root.findall("UnitDefinitions") + root.findall("TypeDefinitions"):
            root.remove(old)
        _insert_definitions(root, used, enumerations, _add_float64_type, _add_fmi3_enumeration)
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)


def _annotate(variables, units, bounds, enumerations, element_of):
    """Set declaredType, unit, min and max on ``element_of(variable)`` for each model variable, and make the
    variables of ``enumerations`` Enumerations of their type; return the units used, ``{unit: (FMI unit name,
    declared type, exponents)}``."""
    used = {}
    for variable in variables:
        name = variable.get("name")
        element = element_of(variable)
        if name in enumerations:
            if element.tag not in ("Integer", "Int64", "Enumeration"):
                raise ModelDescriptionError(f"variable {name} is an enumeration but the library wrote {element.tag}")
            element.tag = "Enumeration"
            element.set("declaredType", enumerations[name][0])
        unit = units[name]
        if unit not in DIMENSIONLESS:
            if unit not in UNITS:
                raise ModelDescriptionError(f"variable {name} has the unit {unit!r}, which the builder does not know")
            fmi_unit, declared, _ = used[unit] = UNITS[unit]
            element.set("declaredType", declared)
            element.set("unit", fmi_unit)
        for key, bound in zip(("min", "max"), bounds[name]):
            if bound is not None:
                element.set(key, repr(bound) if element.tag in ("Real", "Float64") else str(int(bound)))
    return used


def _insert_definitions(root, used, enumerations, add_type, add_enumeration):
    """Insert UnitDefinitions and TypeDefinitions of the ``used`` units after the CoSimulation element, each type
    added by ``add_type(type_definitions, declared type, FMI unit)``, then the types of ``enumerations`` by
    ``add_enumeration(type_definitions, name, items)``; and the DefaultExperiment."""
    unit_definitions = ET.Element("UnitDefinitions")
    type_definitions = ET.Element("TypeDefinitions")
    for fmi_unit, declared, exponents in sorted(used.values(), key=lambda entry: entry[1]):
        unit = ET.SubElement(unit_definitions, "Unit", name=fmi_unit)
        ET.SubElement(unit, "BaseUnit", {k: str(e) for k, e in exponents.items()})
        add_type(type_definitions, declared, fmi_unit)
    for name, items in sorted(set(map(tuple, enumerations.values()))):
        add_enumeration(type_definitions, name, items)
    position = list(root).index(root.find("CoSimulation")) + 1
    root.insert(position, unit_definitions)
    root.insert(position + 1, type_definitions)
    for old in root.findall("DefaultExperiment"):
        root.remove(old)
    root.insert(list(root).index(root.find("ModelVariables")), ET.Element("DefaultExperiment", DEFAULT_EXPERIMENT))


def _add_simple_type(type_definitions, declared, fmi_unit):
    simple = ET.SubElement(type_definitions, "SimpleType", name=declared)
    ET.SubElement(simple, "Real", quantity=declared, unit=fmi_unit)


def _add_float64_type(type_definitions, declared, fmi_unit):
    ET.SubElement(type_definitions, "Float64Type", name=declared, quantity=declared, unit=fmi_unit)


def _add_items(parent, items):
    for code, item, description in items:
        ET.SubElement(parent, "Item", name=item, value=str(code), description=description)


def _add_fmi2_enumeration(type_definitions, name, items):
    _add_items(ET.SubElement(ET.SubElement(type_definitions, "SimpleType", name=name), "Enumeration"), items)


def _add_fmi3_enumeration(type_definitions, name, items):
    _add_items(ET.SubElement(type_definitions, "EnumerationType", name=name), items)


#: the capabilities FMI 2's ModelExchange element shares with its CoSimulation element
SHARED_CAPABILITIES = ("needsExecutionTool", "canBeInstantiatedOnlyOncePerProcess", "canGetAndSetFMUstate",
                       "canSerializeFMUstate")


def _fmi2_exchange_capabilities(root):
    """A ModelExchange element (an FMI 2 FMU that offers both interfaces through one binary) takes the capabilities
    :data:`SHARED_CAPABILITIES` of the CoSimulation element, which the library's builder wrote."""
    exchange, co_simulation = root.find("ModelExchange"), root.find("CoSimulation")
    if exchange is None:
        return
    for name in SHARED_CAPABILITIES:
        if co_simulation.get(name) is not None:
            exchange.set(name, co_simulation.get(name))


def _fmi2_structure(structure, variables, dependencies):
    """FMI 2's ModelStructure: every output in Outputs and InitialUnknowns; its direct dependencies on inputs in
    Outputs where ``dependencies`` names them, else omitted (it may depend on every input); for model exchange,
    every state derivative (a Real with a ``derivative`` attribute) in Derivatives and InitialUnknowns."""
    structure.clear()
    index = {v.get("name"): str(i) for i, v in enumerate(variables, start=1)}
    outputs = [v.get("name") for v in variables if v.get("causality") == "output"]
    derivatives = [v.get("name") for v in variables if v.find("Real") is not None and v.find("Real").get("derivative")]
    sections = {"Outputs": outputs, "Derivatives": derivatives, "InitialUnknowns": outputs + derivatives}
    for section, names in sections.items():
        if section == "Derivatives" and not names:
            continue
        node = ET.SubElement(structure, section)
        for name in names:
            unknown = ET.SubElement(node, "Unknown", index=index[name])
            if section == "Outputs" and name in dependencies:
                unknown.set("dependencies", " ".join(index[source] for source in dependencies[name]))
