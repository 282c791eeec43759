"""Compile the loader and put it into a PythonFMU (FMI 2) or pythonfmu3 (FMI 3) FMU as its Linux and Windows binary.

The loader is ``runtime.c`` (CPython and the inner library), ``fast_path.c`` (steps and output reads
without the inner library) and ``state_bytes.c`` (FMU states' bytes without the slave's Python), with the front of
the FMU's FMI version (``fmi2_front.c`` or ``fmi3_front.c``) and the platform layer of the target
(``platform_posix.c`` or ``platform_windows.c``).

- Linux: ``binaries/<linux folder>/<model identifier>.so``; the library's own binary stays beside it as
  ``<model identifier>_pythonfmu.so``, and the start guard (``start_guard.c``, the lock under which the first
  loader of a process starts CPython, shared by every FMU with this loader) as ``sbf_start_guard.so``. The loader
  records the CPython shared library of the Python that builds the FMU (path and soname) as the ones to try after
  ``$SBF_LIBPYTHON``. The compiler is ``$CC`` (default ``cc``); without a working one the FMU keeps its library's
  binary, which loads only inside a Python process, and the build says so on stderr.
- Windows (x86_64): ``binaries/<windows folder>/<model identifier>.dll``, the library's own as
  ``<model identifier>_pythonfmu.dll`` (the start lock is a named mutex: no guard library), and the trimmed
  embeddable CPython in ``python/`` beside them (:mod:`stickslip.fmu.bundle.windows_python`; left out, with a note on
  stderr, where the build cannot get it). It tries the process's own CPython, ``$SBF_LIBPYTHON``, that bundled
  one, then ``python3XY.dll`` of the building Python's version. The compiler is
  ``$SBF_WINDOWS_CC`` (default ``x86_64-w64-mingw32-gcc``, Debian's ``gcc-mingw-w64-x86-64``); without it the FMU
  has no Windows binaries (the library's own would not do what the model description declares), and the build
  says so on stderr.
- aarch64 Linux (FMI 3 only): ``binaries/aarch64-linux/``, the loader cross-compiled, alone: pythonfmu3's binary
  built for aarch64 is packed with a CPython for aarch64 (:mod:`stickslip.fmu.bundle.aarch64_binaries`), and the
  loader loads it from there.
"""

import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path
from xml.etree import ElementTree

from ..bundle import packing, windows_python
from ..archive import read_entries, write_entries
from ..documentation import with_carried_licenses
from ..bundle.floors import PYTHON_FLOORS
from ..bundle.linux_python import linux_bundle
from ..bundle import aarch64_binaries, pythonfmu3_binary

HERE = Path(__file__).resolve().parent
#: FMI version: (the front's source, the FMU's folder of Linux binaries, the library that built the FMU)
FRONTS = {2: (HERE / "fmi2_front.c", "binaries/linux64", "PythonFMU"),
          3: (HERE / "fmi3_front.c", "binaries/x86_64-linux", "pythonfmu3")}
#: FMI version: the FMU's folder of Windows (x86_64) binaries
WINDOWS_FOLDERS = {2: "binaries/win64", 3: "binaries/x86_64-windows"}
RUNTIME = (HERE / "runtime.c", HERE / "runtime.h", HERE / "fast_path.c", HERE / "fast_path.h", HERE / "platform.h",
           HERE / "carried.c", HERE / "carried.h", HERE / "state_bytes.c", HERE / "state_bytes.h")
PLATFORMS = {"linux": HERE / "platform_posix.c", "windows": HERE / "platform_windows.c"}
#: the variable naming the C++ compiler of pythonfmu3's x86_64 binary that the FMI 3 FMU's CPython carries, and its
#: default
CXX_VARIABLE, CXX = "CXX", "c++"
#: the variable naming the cross-compiler of the Windows binaries, and its default
WINDOWS_CC_VARIABLE, WINDOWS_CC = "SBF_WINDOWS_CC", "x86_64-w64-mingw32-gcc"
START_GUARD = HERE / "start_guard.c"
#: the start guard's file name beside the loader
START_GUARD_NAME = "sbf_start_guard.so"
#: what a built binary depends on
SOURCES = (*RUNTIME, START_GUARD, *PLATFORMS.values(), *(front for front, _, _ in FRONTS.values()),
           Path(__file__).resolve())
