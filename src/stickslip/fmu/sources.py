"""Where the FMUs' sources are, and the tag that names one build of them.

The slaves come from the package ``stickslip.fmu_src`` (the project's top-level ``fmu_src/``, mapped into the
package), the runtime from ``stickslip/core``, the loader from :mod:`stickslip.fmu.loader`. The tag (10 hex
digits of a sha256 over all of them and the builder modules) names the slave's package inside the FMU, so
that two builds never share a slave in one process, and tells whether an FMU is current; the runtime tag (over the
runtime and what lays it out) names the runtime's package, the same in the FMI 2 and FMI 3 FMUs.
"""

import zipfile
from pathlib import Path

from .. import fmu_src
from . import loader
from .compile_runtime import files_tag, runtime_tag  # the tags are made there: setup.py uses them too

MODEL_NAME = "SpringBlockFriction"
SLAVE_FOLDER = Path(fmu_src.__file__).resolve().parent
RUNTIME = Path(__file__).resolve().parents[1] / "core"
INTERFACE = SLAVE_FOLDER / "block_interface.py"
#: how a slave offers itself to the C loader (the block's FMUs and the coupling FMU bundle it)
LOADER_BINDING = SLAVE_FOLDER / "loader_binding.py"
#: FMI version: the slave's source
SLAVES = {2: SLAVE_FOLDER / "SpringBlockFriction.py", 3: SLAVE_FOLDER / "SpringBlockFriction_fmi3.py"}
#: FMI version: the prefix of the module the FMI library loads (the tag follows)
MODULE_PREFIXES = {2: "springblockfriction_", 3: "springblockfriction3_"}
#: the builder modules whose source decides an FMU's content
BUILDERS = (*(Path(__file__).resolve().with_name(name) for name in
              ("build.py", "archive.py", "model_description.py", "staging.py", "compile_runtime.py", "sources.py",
               "trim.py", "documentation.py", "floors.py", "windows_needs.py", "windows_python.py")),
            *sorted(Path(__file__).resolve().with_name("bundle").glob("*.py")), *loader.SOURCES)


def source_tag(fmi_version=2):
    """10 hex digits identifying the runtime, the slave of ``fmi_version``, the shared table and the builders."""
    return files_tag([*_runtime_sources(), SLAVES[fmi_version], INTERFACE, LOADER_BINDING, *BUILDERS])


def sources_tag():
    """10 hex digits identifying the sources of every FMU this package builds (both slaves): the name of the user's
    cache folder of FMUs built from them (:func:`stickslip.fmu.build.default_fmu_path`)."""
    return files_tag([*_runtime_sources(), *SLAVES.values(), INTERFACE, LOADER_BINDING, *BUILDERS])


def _runtime_sources():
    return sorted(p for p in RUNTIME.rglob("*.py") if "__pycache__" not in p.parts)


def built_tag(fmu_path, fmi_version=2):
    """The source tag the FMU at ``fmu_path`` was built from (None if it has none)."""
    prefix = MODULE_PREFIXES[fmi_version]
    with zipfile.ZipFile(fmu_path) as fmu:
        module = fmu.read("resources/slavemodule.txt").decode().strip()
    return module[len(prefix):] if module.startswith(prefix) else None


def is_current(fmu_path, fmi_version=2):
    """True if the FMU of ``fmi_version`` at ``fmu_path`` exists and was built from the current sources."""
    fmu_path = Path(fmu_path)
    return fmu_path.is_file() and built_tag(fmu_path, fmi_version) == source_tag(fmi_version)
