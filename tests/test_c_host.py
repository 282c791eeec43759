"""The FMUs outside Python: plain C importers (``stickslip.c_host``, FMI 2 and FMI 3 co-simulation) open their
Linux binaries with ``dlopen(RTLD_NOW | RTLD_LOCAL)``, nothing preloaded, and drive them as FMPy does.

Every run is a child process (a crash shows as a return code, not a dead pytest),
started with only ``PATH`` from this environment. Its results are compared with
FMPy driving the same FMU here (bit for bit). Also: what a user of
``fmpy.simulate_fmu`` with default settings sees for a bad parameter, other
CPython versions through ``SBF_LIBPYTHON``, and the build without a C compiler.
"""

import glob
import math
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

import pythonfmu
import pythonfmu3
from stickslip.hosts.c_host import run_host
from stickslip.hosts.fmpy_host import run_fmu
from stickslip.fmu import build, staging
from stickslip.fmu.loader import LIBPYTHON_VARIABLE
from stickslip.fmu.loader.install import build_libpython
from stickslip.suite.scenario import load_scenario
from stickslip.stress.session import FmuCallError, FmuSession, fmi2Error

import machine_needs

SCENE = load_scenario(Path(__file__).resolve().parents[1] / "scenarios" / "elmer-fig3-v0.1.toml")
START = SCENE.start_values()
SHORT = 20.0  # s: stop time of the runs that check behaviour rather than the whole scene
BAD_MASS = "M = -1.0 kg is out of range: allowed is a finite value in (0, inf)"
PYTHONFMU_BINARY = Path(pythonfmu.__file__).parent / "resources" / "binaries" / "linux64" / "libpythonfmu-export.so"


@pytest.fixture(scope="module")
def folder(unzipped):
    return unzipped[0]


@pytest.fixture(scope="module")
def fmpy_x(fmu_path):
    """FMPy's (times, x) of the scene up to ``stop`` s, memoized."""
    runs = {}

    def x(stop):
        if stop not in runs:
            result = run_fmu(fmu_path, START, stop, SCENE.output_interval, outputs=["x"])
            runs[stop] = (list(result["time"]), list(result["x"]))
        return runs[stop]

    return x


def completed(run):
    assert run.completed, f"host exit {run.returncode}: {run.lines[-3:]} {run.logs} {run.stderr[-2000:]}"
    return run


def test_the_linux_binary_is_the_loader_with_pythonfmus_binary_beside_it(fmu_path):
    machine_needs.c_compiler("the FMU's Linux loader")
    pythonfmu_binary = PYTHONFMU_BINARY.read_bytes()
    with zipfile.ZipFile(fmu_path) as fmu:
        assert fmu.read("binaries/linux64/SpringBlockFriction_pythonfmu.so") == pythonfmu_binary
        assert fmu.read("binaries/linux64/SpringBlockFriction.so") != pythonfmu_binary


def test_elmer_fig3_in_the_c_host_is_bit_identical_to_fmpy(host, folder, fmpy_x):
    run = completed(run_host(host, folder, "run", SCENE.stop_time, SCENE.output_interval, START))
    assert run.series("x") == fmpy_x(SCENE.stop_time)
    assert run.logs == []  # logging off and nothing wrong: the host's logger hears nothing


def test_bad_parameter_with_logging_off_names_it_and_the_host_goes_on(host, folder, fmpy_x):
    settings = [*START.items(), ("M", -1.0)]  # the second instance gets all but the last
    run = completed(run_host(host, folder, "bad", SHORT, SCENE.output_interval, settings))
    assert int(run.value("status")[1]) == 3  # fmi2Error, at fmi2ExitInitializationMode
    errors = [text for status, instance, text in run.logs if instance == "bad" and status == 3]
    assert any(BAD_MASS in text for text in errors), run.logs
    # the bad instance was freed; a new one (valid M) runs normally in the same process
    assert [log for log in run.logs if log[1] != "bad"] == []
    assert run.series("x") == fmpy_x(SHORT)


