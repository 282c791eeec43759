"""Build the SpringBlockFriction FMU (FMI 2.0 co-simulation) with PythonFMU.

The runtime ``stickslip/core`` is bundled into the FMI 2 FMU's resources as the
package ``sbf_runtime_<tag>``, together with the slave (``fmu_slave``) and the
variable table the slaves share (``block_interface``), loaded through the module
``springblockfriction_<tag>`` (layout, byte-compiled and mypyc-compiled modules:
:mod:`stickslip.fmu_staging`), where ``<tag>`` is 10 hex digits of a sha256 over
the runtime, the slave, the shared table and the builders. A host that imported
its own ``stickslip``, or another build of this FMU (or the FMI 3 one, whose tag
differs), therefore never hands the FMU a
different copy of the runtime. PythonFMU's model description is then completed:
units, declared types, bounds, InitialUnknowns, a default experiment and the
FMU-state capabilities. Its linux64 binary becomes the loader of
:mod:`stickslip.fmu_loader`, so that the FMU also runs in hosts that are not
Python processes. :mod:`stickslip.fmu3_build` builds the FMI 3 FMU beside it.
"""

import hashlib
import importlib
import os
import sys
import tempfile
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

from . import fmu_loader
from .fmi_host import preserved_sys_path
from .fmu_staging import FMI2_LOADER, STAGING_SOURCES, stage_runtime

REPO = Path(__file__).resolve().parents[2]
RUNTIME = Path(__file__).resolve().parent / "core"
SLAVE = REPO / "fmu_src" / "SpringBlockFriction.py"
INTERFACE = REPO / "fmu_src" / "block_interface.py"
MODEL_NAME = "SpringBlockFriction"
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
}
DIMENSIONLESS = ("", "1")


class BuildError(RuntimeError):
    """The FMU cannot be built from the current sources."""


def source_tag(slave=SLAVE, builders=tuple(fmu_loader.SOURCES) + STAGING_SOURCES):
    """10 hex digits identifying the runtime, the slave, the shared table and the builder sources
    (``builders``: more than this module; by default the FMI 2 FMU's loader and staging)."""
    sources = sorted(p for p in RUNTIME.rglob("*.py") if "__pycache__" not in p.parts)
    digest = hashlib.sha256()
    for path in [*sources, slave, INTERFACE, Path(__file__).resolve(), *builders]:
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()[:10]


def built_tag(fmu_path, prefix="springblockfriction_"):
    """The source tag an existing FMU was built from (None if it has none)."""
    with zipfile.ZipFile(fmu_path) as fmu:
        module = fmu.read("resources/slavemodule.txt").decode().strip()
    return module[len(prefix):] if module.startswith(prefix) else None


def forget_modules(tag, module):
    """Drop the bundled modules that building imported into this process."""
    for name in [m for m in sys.modules if m == module or m.split(".")[0].endswith(f"_{tag}")]:
        del sys.modules[name]


def build(dest=REPO / "dist" / f"{MODEL_NAME}.fmu", pure=False):
    """Build the FMU at ``dest`` (replaced atomically) and return its path; ``pure``: leave the runtime
    uncompiled, under a package name of its own (so it runs beside the compiled FMU in one process)."""
    from pythonfmu import FmuBuilder

    return build_staged(dest, source_tag() + ("p" if pure else ""), SLAVE, FmuBuilder, complete_model_description,
                        compiled=not pure, canGetAndSetFMUstate=True, canSerializeFMUstate=True)


def build_staged(dest, tag, slave, builder, complete, fmi_version=2, loader=FMI2_LOADER, compiled=True,
                 **capabilities):
    """Build the FMU at ``dest`` (replaced atomically) from the slave source ``slave``, staged with the runtime
    under ``tag`` (:func:`~stickslip.fmu_staging.stage_runtime`) and built by the library's ``builder`` (PythonFMU's
    or pythonfmu3's ``FmuBuilder``, with ``capabilities``); its model description passes through
    ``complete(xml, units, bounds)``, its linux64 binary becomes the FMI ``fmi_version`` loader. Returns ``dest``."""
    dest = Path(dest).resolve()
    dest.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="sbf_build_") as tmp:
        staged = stage_runtime(Path(tmp), tag, RUNTIME, slave, INTERFACE, MODEL_NAME, compiled=compiled, loader=loader)
        try:
            with preserved_sys_path():  # the builder, and the import below, put the staging folder on sys.path
                built = builder.build_FMU(staged.script, dest=Path(tmp) / "out", project_files=staged.project_files(),
                                          **capabilities)
                sys.path.insert(0, tmp)
                instance = getattr(importlib.import_module(staged.module), MODEL_NAME)(instance_name="build")
        finally:  # ... and the modules imported
            forget_modules(tag, staged.module)
        write_completed(
            built, dest, lambda xml: complete(xml, instance.variable_units, instance.variable_bounds),
            finish=lambda partial: _finish_staged(partial, staged, fmi_version),
        )
    return dest


