"""Lay out the FMUs' Python code (:func:`stickslip.fmu.build.build`): what PythonFMU or pythonfmu3 loads, and
how fast.

In the FMU's ``resources/``:

- ``sbf_runtime_<runtime tag>/``: the runtime ``stickslip/core``, the same in the FMI 2 and FMI 3 FMUs: its
  ``__init__.py``, its compiled modules (below) and the rest of its modules in ``sources.zip``;
- ``sbf_slave_<tag>.zip``: the package ``sbf_slave_<tag>``, the slave (``fmu_slave.py``, from
  ``fmu_src/SpringBlockFriction.py`` or ``fmu_src/SpringBlockFriction_fmi3.py``), the variable table the two slaves
  share (``block_interface.py``, from ``fmu_src/``) and the loader binding, their imports renamed to the two
  packages;
- in both archives (:mod:`stickslip.fmu.trim` packs them: a host extracts one file, not a folder of them), the
  modules' byte code for the building Python (unchecked-hash ``.pyc``: valid whatever times the extraction gives the
  files, so a host with that Python compiles none of them, only the runtime's few lines of ``__init__.py``);
- the hot modules of the runtime compiled by mypyc under that package name, for the building
  Python (:mod:`stickslip.fmu.compile_runtime`; the group library ``<hash>__mypyc`` goes to the top
  of ``resources/``), unless the build is pure or cannot compile (no C compiler: the FMU is then
  pure Python, and the build says so on stderr), and for the other CPython versions it finds compiled in
  :data:`OTHER_PYTHONS` (their files' names carry the version: each Python loads its own). A host that cannot
  load them (another Python version or platform) runs the sources (``core/_implementation.py``). Compiled files are cached
  in the user's cache folder (``$XDG_CACHE_HOME/stickslip/fmu-runtime``, default
  ``~/.cache/...``) by package name (the runtime tag: one compilation serves both FMUs), Python and toolchain (mypy, setuptools, compiler
  and flags);
- ``springblockfriction_<tag>.py`` (FMI 3: ``springblockfriction3_<tag>.py``): the module PythonFMU
  (pythonfmu3) loads, a few lines (:data:`FMI2_LOADER`, :data:`FMI3_LOADER`), the first of which put the
  library's own package and the slave's, each packed into one file (:data:`PACKAGE_ARCHIVE`,
  :mod:`stickslip.fmu.trim`), on ``sys.path`` beside it. PythonFMU 0.7.0 compiles
  and runs that module's source at every ``fmi2Instantiate`` (to find the slave class by its MRO; with
  the 300-line slave there, that was 2 ms of each instantiation and a leaked copy of the class), so the
  slave's own source, imported once per process, stays out of it.
"""

import os
import re
import shutil
import subprocess
import sys
import sysconfig
import time
from dataclasses import dataclass, field
from pathlib import Path

from .compile_runtime import (COMPILED_ARTIFACTS, COMPILED_MODULES, COMPLETE, MYPY_LICENSE, PREBUILT, RUNTIME_PREFIX,
                              USER_CACHE, WINDOWS_PLATFORM, CompileError, compile_in_place, implementation, prebuilt_key,
                              store, toolchain_tag)
from .sources import LOADER_BINDING

#: the packages of an FMU's ``resources/``: the runtime (the same in every FMU built from the same runtime, so that
#: the FMI 2 and FMI 3 FMUs share one compilation and a process that loads both shares one copy) and the slave
SLAVE_PREFIX = "sbf_slave_"
CACHE = USER_CACHE / "fmu-runtime"
#: the runtime compiled for other CPython versions of this platform, and for Windows (x86_64), one folder per
#: :func:`~stickslip.fmu.compile_runtime.prebuilt_key` of that version and platform (``scripts/other_pythons.py
#: compile`` makes them): an FMU carries every one of its runtime package besides the building Python's
OTHER_PYTHONS = CACHE / "other-pythons"