LIBPYTHON_VARIABLE = "SBF_LIBPYTHON"  # the loader's override: path or name of a CPython shared library


def build_libpython():
    """``(path, soname)`` of this Python's shared library; the path is "" if Python is not built shared."""
    version = sysconfig.get_config_var("LDVERSION") or f"{sys.version_info[0]}.{sys.version_info[1]}"
    soname = f"libpython{version}.so.1.0"
    path = ""
    if sysconfig.get_config_var("Py_ENABLE_SHARED"):
        candidate = Path(sysconfig.get_config_var("LIBDIR") or "") / (sysconfig.get_config_var("INSTSONAME") or soname)
        path = str(candidate) if candidate.is_file() else ""
    return path, soname


def _c_string(text):
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def model_token(model_description, fmi_version):
    """The GUID (FMI 2) or instantiation token (FMI 3) in the bytes of a ``modelDescription.xml``."""
    return ElementTree.fromstring(model_description).get("guid" if fmi_version == 2 else "instantiationToken")


def offers_model_exchange(model_description):
    """True if the bytes of a ``modelDescription.xml`` declare model exchange (a ModelExchange element)."""
    return ElementTree.fromstring(model_description).find("ModelExchange") is not None


def compile_loader(dest, inner_name, slave_survives_release, fmi_version=2, token="", model_exchange=False,
                   bundle=None, packed=None, compiler=None):
    """Compile the Linux loader of ``fmi_version`` to ``dest``, forwarding to ``inner_name`` beside it and accepting
    the GUID or instantiation token ``token`` only, and the start guard beside ``dest`` (``START_GUARD_NAME``);
    ``model_exchange``: an FMI 2 loader that makes model-exchange instances (the inner library has none, the slave
    answers them); ``bundle``: the :class:`~stickslip.fmu.bundle.linux_python.Bundle` the FMU carries beside the
    loader, if any, packed as ``packed`` (:class:`~stickslip.fmu.bundle.packing.Packed`); ``compiler``: a
    cross-compiler for another Linux machine (default ``$CC``, else ``cc``), whose loader then tries no library of the
    build's CPython. None on success, else why not."""
    cross, compiler = compiler is not None, compiler or os.environ.get("CC") or "cc"
    if shutil.which(compiler) is None:
        return f"no C compiler ({compiler!r} not found; set CC)"
    path, soname = build_libpython()
    path = "" if cross else path
    command = [
        compiler, "-O2", "-shared", "-fPIC", "-fvisibility=hidden", "-o", str(dest),
        *_loader_sources(fmi_version, "linux"),
        *_loader_defines(inner_name, token, slave_survives_release, soname, model_exchange and fmi_version == 2,
                                fmi_version),
        f"-DSBF_START_GUARD={_c_string(START_GUARD_NAME)}", f"-DSBF_BUILD_LIBPYTHON={_c_string(path)}",
        *_bundle_defines(bundle, packed), "-ldl", "-lpthread"]
    guard = [compiler, "-O2", "-shared", "-fPIC", "-fvisibility=hidden", "-o",
             str(Path(dest).with_name(START_GUARD_NAME)), str(START_GUARD), "-lpthread"]
    return _run_compiler(compiler, (command, guard))


def windows_compiler():
    """``(the Windows cross-compiler's command, None)``, or ``(that command, why it cannot be used)``."""
    compiler = os.environ.get(WINDOWS_CC_VARIABLE) or WINDOWS_CC
    if shutil.which(compiler) is None:
        return compiler, (f"no Windows cross-compiler ({compiler!r} not found; install mingw-w64 or set "
                          f"{WINDOWS_CC_VARIABLE})")
    return compiler, None


