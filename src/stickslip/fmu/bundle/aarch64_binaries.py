"""The FMI 3 FMU's aarch64 Linux binaries (``binaries/aarch64-linux/``), cross-compiled on the building machine with
Debian's GCC for arm64 (``aarch64-linux-gnu-gcc`` and ``-g++``, Debian's packages gcc-aarch64-linux-gnu and
g++-aarch64-linux-gnu; ``$SBF_AARCH64_CC`` and ``$SBF_AARCH64_CXX`` name others):

- the loader (``stickslip.fmu.loader``'s sources) as ``<model identifier>.so``, with the start guard;
- pythonfmu3's binary, built from the C++ sources of its source distribution on PyPI (the version the building
  Python has, downloaded with pip into the user's cache once) as ``<model identifier>_pythonfmu.so``, with
  libstdc++ and libgcc linked in and hidden, so that it needs glibc alone; compiled once per sources and compiler
  into the user's cache;
- the CPython of :mod:`stickslip.fmu.bundle.aarch64_python`, packed as the x86_64 one
  (:mod:`stickslip.fmu.bundle.packing`: ``extra/stickslip/python-aarch64-linux.tar.lzma``), which the loader unpacks
  into the user's cache where it starts it.

The FMI 2 FMUs get none: PythonFMU publishes neither an aarch64 binary nor its C++ sources on PyPI (its
distributions carry the x86_64 Linux and Windows binaries only), and the loader forwards every FMI 2 call it does not
answer itself to that binary. Where a part cannot be had, the FMU has no aarch64 binaries and the build says why.
"""

import functools
import hashlib
import os
import shutil
import subprocess
import sys
import sysconfig
import tarfile
import tempfile
from importlib import metadata
from pathlib import Path

from ..compile_runtime import USER_CACHE
from ..documentation import with_carried_licenses
from .aarch64_python import aarch64_bundle
from .debian_packages import SAFE_EXTRACTION, replace_folder
from .packing import pack_folder

#: the FMU's folder of aarch64 Linux binaries (FMI 3's platform tuple)
FOLDER = "binaries/aarch64-linux"
#: the variables naming the cross-compilers, and their defaults (Debian's)
CC_VARIABLE, CC = "SBF_AARCH64_CC", "aarch64-linux-gnu-gcc"
CXX_VARIABLE, CXX = "SBF_AARCH64_CXX", "aarch64-linux-gnu-g++"
#: where pythonfmu3's source distribution, its aarch64 binary and the aarch64 loaders are kept
CACHE = USER_CACHE / "aarch64"
#: the folder of the loader's C sources, on which a cached loader depends
LOADER_SOURCES = Path(__file__).resolve().parents[1] / "loader"
#: the C++ sources of pythonfmu3's binary in its source distribution, below ``pythonfmu3/pythonfmu-export/src``
INNER_SOURCES = ("cppfmu/cppfmu_cs.cpp", "cppfmu/fmi_functions.cpp", "pythonfmu/PySlaveInstance.cpp")
#: how pythonfmu3's binary is compiled: as its CMake build does (C++17, the stable ABI, optimized), with the C++
#: runtime linked in and its symbols kept out of the dynamic symbol table, and the sections of that runtime the
#: binary does not use left out (1.32 MB without, 0.86 MB with)
INNER_FLAGS = ("-O2", "-DNDEBUG", "-std=c++17", "-shared", "-fPIC", "-DPy_LIMITED_API", "-static-libstdc++",
               "-static-libgcc", "-Wl,--exclude-libs,ALL", "-s", "-ffunction-sections", "-fdata-sections",
               "-Wl,--gc-sections")


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
    one carries; ``compile_loader``: the loader's compile function); a note on stderr where it cannot."""
    if arguments[1] != 3:
        return
    why = _install(entries, model_identifier, arguments, linux_bundle, compile_loader)
    if why:
        print(f"note: the {model_identifier} FMU has no aarch64 Linux binaries: {why}", file=sys.stderr)


def _install(entries, model_identifier, arguments, linux_bundle, compile_loader):
    (cc, cxx), why = compilers()
    if why:
        return why
    if linux_bundle is None:
        return "the FMU carries no CPython for x86_64 Linux, whose modules the aarch64 one would carry"
    bundle = aarch64_bundle(linux_bundle)
    if isinstance(bundle, str):
        return bundle
    inner, why = inner_binary(cxx)
    if inner is None:
        return why
    inner_name = f"{model_identifier}_pythonfmu.so"
    packed = pack_folder(FOLDER.split("/")[1], bundle.entries)
    loader, why = _loader(compile_loader, (f"{model_identifier}.so", inner_name, *arguments), bundle, packed, cc)
    if why:
        return why
    entries.update({f"{FOLDER}/{path.name}": path.read_bytes() for path in sorted(loader.iterdir())})
    entries[f"{FOLDER}/{inner_name}"] = inner.read_bytes()
    entries[packed.name] = packed.data
    with_carried_licenses(entries, bundle.licenses, f"the CPython for aarch64 hosts without one, with the libraries it "
                          f"needs that are not glibc's ({packed.name})")
    with_carried_licenses(entries, _runtime_licenses(cxx), f"the C++ runtime linked into pythonfmu3's aarch64 binary "
                          f"({FOLDER}/{inner_name}), under the GCC Runtime Library Exception")
    return None