@dataclass(frozen=True)
class LoaderModule:
    """The module the FMI library loads: ``prefix`` of its name (the source tag follows) and its source, a
    ``template`` formatted with the slave's ``package``, the slave class ``model_name`` and the names of the
    library's ``archive`` and of the ``slave_archive``."""

    prefix: str
    template: str


#: the zip archive in ``resources/`` that holds a package (``{package}``: its name) with its byte code: the FMI
#: library's and the slave's
PACKAGE_ARCHIVE = "{package}.zip"
#: the loader modules' first lines: the archives of the library's package (``{archive}``) and of the slave's
#: (``{slave_archive}``), :data:`PACKAGE_ARCHIVE` each, go first on ``sys.path`` (where the library's binary put
#: ``resources/``), once
_PACKAGES_ON_PATH = (
    "import os\nimport sys\n\n"
    "_packed = [os.path.join(os.path.dirname(__file__), name) for name in ({archive!r}, {slave_archive!r})]\n"
    "sys.path[:0] = [path for path in _packed if path not in sys.path]  # the FMI library and the slave\n\n")
#: PythonFMU 0.7.0 compiles and runs this module's source at every fmi2Instantiate in the module's globals, which
#: it releases once per instance: the loader binding holds them (``hold_loader_namespace``). The slave's class is
#: imported, once per process: a class defined here would be made again at every instantiation, and PythonFMU keeps
#: each copy (25 kB per instance).
FMI2_TEMPLATE = _PACKAGES_ON_PATH + (
    "from {package}.fmu_slave import {model_name}  # noqa: F401\n"
    "from {package}.loader_binding import hold_loader_namespace\n\n"
    "hold_loader_namespace(globals())  # PythonFMU releases this module's globals once per instance\n")
FMI2_LOADER = LoaderModule("springblockfriction_", FMI2_TEMPLATE)
#: pythonfmu3 0.3.4 imports this module once and takes the slave class by the name in its first line that reads
#: ``class <name>(... Fmi3SlaveBase ...):`` (a regular expression over the file, in its builder and its binary):
#: the class is defined here, a subclass adding nothing.
FMI3_LOADER = LoaderModule("springblockfriction3_", _PACKAGES_ON_PATH + (
    "from pythonfmu3 import Fmi3SlaveBase\n\nfrom {package} import fmu_slave\n\n\n"
    "class {model_name}(fmu_slave.{model_name}, Fmi3SlaveBase):\n"
    '    """The slave (fmu_slave), named where pythonfmu3 looks for it."""\n'))
#: the slave package's ``__init__.py`` (``{runtime}``: the runtime's package; ``{packed}``: the archive of its sources
#: in its folder, :data:`~stickslip.core._implementation.PACKED`). A process may have imported the
#: runtime's package from another FMU of the same runtime, whose files a host may have removed since: a module it
#: imports later (one the other FMU's slave never imported) is then found in this FMU's copy, in ``resources/``
#: beside the package's archive (or its folder, where the builder imports it).
SLAVE_PACKAGE_INIT = (
    '"""The FMU\'s slave and the variable table it shares; this FMU\'s copy of the runtime first on its path."""\n\n'
    "import os\n\nimport {runtime}\n\n"
    "_beside = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # resources/, or the archive in it\n"
    "_copy = os.path.join(os.path.dirname(_beside) if os.path.isfile(_beside) else _beside, {runtime!r})\n"
    "if _copy not in {runtime}.__path__:  # its compiled modules, then its packed sources\n"
    "    {runtime}.__path__[:0] = [_copy, os.path.join(_copy, {packed!r})]\n")
#: FMI version: its loader module
LOADERS = {2: FMI2_LOADER, 3: FMI3_LOADER}


class StagingError(RuntimeError):
    """The FMU's Python code cannot be laid out from the current sources."""


