"""The FMUs' runtime compiled for Windows on Linux (``src/stickslip/fmu/windows_runtime.py``: mypyc's C for CPython
3.13, cross-compiled with MinGW-w64): the FMU carries it beside the Linux files, python.org's embeddable CPython 3.13
imports it under Wine in the project's C host built for Windows (not the runtime's sources), and it gives the numbers
of the runtime's sources there and of the Linux host, bit for bit. Compiled as ``scripts/other_pythons.py compile``
does, in a venv of pyenv's CPython 3.13 with the build's mypy (``.venv-pythons/3.13-compile``, made once, about 1
minute), into a folder of the tests' own in the user's cache (kept there, like the build's: compiled once per
runtime), not the one ``scripts/other_pythons.py compile`` fills, whose runtimes every FMU built after it carries:
the other tests' FMUs, built before or after this test or beside it in another process, stay the same bytes.
Skipped, with the reason, where pyenv has
no CPython 3.13 or Wine, MinGW-w64 or the embeddable Python are missing (scripts/test.sh installs them). Also: without
the cross-compiler the Windows runtime is not compiled, saying why."""

import importlib.metadata
import importlib.util
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from stickslip.fmu import build, compile_runtime, windows_runtime
from stickslip.fmu import staging

import machine_needs
from test_windows_loader import SCENE, START, folders, linux_run, wine_env, windows_hosts, windows_run  # noqa: F401

REPO = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("other_pythons", REPO / "scripts" / "other_pythons.py")
other_pythons = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(other_pythons)
WINDOWS_PYTHON = ".".join(map(str, windows_runtime.WINDOWS_PYTHON))
#: the FMU's compiled files for Windows CPython 3.13: the suffix of their names
SUFFIX = f".cp{WINDOWS_PYTHON.replace('.', '')}-win_amd64.pyd"
#: the runtimes compiled here, in place of staging.OTHER_PYTHONS for this module's build only
OTHER_PYTHONS = staging.CACHE / "tests-other-pythons"


@pytest.fixture(scope="module")
def windows_fmu(tmp_path_factory):
    """The extracted FMI 2 FMU, built with the runtime compiled for Windows (compiled first if the cache lacks it),
    and the runtime's package name."""
    machine_needs.windows_cc("the runtime compiled for Windows")
    python = other_pythons.pyenv_pythons().get(WINDOWS_PYTHON)
    if python is None:
        pytest.skip(f"compiling the runtime for Windows needs CPython {WINDOWS_PYTHON}: pyenv has none under "
                    f"{other_pythons.PYENV_VERSIONS}")
    package = compile_runtime.RUNTIME_PREFIX + compile_runtime.runtime_tag()
    name = f"{package}-cpython-{WINDOWS_PYTHON.replace('.', '')}-{compile_runtime.WINDOWS_PLATFORM}"
    pins = [f"{tool}=={importlib.metadata.version(tool)}" for tool in ("mypy", "setuptools")]
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(staging, "OTHER_PYTHONS", OTHER_PYTHONS)
        other_pythons.compile_with(python, REPO / ".venv-pythons" / f"{WINDOWS_PYTHON}-compile", pins,
                                   Path(windows_runtime.__file__), name, f"CPython {WINDOWS_PYTHON} on Windows")
        assert (OTHER_PYTHONS / name / compile_runtime.COMPLETE).is_file()
        fmu = build(tmp_path_factory.mktemp("windows_compiled") / "SpringBlockFriction.fmu")
    folder = fmu.with_suffix("")
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(folder)
    return folder, package


def test_the_fmu_carries_the_runtime_compiled_for_windows_beside_linuxs(windows_fmu):
    folder, package = windows_fmu
    resources = folder / "resources"
    for name in compile_runtime.COMPILED_MODULES:
        assert (resources / package / f"{name}{SUFFIX}").is_file()
        assert list((resources / package).glob(f"{name}.cpython-*-linux-gnu.so"))
    groups = list(resources.glob(f"*__mypyc{SUFFIX}"))
    assert len(groups) == 1
    imports = subprocess.run(["x86_64-w64-mingw32-objdump", "-p", str(groups[0])], capture_output=True, text=True)
    assert imports.returncode == 0
    dlls = {line.split(":")[1].strip().lower() for line in imports.stdout.splitlines() if "DLL Name:" in line}
    assert dlls == {f"python{WINDOWS_PYTHON.replace('.', '')}.dll", "kernel32.dll", "msvcrt.dll"}


