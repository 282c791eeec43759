"""Build the SpringBlockFriction FMU (FMI 2.0 co-simulation) with PythonFMU.

The runtime ``stickslip/core`` and the slave are bundled into the FMU's resources
as the package ``sbf_runtime_<tag>``, loaded through the module
``springblockfriction_<tag>`` (layout: :mod:`stickslip.fmu_staging`), where
``<tag>`` is 10 hex digits of a sha256 over the runtime, the slave and the builder. A host that imported its own
``stickslip``, or another build of this FMU, therefore never hands the FMU a
different copy of the runtime. PythonFMU's model description is then completed:
units, declared types, bounds, InitialUnknowns, a default experiment and the
FMU-state capabilities.
"""

import hashlib
import os
import sys
import tempfile
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

from .fmi_host import preserved_sys_path
from .fmu_staging import stage_runtime

REPO = Path(__file__).resolve().parents[2]
RUNTIME = Path(__file__).resolve().parent / "core"
SLAVE = REPO / "fmu_src" / "SpringBlockFriction.py"
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
}
DIMENSIONLESS = ("", "1")


class BuildError(RuntimeError):
    """The FMU cannot be built from the current sources."""


def _sources():
    here = Path(__file__).resolve()
    builders = [here, here.with_name("fmu_staging.py"), here.with_name("compile_runtime.py")]
    return sorted(p for p in RUNTIME.rglob("*.py") if "__pycache__" not in p.parts) + [SLAVE] + builders


def source_tag():
    """10 hex digits identifying the runtime, slave and builder sources."""
    digest = hashlib.sha256()
    for path in _sources():
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()[:10]


def built_tag(fmu_path):
    """The source tag an existing FMU was built from (None if it has none)."""
    with zipfile.ZipFile(fmu_path) as fmu:
        module = fmu.read("resources/slavemodule.txt").decode().strip()
    prefix = "springblockfriction_"
    return module[len(prefix):] if module.startswith(prefix) else None


def build(dest=REPO / "dist" / f"{MODEL_NAME}.fmu", pure=False):
    """Build the FMU at ``dest`` (replaced atomically) and return its path; ``pure``: leave the runtime
    uncompiled, under a package name of its own (so it runs beside the compiled FMU in one process)."""
    from pythonfmu import FmuBuilder

    dest = Path(dest).resolve()
    dest.parent.mkdir(parents=True, exist_ok=True)
    tag = source_tag() + ("p" if pure else "")

    with tempfile.TemporaryDirectory(prefix="sbf_build_") as tmp:
        staged = stage_runtime(Path(tmp), tag, RUNTIME, SLAVE, MODEL_NAME, compiled=not pure)
        try:
            with preserved_sys_path():  # PythonFMU leaves the temporary folder on sys.path
                built = FmuBuilder.build_FMU(
                    staged.script, dest=Path(tmp) / "out", project_files=[staged.package_dir],
                    canGetAndSetFMUstate=True, canSerializeFMUstate=True,
                )
            slave = getattr(sys.modules[staged.module], MODEL_NAME)(instance_name="build")
        finally:  # ... and the modules imported
            for name in [m for m in sys.modules if m == staged.module or m.split(".")[0] == staged.package_dir.name]:
                del sys.modules[name]
        partial = dest.with_name(f".{dest.name}.{os.getpid()}.part")
        with zipfile.ZipFile(built) as source, zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as target:
            for item in source.infolist():
                data = source.read(item)
                if item.filename == "modelDescription.xml":
                    data = complete_model_description(data, slave.units, slave.bounds)
                target.writestr(item.filename, data)
            staged.add_to(target)
        os.replace(partial, dest)
    return dest


def complete_model_description(xml, units, bounds):
    """Add units, declared types, bounds, InitialUnknowns and a DefaultExperiment to PythonFMU's XML."""
    root = ET.fromstring(xml)
    variables = root.find("ModelVariables")
    used = {}
    for variable in variables:
        name = variable.get("name")
        value = variable[0]
        unit = units[name]
        if unit not in DIMENSIONLESS:
            if unit not in UNITS:
                raise BuildError(f"variable {name} has the unit {unit!r}, which the builder does not know")
            fmi_unit, declared, _ = used[unit] = UNITS[unit]
            value.set("declaredType", declared)
            value.set("unit", fmi_unit)
        for key, bound in zip(("min", "max"), bounds[name]):
            if bound is not None:
                value.set(key, repr(bound) if value.tag == "Real" else str(int(bound)))

    unit_definitions = ET.Element("UnitDefinitions")
    type_definitions = ET.Element("TypeDefinitions")
    for fmi_unit, declared, exponents in sorted(used.values(), key=lambda entry: entry[1]):
        unit = ET.SubElement(unit_definitions, "Unit", name=fmi_unit)
        ET.SubElement(unit, "BaseUnit", {k: str(e) for k, e in exponents.items()})
        simple = ET.SubElement(type_definitions, "SimpleType", name=declared)
        ET.SubElement(simple, "Real", quantity=declared, unit=fmi_unit)
    position = list(root).index(root.find("CoSimulation")) + 1
    root.insert(position, unit_definitions)
    root.insert(position + 1, type_definitions)

    for old in root.findall("DefaultExperiment"):
        root.remove(old)
    root.insert(list(root).index(variables), ET.Element("DefaultExperiment", DEFAULT_EXPERIMENT))

    structure = root.find("ModelStructure")
    structure.clear()
    outputs = [str(i) for i, v in enumerate(variables, start=1) if v.get("causality") == "output"]
    for section in ("Outputs", "InitialUnknowns"):  # dependencies omitted: may depend on every input
        node = ET.SubElement(structure, section)
        for index in outputs:
            ET.SubElement(node, "Unknown", index=index)

    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)