@dataclass
class StagedRuntime:
    """The staged code in a build folder: ``script``, ``package_dir`` (the runtime) and ``slave_dir`` (the slave's
    package) go to PythonFMU's builder; ``extra_files`` (archive name -> path) are the files its builder may leave
    out of the FMU."""

    script: Path
    package_dir: Path
    slave_dir: Path
    module: str
    extra_files: dict = field(default_factory=dict)

    def project_files(self):
        """What the library's builder copies into ``resources/``: the two packages, and the compiled group library
        beside them (the builder imports the slave to write the model description, and pythonfmu3 imports it
        from the copy)."""
        return [self.package_dir, self.slave_dir, *(path for arcname, path in sorted(self.extra_files.items())
                                                    if arcname.count("/") == 1)]

    def add_to(self, entries):
        """Add those of :attr:`extra_files` that the FMU's ``entries`` (``{name: bytes}``) do not have yet."""
        for arcname, path in self.extra_files.items():
            entries.setdefault(arcname, path.read_bytes())


def stage_runtime(folder, tags, runtime, slave, interface, model_name, compiled=True, loader=FMI2_LOADER,
                  library="pythonfmu"):
    """Stage the runtime folder ``runtime`` as :data:`RUNTIME_PREFIX` ``<runtime tag>``, the slave source ``slave``
    (class ``model_name``) with the shared variable table ``interface`` as :data:`SLAVE_PREFIX` ``<tag>``, and the
    ``loader`` module in ``folder``; ``tags``: ``(tag, runtime tag)``; ``compiled``: also compile the runtime's hot
    modules (if this machine can); ``library``: the FMI library's package."""
    tag, runtime_tag = tags
    package, slave_package, module = f"{RUNTIME_PREFIX}{runtime_tag}", f"{SLAVE_PREFIX}{tag}", f"{loader.prefix}{tag}"
    package_dir, slave_dir = Path(folder) / package, Path(folder) / slave_package
    shutil.copytree(runtime, package_dir, ignore=shutil.ignore_patterns(*COMPILED_ARTIFACTS))
    slave_dir.mkdir()
    (slave_dir / "__init__.py").write_text(SLAVE_PACKAGE_INIT.format(runtime=package,
                                                                     packed=implementation.PACKED))
    interface_code = rewrite_once(interface, r"\bstickslip\.core\b", package,
                                  "the runtime as 'from stickslip.core import ...'")
    (slave_dir / "block_interface.py").write_text(
        rewrite_once(interface, r"\bstickslip\.fmu_src\.loader_binding\b", f"{slave_package}.loader_binding",
                     "the loader binding as 'from stickslip.fmu_src.loader_binding import ...'", interface_code))
    shutil.copyfile(LOADER_BINDING, slave_dir / LOADER_BINDING.name)
    slave_code = rewrite_once(slave, r"\bstickslip\.core\b", package, "the runtime as 'from stickslip.core import ...'",
                              optional=True)
    slave_code = rewrite_once(slave, r"\bfrom block_interface import\b", f"from {slave_package}.block_interface import",
                              "the shared table as 'from block_interface import ...'", slave_code)
    (slave_dir / "fmu_slave.py").write_text(slave_code)
    script = Path(folder) / f"{module}.py"
    script.write_text(loader.template.format(package=slave_package, model_name=model_name,
                                             archive=PACKAGE_ARCHIVE.format(package=library),
                                             slave_archive=PACKAGE_ARCHIVE.format(package=slave_package)))
    staged = StagedRuntime(script, package_dir, slave_dir, module)
    if compiled:
        staged.extra_files.update(_compiled(Path(folder), package))
    return staged


def rewrite_once(path, pattern, replacement, what, code=None, optional=False):
    """``code`` (default: the text of ``path``) with ``pattern`` replaced; StagingError unless it occurs once
    (or, if ``optional``, at most once)."""
    code, count = re.subn(pattern, replacement, Path(path).read_text() if code is None else code)
    if count > 1 or (count == 0 and not optional):
        raise StagingError(f"{path} must import {what} {'at most' if optional else 'exactly'} once")
    return code


