"""The CPython an FMU carries for Linux hosts that have none: the building Python's shared library, the part of its
standard library the FMU's Python code imports, and the libraries beside them that glibc does not provide.

The bundle lies in ``python/`` beside the Linux loader (``binaries/<linux folder>/python/``):

- ``libpython3.X.so.1.0``, stripped of what no loader needs (its symbol table for debuggers);
- ``python3X.zip``: the standard-library modules as byte code (stored, so that zipimport needs no zlib);
- ``lib-dynload/``: the standard library's extension modules among them;
- ``lib/``: the libraries those extension modules and the FMI library's binary need that are not glibc's
  (``ldd``: zlib, libffi, libuuid; for PythonFMU's binary libstdc++ and libgcc_s), or, for pythonfmu3, instead of
  its C++ runtime a build of its binary with that runtime linked in (:data:`CARRIED_INNER`,
  :mod:`stickslip.fmu.bundle.pythonfmu3_binary`);
- ``python3.X._pth``: sys.path, exactly the zip and ``lib-dynload/``. The loader starts a CPython with the program
  name ``<library's folder>/python3.X`` (``sbf_python_program_name`` in ``platform_posix.c``), and CPython's path
  calculation takes the ``._pth`` beside that name as the whole of sys.path, ignoring PYTHONHOME and PYTHONPATH.

The modules are measured: a child of the building Python (isolated, without ``site``) imports the FMU's slave
module as the FMI library does, and the Python code of the project's other FMUs (:data:`COMPANIONS`), and every
standard-library module it then holds goes in, with the codecs Python itself may import when it starts
(:data:`CODECS`). The loader starts this CPython only where the host process has no
Python of its own and ``$SBF_LIBPYTHON`` is not set (``runtime.c``, ``find_libpython``), and loads the libraries of
``lib/`` only where the system has none by their names (the FMI library's C++ runtime, or the binary carried in its
place: only where the FMU's binary does not load), so that a host keeps its own.
"""

import importlib.util
import json
import os
import py_compile
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

from ..archive import ZIP_EPOCH
from .packing import PYTHON_FOLDER

#: the name in ``lib/`` of the FMI library's binary carried for hosts on which the FMU's does not load
CARRIED_INNER = "libpythonfmu3-export.so"
#: libraries every Linux system has (glibc's), never bundled
GLIBC_LIBRARIES = re.compile(r"(libc|libm|libdl|libpthread|librt|libutil|libresolv|ld-linux-x86-64)\.so")
#: the FMI libraries whose Python parts the project's FMUs carry
FMI_LIBRARIES = ("pythonfmu", "pythonfmu3")
#: the packages of every FMU this project builds (the FMI libraries' Python parts and the runtime), imported after the
#: FMU's own slave module: the FMUs of one build then carry the same modules, so that whichever of them starts Python
#: in a process, the others find what they import
COMPANIONS = (*FMI_LIBRARIES, "stickslip.core")
#: what a child of the building Python prints: the file of every module it imported, after importing the FMU's
#: slave module (argv[1]) from its resources folder (argv[2]) as the FMI library does, then COMPANIONS from the
#: folders after it, the FMI libraries without their builders (which the FMUs leave out: stickslip.fmu.trim)
PROBE = ("import importlib, json, sys, types\n"
         "sys.path[:0] = sys.argv[2:]\n"
         "importlib.import_module(sys.argv[1])\n"
         f"for name in {FMI_LIBRARIES!r}:\n"
         "    sys.modules.setdefault(f'{name}.builder', types.ModuleType(f'{name}.builder')).FmuBuilder = None\n"
         f"for name in {COMPANIONS!r}: importlib.import_module(name)\n"
         "print(json.dumps(sorted({getattr(m.__spec__, 'origin', None) or '' for m in list(sys.modules.values())"
         " if getattr(m, '__spec__', None)})))\n")
#: the codecs of ``encodings`` carried besides those measured: Python imports the one of the host's locale when it
#: starts (UTF-8 in the C locale, which turns on its UTF-8 mode), so every codec a Linux locale may name, without
#: the East Asian ones (which need extension modules of their own) and the byte-to-byte ones no locale names
CODECS = ("__init__", "aliases", "ascii", "latin_1", "utf_*", "cp125?", "iso8859_*", "koi8_*", "charmap")
#: the extension modules left out although imported: the standard library imports each in a ``try`` and runs as
#: Python without it, the same (``datetime``, ``json``, ``typing``, ``opcode``; ``xml.etree.ElementTree``, whose
#: ``_elementtree`` alone imports ``pyexpat``), and the FMUs use what they speed up only where they are built (the
#: model description) or save a state in JSON (not the loader's bytes). Not ``_uuid``: without it, the ``uuid1()`` of
#: the FMI libraries' slaves at every instantiation imports ``random``. The Windows CPython carries none of them
#: either (but those built into its DLL). The x86_64 pack is 0.13 MB smaller.
OPTIONAL_EXTENSIONS = ("_datetime", "_json", "_elementtree", "pyexpat", "_typing", "_opcode")


