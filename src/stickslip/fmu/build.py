"""Build the SpringBlockFriction FMUs: FMI 2.0 co-simulation (PythonFMU) and FMI 3.0 co-simulation and model
exchange (pythonfmu3), with one function, :func:`build`.

The runtime ``stickslip/core`` is bundled into the FMU's resources as the package ``sbf_runtime_<runtime tag>``,
the slave (``fmu_slave``) and the variable table the slaves share (``block_interface``) as ``sbf_slave_<tag>``,
loaded through the module ``springblockfriction_<tag>`` (FMI 3: ``springblockfriction3_<tag>``; layout,
byte-compiled and mypyc-compiled modules: :mod:`stickslip.fmu.staging`); ``<tag>`` is
:func:`~stickslip.fmu.sources.source_tag`, ``<runtime tag>`` :func:`~stickslip.fmu.sources.runtime_tag`. A host
that imported its own ``stickslip``, or another build of this FMU, therefore never hands the FMU a different copy
of the runtime; the FMI 2 and FMI 3 FMUs of one build carry the same runtime package, compiled once. The library's model description is then completed
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

from . import archive, documentation, loader, model_description, trim
from .bundle import floors, platform_needs, windows_python
from .compile_runtime import USER_CACHE
from .sources import (MODEL_NAME, RUNTIME, INTERFACE, SLAVES, is_current, runtime_tag, source_tag,  # noqa: I001
                      sources_tag)
from .python_path import preserved_sys_path
from .staging import LOADERS, stage_runtime

#: the FMI versions this package builds
FMI_VERSIONS = (2, 3)
#: the FMI versions whose FMU declares the law selectors Enumerations (the others: Integers holding the same codes).
#: FMI 2's stays Integer: libcosim (0.0.6, and ecos, built on it) lists no Enumeration variable of an FMI 2 FMU, so
#: a law could no longer be chosen there.
ENUMERATION_VERSIONS = (3,)
#: what the FMU's documentation says the model is
SUMMARY = (
    "A block of mass M on a surface moving at v_drive, tied to a wall by a spring of stiffness kappa, with dry "
    "friction: while it slips, the kinetic law F_K of the sliding speed acts against the sliding; it sticks when "
    "the sliding speed reaches zero and the static friction F_S can hold the spring and external forces, and "
    "breaks away when they exceed F_S, which may grow with the time stuck (aging). The FMU locates every stick "
    "and slip event inside a step. Inputs: the surface velocity v_drive and an external force F_ext on the block; "
    "outputs: its position, velocity, forces, mode and event counts.")
#: FMI version: the FMU's file name
FILE_NAMES = {2: f"{MODEL_NAME}.fmu", 3: f"{MODEL_NAME}-fmi3.fmu"}
#: the checkout this module would lie in (``src/stickslip/fmu/``), if it is one: then its ``dist/`` holds the FMUs
CHECKOUT = Path(__file__).resolve().parents[3]


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
    """Where :func:`ensure_fmu` keeps the FMU of ``fmi_version`` (:data:`FILE_NAMES`) when no command names one: in
    ``$STICKSLIP_DIST`` if set, else in a checkout its ``dist/``, else the user's cache
    (``$XDG_CACHE_HOME/stickslip/fmus/<sources tag>/``, default ``~/.cache/...``: one folder per state of the
    sources, :func:`~stickslip.fmu.sources.sources_tag`)."""
    named = os.environ.get("STICKSLIP_DIST")
    if named:
        folder = Path(named).resolve()
    elif in_checkout():
        folder = CHECKOUT / "dist"
    else:
        folder = USER_CACHE / "fmus" / sources_tag()
    return folder / FILE_NAMES[fmi_version]


def in_checkout():
    """True if this package runs from a checkout of its sources (:data:`CHECKOUT`), not from an installation."""
    return (CHECKOUT / "pyproject.toml").is_file() and (CHECKOUT / "build_fmu.py").is_file()


def ensure_fmu(fmu_path=None, fmi_version=2):
    """Build the FMU of ``fmi_version`` at ``fmu_path`` (default :func:`default_fmu_path`) unless it is current,
    saying where on stderr; return its path."""
    fmu_path = Path(fmu_path or default_fmu_path(fmi_version))
    if not is_current(fmu_path, fmi_version):
        announce_build(fmu_path)
        build(fmu_path, fmi_version)
    return fmu_path


def announce_build(path):
    """Say on stderr that the FMU at ``path`` is being built (it was missing or built from other sources)."""
    print(f"stickslip: building {Path(path).resolve()} (missing or out of date) ...", file=sys.stderr, flush=True)


def build(dest=None, fmi_version=2, pure=False, carry_python=True):
    """Build the FMU of ``fmi_version`` at ``dest`` (default :func:`default_fmu_path`; replaced atomically) and
    return its path. ``pure``: leave the runtime uncompiled, under a package name of its own (so it runs beside
    the compiled FMU in one process). ``carry_python``: False leaves out the CPythons the FMU carries for hosts
    without one (:mod:`stickslip.fmu.bundle`), to measure what they cost."""
    dest = Path(dest or default_fmu_path(fmi_version)).resolve()
    dest.parent.mkdir(parents=True, exist_ok=True)
    library = LIBRARIES[fmi_version]
    builder = importlib.import_module(library.module).FmuBuilder
    tags = (source_tag(fmi_version) + ("p" if pure else ""), runtime_tag() + ("p" if pure else ""))
    tag = tags[0]
    with tempfile.TemporaryDirectory(prefix="sbf_build_") as tmp:
        staged = stage_runtime(Path(tmp), tags, RUNTIME, SLAVES[fmi_version], INTERFACE, MODEL_NAME,
                               compiled=not pure, loader=LOADERS[fmi_version], library=library.module)
        try:
            with preserved_sys_path():  # the builder, and the import below, put the staging folder on sys.path
                built = builder.build_FMU(staged.script, dest=Path(tmp) / "out", project_files=staged.project_files(),
                                          **library.capabilities)
                sys.path.insert(0, tmp)
                instance = getattr(importlib.import_module(staged.module), MODEL_NAME)(instance_name="build")
        finally:  # ... and the modules imported
            forget_modules(tags, staged.module)
        entries = archive.read_entries(built)
        entries["modelDescription.xml"] = model_description.complete(
            entries["modelDescription.xml"], instance.variable_units, instance.variable_bounds, fmi_version,
            *archive.identity(MODEL_NAME, fmi_version, tag), dependencies=instance.output_dependencies,
            enumerations=instance.variable_enumerations if fmi_version in ENUMERATION_VERSIONS else None)
        staged.add_to(entries)
        trim.trim(entries, fmi_version, staged.slave_dir.name, staged.package_dir.name)
        compiled = any(name.endswith(".so") for name in entries if name.startswith("resources/"))
        entries.update(documentation.entries(entries["modelDescription.xml"], SUMMARY,
                                             ("stickslip", library.module, *(("mypy",) if compiled else ())),
                                             instance.variable_enumerations))
        write_with_loader(dest, entries, MODEL_NAME, fmi_version, carry_python)
    return dest


def forget_modules(tags, module):
    """Drop the bundled modules that building imported into this process: ``module`` (the one the FMI library loads)
    and the packages whose names end with ``_<tag>`` for one of ``tags``."""
    for name in [m for m in sys.modules if m == module or m.split(".")[0].endswith(tuple(f"_{t}" for t in tags))]:
        del sys.modules[name]


def write_with_loader(dest, entries, model_name, fmi_version=2, carry_python=True):
    """Write the FMU ``model_name`` of ``fmi_version`` with the ``entries`` (``{name: bytes}``) to ``dest``
    (replaced atomically, reproducibly: :mod:`stickslip.fmu.archive`), with the loader as its Linux and Windows
    binary and, in its documentation, what the host machine needs of the binaries it ends up with
    (:mod:`stickslip.fmu.bundle.floors`) and the licence of the CPython its Windows binaries carry, if they do.
    """
    partial = dest.with_name(f".{dest.name}.{os.getpid()}.part")
    archive.write_entries(partial, entries)
    loader.install(partial, model_name, slave_survives_release=True, fmi_version=fmi_version,
                   carry_python=carry_python)
    built = archive.read_entries(partial)
    if windows_python.LICENSE_ENTRY in built:  # the Windows binaries carry CPython
        built[documentation.INDEX] = documentation.with_license(built[documentation.INDEX], "python")
    built[floors.DEPENDENCIES_FILE] = platform_needs.dependencies_text(model_name, built).encode()
    archive.write_entries(partial, built)
    os.replace(partial, dest)