#: {runtime package: why it stays pure Python}, for the builds of this process (said once, on the first)
_NOT_COMPILED = {}
#: the runtime packages whose compiled versions this process has said
_ANNOUNCED = set()


def _compiled(folder, package):
    """The compiled modules of ``folder/package`` (those the package brought, :data:`PREBUILT`, else from the cache
    or compiled now): ``{archive name: path}``; none if it cannot be compiled (the build says why once)."""
    cache = PREBUILT / prebuilt_key(package)
    if not (cache / COMPLETE).is_file():
        cache = CACHE / f"{prebuilt_key(package)}-{toolchain_tag()}"
    if package in _NOT_COMPILED:
        return {}
    if not (cache / COMPLETE).is_file():
        start = time.monotonic()
        try:
            files = compile_in_place(folder, package, announce=lambda: print(
                f"stickslip: compiling the FMUs' runtime {package} with mypyc ({len(COMPILED_MODULES)} modules, once "
                f"for every FMU built from it; kept in {CACHE}) ...", file=sys.stderr))
        except CompileError as exc:
            _NOT_COMPILED[package] = str(exc)
            print(f"stickslip: the FMUs' runtime stays pure Python (same results, slower): {exc}", file=sys.stderr)
            return {}
        print(f"stickslip: ... compiled in {time.monotonic() - start:.0f} s", file=sys.stderr)
        store(files, folder, cache)
    others = sorted(other for platform in (sysconfig.get_platform(), WINDOWS_PLATFORM)
                    for other in OTHER_PYTHONS.glob(f"{package}-*-{platform}")
                    if (other / COMPLETE).is_file() and other.name != prebuilt_key(package))
    if package not in _ANNOUNCED:
        _ANNOUNCED.add(package)
        versions = [_python_version(sys.implementation.cache_tag), *(_python_version(o.name) for o in others)]
        print(f"stickslip: the FMUs' runtime {package} is compiled for CPython {', '.join(versions)} (other versions "
              f"run its sources; more: python scripts/other_pythons.py compile)", file=sys.stderr)
    out = {}
    for source in (cache, *others):
        for path in source.rglob("*"):
            if path.is_file() and path.name not in (COMPLETE, MYPY_LICENSE):
                relative = path.relative_to(source)
                shutil.copy2(path, folder / relative)
                out[f"resources/{relative.as_posix()}"] = folder / relative
    return out


def _python_version(tag):
    """"3.13" of a name holding the cache tag ``cpython-313``, "3.13 on Windows" of one compiled for Windows."""
    digits = re.search(r"cpython-(\d)(\d+)", tag)
    return f"{digits[1]}.{digits[2]}{' on Windows' if tag.endswith(WINDOWS_PLATFORM) else ''}"


def byte_compile(package_dir):
    """Unchecked-hash ``.pyc`` of every module in ``package_dir``: ``{archive name: path}``.

    They name their sources ``<package>/<module>.py``, not the build folder (importing them names the real path).
    A new interpreter writes them, without ``site`` and with a fixed hash seed: marshal's bytes depend on the
    interpreter's state (which objects other modules also hold, the order of sets), so only then do two builds
    write the same bytes.
    """
    command = [sys.executable, "-S", "-s", "-m", "compileall", "-q", "-d", package_dir.name,
               "--invalidation-mode", "unchecked-hash", str(package_dir)]
    run = subprocess.run(command, env={**os.environ, "PYTHONHASHSEED": "0"}, capture_output=True, text=True)
    if run.returncode != 0:
        raise StagingError(f"byte-compiling {package_dir} failed: {(run.stdout + run.stderr).strip()[-2000:]}")
    return {f"resources/{path.relative_to(package_dir.parent).as_posix()}": path
            for path in package_dir.glob("__pycache__/*.pyc")}
