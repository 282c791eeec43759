"""Build the SpringBlockFriction FMUs: FMI 2.0 co-simulation (PythonFMU) and FMI 3.0 co-simulation and model
exchange (pythonfmu3), with one function, :func:`build`.

The runtime ``stickslip/core`` is bundled into the FMU's resources as the package ``sbf_runtime_<tag>``,
together with the slave (``fmu_slave``) and the variable table the slaves share (``block_interface``), loaded
through the module ``springblockfriction_<tag>`` (FMI 3: ``springblockfriction3_<tag>``; layout, byte-compiled
and mypyc-compiled modules: :mod:`stickslip.fmu.staging`); ``<tag>`` is :func:`~stickslip.fmu.sources.source_tag`.
A host that imported its own ``stickslip``, or another build of this FMU, therefore never hands the FMU a
different copy of the runtime. The library's model description is then completed
(:mod:`stickslip.fmu.model_description`) and its Linux binary becomes the loader of
:mod:`stickslip.fmu.loader`, so that the FMU also runs in hosts that are not Python processes.
"""

import importlib
import os
import sys
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

from . import loader, model_description
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
                               compiled=not pure, loader=LOADERS[fmi_version])
        try:
            with preserved_sys_path():  # the builder, and the import below, put the staging folder on sys.path
                built = builder.build_FMU(staged.script, dest=Path(tmp) / "out", project_files=staged.project_files(),
                                          **library.capabilities)
                sys.path.insert(0, tmp)
                instance = getattr(importlib.import_module(staged.module), MODEL_NAME)(instance_name="build")
        finally:  # ... and the modules imported
            _forget_modules(tag, staged.module)
        _write_completed(
            built, dest,
            lambda xml: model_description.complete(xml, instance.variable_units, instance.variable_bounds, fmi_version),
            finish=lambda partial: _finish_staged(partial, staged, fmi_version),
        )
    return dest


def _forget_modules(tag, module):
    """Drop the bundled modules that building imported into this process."""
    for name in [m for m in sys.modules if m == module or m.split(".")[0].endswith(f"_{tag}")]:
        del sys.modules[name]


def _finish_staged(partial, staged, fmi_version):
    """Add the staged files the library's builder leaves out, then make the loader the Linux binary."""
    with zipfile.ZipFile(partial, "a", zipfile.ZIP_DEFLATED) as fmu:
        staged.add_to(fmu)
    loader.install(partial, MODEL_NAME, slave_survives_release=True, fmi_version=fmi_version)


def _write_completed(built, dest, complete, finish=None):
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
