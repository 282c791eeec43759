"""Build the SpringBlockFriction FMU for FMI 3.0 (co-simulation and model exchange) with pythonfmu3.

The same runtime (compiled where this machine can), variable table, layout and tagging as the FMI 2 FMU
(:mod:`stickslip.fmu_build`, :mod:`stickslip.fmu_staging`); the slave is ``fmu_src/SpringBlockFriction_fmi3.py``,
loaded by pythonfmu3 through the module ``springblockfriction3_<tag>``. pythonfmu3's
model description is completed with units, declared types, bounds and a default experiment, and states
the capabilities: FMU state get/set/serialize, variable communication step, no completed-step calls.
Its x86_64-linux binary is the loader (:mod:`stickslip.fmu_loader`, FMI 3 front) in front of pythonfmu3's,
so that it loads in hosts without Python too.
"""

from pathlib import Path
from xml.etree import ElementTree as ET

from . import fmu_loader
from .fmu_build import MODEL_NAME, REPO, annotate_variables, build_staged, built_tag, insert_definitions, source_tag
from .fmu_staging import FMI3_LOADER, STAGING_SOURCES

SLAVE3 = REPO / "fmu_src" / "SpringBlockFriction_fmi3.py"
MODULE_PREFIX = FMI3_LOADER.prefix
CAPABILITIES = {"canGetAndSetFMUState": True, "canSerializeFMUState": True,
                "canHandleVariableCommunicationStepSize": True, "needsCompletedIntegratorStep": False}


def default_fmu3_path():
    """``<repo>/dist/SpringBlockFriction-fmi3.fmu``."""
    return REPO / "dist" / f"{MODEL_NAME}-fmi3.fmu"


def source_tag3():
    """10 hex digits identifying the sources of the FMI 3 FMU."""
    return source_tag(SLAVE3, builders=[Path(__file__).resolve(), *fmu_loader.SOURCES, *STAGING_SOURCES])


def is_current(fmu_path):
    """True if the FMI 3 FMU at ``fmu_path`` exists and was built from the current sources."""
    fmu_path = Path(fmu_path)
    return fmu_path.is_file() and built_tag(fmu_path, MODULE_PREFIX) == source_tag3()


def build3(dest=None):
    """Build the FMI 3 FMU at ``dest`` (default :func:`default_fmu3_path`, replaced atomically); return its path."""
    from pythonfmu3 import FmuBuilder

    return build_staged(dest or default_fmu3_path(), source_tag3(), SLAVE3, FmuBuilder, complete_model_description3,
                        fmi_version=3, loader=FMI3_LOADER, **CAPABILITIES)


def complete_model_description3(xml, units, bounds):
    """Add units, declared types, bounds and a DefaultExperiment to pythonfmu3's XML."""
    root = ET.fromstring(xml)
    used = annotate_variables(root.find("ModelVariables"), units, bounds, lambda variable: variable)
    for old in root.findall("UnitDefinitions") + root.findall("TypeDefinitions"):
        root.remove(old)
    insert_definitions(root, used, _add_float64_type, root.find("CoSimulation"))
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)


def _add_float64_type(type_definitions, declared, fmi_unit):
    ET.SubElement(type_definitions, "Float64Type", name=declared, quantity=declared, unit=fmi_unit)