def _finish_staged(partial, staged, fmi_version):
    """Add the staged files the library's builder leaves out, then make the loader the linux64 binary."""
    with zipfile.ZipFile(partial, "a", zipfile.ZIP_DEFLATED) as fmu:
        staged.add_to(fmu)
    fmu_loader.install(partial, MODEL_NAME, slave_survives_release=True, fmi_version=fmi_version)


def write_completed(built, dest, complete, finish=None):
    """Copy the FMU ``built`` to ``dest`` (replaced atomically), its model description passed through ``complete``
    and the copy then through ``finish(path)`` if given."""
    partial = dest.with_name(f".{dest.name}.{os.getpid()}.part")
    with zipfile.ZipFile(built) as source, zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as target:
        for item in source.infolist():
            data = source.read(item)
            target.writestr(item.filename, complete(data) if item.filename == "modelDescription.xml" else data)
    if finish is not None:
        finish(partial)
    os.replace(partial, dest)


def annotate_variables(variables, units, bounds, element_of):
    """Set declaredType, unit, min and max on ``element_of(variable)`` for each model variable; return the units
    used, ``{unit: (FMI unit name, declared type, exponents)}``."""
    used = {}
    for variable in variables:
        name = variable.get("name")
        element = element_of(variable)
        unit = units[name]
        if unit not in DIMENSIONLESS:
            if unit not in UNITS:
                raise BuildError(f"variable {name} has the unit {unit!r}, which the builder does not know")
            fmi_unit, declared, _ = used[unit] = UNITS[unit]
            element.set("declaredType", declared)
            element.set("unit", fmi_unit)
        for key, bound in zip(("min", "max"), bounds[name]):
            if bound is not None:
                element.set(key, repr(bound) if element.tag in ("Real", "Float64") else str(int(bound)))
    return used


def insert_definitions(root, used, add_type, after):
    """Insert UnitDefinitions and TypeDefinitions of the ``used`` units after the element ``after`` of ``root``,
    each type added by ``add_type(type_definitions, declared type, FMI unit)``; and the DefaultExperiment."""
    unit_definitions = ET.Element("UnitDefinitions")
    type_definitions = ET.Element("TypeDefinitions")
    for fmi_unit, declared, exponents in sorted(used.values(), key=lambda entry: entry[1]):
        unit = ET.SubElement(unit_definitions, "Unit", name=fmi_unit)
        ET.SubElement(unit, "BaseUnit", {k: str(e) for k, e in exponents.items()})
        add_type(type_definitions, declared, fmi_unit)
    position = list(root).index(after) + 1
    root.insert(position, unit_definitions)
    root.insert(position + 1, type_definitions)
    for old in root.findall("DefaultExperiment"):
        root.remove(old)
    root.insert(list(root).index(root.find("ModelVariables")), ET.Element("DefaultExperiment", DEFAULT_EXPERIMENT))


def _add_simple_type(type_definitions, declared, fmi_unit):
    simple = ET.SubElement(type_definitions, "SimpleType", name=declared)
    ET.SubElement(simple, "Real", quantity=declared, unit=fmi_unit)


def complete_model_description(xml, units, bounds):
    """Add units, declared types, bounds, InitialUnknowns and a DefaultExperiment to PythonFMU's XML."""
    root = ET.fromstring(xml)
    variables = root.find("ModelVariables")
    used = annotate_variables(variables, units, bounds, lambda variable: variable[0])
    insert_definitions(root, used, _add_simple_type, root.find("CoSimulation"))

    structure = root.find("ModelStructure")
    structure.clear()
    outputs = [str(i) for i, v in enumerate(variables, start=1) if v.get("causality") == "output"]
    for section in ("Outputs", "InitialUnknowns"):  # dependencies omitted: may depend on every input
        node = ET.SubElement(structure, section)
        for index in outputs:
            ET.SubElement(node, "Unknown", index=index)

    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)
