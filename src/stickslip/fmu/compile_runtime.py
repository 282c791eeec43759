"""Compile the runtime's hot modules ahead of time with mypyc, from their Python sources.

Used at build time only, without importing ``stickslip`` (``setup.py`` loads this file by
path): by ``setup.py`` for the installed package and, beside it, the FMUs' renamed copy
(:func:`compile_fmu_runtime`, run as ``python compile_runtime.py CORE DEST``, compiled under its
final name ``sbf_runtime_<runtime tag>`` into the package's :data:`PREBUILT`), and by
:mod:`stickslip.fmu.staging` for that copy where the package brought none. mypyc makes
one shared library for the group (``<hash>__mypyc``, a top-level module) and a small
extension module per compiled module. The list of modules and the freshness stamp are
those of ``core/_implementation.py``, which picks the compiled or the pure modules at import.
Extensions are optional: without a working C compiler the build goes on, pure Python.
"""

import hashlib
import importlib.metadata
import importlib.util
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
_spec = importlib.util.spec_from_file_location("_implementation", HERE.parent / "core" / "_implementation.py")
implementation = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(implementation)
COMPILED_MODULES = implementation.COMPILED_MODULES
#: what the FMU's compiled files are built with besides Python's flags, after them: no debug information
#: (``-g0`` overrides Python's ``-g``; GCC's code does not depend on it) and no symbol table (``-s``, the linker)
SIZE_FLAGS = {"CFLAGS": "-g0", "LDFLAGS": "-s"}
#: the FMUs' runtime package: this prefix, then :func:`runtime_tag`
RUNTIME_PREFIX = "sbf_runtime_"
#: files of an in-place compiled ``stickslip/core`` (pip install -e) that never go into the FMUs' copy
COMPILED_ARTIFACTS = ("__pycache__", "*.pyc", "*.so", "*.pyd", implementation.STAMP)
#: ``sysconfig.get_platform()`` of 64-bit Windows, for which :mod:`windows_runtime` compiles the runtime on Linux
WINDOWS_PLATFORM = "win-amd64"
#: the FMUs' runtime compiled when the package was built (setup.py), one folder per :func:`prebuilt_key`
PREBUILT = HERE / "prebuilt"
#: the user's cache folder of stickslip (``$XDG_CACHE_HOME/stickslip``, default ``~/.cache/stickslip``): compiled
#: runtimes, the Windows CPython's package, FMUs built outside a checkout
USER_CACHE = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "stickslip"
#: the file that marks a folder of compiled files complete, and mypy's licence beside them (mypyc's C runtime is in
#: the compiled files: the FMUs' documentation carries it)
COMPLETE, MYPY_LICENSE = "complete", "mypy-license.txt"


def files_tag(paths):
    """10 hex digits of a sha256 over the names and contents of the files ``paths``, in that order."""
    digest = hashlib.sha256()
    for path in map(Path, paths):
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()[:10]


def runtime_tag(core=HERE.parent / "core"):
    """10 hex digits identifying the runtime as the FMUs carry it: the sources of ``core`` and the builder modules
    that lay it out and compile it. It names the FMUs' runtime package, which FMUs of the same runtime share."""
    sources = sorted(p for p in Path(core).rglob("*.py") if "__pycache__" not in p.parts)
    builders = ("staging.py", "compile_runtime.py", "windows_runtime.py", "trim.py")
    return files_tag([*sources, *(HERE / name for name in builders)])


def prebuilt_key(package):
    """The folder name of the compiled ``package`` for this Python and platform."""
    return f"{package}-{sys.implementation.cache_tag}-{sysconfig.get_platform()}"


class CompileError(RuntimeError):
    """The runtime could not be compiled (no mypyc, no C compiler, or a compile error)."""


def extensions(package_dir):
    """mypyc's optional setuptools extensions for the compiled modules of ``package_dir``, given relative to
    the current folder, which is the root of the import path (``src`` or the FMU's ``resources``)."""
    from mypyc.build import mypycify

    built = mypycify([os.path.join(package_dir, f"{name}.py") for name in COMPILED_MODULES], opt_level="3")
    for extension in built:
        extension.optional = True  # no compiler: setuptools warns and the package stays pure Python
    return built


def remove_compiled(root, package_dir):
    """Delete compiled modules and mypyc group libraries left in ``package_dir`` and ``root`` by earlier builds."""
    for path in [*Path(package_dir).glob("*.so"), *Path(package_dir).glob("*.pyd"),
                 *Path(root).glob("*__mypyc.*.so"), *Path(root).glob("*__mypyc.*.pyd"),
                 Path(package_dir) / implementation.STAMP]:
        path.unlink(missing_ok=True)


def write_stamp(package_dir):
    """Record the digest of the sources the compiled modules are built from (replaced atomically: a process that
    imports the runtime meanwhile, e.g. a test while another builds a wheel, reads the old stamp or the new)."""
    stamp = Path(package_dir) / implementation.STAMP
    partial = stamp.with_name(f".{stamp.name}.{os.getpid()}")
    partial.write_text(implementation.sources_digest(package_dir) + "\n")
    os.replace(partial, stamp)


def toolchain_tag():
    """A short hash of what decides the compiled bytes besides the sources: this file (how it compiles), the
    versions of mypy and setuptools (setuptools decides how ``$CFLAGS`` combines with Python's own flags),
    Python's compiler and flags, and the compiler variables of the environment. The compile cache keys on it, so a build never reuses files
    another toolchain compiled."""
    parts = [Path(__file__).read_text(), _version("mypy"), _version("setuptools")]
    parts += [str(sysconfig.get_config_var(name)) for name in ("CC", "CFLAGS", "LDSHARED")]
    parts += [os.environ.get(name, "") for name in ("CC", "CFLAGS", "LDFLAGS", "LDSHARED")]
    return hashlib.sha256("\0".join(parts).encode()).hexdigest()[:10]


