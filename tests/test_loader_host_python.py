"""Which CPython the loader runs the FMU's Python code in, and what of the host's environment reaches it: a host
process whose own CPython is older than the FMU's Python code needs (FMI 2: 3.8, FMI 3: 3.9), or an
``SBF_LIBPYTHON`` naming one, is refused with the version found and the version needed, before anything is imported
(pythonfmu3's import under 3.8 crashed the host); every ``PYTHON*`` variable, set to junk, neither stops nor changes
the CPython the FMU carries. Every host is a child process whose exit status is checked. The older Pythons are
pyenv's (skipped where pyenv lacks them)."""

import subprocess
from pathlib import Path

import pytest

from stickslip.fmu.loader import LIBPYTHON_VARIABLE
from stickslip.fmu.bundle.floors import PYTHON_FLOORS
from stickslip.hosts.c_host import run_host

PYENV = Path.home() / ".pyenv" / "versions"
HOST = Path(__file__).resolve().with_name("instantiate_host.py")
STUCK = {"v_start": 0.1}  # the default block, stuck: x = 0.1 t
#: every environment variable CPython 3.8-3.13 reads (its -E ignores them all), each with a value it refuses or
#: that would change what it does
JUNK = {name: "junk" for name in (
    "PYTHONHOME", "PYTHONPATH", "PYTHONSTARTUP", "PYTHONOPTIMIZE", "PYTHONBREAKPOINT", "PYTHONDEBUG",
    "PYTHONINSPECT", "PYTHONUNBUFFERED", "PYTHONVERBOSE", "PYTHONCASEOK", "PYTHONDONTWRITEBYTECODE",
    "PYTHONPYCACHEPREFIX", "PYTHONHASHSEED", "PYTHONINTMAXSTRDIGITS", "PYTHONIOENCODING", "PYTHONNOUSERSITE",
    "PYTHONUSERBASE", "PYTHONEXECUTABLE", "PYTHONWARNINGS", "PYTHONFAULTHANDLER", "PYTHONTRACEMALLOC",
    "PYTHONPROFILEIMPORTTIME", "PYTHONASYNCIODEBUG", "PYTHONMALLOC", "PYTHONMALLOCSTATS", "PYTHONLOCALE",
    "PYTHONCOERCECLOCALE", "PYTHONDEVMODE", "PYTHONUTF8", "PYTHONWARNDEFAULTENCODING", "PYTHONNODEBUGRANGES",
    "PYTHONPERFSUPPORT", "PYTHONSAFEPATH", "PYTHONPLATLIBDIR", "PYTHON_CPU_COUNT", "PYTHON_FROZEN_MODULES",
    "PYTHON_GIL", "PYTHON_COLORS", "PYTHON_BASIC_REPL", "PYTHON_HISTORY", "PYTHONLEGACYWINDOWSFSENCODING",
    "PYTHONLEGACYWINDOWSSTDIO", "PYTHONTHREADDEBUG", "PYTHONDUMPREFS", "PYTHON_PERF_JIT_SUPPORT")}


def pyenv_python(version):
    """pyenv's CPython ``version`` ("3.8"): (its interpreter, its shared library); skips where pyenv has none."""
    found = sorted(PYENV.glob(f"{version}.*/bin/python{version}"))
    if not found:
        pytest.skip(f"pyenv has no CPython {version} under {PYENV}")
    library = next(found[-1].parent.parent.glob("lib/libpython3*.so.1.0"), None)
    return found[-1], library


@pytest.fixture(params=[2, 3], ids=["fmi2", "fmi3"])
def fmu(request):
    """(FMI version, the extracted FMU's folder, the C host of that version)"""
    suffix = "" if request.param == 2 else "3"
    return (request.param, request.getfixturevalue(f"unzipped{suffix}")[0],
            request.getfixturevalue(f"host{suffix}"))


@pytest.mark.parametrize("version", ["3.6", "3.7", "3.8", "3.9"])
def test_a_host_with_an_older_python_is_refused_naming_both_versions(fmu, version):
    fmi, folder, _ = fmu
    python, _ = pyenv_python(version)
    run = subprocess.run([str(python), str(HOST), str(folder)], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]  # no crash
    lines = run.stdout.splitlines()
    floor = PYTHON_FLOORS[fmi]
    if tuple(int(part) for part in version.split(".")) >= floor:
        assert lines[-1] == "instance made", run.stdout
        return
    full = subprocess.run([str(python), "-c", "import platform; print(platform.python_version())"],
                          capture_output=True, text=True, check=True).stdout.strip()
    assert lines == [f"log 4 the host process's own CPython is version {full}; this FMU needs CPython "
                     f"{floor[0]}.{floor[1]} or newer: run it in a host process with a newer CPython, or in one "
                     "without Python (the FMU then starts its own)", "instance NULL"]


def test_sbf_libpython_naming_an_older_python_is_refused(fmu):
    fmi, folder, host = fmu
    _, library = pyenv_python("3.8")
    if library is None:
        pytest.skip("pyenv's CPython 3.8 is not built shared")
    run = run_host(host, folder, "run", 1.0, 0.5, STUCK, env={LIBPYTHON_VARIABLE: str(library)})
    if fmi == 2:  # it runs the FMI 2 FMU
        assert run.completed, (run.returncode, run.logs, run.stderr[-2000:])
        return
    assert run.returncode == 1 and run.lines == [["failed", "fmi3InstantiateCoSimulation", "NULL"]]
    assert [text for _, _, text in run.logs] == [
        f"{library} is version 3.8.{library.parent.parent.name.split('.')[2]}; this FMU needs CPython 3.9 or newer: "
        f"point {LIBPYTHON_VARIABLE} at a newer CPython's shared library, or unset it"]


@pytest.mark.parametrize("variable", sorted(JUNK))
def test_a_junk_python_variable_changes_nothing(fmu, variable):
    """The FMU's own CPython (no SBF_LIBPYTHON, not a Python host) starts as without the variable: the same
    results, nothing on stderr."""
    _, folder, host = fmu
    plain = run_host(host, folder, "run", 1.0, 0.5, STUCK)
    run = run_host(host, folder, "run", 1.0, 0.5, STUCK, env={variable: JUNK[variable]})
    assert run.completed, (run.returncode, run.logs, run.stderr[-2000:])
    assert run.lines == plain.lines and run.stderr == plain.stderr == ""
