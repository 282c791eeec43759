"""pythonfmu3's binary built from the C++ sources of its source distribution on PyPI, with libstdc++ and libgcc
linked in and hidden, so that it needs glibc alone: the FMI 3 FMU's aarch64 binary, packed with its aarch64 CPython
(:mod:`stickslip.fmu.bundle.aarch64_binaries`), and the x86_64 one its carried CPython holds for hosts on which
the wheel's binary does not load (no C++ runtime, or one older than it needs), in place of a carried libstdc++.

The source distribution is the version the building Python has, downloaded with pip into :data:`CACHE` once; each
binary is compiled once per sources and compiler into :data:`CACHE`.
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
from .debian_packages import SAFE_EXTRACTION

#: where pythonfmu3's source distribution and the binaries compiled from it are kept
CACHE = USER_CACHE / "pythonfmu3"
#: the C++ sources of pythonfmu3's binary in its source distribution, below ``pythonfmu3/pythonfmu-export/src``
SOURCES = ("cppfmu/cppfmu_cs.cpp", "cppfmu/fmi_functions.cpp", "pythonfmu/PySlaveInstance.cpp")
#: how it is compiled: as its CMake build does (C++17, the stable ABI, optimized), with the C++ runtime linked in and
#: its symbols kept out of the dynamic symbol table, and the sections of that runtime the binary does not use left
#: out (aarch64: 1.32 MB without, 0.86 MB with)
FLAGS = ("-O2", "-DNDEBUG", "-std=c++17", "-shared", "-fPIC", "-DPy_LIMITED_API", "-static-libstdc++",
         "-static-libgcc", "-Wl,--exclude-libs,ALL", "-s", "-ffunction-sections", "-fdata-sections",
         "-Wl,--gc-sections")


@functools.cache
def static_binary(cxx):
    """``(path, None)`` of pythonfmu3's binary compiled with the C++ compiler ``cxx`` (in :data:`CACHE`, compiled if
    missing), or ``(None, why not)``; once per process and compiler."""
    if shutil.which(cxx) is None:
        return None, f"no C++ compiler ({cxx!r} not found)"
    sdist, why = _sdist()
    if sdist is None:
        return None, why
    version = subprocess.run([cxx, "--version"], capture_output=True, text=True).stdout.split("\n", 1)[0]
    key = hashlib.sha256("\0".join((sdist.read_bytes().hex(), version, *FLAGS)).encode()).hexdigest()[:16]
    dest = CACHE / f"libpythonfmu-export-{key}.so"
    if dest.is_file():
        return dest, None
    with tempfile.TemporaryDirectory(prefix="sbf_pythonfmu3_") as tmp:
        with tarfile.open(sdist) as archive:
            members = [m for m in archive.getmembers() if "/pythonfmu-export/src/" in m.name and m.isfile()]
            archive.extractall(tmp, members=members, **SAFE_EXTRACTION)
        src = next(Path(tmp).glob("*/pythonfmu3/pythonfmu-export/src"))
        partial = CACHE / f".{dest.name}.{os.getpid()}"
        command = [cxx, *FLAGS, f"-ffile-prefix-map={src}=pythonfmu-export", "-I", str(src), "-I",
                   sysconfig.get_paths()["include"], "-o", str(partial), *(str(src / name) for name in SOURCES)]
        run = subprocess.run(command, capture_output=True, text=True)
        if run.returncode != 0:
            return None, f"{cxx} failed to compile pythonfmu3's binary: {run.stderr.strip()[-2000:]}"
        os.replace(partial, dest)
    return dest, None


def runtime_licenses(cxx):
    """{Debian package: its copyright file} of the C++ runtime that ``cxx`` links in statically (libstdc++), where
    dpkg knows its package; else none."""
    library = subprocess.run([cxx, "-print-file-name=libstdc++.a"], capture_output=True, text=True).stdout.strip()
    owner = subprocess.run(["dpkg", "-S", os.path.realpath(library)], capture_output=True, text=True) if shutil.which(
        "dpkg") and library else None
    package = owner.stdout.split(":", 1)[0] if owner and owner.returncode == 0 else ""
    copyright_file = Path("/usr/share/doc", package, "copyright")
    return {package: copyright_file.read_bytes()} if package and copyright_file.is_file() else {}


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