def _runtime_licenses(cxx):
    """{Debian package: its copyright file} of the C++ runtime that ``cxx`` links in statically (libstdc++), where
    dpkg knows its package; else none."""
    library = subprocess.run([cxx, "-print-file-name=libstdc++.a"], capture_output=True, text=True).stdout.strip()
    owner = subprocess.run(["dpkg", "-S", os.path.realpath(library)], capture_output=True, text=True) if shutil.which(
        "dpkg") and library else None
    package = owner.stdout.split(":", 1)[0] if owner and owner.returncode == 0 else ""
    copyright_file = Path("/usr/share/doc", package, "copyright")
    return {package: copyright_file.read_bytes()} if package and copyright_file.is_file() else {}


def _loader(compile_loader, arguments, bundle, packed, cc):
    """``(the folder holding the aarch64 loader and its start guard, None)``, compiled with ``cc`` by
    ``compile_loader`` for the CPython ``bundle`` packed as ``packed`` (``arguments``: the loader's file name, then
    that function's) unless :data:`CACHE` has them from the same sources and arguments, or ``(None, why not)``."""
    version = subprocess.run([cc, "--version"], capture_output=True, text=True).stdout.split("\n", 1)[0]
    digest = hashlib.sha256(repr((arguments, bundle.libpython, bundle.python_needs, bundle.inner_needs, packed.name,
                                  packed.key, packed.tar_size, packed.files, version)).encode())
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


@functools.cache
def inner_binary(cxx):
    """``(path, None)`` of pythonfmu3's binary for aarch64 compiled with ``cxx`` (in :data:`CACHE`, compiled if
    missing), or ``(None, why not)``; once per process."""
    sdist, why = _sdist()
    if sdist is None:
        return None, why
    version = subprocess.run([cxx, "--version"], capture_output=True, text=True).stdout.split("\n", 1)[0]
    key = hashlib.sha256("\0".join((sdist.read_bytes().hex(), version, *INNER_FLAGS)).encode()).hexdigest()[:16]
    dest = CACHE / f"libpythonfmu-export-{key}.so"
    if dest.is_file():
        return dest, None
    with tempfile.TemporaryDirectory(prefix="sbf_pythonfmu3_") as tmp:
        with tarfile.open(sdist) as archive:
            members = [m for m in archive.getmembers() if "/pythonfmu-export/src/" in m.name and m.isfile()]
            archive.extractall(tmp, members=members, **SAFE_EXTRACTION)
        src = next(Path(tmp).glob("*/pythonfmu3/pythonfmu-export/src"))
        partial = CACHE / f".{dest.name}.{os.getpid()}"
        command = [cxx, *INNER_FLAGS, f"-ffile-prefix-map={src}=pythonfmu-export", "-I", str(src), "-I",
                   sysconfig.get_paths()["include"], "-o", str(partial), *(str(src / name) for name in INNER_SOURCES)]
        run = subprocess.run(command, capture_output=True, text=True)
        if run.returncode != 0:
            return None, f"{cxx} failed to compile pythonfmu3's binary: {run.stderr.strip()[-2000:]}"
        os.replace(partial, dest)
    return dest, None


def _sdist():
    """``(path, None)`` of the source distribution of the pythonfmu3 this Python has (in :data:`CACHE`, downloaded
    there with pip if missing), or ``(None, why not)``."""
    version = metadata.version("pythonfmu3")
    CACHE.mkdir(parents=True, exist_ok=True)
    path = CACHE / f"pythonfmu3-{version}.tar.gz"
    if path.is_file():
        return path, None
    command = [sys.executable, "-m", "pip", "download", "-q", "--no-deps", "--no-binary", ":all:", "--timeout", "30",
               "--retries", "1", f"pythonfmu3=={version}", "-d", str(CACHE)]
    try:
        run = subprocess.run(command, capture_output=True, text=True, timeout=600)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return None, f"pip download of pythonfmu3=={version}'s sources failed: {exc}"
    if run.returncode != 0 or not path.is_file():
        return None, f"pip download of pythonfmu3=={version}'s sources failed: {run.stderr.strip()[-500:]}"
    return path, None