@dataclass(frozen=True)
class Bundle:
    """A Linux CPython bundle: ``entries`` ({path below the loader's folder: bytes}), ``libpython`` (the library's
    path there), ``python_needs`` (the libraries of ``lib/`` that its extension modules need) and ``inner_needs``
    (those the FMI library's binary needs), paths below the loader's folder in the order they are to be loaded;
    ``licenses``: {name: licence text (bytes)} of what it holds (CPython's, and the Debian copyright file of each
    library's package where the system has one); ``inner``: the path of the FMI library's binary it carries in place
    of ``inner_needs`` ("" if none)."""

    entries: dict
    libpython: str
    python_needs: tuple
    inner_needs: tuple
    licenses: dict
    inner: str = ""


def linux_bundle(entries, inner_binary, carried_inner=None):
    """The :class:`Bundle` for the FMU whose ``entries`` ({archive name: bytes}) hold its ``resources/`` and whose FMI
    library's Linux binary is ``inner_binary`` (bytes), carrying ``carried_inner`` (the path of a build of that binary
    that needs glibc alone, or None: the libraries ``inner_binary`` needs instead); a string saying why not where
    this Python has no shared library."""
    stdlib, dynload = Path(sysconfig.get_paths()["stdlib"]), Path(sysconfig.get_config_var("DESTSHARED") or "")
    libpython = _shared_library()
    if libpython is None:
        return (f"this Python ({sys.executable}, {sys.version.split()[0]}) has no shared library "
                f"(it was not built with --enable-shared)")
    version = f"{sys.version_info[0]}.{sys.version_info[1]}"
    zip_name = f"python{sys.version_info[0]}{sys.version_info[1]}.zip"
    with tempfile.TemporaryDirectory(prefix="sbf_python_") as tmp:
        tmp = Path(tmp)
        modules, extensions = _split(_imported_files(entries, tmp / "fmu"), stdlib, dynload)
        files = {f"{PYTHON_FOLDER}/{libpython.name}": libpython,
                 **{f"{PYTHON_FOLDER}/lib-dynload/{path.name}": path for path in extensions}}
        inner = tmp / "inner.so"
        inner.write_bytes(inner_binary)
        python_needs = _needed_libraries(files.values())
        inner_needs = _needed_libraries([inner]) if carried_inner is None else {}
        for path in {**python_needs, **inner_needs}.values():
            files[f"{PYTHON_FOLDER}/lib/{path.name}"] = path
        if carried_inner is not None:
            files[f"{PYTHON_FOLDER}/lib/{CARRIED_INNER}"] = Path(carried_inner)
        out = {name: _stripped(path, tmp) for name, path in files.items()}
        licenses = _licenses(stdlib, {**python_needs, **inner_needs}.values())
    out[f"{PYTHON_FOLDER}/{zip_name}"] = _module_zip(modules, stdlib)
    out[f"{PYTHON_FOLDER}/python{version}._pth"] = f"{zip_name}\nlib-dynload\n".encode()
    return Bundle(out, f"{PYTHON_FOLDER}/{libpython.name}",
                  tuple(f"{PYTHON_FOLDER}/lib/{name}" for name in python_needs),
                  tuple(f"{PYTHON_FOLDER}/lib/{name}" for name in inner_needs), licenses,
                  f"{PYTHON_FOLDER}/lib/{CARRIED_INNER}" if carried_inner is not None else "")


def _shared_library():
    """This Python's shared library (a Path), or None if it has none."""
    if not sysconfig.get_config_var("Py_ENABLE_SHARED"):
        return None
    path = Path(sysconfig.get_config_var("LIBDIR") or "") / (sysconfig.get_config_var("INSTSONAME") or "")
    return path if path.is_file() else None


def _imported_files(entries, folder):
    """The files of the modules a child of this Python holds after importing the FMU's slave module (the one named
    in ``resources/slavemodule.txt``) from the FMU's resources, written below ``folder``."""
    for name, data in entries.items():
        if name.startswith("resources/"):
            (folder / name).parent.mkdir(parents=True, exist_ok=True)
            (folder / name).write_bytes(data)
    module = entries["resources/slavemodule.txt"].decode().strip()
    companions = sorted({str(Path(importlib.util.find_spec(name.split(".")[0]).origin).parents[1])
                         for name in COMPANIONS})
    result = subprocess.run([sys.executable, "-I", "-S", "-c", PROBE, module, str(folder / "resources"), *companions],
                            capture_output=True, text=True, cwd=folder)
    if result.returncode != 0:
        raise RuntimeError(f"importing the FMU's slave module {module} to measure the modules it needs failed:\n"
                           f"{result.stderr[-3000:]}")
    return [Path(origin) for origin in json.loads(result.stdout) if os.path.isabs(origin)]


