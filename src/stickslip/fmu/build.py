"""Build the SpringBlockFriction FMUs: FMI 2.0 co-simulation (PythonFMU) and FMI 3.0 co-simulation and model
exchange (pythonfmu3), with one function, :func:`build`.

The runtime ``stickslip/core`` is bundled into the FMU's resources as the package ``sbf_runtime_<tag>``,
together with the slave (``fmu_slave``) and the variable table the slaves share (``block_interface``), loaded
through the module ``springblockfriction_<tag>`` (FMI 3: ``springblockfriction3_<tag>``; layout, byte-compiled
and mypyc-compiled modules: :mod:`stickslip.fmu.staging`); ``<tag>`` is :func:`~stickslip.fmu.sources.source_tag`.
A host that imported its own ``stickslip``, or another build of this FMU, therefore never hands the FMU a
different copy of the runtime. The library's model description is then completed
(:mod:`stickslip.fmu.model_description`), what no host needs left out (:mod:`stickslip.fmu.trim`), and its
Linux binary becomes the loader of
:mod:`stickslip.fmu.loader`, so that the FMU also runs in hosts that are not Python processes. Building twice
from the same sources with the same Python and compiler gives the same bytes (:mod:`stickslip.fmu.archive`).
"""

import importlib
import os
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from . import archive, loader, model_description, trim
from .sources import MODEL_NAME, RUNTIME, INTERFACE, SLAVES, is_current, source_tag
from .python_path import preserved_sys_path
from .staging import LOADERS, stage_runtime

#: the FMI versions this package builds
FMI_VERSIONS = (2, 3)
#: FMI version: the FMU's file name
FILE_NAMES = {2: f"{MODEL_NAME}.fmu", 3: f"{MODEL_NAME}-fmi3.fmu"}


@dataclass(frozen=True)
class Library:
    """The FMI library that builds one FMI version: its module (holding ``FmuBuilder``) and the capabilities the
    builder writes into the model description."""

    module: str
    capabilities: dict


LIBRARIES = {
    2: Library("pythonfmu", {"canGetAndSetFMUstate": True, "canSerializeFMUstate": True}),
    3: Library("pythonfmu3", {"canGetAndSetFMUState": True, "canSerializeFMUState": True,
                              "canHandleVariableCommunicationStepSize": True, "needsCompletedIntegratorStep": False}),
}


def default_fmu_path(fmi_version=2):
    """Where :func:`ensure_fmu` keeps the FMU of ``fmi_version``: ``dist/<file name>`` in the current folder
    (``$STICKSLIP_DIST`` instead of ``dist`` if set)."""
    return Path(os.environ.get("STICKSLIP_DIST") or "dist").resolve() / FILE_NAMES[fmi_version]


def ensure_fmu(fmu_path=None, fmi_version=2):
    """Build the FMU of ``fmi_version`` at ``fmu_path`` (default :func:`default_fmu_path`) unless it is current;
    return its path."""
    fmu_path = Path(fmu_path or default_fmu_path(fmi_version))
    if not is_current(fmu_path, fmi_version):
        build(fmu_path, fmi_version)
    return fmu_path


def build(dest=None, fmi_version=2, pure=False):
    """Build the FMU of ``fmi_version`` at ``dest`` (default :func:`default_fmu_path`; replaced atomically) and
    return its path. ``pure``: leave the runtime uncompiled, under a package name of its own (so it runs beside
    the compiled FMU in one process)."""
    dest = Path(dest or default_fmu_path(fmi_version)).resolve()
    dest.parent.mkdir(parents=True, exist_ok=True)
    library = LIBRARIES[fmi_version]
    builder = importlib.import_module(library.module).FmuBuilder
    tag = source_tag(fmi_version) + ("p" if pure else "")
    with tempfile.TemporaryDirectory(prefix="sbf_build_") as tmp:
        staged = stage_runtime(Path(tmp), tag, RUNTIME, SLAVES[fmi_version], INTERFACE, MODEL_NAME,
                               compiled=not pure, loader=LOADERS[fmi_version], library=library.module)
        try:
            with preserved_sys_path():  # the builder, and the import below, put the staging folder on sys.path
                built = builder.build_FMU(staged.script, dest=Path(tmp) / "out", project_files=staged.project_files(),
                                          **library.capabilities)
                sys.path.insert(0, tmp)
                instance = getattr(importlib.import_module(staged.module), MODEL_NAME)(instance_name="build")
        finally:  # ... and the modules imported
            forget_modules(tag, staged.module)
        entries = archive.read_entries(built)
        entries["modelDescription.xml"] = model_description.complete(
            entries["modelDescription.xml"], instance.variable_units, instance.variable_bounds, fmi_version,
            *archive.identity(MODEL_NAME, fmi_version, tag), dependencies=instance.output_dependencies)
        staged.add_to(entries)
        trim.trim(entries, fmi_version, staged.package_dir.name)
        _write_with_loader(dest, entries, fmi_version)
    return dest


def forget_modules(tag, module):
    """Drop the bundled modules that building imported into this process: ``module`` (the one the FMI library loads)
    and the packages whose names end in ``_<tag>``."""
    for name in [m for m in sys.modules if m == module or m.split(".")[0].endswith(f"_{tag}")]:
        del sys.modules[name]


def _write_with_loader(dest, entries, fmi_version):
    """Write the FMU's ``entries`` (``{name: bytes}``) to ``dest`` (replaced atomically, reproducibly:
    :mod:`stickslip.fmu.archive`), with the loader as its Linux binary."""
    partial = dest.with_name(f".{dest.name}.{os.getpid()}.part")
    archive.write_entries(partial, entries)
    loader.install(partial, MODEL_NAME, slave_survives_release=True, fmi_version=fmi_version)
    os.replace(partial, dest)