def compile_windows_loader(dest, inner_name, slave_survives_release, fmi_version=2, token="", model_exchange=False,
                           bundled="", packed=None):
    """Cross-compile the Windows (x86_64) loader of ``fmi_version`` to ``dest`` (arguments as
    :func:`compile_loader`), linked statically (it needs only Windows' own kernel32.dll and msvcrt.dll); ``bundled``:
    the path of the CPython DLL the FMU carries below its ``python`` folder ("" if none), packed as ``packed``; None
    on success, else why not."""
    compiler, why_not = windows_compiler()
    if why_not:
        return why_not
    soname = f"python{sys.version_info[0]}{sys.version_info[1]}.dll"
    # no time stamp, a fixed image base: the same sources give the same bytes in any folder
    command = [compiler, "-O2", "-shared", "-static", "-s", "-Wl,--no-insert-timestamp,--disable-auto-image-base",
               "-o", str(dest), *_loader_sources(fmi_version, "windows"),
               *_loader_defines(inner_name, token, slave_survives_release, soname, model_exchange and fmi_version == 2,
                                fmi_version),
               f"-DSBF_BUNDLED_LIBPYTHON={_c_string(bundled)}",
               f"-DSBF_BUNDLED_PYTHON_NEEDS={''.join(_c_string(path) + ',' for path in _carried_dlls(bundled))}",
               *_packed_defines(packed)]
    return _run_compiler(compiler, (command,))


def _carried_dlls(bundled):
    """The DLLs that the extension modules of the CPython at ``bundled`` (relative to the loader's folder, "" if none)
    import, beside it: the loader loads them by their paths before it starts that CPython, since Windows does not
    find them beside the extension module where the folder's path has a ';' (its search path is a ';'-separated
    list)."""
    if not bundled:
        return []
    folder = bundled.rsplit("\\", 1)[0]
    return [f"{folder}\\{name}" for name in windows_python.EXTENSIONS if name.endswith(".dll")]


def _bundle_defines(bundle, packed):
    """The defines that tell the Linux loader where the CPython ``bundle`` lies, packed as ``packed`` (none
    without one)."""
    if bundle is None:
        return []
    return [f"-DSBF_BUNDLED_LIBPYTHON={_c_string(bundle.libpython)}",
            f"-DSBF_BUNDLED_PYTHON_NEEDS={''.join(_c_string(path) + ',' for path in bundle.python_needs)}",
            f"-DSBF_BUNDLED_INNER_NEEDS={''.join(_c_string(path) + ',' for path in bundle.inner_needs)}",
            f"-DSBF_BUNDLED_INNER={_c_string(bundle.inner)}",
            *_packed_defines(packed)]


def _packed_defines(packed):
    """The defines that tell the loader where its CPython is packed and what it holds (carried.c; none without
    one)."""
    if packed is None:
        return []
    files = "".join(f"{{{_c_string(name)}, {size}}}," for name, size in packed.files)
    return [f"-DSBF_CARRIED_PACK={_c_string(packed.name)}", f"-DSBF_CARRIED_KEY={_c_string(packed.key)}",
            f"-DSBF_CARRIED_TAR_SIZE={packed.tar_size}", f"-DSBF_CARRIED_FILES={files}",
            f"-DSBF_CARRIED_FILTER={packing.FILTER_NUMBERS[packed.branch_filter]}"] + ([
        f"-DSBF_CARRIED_SHARED_PACK={_c_string(packing.SHARED_PACK)}",
        f"-DSBF_CARRIED_SHARED_PREFIX={_c_string(packing.shared_prefix(packing.carried_python_platform(packed.name)))}"]
        if packed.shared else [])


def _loader_sources(fmi_version, platform):
    return [str(FRONTS[fmi_version][0]), *(str(path) for path in RUNTIME if path.suffix == ".c"),
            str(PLATFORMS[platform])]


def _loader_defines(inner_name, token, slave_survives_release, soname, model_exchange, fmi_version):
    return [f"-DSBF_INNER_LIBRARY={_c_string(inner_name)}", f"-DSBF_TOKEN={_c_string(token)}",
            f"-DSBF_LIBPYTHON_SONAME={_c_string(soname)}",
            f"-DSBF_PYTHON_FLOOR_MINOR={PYTHON_FLOORS[fmi_version][1]}"] + (
        ["-DSBF_SLAVE_SURVIVES_RELEASE"] if slave_survives_release else []) + (
        ["-DSBF_MODEL_EXCHANGE"] if model_exchange else [])