def _split(files, stdlib, dynload):
    """``(standard-library modules' sources, standard-library extension modules)`` among ``files``, with the
    codecs of :data:`CODECS`, without :data:`OPTIONAL_EXTENSIONS`."""
    codecs = {path for pattern in CODECS for path in (stdlib / "encodings").glob(f"{pattern}.py")}
    modules = sorted({path for path in files if path.suffix == ".py" and path.is_relative_to(stdlib)
                      and "site-packages" not in path.parts} | codecs)
    extensions = sorted(path for path in files if path.suffix == ".so" and path.parent == dynload
                        and path.name.split(".")[0] not in OPTIONAL_EXTENSIONS)
    return modules, extensions


def _needed_libraries(binaries):
    """{file name: path} of the libraries that ``binaries`` (paths) need, directly or through each other, that are
    not glibc's, in an order that loads each after the ones it needs (as ``ldd`` finds them here)."""
    found = {}
    for binary in binaries:
        result = subprocess.run(["ldd", str(binary)], capture_output=True, text=True)
        for line in result.stdout.splitlines():
            match = re.match(r"\s*(\S+) => (/\S+)", line)
            if match and not GLIBC_LIBRARIES.match(match[1]) and not match[1].startswith("libpython"):
                found[match[1]] = Path(match[2])
    return dict(sorted(found.items(), key=lambda item: _needs_count(item[1])))


def _needs_count(path):
    """How many non-glibc libraries the library at ``path`` needs (those needing none are loaded first)."""
    result = subprocess.run(["ldd", str(path)], capture_output=True, text=True)
    return sum(1 for line in result.stdout.splitlines()
               if "=>" in line and not GLIBC_LIBRARIES.match(line.strip()))


def _licenses(stdlib, libraries):
    """{name: licence text}: CPython's (``LICENSE.txt`` of its standard library), and for each of ``libraries``
    (paths) the copyright file of the Debian package that holds it, named after the package; a library of no
    package is left out (the FMU's documentation then does not name its licence)."""
    texts = {"cpython": (stdlib / "LICENSE.txt").read_bytes()} if (stdlib / "LICENSE.txt").is_file() else {}
    for library in libraries:
        real = os.path.realpath(library)
        for candidate in (real, real.removeprefix("/usr") if real.startswith("/usr/lib") else "/usr" + real):
            found = subprocess.run(["dpkg", "-S", candidate], capture_output=True, text=True) if shutil.which(
                "dpkg") else None
            package = found.stdout.split(":", 1)[0] if found and found.returncode == 0 else ""
            copyright_file = Path("/usr/share/doc", package, "copyright")
            if package and copyright_file.is_file():
                texts[package] = copyright_file.read_bytes()
                break
    return texts


def _stripped(path, tmp):
    """The bytes of the shared library at ``path`` without its symbol table and debugging sections (the dynamic
    symbols stay), or as they are where ``strip`` is missing or fails."""
    copy = tmp / f"strip_{path.name}"
    shutil.copyfile(path, copy)
    if shutil.which("strip"):
        subprocess.run(["strip", "--strip-unneeded", str(copy)], capture_output=True)
    return copy.read_bytes()


def _module_zip(modules, stdlib):
    """The bytes of a zip archive (stored) holding each module's byte code under its path relative to ``stdlib``:
    the installation's own ``__pycache__`` file (the same bytes at every build: byte code compiled in this process
    would depend on its state), else one compiled here. No source beside them: zipimport takes them as they are."""
    out = tempfile.SpooledTemporaryFile()
    with tempfile.TemporaryDirectory(prefix="sbf_pyc_") as tmp, zipfile.ZipFile(out, "w") as archive:
        for path in modules:
            name = path.relative_to(stdlib).with_suffix(".pyc")
            cached = Path(importlib.util.cache_from_source(str(path)))
            if not cached.is_file():
                cached = Path(py_compile.compile(str(path), cfile=str(Path(tmp) / "module.pyc"), dfile=str(name),
                                                 doraise=True))
            archive.writestr(zipfile.ZipInfo(str(name), ZIP_EPOCH), cached.read_bytes())
    out.seek(0)
    return out.read()
