"""Build ``ChainCoupling.fmu``: the coupling springs acting on one block of a chain (``fmu_src/ChainCoupling.py``),
FMI 2 co-simulation, so that an engine wires a chain from FMUs alone (the SSP of :mod:`stickslip.systems.ssp`).

A pure-Python PythonFMU slave, laid out, trimmed and fronted as the block's (:mod:`stickslip.fmu.staging`,
:mod:`stickslip.fmu.trim`): its model description gets units, the stiffnesses' lower bound 0 and a GUID that
follows from the sources (:func:`coupling_tag`), and its Linux binary becomes the loader of
:mod:`stickslip.fmu.loader`, so that it also runs in hosts that are not Python processes, and reports the slave's
refusals as fmi2Error with the instance going on (the slave balances PythonFMU's release of it).
"""

import shutil
import tempfile
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

from . import archive, documentation, model_description, trim
from .build import announce_build, default_fmu_path, forget_modules, write_with_loader
from .python_path import preserved_sys_path
from .sources import BUILDERS, LOADER_BINDING, SLAVE_FOLDER, files_tag
from .staging import FMI2_TEMPLATE, PACKAGE_ARCHIVE, rewrite_once

COUPLING_NAME = "ChainCoupling"
COUPLING_FILE = f"{COUPLING_NAME}.fmu"
COUPLING_SLAVE = SLAVE_FOLDER / f"{COUPLING_NAME}.py"
#: variable: unit as model_description.UNITS names it
UNITS = {"x_left": "m", "x": "m", "x_right": "m", "kc_left": "N/m", "kc_right": "N/m", "F": "N"}
BOUNDS = {name: ((0.0, None) if name.startswith("kc_") else (None, None)) for name in UNITS}
#: what the FMU's documentation says the model is
SUMMARY = ("The coupling springs of one block in a chain of blocks: the force F = kc_left (x_left - x) + kc_right "
           "(x_right - x) that the springs to its neighbours (positions x_left and x_right) exert on the block at x. "
           "An engine wires it between SpringBlockFriction FMUs, F to the block's F_ext input.")


def coupling_tag():
    """10 hex digits over the slave, the loader binding, this builder and the other builder modules (staging, trim,
    model description, documentation, the loader's sources...): they decide the FMU's content."""
    return files_tag((COUPLING_SLAVE, LOADER_BINDING, Path(__file__), *BUILDERS))


def _staged_slave(folder, tag):
    """Lay out the slave in ``folder`` as the block's is (:mod:`stickslip.fmu.staging`): the package
    ``sbf_coupling_<tag>`` (a name only this build uses) with the slave as ``fmu_slave`` and the loader binding
    beside it, and the module PythonFMU loads, ``chaincoupling_<tag>.py``, which imports the slave's class (once per
    process) from the package. ``(that module's path, the package's folder)``."""
    package = folder / f"sbf_coupling_{tag}"
    package.mkdir()
    (package / "__init__.py").write_text('"""The ChainCoupling FMU\'s slave and its loader binding."""\n')
    (package / "fmu_slave.py").write_text(rewrite_once(COUPLING_SLAVE, r"\bfrom loader_binding import\b",
                                                       f"from {package.name}.loader_binding import",
                                                       "the loader binding as 'from loader_binding import ...'"))
    shutil.copyfile(LOADER_BINDING, package / LOADER_BINDING.name)
    script = folder / f"chaincoupling_{tag}.py"
    script.write_text(FMI2_TEMPLATE.format(package=package.name, model_name=COUPLING_NAME,
                                           archive=PACKAGE_ARCHIVE.format(package="pythonfmu"),
                                           slave_archive=PACKAGE_ARCHIVE.format(package=package.name)))
    return script, package


def default_coupling_path():
    """``ChainCoupling.fmu`` beside the block's default FMI 2 FMU (:func:`~stickslip.fmu.build.default_fmu_path`)."""
    return default_fmu_path(2).with_name(COUPLING_FILE)


def coupling_is_current(path):
    """True if the coupling FMU at ``path`` exists and was built from the current sources."""
    path = Path(path)
    if not path.is_file():
        return False
    with zipfile.ZipFile(path) as fmu:
        guid = ET.fromstring(fmu.read("modelDescription.xml")).get("guid")
    return guid == archive.identity(COUPLING_NAME, 2, coupling_tag())[0]


def ensure_coupling_fmu(path=None):
    """Build the coupling FMU at ``path`` (default :func:`default_coupling_path`) unless it is current; its path."""
    path = Path(path or default_coupling_path())
    if not coupling_is_current(path):
        announce_build(path)
        build_coupling(path)
    return path


def build_coupling(dest=None):
    """Build the coupling FMU at ``dest`` (default :func:`default_coupling_path`; replaced atomically); its path."""
    from pythonfmu import FmuBuilder

    dest = Path(dest or default_coupling_path()).resolve()
    dest.parent.mkdir(parents=True, exist_ok=True)
    tag = coupling_tag()
    with tempfile.TemporaryDirectory(prefix="sbf_coupling_") as tmp:
        script, package = _staged_slave(Path(tmp), tag)
        try:
            with preserved_sys_path():  # PythonFMU leaves the source folder on sys.path
                built = FmuBuilder.build_FMU(script, dest=Path(tmp) / "out", project_files=[package],
                                             canGetAndSetFMUstate=True, canSerializeFMUstate=True)
        finally:  # the builder imported the staged modules
            forget_modules((tag,), script.stem)
        entries = archive.read_entries(built)
        entries["modelDescription.xml"] = model_description.complete(
            entries["modelDescription.xml"], UNITS, BOUNDS, 2, *archive.identity(COUPLING_NAME, 2, tag))
        trim.trim(entries, 2, package.name)
        entries.update(documentation.entries(entries["modelDescription.xml"], SUMMARY, ("stickslip", "pythonfmu")))
        write_with_loader(dest, entries, COUPLING_NAME)
    return dest