def _version(distribution):
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return "none"


def store(files, root, target):
    """Copy the compiled ``files`` (paths below ``root``) to ``target`` (replaced), with mypy's licence, and mark it
    complete."""
    shutil.rmtree(target, ignore_errors=True)
    for path in files:
        destination = Path(target) / Path(path).relative_to(root)
        destination.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(path, destination)
    try:
        licence = [f for f in importlib.metadata.distribution("mypy").files or [] if f.name.startswith("LICENSE")]
    except importlib.metadata.PackageNotFoundError:
        licence = []
    if licence:
        (Path(target) / MYPY_LICENSE).write_text(licence[0].read_text(encoding="utf-8"), encoding="utf-8")
    (Path(target) / COMPLETE).write_text("")


def compile_fmu_runtime(core, dest):
    """Compile a copy of the runtime ``core`` as the FMUs' runtime package into ``dest/<key>`` (:func:`prebuilt_key`;
    ``dest`` is emptied first); raises CompileError."""
    package = RUNTIME_PREFIX + runtime_tag(core)
    shutil.rmtree(dest, ignore_errors=True)
    with tempfile.TemporaryDirectory(prefix="sbf_prebuild_") as tmp:
        shutil.copytree(core, Path(tmp) / package, ignore=shutil.ignore_patterns(*COMPILED_ARTIFACTS))
        store(compile_in_place(tmp, package), tmp, Path(dest) / prebuilt_key(package))
    return package


def main(argv):
    """``compile_runtime.py CORE DEST``: :func:`compile_fmu_runtime`; exit status 0 also when it cannot compile (the
    FMUs' builder then compiles it or leaves it pure Python, and says so)."""
    return run_saying(compile_fmu_runtime, argv, ("with the package", "(mypyc)"), failure_status=0)


def run_saying(compile_function, argv, wording, failure_status):
    """Run ``compile_function(*argv)`` (which returns the runtime's package name) and say on stderr what came of it;
    ``wording``: how the runtime was not compiled and how it was, in those sentences. The exit status: 0, or
    ``failure_status`` if it could not compile."""
    start = time.monotonic()
    try:
        package = compile_function(*argv)
    except CompileError as exc:
        print(f"stickslip: the FMUs' runtime was not compiled {wording[0]}: {exc}", file=sys.stderr)
        return failure_status
    print(f"stickslip: the FMUs' runtime {package} is compiled {wording[1]} in {time.monotonic() - start:.0f} s",
          file=sys.stderr)
    return 0


def missing_tools():
    """The packages that compiling needs and this environment lacks (mypyc, setuptools)."""
    return [name for name in ("mypyc", "setuptools") if importlib.util.find_spec(name) is None]


def compile_in_place(root, package, announce=None):
    """Compile ``root/package`` in place; its compiled files (paths), or CompileError saying why not.
    ``announce``: called once mypyc is found, before it runs.

    The C compiler maps ``root`` to ``.`` and mypyc's C runtime (in the environment's site-packages) to
    ``mypyc/lib-rt`` in the paths it records, so that the files do not depend on the folder they were compiled in
    nor on the environment; mypyc runs with a fixed hash seed (the order of sets). The files carry no debug
    information nor symbol table (:data:`SIZE_FLAGS`; the same machine code): every host extracts them before
    its first step.
    """
    package_dir = Path(root) / package
    missing = missing_tools()
    if missing:
        raise CompileError(f"{' and '.join(missing)} not installed in {sys.prefix} (pip compiles stickslip's own "
                           f"runtime in a build environment of its own; the FMUs' copy is compiled where they are "
                           f"built): pip install 'stickslip[compile]' (mypy, which brings mypyc, and setuptools)")
    if announce is not None:
        announce()
    remove_compiled(root, package_dir)
    script = (
        f"import importlib.util as u; s = u.spec_from_file_location('compile_runtime', {str(Path(__file__).resolve())!r}); "
        f"c = u.module_from_spec(s); s.loader.exec_module(c); "
        f"from setuptools import setup; "
        f"setup(ext_modules=c.extensions({package!r}), "
        f"script_args=['build_ext', '--inplace', '--quiet', '--parallel', '{os.cpu_count() or 1}'])"
    )
    try:
        lib_rt = Path(importlib.util.find_spec("mypyc").submodule_search_locations[0]) / "lib-rt"
        prefix_maps = f"-ffile-prefix-map={Path(root).resolve()}=. -ffile-prefix-map={lib_rt.resolve()}=mypyc/lib-rt"
        environment = {**os.environ, "PYTHONHASHSEED": "0",
                       "CFLAGS": f"{os.environ.get('CFLAGS', '')} {prefix_maps} {SIZE_FLAGS['CFLAGS']}".strip(),
                       "LDFLAGS": f"{os.environ.get('LDFLAGS', '')} {SIZE_FLAGS['LDFLAGS']}".strip()}
        run = subprocess.run([sys.executable, "-c", script], cwd=root, env=environment, capture_output=True,
                             text=True, timeout=1200)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise CompileError(f"mypyc did not run: {exc}") from exc
    modules = [path for name in COMPILED_MODULES for path in package_dir.glob(f"{name}.*.so")]
    groups = list(Path(root).glob("*__mypyc.*.so"))
    if run.returncode != 0 or len(modules) != len(COMPILED_MODULES) or not groups:
        tail = "\n".join((run.stderr or run.stdout).strip().splitlines()[-5:])
        raise CompileError(f"mypyc/C compilation failed (exit {run.returncode}): {tail}")
    write_stamp(package_dir)
    return [*modules, *groups, package_dir / implementation.STAMP]


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
