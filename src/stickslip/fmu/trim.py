"""Leave out of an FMU the files no host imports or loads, and pack the FMI library's package into one file
(a host extracts every file before the first step, at about 0.2 ms a file here, and imports every
module at the first instantiation).

- The FMI library's C++ sources (``sources/``, pythonfmu3's): they build its binary, which is not the FMU's
  binary (:mod:`stickslip.fmu.documentation` says where the binaries come from).
- The FMI library's modules that only build or deploy FMUs (:data:`BUILD_ONLY_MODULES`): a host imports the
  library's slave classes, never its builder, which cannot run from an FMU anyway (its binaries are not there).
  The library's ``__init__.py`` loses its import of the builder, which took argparse, logging, inspect and
  xml.dom.minidom into every host process.
- The rest of the library's package, and the slave's package, each go into one zip archive
  (``resources/<package>.zip``, :data:`~stickslip.fmu.staging.PACKAGE_ARCHIVE`), each module with its
  byte-compiled file for the building Python beside it (zipimport's layout; another Python compiles the source in
  memory), which the loader module puts on ``sys.path``: a host extracts one file for each, and creates and
  removes no folder for them (each folder a host removes cost 1-4 ms on this machine's disk).
- The runtime's modules but its ``__init__.py`` go into one zip archive in the runtime's folder
  (:data:`~stickslip.core._implementation.PACKED`, zipimport's layout, the package's ``__init__.py`` puts it on the
  package's path after the folder), where the compiled modules (mypyc) and ``compiled_sources.crc32`` stay, and
  no ``__pycache__`` folder does. The archive holds no byte code of the modules that ship compiled: the building
  Python loads the compiled modules, and another Python cannot use those ``.pyc`` files. Their sources are
  there: another Python or platform runs them, and ``compiled_sources.crc32`` is checked against them.
"""

import io
import re
import tempfile
from pathlib import Path

from .archive import write_entries
from .compile_runtime import COMPILED_MODULES, implementation
from .staging import PACKAGE_ARCHIVE, byte_compile

#: FMI version: the FMI library's package in ``resources/``
LIBRARY_PACKAGES = {2: "pythonfmu", 3: "pythonfmu3"}
#: the FMI library's modules that only its builder and command line import
BUILD_ONLY_MODULES = ("__main__", "builder", "csvbuilder", "deploy", "osutil")
#: the line of the library's ``__init__.py`` that imports its builder
BUILDER_IMPORT = re.compile(r"^from \.builder import FmuBuilder\n", re.MULTILINE)


class TrimError(RuntimeError):
    """The FMI library's ``__init__.py`` does not import its builder as this module expects."""


def trim(entries, fmi_version, slave, package=None):
    """Drop from ``entries`` (``{archive name: bytes}``, changed in place) what no host of the FMU needs, and pack
    the library's and the ``slave``'s package; ``package``: the runtime's package name (``sbf_runtime_<runtime
    tag>``; its files are the same in every FMU of that runtime, which a process that loads several of them shares),
    None where the FMU has no runtime."""
    library = LIBRARY_PACKAGES[fmi_version]
    for name in [name for name in entries if name.startswith("sources/")]:
        del entries[name]  # the library's C++ sources of its binary, which is not the FMU's (see documentation)
    _trim_library(entries, f"resources/{library}")
    _pack(entries, library)
    _pack(entries, slave)
    if package is not None:
        _pack_runtime(entries, package)


def _trim_library(entries, library):
    """Drop the FMI library's build-only modules from ``entries`` and its builder's import from its
    ``__init__.py``; ``library``: the package's folder in the archive."""
    for module in BUILD_ONLY_MODULES:
        entries.pop(f"{library}/{module}.py", None)
    init = f"{library}/__init__.py"
    code, count = BUILDER_IMPORT.subn("", entries[init].decode())
    if count != 1:
        raise TrimError(f"{init} must import its builder once as 'from .builder import FmuBuilder'")
    entries[init] = code.encode()


def _pack(entries, package):
    """Replace the entries of ``package`` in ``resources/`` by its archive :data:`PACKAGE_ARCHIVE` there: its
    sources, each with its byte code beside it (any ``__pycache__`` of the package left out)."""
    prefix = f"resources/{package}/"
    sources = {name[len(prefix):]: entries.pop(name) for name in sorted(entries) if name.startswith(prefix)}
    entries[f"resources/{PACKAGE_ARCHIVE.format(package=package)}"] = _archive(package, sources, f"{package}/")


def _pack_runtime(entries, package):
    """Move the modules of the runtime's ``package`` but its ``__init__.py`` into its archive
    :data:`~stickslip.core._implementation.PACKED` in its folder (the byte code of the compiled modules, if the
    folder has them, left out), and drop its ``__pycache__``."""
    prefix = f"resources/{package}/"
    compiled = f"{prefix}{implementation.STAMP}" in entries  # else pure: their byte code is what a host loads
    for name in [name for name in entries if name.startswith(f"{prefix}__pycache__/")]:
        del entries[name]
    sources = {name[len(prefix):]: entries.pop(name) for name in sorted(entries)
               if name.startswith(prefix) and name.endswith(".py") and name.count("/") == 2
               and name != f"{prefix}__init__.py"}
    entries[f"{prefix}{implementation.PACKED}"] = _archive(
        package, sources, "", lambda module: not (compiled and module in COMPILED_MODULES))


def _archive(package, sources, root, with_byte_code=lambda module: True):
    """The bytes of a zip archive of the modules ``sources`` ({file name in ``package``: bytes}) under ``root``, each
    for which ``with_byte_code(module name)`` holds with its byte code beside it (zipimport's layout)."""
    modules = {f"{root}{name}": data for name, data in sources.items() if "/__pycache__/" not in f"/{name}"}
    with tempfile.TemporaryDirectory(prefix="sbf_package_") as tmp:
        for name, data in sources.items():
            (Path(tmp) / package / name).parent.mkdir(parents=True, exist_ok=True)
            (Path(tmp) / package / name).write_bytes(data)
        for path in byte_compile(Path(tmp) / package).values():
            module = path.name.split(".")[0]
            if with_byte_code(module):
                modules[f"{root}{module}.pyc"] = path.read_bytes()
    packed = io.BytesIO()
    write_entries(packed, modules)
    return packed.getvalue()