def test_after_a_bad_parameter_fmi2Reset_makes_the_instance_usable_again(host, folder, fmpy_x):
    settings = [*START.items(), ("M", -1.0)]  # after the reset: all but the last
    run = completed(run_host(host, folder, "reset", SHORT, SCENE.output_interval, settings))
    statuses = [line[1:] for line in run.lines if line[0] == "status"]
    assert statuses == [["exit", "3"], ["reset", "0"]]
    assert [status for status, _, _ in run.logs] == [3]
    assert run.series("x") == fmpy_x(SHORT)


@pytest.mark.parametrize("mode", ["two", "threads"])
def test_two_instances_on_one_thread_and_on_two_threads(host, folder, fmpy_x, mode):
    """"two": stepped alternately on one thread; "threads": each on its own thread at the same time."""
    run = completed(run_host(host, folder, mode, SHORT, SCENE.output_interval, START))
    assert run.series("a") == fmpy_x(SHORT)
    assert run.series("b") == fmpy_x(SHORT)


def test_get_set_and_serialized_state_replay_exactly(host, folder, fmpy_x):
    run = completed(run_host(host, folder, "state", SHORT, SCENE.output_interval, START))
    times, x = fmpy_x(SHORT)
    second_half = (times[len(times) // 2 + 1:], x[len(x) // 2 + 1:])
    assert run.series("x") == second_half
    assert run.series("r") == second_half  # after fmi2SetFMUstate
    assert run.series("d") == second_half  # after fmi2SerializeFMUstate / fmi2DeSerializeFMUstate


def test_fifty_instantiate_free_cycles_in_one_process(host, folder, fmpy_x):
    stop = 2.0
    run = completed(run_host(host, folder, "cycles", stop, SCENE.output_interval, START, env={"HOST_CYCLES": "50"}))
    ends = [(float(t), float(x)) for _, _, t, x in (line for line in run.lines if line[0] == "c")]
    times, x = fmpy_x(stop)
    assert ends == [(times[-1], x[-1])] * 50


def test_a_libpython_that_cannot_be_found_is_a_logged_error_not_a_crash(host, folder):
    missing = "/nonexistent/libpython3.11.so.1.0"
    run = run_host(host, folder, "run", SHORT, SCENE.output_interval, START, env={LIBPYTHON_VARIABLE: missing})
    assert run.lines == [["failed", "fmi2Instantiate", "NULL"]]  # the host got NULL and ended on its own
    assert run.returncode == 1
    [(status, _, text)] = run.logs
    assert status == 4 and f"{LIBPYTHON_VARIABLE}={missing}" in text and "cannot open shared object" in text


def test_a_pythonhome_for_another_python_does_not_reach_an_installations_cpython(host, folder, fmpy_x):
    """With a CPython of an installation (the build's, named by SBF_LIBPYTHON), as with the one the FMU carries
    (tests/test_loader_host_python.py): the loader's CPython reads no environment variable."""
    run = run_host(host, folder, "run", SHORT, SCENE.output_interval, START,
                   env={"PYTHONHOME": "/nonexistent", LIBPYTHON_VARIABLE: build_libpython()[0]})
    assert completed(run).series("x") == fmpy_x(SHORT)


OTHER_PYTHONS = sorted(glob.glob("/root/.pyenv/versions/3.*/lib/libpython3.*.so.1.0")
                       + glob.glob("/usr/lib/x86_64-linux-gnu/libpython3.*.so.1.0"))


@pytest.mark.skipif(not OTHER_PYTHONS, reason="no other CPython shared library on this machine")
@pytest.mark.parametrize("libpython", OTHER_PYTHONS, ids=lambda path: path.split("/")[-1] + path.split("/")[1])
def test_other_cpythons_through_the_override(host, folder, fmpy_x, libpython):
    """CPython 3.8 and newer run the scene; 3.10 to 3.13 bit for bit like FMPy (3.11), 3.8 and 3.9 within
    rounding (their float arithmetic in the runtime differs in the last bits); older ones are refused."""
    run = run_host(host, folder, "run", SHORT, SCENE.output_interval, START, env={LIBPYTHON_VARIABLE: libpython})
    version = tuple(int(p) for p in Path(libpython).name[len("libpython"):].split(".so")[0].rstrip("m").split("."))
    if version < (3, 8):
        assert run.lines == [["failed", "fmi2Instantiate", "NULL"]] and run.returncode == 1
        assert "; this FMU needs CPython 3.8 or newer" in run.logs[0][2]
        return
    times, x = completed(run).series("x")
    expected_times, expected_x = fmpy_x(SHORT)
    assert times == expected_times
    if version >= (3, 10):
        assert x == expected_x
    else:
        np.testing.assert_allclose(x, expected_x, rtol=0, atol=1e-12)


@pytest.mark.parametrize("name, value, expected", [
    ("M", -1.0, BAD_MASS),
    ("F_ext", 1e200, "|F_ext| = 1e+200 N (F_ext = 1e+200 N) is out of range: allowed is at most 1e+150 N"),
    ("F_ext", math.nan, "F_ext = nan N is out of range: allowed is a finite value in (-inf, inf)"),
], ids=["bad-parameter", "overflowing-input", "nan-input"])
def test_with_logging_off_fmpy_gets_the_error_and_its_message(fmu_path, name, value, expected):
    """FMPy's FMU2Slave with loggingOn = false: a bad parameter (at fmi2ExitInitializationMode) or input (at
    fmi2DoStep) is fmi2Error, and the logger received the message naming the variable and its range."""
    machine_needs.c_compiler("the FMU's Linux loader")
    stick_slip = {"kinetic.F0": 0.5, "static.F0": 1.0, "v_start": 0.1}
    parameter = {name: value} if name == "M" else {}
    with FmuSession(fmu_path) as session:
        inst = None
        try:
            inst = session.instantiate(session.start_values({**stick_slip, **parameter}), logging_on=False)
            inst.do_step(0.5)
            inst.set_value(name, value)
            inst.do_step(0.5)
        except FmuCallError as exc:
            error = exc
        finally:
            if inst is not None:
                inst.free()  # terminated and freed after fmi2Error
        assert error.status == fmi2Error
        assert error.function == ("fmi2ExitInitializationMode" if name == "M" else "fmi2SetReal")
        assert any(expected in message for message in error.messages), error.messages


def test_fmpy_default_settings_show_the_message_naming_the_parameter(fmu_path):
    """``fmpy.simulate_fmu`` with no logger and logging off prints the FMU's error before raising."""
    machine_needs.c_compiler("the FMU's Linux loader")
    code = ("import fmpy, sys\n"
            "try:\n"
            f"    fmpy.simulate_fmu({str(fmu_path)!r}, stop_time=1.0, start_values={{'M': -1.0}})\n"
            "except Exception as exc:\n"
            "    print('raised', exc)\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert "[ERROR] " in result.stdout and BAD_MASS in result.stdout
    assert "raised fmi2ExitInitializationMode failed with status 3 (error)" in result.stdout


def test_without_a_c_compiler_the_build_keeps_pythonfmus_binary_and_says_so(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    # where the runtime is compiled neither in the package nor in the cache for this compiler, the build records
    # that it stays pure: for this test only, not for the builds the process makes after it
    monkeypatch.setattr(staging, "_NOT_COMPILED", {})
    fmu = build(tmp_path / "SpringBlockFriction.fmu")
    assert "keeps PythonFMU's linux64 binary" in capsys.readouterr().err
    pythonfmu_binary = PYTHONFMU_BINARY.read_bytes()
    with zipfile.ZipFile(fmu) as archive:
        assert archive.read("binaries/linux64/SpringBlockFriction.so") == pythonfmu_binary
        assert "binaries/linux64/SpringBlockFriction_pythonfmu.so" not in archive.namelist()


# ---------------------------------------------------------------------------
# the FMI 3 FMU in the FMI 3 C host (co-simulation)
# ---------------------------------------------------------------------------

PYTHONFMU3_BINARY = (Path(pythonfmu3.__file__).parent / "resources" / "binaries" / "x86_64-linux"
                     / "libpythonfmu-export.so")


@pytest.fixture(scope="module")
def fmpy3_x(fmu3_path):
    """FMPy's (times, x) of the scene through the FMI 3 FMU's co-simulation up to ``stop`` s, memoized."""
    runs = {}

    def x(stop):
        if stop not in runs:
            result = run_fmu(fmu3_path, START, stop, SCENE.output_interval, interface="cs", outputs=["x"])
            runs[stop] = (list(result["time"]), list(result["x"]))
        return runs[stop]

    return x


def test_the_fmi3_linux_binary_is_the_loader_with_pythonfmu3s_binary_beside_it(fmu3_path):
    machine_needs.c_compiler("the FMU's Linux loader")
    with zipfile.ZipFile(fmu3_path) as fmu:
        assert fmu.read("binaries/x86_64-linux/SpringBlockFriction_pythonfmu.so") == PYTHONFMU3_BINARY.read_bytes()
        assert fmu.read("binaries/x86_64-linux/SpringBlockFriction.so") != PYTHONFMU3_BINARY.read_bytes()


def test_elmer_fig3_in_the_fmi3_c_host_is_bit_identical_to_fmpy(host3, unzipped3, fmpy3_x):
    run = completed(run_host(host3, unzipped3[0], "run", SCENE.stop_time, SCENE.output_interval, START))
    assert run.series("x") == fmpy3_x(SCENE.stop_time)
    assert run.logs == []


def test_fmi3_bad_parameter_with_logging_off_names_it_and_the_host_goes_on(host3, unzipped3, fmpy3_x):
    settings = [*START.items(), ("M", -1.0)]  # the second instance gets all but the last
    run = completed(run_host(host3, unzipped3[0], "bad", SHORT, SCENE.output_interval, settings))
    assert int(run.value("status")[1]) == 3  # fmi3Error, at fmi3ExitInitializationMode
    assert [(status, instance) for status, instance, _ in run.logs] == [(3, "bad")]
    assert BAD_MASS in run.logs[0][2]
    assert run.series("x") == fmpy3_x(SHORT)  # the bad instance was freed; a new one runs normally


def test_fmi3_a_libpython_that_cannot_be_found_is_a_logged_error_not_a_crash(host3, unzipped3):
    missing = "/nonexistent/libpython3.11.so.1.0"
    run = run_host(host3, unzipped3[0], "run", SHORT, SCENE.output_interval, START, env={LIBPYTHON_VARIABLE: missing})
    assert run.lines == [["failed", "fmi3InstantiateCoSimulation", "NULL"]]
    assert run.returncode == 1
    [(status, _, text)] = run.logs
    assert status == 4 and f"{LIBPYTHON_VARIABLE}={missing}" in text


# ---------------------------------------------------------------------------
# process exit (both FMUs)
# ---------------------------------------------------------------------------

VALGRIND = shutil.which("valgrind")


@pytest.mark.skipif(VALGRIND is None, reason="valgrind is not installed")
@pytest.mark.parametrize("fmi_version", [2, 3])
def test_no_invalid_memory_access_up_to_the_process_exit(request, unzipped, unzipped3, fmi_version):
    """PythonFMU's and pythonfmu3's binaries destroy their Python start-up object twice at exit (a write into
    freed memory after which glibc aborted 2 of 14 test runs); the loader resets it once before. memcheck
    reports that write in the C host unless the loader does (checked by removing its exit handler)."""
    host = request.getfixturevalue("host" if fmi_version == 2 else "host3")  # skipped where it cannot be built
    folder = (unzipped if fmi_version == 2 else unzipped3)[0]
    run = run_host(host, folder, "run", 1.0, 0.5, START, wrapper=[VALGRIND, "--error-exitcode=99"])
    assert completed(run).series("x")[0] == [0.0, 0.5, 1.0]
    assert "ERROR SUMMARY: 0 errors" in run.stderr, run.stderr[-3000:]
