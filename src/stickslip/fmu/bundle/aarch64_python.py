"""The CPython the FMI 3 FMU carries for aarch64 Linux hosts that have none: Debian 12's arm64 build of CPython
3.11 (:mod:`stickslip.fmu.bundle.debian_packages`), cut to what the x86_64 bundle holds.

It is laid out as the x86_64 one (:mod:`stickslip.fmu.bundle.linux_python`, whose :class:`Bundle` it is), packed
as it is (:mod:`stickslip.fmu.bundle.packing`, ``extra/stickslip/python-aarch64-linux.tar.lzma``, unpacked by the
aarch64 loader where it starts it), and holds the same modules, measured there:

- ``libpython3.11.so.1.0``: Debian's, as it ships (stripped);
- ``python311.zip``: the same standard-library modules as the x86_64 bundle's zip (every module the FMUs' Python
  code imports, and the codecs), compiled from Debian's sources by a new interpreter of the build's CPython (the
  same byte code format for every 3.11), stored;
- ``lib-dynload/``: Debian's arm64 builds of the x86_64 bundle's extension modules, except those Debian builds
  into its libpython (``math``, ``_struct``, ``zlib``, ``pyexpat``, ...);
- ``lib/``: the libraries those and the libpython need that are not glibc's (zlib, expat, libffi, libuuid), read
  from their ELF dynamic sections;
- ``python3.11._pth``: sys.path, the zip and ``lib-dynload/``.

The FMI library's binary, which :mod:`stickslip.fmu.bundle.aarch64_binaries` adds to ``lib/`` (``inner``), needs no
library beside glibc, so ``inner_needs`` is empty. A build whose CPython is not 3.11 cannot compile byte code for
Debian 12's, and leaves the platform out.
"""

import functools
import io
import os
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

from ..archive import ZIP_EPOCH
from . import debian_packages
from .floors import binary_needs
from .linux_python import Bundle
from .packing import PYTHON_FOLDER

#: the CPython version of Debian 12's packages, and the name of its standard library's zip in the bundles
VERSION = (3, 11)
ZIP_NAME = f"python{VERSION[0]}{VERSION[1]}.zip"
#: the folders of the unpacked packages that hold the standard library, its extension modules and the libraries
STDLIB, DYNLOAD = "usr/lib/python3.11", "usr/lib/python3.11/lib-dynload"
LIBRARY_FOLDERS = ("lib/aarch64-linux-gnu", "usr/lib/aarch64-linux-gnu")
#: glibc's libraries, which every aarch64 Linux machine has (never carried)
GLIBC = ("libc.so.6", "libm.so.6", "libdl.so.2", "libpthread.so.0", "librt.so.1", "libutil.so.1",
         "ld-linux-aarch64.so.1")
#: the file name suffix of Debian's arm64 extension modules
SUFFIX = ".cpython-311-aarch64-linux-gnu.so"
#: the Debian packages whose copyright files name the licences of what the bundle holds, each with its library that
#: the bundle must hold for the licence to go in (None: the CPython's, always)
LICENSED_PACKAGES = {"libpython3.11-minimal": None, "zlib1g": "libz.so.1", "libexpat1": "libexpat.so.1",
                     "libffi8": "libffi.so.8", "libuuid1": "libuuid.so.1"}


class BundleError(RuntimeError):
    """The arm64 packages lack what the x86_64 bundle holds."""


def aarch64_bundle(linux_bundle):
    """The :class:`Bundle` for aarch64 with the modules of the x86_64 ``linux_bundle``; a string saying why not."""
    if sys.version_info[:2] != VERSION:
        return (f"the build's CPython is {sys.version_info[0]}.{sys.version_info[1]}, and Debian 12's arm64 CPython "
                f"is {VERSION[0]}.{VERSION[1]}: its byte code cannot be compiled here")
    root, why = debian_packages.arm64_root()
    if root is None:
        return f"Debian's arm64 packages of CPython could not be had: {why}"
    folder = f"{PYTHON_FOLDER}/"
    with zipfile.ZipFile(io.BytesIO(linux_bundle.entries[f"{folder}{ZIP_NAME}"])) as modules:
        names = tuple(name for name in modules.namelist() if name.endswith(".pyc"))
    extensions = tuple(name.rsplit("/", 1)[1].split(".")[0] for name in linux_bundle.entries
                       if name.startswith(folder + "lib-dynload/"))
    try:
        return _bundle(root, names, extensions)
    except (BundleError, OSError, subprocess.SubprocessError) as exc:
        return str(exc)