def _run_compiler(compiler, commands):
    """Run each of ``commands``; None if all succeed, else the compiler's complaint."""
    for step in commands:
        result = subprocess.run(step, capture_output=True, text=True)
        if result.returncode != 0:
            return f"{compiler} failed: {result.stderr.strip()[-2000:]}"
    return None


def install(fmu_path, model_identifier, slave_survives_release=False, fmi_version=2, carry_python=True):
    """Replace the Linux and Windows binaries of the FMI ``fmi_version`` FMU at ``fmu_path`` (rewritten in place) by
    the loader.

    ``slave_survives_release``: the slave's methods balance PythonFMU's release of the slave on an exception
    (as ``fmu_src/SpringBlockFriction.py`` does); the loader then reports their failures as fmi2Error, which
    lets the host reset or free the instance, instead of the library's fatal status. ``carry_python``: the FMU
    carries a CPython for each platform where the build can have one (False: for hosts that have their own).

    The FMU is written again as :func:`stickslip.fmu.archive.write_entries` writes it (reproducibly).
    Returns True if the Linux loader was installed; False (after a notice on stderr) if the FMU keeps
    its library's Linux binary because no C compiler works. Without a Windows cross-compiler the FMU loses its
    Windows binaries (a notice on stderr).
    """
    fmu_path = Path(fmu_path)
    entries = read_entries(fmu_path)
    token = model_token(entries["modelDescription.xml"], fmi_version)
    arguments = (slave_survives_release, fmi_version, token, offers_model_exchange(entries["modelDescription.xml"]))
    with tempfile.TemporaryDirectory(prefix="sbf_loader_") as tmp:
        installed, bundle, packed = _install_linux(entries, Path(tmp), model_identifier, arguments, carry_python)
        packed_aarch64 = aarch64_binaries.install(entries, model_identifier, arguments, bundle, compile_loader)
        shared = packing.shared_pack([packed, packed_aarch64])
        if shared:
            entries[packing.SHARED_PACK] = shared
        _install_windows(entries, Path(tmp), model_identifier, arguments, carry_python)
        _declare_execution_tool(entries)
        write_entries(fmu_path, entries)
    return installed


def _declare_execution_tool(entries):
    """``needsExecutionTool="false"`` in the model description where the binaries of every platform the FMU lists
    carry a CPython (the FMU then runs on a machine with no Python), else as the FMI library wrote it (true)."""
    platforms = {name.split("/")[1] for name in entries if name.startswith("binaries/") and name.count("/") >= 2}
    carrying = {packing.carried_python_platform(name) for name in entries} - {None}
    if platforms and platforms <= carrying:
        entries["modelDescription.xml"] = entries["modelDescription.xml"].replace(
            b'needsExecutionTool="true"', b'needsExecutionTool="false"')


def _install_linux(entries, tmp, model_identifier, arguments, carry_python):
    """The Linux loader in ``entries``: ``(whether it was installed, the CPython bundle it carries or None, that
    bundle's :class:`~stickslip.fmu.bundle.packing.Packed` or None)``."""
    _, folder, library = FRONTS[arguments[1]]
    binary = f"{folder}/{model_identifier}.so"
    inner_name = f"{model_identifier}_pythonfmu.so"
    loader = tmp / binary.rsplit("/", 1)[1]
    bundle = linux_bundle(entries, entries[binary], _carried_inner(model_identifier, arguments[1])) if carry_python \
        else None
    if isinstance(bundle, str):
        print(f"note: the {model_identifier} FMU carries no CPython for Linux hosts without one: {bundle}",
              file=sys.stderr)
        bundle = None
    packed = bundle and packing.pack_folder(folder.split("/")[1], bundle.entries, share=True)
    why_not = compile_loader(loader, inner_name, *arguments, bundle=bundle, packed=packed)
    if why_not is not None:
        print(f"note: the {model_identifier} FMU keeps {library}'s {folder.split('/')[1]} binary, which loads "
              f"only inside a Python process: {why_not}", file=sys.stderr)
        return False, None, None
    _front(entries, binary, inner_name, loader)
    entries[f"{folder}/{START_GUARD_NAME}"] = loader.with_name(START_GUARD_NAME).read_bytes()
    if bundle:
        entries[packed.name] = packed.data
        with_carried_licenses(entries, bundle.licenses, f"the CPython for hosts without one, with the libraries it "
                              f"and the FMI library's binary need that are not glibc's ({packed.name})")
    if bundle and bundle.inner:
        with_carried_licenses(entries, pythonfmu3_binary.runtime_licenses(os.environ.get(CXX_VARIABLE) or CXX),
                              f"the C++ runtime linked into pythonfmu3's binary that {packed.name} holds, under the "
                              f"GCC Runtime Library Exception")
    return True, bundle, packed


