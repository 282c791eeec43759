"""Which implementation of this package runs: its compiled modules or their Python sources.

The modules in :data:`COMPILED_MODULES` may sit beside their sources as extension
modules compiled from them by mypyc (``stickslip.fmu.compile_runtime``). They are used
when all of these hold, else the sources are (same numbers, slower):

- the compiled files for this interpreter are there (another Python version or
  platform has none: the sources are found as usual);
- ``compiled_sources.crc32`` beside them matches the sources (edited sources are never
  shadowed by stale compiled code; a CRC, not a cryptographic hash: it guards against edits, not
  attacks, and costs no OpenSSL load at the FMU's first instantiation);
- the environment variable ``STICKSLIP_PURE_PYTHON`` is not set to a non-empty value;
- they load (an ImportError, e.g. a missing shared library, falls back).

This module is never compiled, and uses only the standard library, so the FMU's
renamed copy of the package (``sbf_runtime_<tag>``) makes the same choice. In that copy the
modules' sources (all but ``__init__.py``) are packed with their byte code into one file,
:data:`PACKED` in the package's folder (``stickslip.fmu.trim``), which ``__init__.py`` puts on
the package's path after the folder: the compiled modules in the folder come first.
"""

import importlib
import importlib.util
import os
import sys
import zipimport
import zlib
from importlib.machinery import EXTENSION_SUFFIXES

COMPILED_MODULES = (
    "laws", "model", "integrators", "poly", "rootfind", "numeric_slip", "linear_slip", "stuck", "segments", "trajectory",
    "state_bytes",
)
STAMP = "compiled_sources.crc32"
PURE_ENV = "STICKSLIP_PURE_PYTHON"
#: the zip archive in the package's folder that holds its modules' sources where they are packed (an FMU's copy)
PACKED = "sources.zip"


def sources_digest(folder):
    """CRC-32 (8 hex digits) of the names and sources of :data:`COMPILED_MODULES` in ``folder`` (or in its
    :data:`PACKED` archive)."""
    crc = 0
    for name in COMPILED_MODULES:
        crc = zlib.crc32(name.encode() + b"\0" + _source(folder, name) + b"\0", crc)
    return f"{crc:08x}"


def _source(folder, name):
    """The bytes of the module ``name``'s source in ``folder``, else in its :data:`PACKED` archive."""
    path = os.path.join(folder, f"{name}.py")
    if os.path.isfile(path):
        with open(path, "rb") as source:
            return source.read()
    return zipimport.zipimporter(os.path.join(folder, PACKED)).get_data(f"{name}.py")


def select(package, folder):
    """Import ``package``'s compiled modules, or make its sources win; a description of the choice."""
    reason = _reason_against_compiled(folder)
    if reason is None:
        try:
            modules = [importlib.import_module(f"{package}.{name}") for name in COMPILED_MODULES]
            if all(module.__file__.endswith(tuple(EXTENSION_SUFFIXES)) for module in modules):
                return "compiled (mypyc)"
            return "pure Python (its sources were chosen for it)"
        except ImportError as exc:
            reason = f"the compiled modules do not load: {exc}"
            for name in COMPILED_MODULES:
                sys.modules.pop(f"{package}.{name}", None)
    if _has_compiled(folder):
        sys.meta_path.insert(0, _SourcesFirst(package, folder))
    return f"pure Python ({reason})"


def import_pure_copy(folder, alias):
    """The package in ``folder`` from its Python sources only, imported as the separate package ``alias``
    (to run both implementations side by side: benchmark, agreement tests)."""
    if alias in sys.modules:
        return sys.modules[alias]
    sys.meta_path.insert(0, _SourcesFirst(alias, folder))
    spec = importlib.util.spec_from_file_location(alias, os.path.join(folder, "__init__.py"),
                                                  submodule_search_locations=[folder])
    module = importlib.util.module_from_spec(spec)
    sys.modules[alias] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[alias]
        raise
    return module


def _has_compiled(folder):
    return any(os.path.exists(os.path.join(folder, f"{COMPILED_MODULES[0]}{suffix}")) for suffix in EXTENSION_SUFFIXES)


def _reason_against_compiled(folder):
    if os.environ.get(PURE_ENV):
        return f"{PURE_ENV} is set"
    if not all(any(os.path.exists(os.path.join(folder, f"{name}{suffix}")) for suffix in EXTENSION_SUFFIXES)
               for name in COMPILED_MODULES):
        return "no compiled modules for this Python"
    try:
        with open(os.path.join(folder, STAMP)) as stamp:
            if stamp.read().strip() == sources_digest(folder):
                return None
    except OSError:
        pass
    return "the sources changed since they were compiled"


class _SourcesFirst:
    """Meta path finder that loads the package's compiled modules from their ``.py`` sources."""

    def __init__(self, package, folder):
        self.package, self.folder = package, folder

    def find_spec(self, fullname, path=None, target=None):
        package, _, name = fullname.rpartition(".")
        source, packed = os.path.join(self.folder, f"{name}.py"), os.path.join(self.folder, PACKED)
        if package != self.package or name not in COMPILED_MODULES:
            return None  # not ours: the usual search
        if os.path.isfile(source):
            return importlib.util.spec_from_file_location(fullname, source)
        if os.path.isfile(packed):
            return zipimport.zipimporter(packed).find_spec(fullname)
        return None  # a folder gone since (a build's copy of the package): the usual search