@functools.cache  # the same for every FMU a process builds
def _bundle(root, names, extensions):
    """The :class:`Bundle` of the byte code ``names`` and the extension modules ``extensions`` from ``root``."""
    folder, zip_name = f"{PYTHON_FOLDER}/", ZIP_NAME
    libpython = root / "usr/lib/aarch64-linux-gnu" / f"libpython{VERSION[0]}.{VERSION[1]}.so.1.0"
    files = {f"{folder}{libpython.name}": libpython,
             **{f"{folder}lib-dynload/{path.name}": path for path in _extension_modules(root, extensions, libpython)}}
    needs = _needed_libraries(root, list(files.values()))
    files.update({f"{folder}lib/{name}": path for name, path in needs.items()})
    entries = {name: path.read_bytes() for name, path in files.items()}
    entries[folder + zip_name] = _module_zip(root / STDLIB, names)
    entries[f"{folder}python{VERSION[0]}.{VERSION[1]}._pth"] = f"{zip_name}\nlib-dynload\n".encode()
    licenses = {f"{package}-arm64": (root / "usr/share/doc" / package / "copyright").read_bytes()
                for package, library in LICENSED_PACKAGES.items() if library is None or library in needs}
    return Bundle(entries, folder + libpython.name, tuple(f"{folder}lib/{name}" for name in needs), (), licenses)


def _extension_modules(root, names, libpython):
    """Debian's arm64 files of the extension modules ``names``, leaving out those built into its ``libpython``
    (which defines their ``PyInit_<name>``); BundleError naming a module it has in neither form."""
    library = libpython.read_bytes()
    found, missing = [], []
    for name in names:
        path = root / DYNLOAD / f"{name}{SUFFIX}"
        if path.is_file():
            found.append(path)
        elif f"PyInit_{name}\0".encode() not in library:
            missing.append(name)
    if missing:
        raise BundleError(f"Debian's arm64 CPython has no extension module {', '.join(missing)}")
    return found


def _needed_libraries(root, binaries):
    """{file name: path} of the libraries the ELF ``binaries`` (paths) need, directly or through each other, that are
    not glibc's, found in the unpacked packages; those that need none of the others first."""
    found, pending = {}, list(binaries)
    while pending:
        for name in binary_needs(pending.pop().read_bytes()).libraries:
            if name in GLIBC or name in found or name.startswith("libpython"):
                continue
            path = next((root / sub / name for sub in LIBRARY_FOLDERS if (root / sub / name).exists()), None)
            if path is None:
                raise BundleError(f"{name}, which Debian's arm64 CPython needs, is in none of its packages")
            found[name] = path.resolve()
            pending.append(found[name])
    needing = {name: set(binary_needs(path.read_bytes()).libraries) & set(found) for name, path in found.items()}
    return dict(sorted(found.items(), key=lambda item: (len(needing[item[0]]), item[0])))


def _module_zip(stdlib, names):
    """The bytes of a zip (stored) of the byte code ``names`` (``json/decoder.pyc``, ...) compiled from the sources
    below ``stdlib`` by a new interpreter with a fixed hash seed (marshal's bytes then depend on the sources alone),
    as unchecked-hash ``.pyc`` beside where each source would be."""
    with tempfile.TemporaryDirectory(prefix="sbf_arm64_pyc_") as tmp:
        tmp = Path(tmp)
        for name in names:
            source = stdlib / Path(name).with_suffix(".py")
            if not source.is_file():
                raise BundleError(f"Debian's arm64 CPython lacks the standard library module {source.name} "
                                  f"({name} in the x86_64 bundle)")
            (tmp / name).parent.mkdir(parents=True, exist_ok=True)
            (tmp / name).with_suffix(".py").write_bytes(source.read_bytes())
        run = subprocess.run([sys.executable, "-S", "-s", "-m", "compileall", "-q", "-b", "-d", "",
                              "--invalidation-mode", "unchecked-hash", str(tmp)],
                             env={**os.environ, "PYTHONHASHSEED": "0"}, capture_output=True, text=True)
        if run.returncode != 0:
            raise BundleError(f"byte-compiling Debian's standard library failed: {run.stdout + run.stderr}"[-2000:])
        out = tempfile.SpooledTemporaryFile()
        with zipfile.ZipFile(out, "w") as archive:
            for name in sorted(names):
                archive.writestr(zipfile.ZipInfo(name, ZIP_EPOCH), (tmp / name).read_bytes())
        out.seek(0)
        return out.read()
