"""What some tests need from the machine beyond the Python packages; each function skips the calling test, saying
what is missing and what needed it, where the machine does not have it (never a failure, never a silent pass)."""

import ctypes.util
import os
import shutil

import pytest

from stickslip.fmu.loader.install import build_libpython


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
