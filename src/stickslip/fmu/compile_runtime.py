"""Compile the runtime's hot modules ahead of time with mypyc, from their Python sources.

Used at build time only, without importing ``stickslip`` (``setup.py`` loads this file by
path): by ``setup.py`` for the installed package, and by :mod:`stickslip.fmu.staging` for
the FMU's renamed copy (compiled under its final name ``sbf_runtime_<tag>``). mypyc makes
one shared library for the group (``<hash>__mypyc``, a top-level module) and a small
extension module per compiled module. The list of modules and the freshness stamp are
those of ``core/_implementation.py``, which picks the compiled or the pure modules at import.
Extensions are optional: without a working C compiler the build goes on, pure Python.
"""

import hashlib
import importlib.metadata
import importlib.util
import os
import subprocess
import sys
import sysconfig
from pathlib import Path

HERE = Path(__file__).resolve().parent
_spec = importlib.util.spec_from_file_location("_implementation", HERE.parent / "core" / "_implementation.py")
implementation = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(implementation)
COMPILED_MODULES = implementation.COMPILED_MODULES
#: what the FMU's compiled files are built with besides Python's flags, after them: no debug information
#: (``-g0`` overrides Python's ``-g``; GCC's code does not depend on it) and no symbol table (``-s``, the linker)
SIZE_FLAGS = {"CFLAGS": "-g0", "LDFLAGS": "-s"}


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
    """Record the digest of the sources the compiled modules are built from."""
    (Path(package_dir) / implementation.STAMP).write_text(implementation.sources_digest(package_dir) + "\n")


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
    missing = [name for name in ("mypyc", "setuptools") if importlib.util.find_spec(name) is None]
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
