"""The FMI 3 FMU's aarch64 Linux binaries (``binaries/aarch64-linux/``), cross-compiled on the building machine with
Debian's GCC for arm64 (``aarch64-linux-gnu-gcc`` and ``-g++``, Debian's packages gcc-aarch64-linux-gnu and
g++-aarch64-linux-gnu; ``$SBF_AARCH64_CC`` and ``$SBF_AARCH64_CXX`` name others):

- the loader (``stickslip.fmu.loader``'s sources) as ``<model identifier>.so``, with the start guard: the only
  files of the folder;
- the CPython of :mod:`stickslip.fmu.bundle.aarch64_python`, packed as the x86_64 one
  (:mod:`stickslip.fmu.bundle.packing`: ``extra/stickslip/python-aarch64-linux.tar.lzma``), which the loader unpacks
  into the user's cache where it starts it;
- in that pack, pythonfmu3's binary built from its source distribution (:mod:`stickslip.fmu.bundle.pythonfmu3_binary`)
  as ``python/lib/libpythonfmu3-export.so``, with libstdc++ and libgcc linked in and hidden, so that it needs glibc
  alone. The loader has no binary beside it to forward to and loads this one, unpacking the pack for it also where
  the host process has a Python of its own; hosts on other machines (FMPy extracts ``binaries/`` and
  ``resources/``) then write only the small loader for aarch64.

The FMI 2 FMUs get none: PythonFMU publishes neither an aarch64 binary nor its C++ sources on PyPI (its
distributions carry the x86_64 Linux and Windows binaries only), and the loader forwards every FMI 2 call it does not
answer itself to that binary. Where a part cannot be had, the FMU has no aarch64 binaries and the build says why.
"""

import dataclasses
import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

from ..compile_runtime import USER_CACHE
from ..documentation import with_carried_licenses
from .aarch64_python import aarch64_bundle
from .debian_packages import replace_folder
from .linux_python import CARRIED_INNER
from .packing import PYTHON_FOLDER, pack_folder
from .pythonfmu3_binary import runtime_licenses, static_binary

#: the FMU's folder of aarch64 Linux binaries (FMI 3's platform tuple)
FOLDER = "binaries/aarch64-linux"
#: the variables naming the cross-compilers, and their defaults (Debian's)
CC_VARIABLE, CC = "SBF_AARCH64_CC", "aarch64-linux-gnu-gcc"
CXX_VARIABLE, CXX = "SBF_AARCH64_CXX", "aarch64-linux-gnu-g++"
#: where the aarch64 loaders are kept
CACHE = USER_CACHE / "aarch64"
#: the folder of the loader's C sources, on which a cached loader depends
LOADER_SOURCES = Path(__file__).resolve().parents[1] / "loader"


def compilers():
    """``((C compiler, C++ compiler), None)``, or ``(those, why they cannot be used)``."""
    found = (os.environ.get(CC_VARIABLE) or CC, os.environ.get(CXX_VARIABLE) or CXX)
    missing = [command for command in found if shutil.which(command) is None]
    return found, (f"no aarch64 cross-compiler ({', '.join(map(repr, missing))} not found; install Debian's "
                   f"gcc-aarch64-linux-gnu and g++-aarch64-linux-gnu, or set {CC_VARIABLE} and {CXX_VARIABLE})"
                   if missing else None)


def install(entries, model_identifier, arguments, linux_bundle, compile_loader):
    """Add the aarch64 binaries to the FMI 3 FMU's ``entries`` (``arguments``: those of the loader's
    ``compile_loader``, the FMI version second; ``linux_bundle``: the x86_64 CPython bundle, whose modules the aarch64
    one carries; ``compile_loader``: the loader's compile function): the
    :class:`~stickslip.fmu.bundle.packing.Packed` CPython they carry, whose standard-library zip goes to the pack the
    Linux platforms share; None, after a note on stderr where it cannot be had."""
    if arguments[1] != 3:
        return None
    packed = _install(entries, model_identifier, arguments, linux_bundle, compile_loader)
    if isinstance(packed, str):
        print(f"note: the {model_identifier} FMU has no aarch64 Linux binaries: {packed}", file=sys.stderr)
        return None
    return packed


def _install(entries, model_identifier, arguments, linux_bundle, compile_loader):
    """What :func:`install` does: the Packed CPython, or a string saying why the platform is left out."""
    (cc, cxx), why = compilers()
    if why:
        return why
    if linux_bundle is None:
        return "the FMU carries no CPython for x86_64 Linux, whose modules the aarch64 one would carry"
    bundle = aarch64_bundle(linux_bundle)
    if isinstance(bundle, str):
        return bundle
    inner, why = static_binary(cxx)
    if inner is None:
        return why
    inner_name = f"{PYTHON_FOLDER}/lib/{CARRIED_INNER}"
    bundle = dataclasses.replace(bundle, entries={**bundle.entries, inner_name: inner.read_bytes()}, inner=inner_name)
    packed = pack_folder(FOLDER.split("/")[1], bundle.entries, share=True)
    loader, why = _loader(compile_loader, (f"{model_identifier}.so", "", *arguments), bundle, packed, cc)
    if why:
        return why
    entries.update({f"{FOLDER}/{path.name}": path.read_bytes() for path in sorted(loader.iterdir())})
    entries[packed.name] = packed.data
    with_carried_licenses(entries, bundle.licenses, f"the CPython for aarch64 hosts without one, with the libraries it "
                          f"needs that are not glibc's ({packed.name})")
    with_carried_licenses(entries, runtime_licenses(cxx), f"the C++ runtime linked into pythonfmu3's aarch64 binary, "
                          f"{inner_name} in {packed.name}, under the GCC Runtime Library Exception")
    return packed


def _loader(compile_loader, arguments, bundle, packed, cc):
    """``(the folder holding the aarch64 loader and its start guard, None)``, compiled with ``cc`` by
    ``compile_loader`` for the CPython ``bundle`` packed as ``packed`` (``arguments``: the loader's file name, then
    that function's) unless :data:`CACHE` has them from the same sources and arguments, or ``(None, why not)``."""
    version = subprocess.run([cc, "--version"], capture_output=True, text=True).stdout.split("\n", 1)[0]
    digest = hashlib.sha256(repr((arguments, bundle.libpython, bundle.python_needs, bundle.inner_needs, bundle.inner,
                                  packed.name, packed.key, packed.tar_size, packed.files, sorted(packed.shared),
                                  version)).encode())
    for source in sorted(LOADER_SOURCES.glob("*.[ch]")):
        digest.update(source.read_bytes())
    folder = CACHE / f"loader-{digest.hexdigest()[:16]}"
    if folder.is_dir():
        return folder, None
    partial = CACHE / f".{folder.name}.{os.getpid()}"
    partial.mkdir(parents=True, exist_ok=True)
    why = compile_loader(partial / arguments[0], *arguments[1:], bundle=bundle, packed=packed, compiler=cc)
    if why:
        shutil.rmtree(partial, ignore_errors=True)
        return None, why
    replace_folder(partial, folder)
    return folder, None