def test_windows_cpython_imports_the_compiled_runtime_and_gets_the_numbers_of_its_sources_and_of_linux(
        wine_env, windows_hosts, windows_fmu, host):
    folder, package = windows_fmu
    verbose = {"SBF_PYTHON_VERBOSE": "1"}  # Python says on stderr from which file it imports each module
    compiled = windows_run(wine_env, windows_hosts, 2, folder, "run", SCENE.stop_time, env=verbose)
    pure = windows_run(wine_env, windows_hosts, 2, folder, "run", SCENE.stop_time,
                       env={**verbose, "STICKSLIP_PURE_PYTHON": "1"})
    linux = linux_run({2: host}, 2, folder, "run", SCENE.stop_time)
    compiled_imports, pure_imports = imports(compiled.stderr, package), imports(pure.stderr, package)
    group = next(folder.glob(f"resources/*__mypyc{SUFFIX}")).name.removesuffix(SUFFIX)
    assert f"extension module '{group}' loaded from " in compiled.stderr and group not in pure.stderr
    # compiled modules that import each other do so inside the group library, without Python's import system
    assert {compiled_imports.get(name) for name in compile_runtime.COMPILED_MODULES} == {SUFFIX, None}
    assert {pure_imports[name] for name in compile_runtime.COMPILED_MODULES} == {".py"}
    (times, x), (pure_times, pure_x), (linux_times, linux_x) = (run.series("x") for run in (compiled, pure, linux))
    assert times == pure_times == linux_times and len(x) == round(SCENE.stop_time / SCENE.output_interval) + 1
    assert x == pure_x == linux_x


def imports(stderr, package):
    """{module of ``package``: the end of the file name Python imported it from} of a host's stderr with
    ``SBF_PYTHON_VERBOSE=1``: ``.py`` for a module imported from its source, the suffix of an extension module's file."""
    sources = {name: ".py"  # from a file, or from the runtime's packed sources (no byte code of these Pythons there)
               for name in re.findall(rf"^import '{package}\.(\w+)' # <(?:\w+\.SourceFileLoader|zipimporter )",
                                      stderr, re.M)}
    extensions = {name: SUFFIX if path.endswith(SUFFIX) else Path(path).suffix
                  for name, path in re.findall(rf"^# extension module '{package}\.(\w+)' loaded from '(.*)'$", stderr,
                                               re.M)}
    return {**sources, **extensions}


def test_without_the_cross_compiler_the_windows_runtime_is_not_compiled_and_says_why(tmp_path):
    run = subprocess.run([sys.executable, windows_runtime.__file__, str(Path(compile_runtime.__file__).parents[1] /
                                                                        "core"), str(tmp_path / "out")],
                         env={"PATH": "/usr/bin:/bin", "SBF_WINDOWS_CC": str(tmp_path / "no-such-cc")},
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 1
    assert f"not compiled for Windows: {tmp_path / 'no-such-cc'}" in run.stderr and "mingw-w64" in run.stderr
    assert not (tmp_path / "out").exists()


def test_the_external_dependencies_list_each_compiled_pyd_and_what_it_needs(windows_fmu):
    """Each compiled module for Windows has its line in documentation/externalDependencies.txt, with the CPython DLL
    it imports, and what those DLLs are is said above (the FMU's own CPython, the UCRT, Windows itself)."""
    folder, package = windows_fmu
    text = (folder / "documentation" / "externalDependencies.txt").read_text()
    pyds = sorted(str(path.relative_to(folder)) for path in (folder / "resources").rglob(f"*{SUFFIX}"))
    assert len(pyds) == len(compile_runtime.COMPILED_MODULES) + 1  # and the group library
    lines = {line.split(": ", 1)[0]: line for line in text.splitlines() if line.startswith("resources/")}
    for name in pyds:
        assert lines.get(name, "").endswith(f"; python{WINDOWS_PYTHON.replace('.', '')}.dll, KERNEL32.dll, msvcrt.dll"), \
            lines.get(name)
    carried = next(line for line in text.splitlines() if line.startswith("- the FMU itself"))
    assert all(name in carried for name in pyds)  # among the binaries that need the FMU's own CPython