def _carried_inner(model_identifier, fmi_version):
    """The path of pythonfmu3's binary built to need glibc alone, which the FMI 3 FMU's CPython carries for hosts on
    which the wheel's does not load, in place of a C++ runtime (:mod:`~stickslip.fmu.bundle.pythonfmu3_binary`);
    None for FMI 2 (PythonFMU publishes no sources), and, after a note on stderr, where it cannot be built (the
    CPython then carries the C++ runtime)."""
    if fmi_version != 3:
        return None
    path, why_not = pythonfmu3_binary.static_binary(os.environ.get(CXX_VARIABLE) or CXX)
    if path is None:
        print(f"note: the {model_identifier} FMU's CPython for Linux hosts without one carries libstdc++ rather than "
              f"pythonfmu3's binary built with it: {why_not}", file=sys.stderr)
    return path


def _install_windows(entries, tmp, model_identifier, arguments, carry_python):
    folder = WINDOWS_FOLDERS[arguments[1]]
    binary = f"{folder}/{model_identifier}.dll"
    if binary not in entries:
        return
    inner_name = f"{model_identifier}_pythonfmu.dll"
    loader = tmp / f"{model_identifier}.dll"
    wanted = carry_python and windows_compiler()[1] is None
    python, bundled = _windows_python(folder, model_identifier) if wanted else ({}, "")
    prefix = f"{folder}/{packing.PYTHON_FOLDER}"
    packed = packing.pack_folder(folder.split("/")[1], python, prefix)
    why_not = compile_windows_loader(loader, inner_name, *arguments, bundled=bundled, packed=packed)
    if why_not is not None:
        for name in [name for name in entries if name.startswith(f"{folder}/")]:
            del entries[name]
        print(f"note: the {model_identifier} FMU has no Windows binaries: {why_not}", file=sys.stderr)
        return
    _front(entries, binary, inner_name, loader)
    entries.update({name: data for name, data in python.items() if not name.startswith(f"{prefix}/")})
    if packed:
        entries[packed.name] = packed.data


def _windows_python(folder, model_identifier):
    """``(entries, path)``: the trimmed embeddable CPython for the Windows binaries in ``folder``
    (:mod:`stickslip.fmu.bundle.windows_python`) and its DLL's path relative to the loader; ``({}, "")`` after a note on
    stderr where the build cannot have it."""
    files, why_not = windows_python.bundle()
    if files is not None:
        try:
            return windows_python.python_entries(folder, files)
        except windows_python.EmbeddableError as exc:
            why_not = str(exc)
    print(f"note: the {model_identifier} FMU's Windows binaries carry no Python (they need one in the host process, "
          f"named by {LIBPYTHON_VARIABLE} or on the PATH): {why_not}", file=sys.stderr)
    return {}, ""


def _front(entries, binary, inner_name, loader):
    """The FMU's ``binary`` kept beside it as ``inner_name``, and the compiled ``loader`` (a path) in its place."""
    entries[f"{binary.rsplit('/', 1)[0]}/{inner_name}"] = entries[binary]
    entries[binary] = loader.read_bytes()
