"""The loader across the life of a host process: unloading the FMU before the threads that called it end, two
FMUs started at the same time on two threads, resources folders whose names the FMI libraries would rewrite, and
Ctrl-C while the model runs. Every host runs in a child process whose exit status is asserted."""

import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from stickslip.fmu.coupling import ensure_coupling_fmu
from stickslip.hosts.c_host import host_command, run_host

STUCK = {"v_start": 0.1}  # the default block, stuck: x = 0.1 t - 0.01 after breakaway
RUNS = {"unload": 10, "pair": 20, "sigint": 20}  # processes per case
FOLDERS = ("100% done", "a%20b", "jürgen dir")


@pytest.fixture(scope="module")
def coupling_folder(tmp_path_factory):
    """The coupling FMU extracted."""
    folder = tmp_path_factory.mktemp("coupling") / "fmu"
    shutil.unpack_archive(str(ensure_coupling_fmu()), str(folder), "zip")
    return folder


def copy_of(folder, where):
    """A copy of the extracted FMU ``folder`` at ``where`` (a new folder)."""
    return shutil.copytree(folder, where)


@pytest.mark.parametrize("which", ["block", "block-fmi3", "coupling"])
def test_a_host_that_unloads_the_fmu_before_its_threads_end_exits_normally(request, coupling_folder, which):
    """Two threads each run an instance, the FMU is unloaded, then the threads end: the destructors of their Python
    thread states must find the loader still there (it crashed with SIGSEGV), in every one of the processes, for
    each FMU with the loader."""
    host, folder, output = {
        "block": lambda: (request.getfixturevalue("host"), request.getfixturevalue("unzipped")[0], "x"),
        "block-fmi3": lambda: (request.getfixturevalue("host3"), request.getfixturevalue("unzipped3")[0], "x"),
        "coupling": lambda: (request.getfixturevalue("host"), coupling_folder, "F")}[which]()
    codes = []
    for _ in range(RUNS["unload"]):
        run = run_host(host, folder, "unload", 2.0, 0.5, output=output, timeout=120)
        codes.append(run.returncode)
        assert run.completed, (run.returncode, run.stderr[-2000:])
        assert run.value("unloaded") == ["0"]
    assert codes == [0] * RUNS["unload"]
    alone = run_host(host, folder, "run", 2.0, 0.5, output=output)
    assert alone.completed
    points = sorted(tuple(line[1:]) for line in run.lines if line[0] in ("a", "b", "x"))
    assert points == sorted(2 * [tuple(line[1:]) for line in alone.lines if line[0] == "x"])


@pytest.mark.parametrize("second", ["copy", "fmi3", "coupling"])
def test_two_fmus_started_at_once_on_two_threads(request, host, unzipped, coupling_folder, tmp_path, second):
    """The FMI 2 block FMU on one thread and another FMU on another (a copy of it in another folder, the FMI 3 block
    FMU, or the coupling FMU), instantiated at the same moment: both start Python through their own loader, which
    must do it once for the process. Every run exits 0 with the results of each FMU run alone."""
    other, output, other_host = {
        "copy": lambda: (copy_of(unzipped[0], tmp_path / "copy"), "x", host),
        "fmi3": lambda: (request.getfixturevalue("unzipped3")[0], "x", request.getfixturevalue("host3")),
        "coupling": lambda: (coupling_folder, "F", host)}[second]()
    alone = run_host(other_host, other, "run", 2.0, 0.5, output=output)
    first_alone = run_host(host, unzipped[0], "run", 2.0, 0.5, STUCK)
    assert alone.completed and first_alone.completed
    command = host_command(host, other, "run", 2.0, 0.5, output=output)
    env = {"HOST_SECOND": " ".join([command[1], command[2], command[3], command[7]])}
    codes = []
    for _ in range(RUNS["pair"]):
        run = run_host(host, unzipped[0], "pair", 2.0, 0.5, STUCK, env=env, timeout=120)
        codes.append(run.returncode)
        assert run.completed, (run.returncode, run.lines[-3:], run.stderr[-2000:])
        assert run.series("a") == first_alone.series("x")
        assert run.series("b") == ([2.0], [alone.series("x")[1][-1]])
    assert codes == [0] * RUNS["pair"]


FMPY_RUN = ("import fmpy, sys; r = fmpy.simulate_fmu(sys.argv[1], stop_time=2.0, output_interval=0.5, "
            "start_values={'v_start': 0.1}, output=['x']); print('x', *r['x'])")


# the resources folder the slave holds, with the loader's fast path bound (FMI 2: the output derivative answers)
SLAVE_FOLDER = textwrap.dedent("""
    import gc, sys
    from fmpy import read_model_description
    from fmpy.fmi2 import FMU2Slave
    from fmpy.fmi3 import FMU3Slave
    folder, fmi = sys.argv[1], int(sys.argv[2])
    description = read_model_description(folder)
    model = description.coSimulation.modelIdentifier
    slave = (FMU2Slave if fmi == 2 else FMU3Slave)(guid=description.guid, unzipDirectory=folder,
                                                     modelIdentifier=model)
    slave.instantiate()
    found = [o for o in gc.get_objects() if type(o).__name__.startswith("SpringBlockFriction")]
    if fmi == 2:
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        reference = [v.valueReference for v in description.modelVariables if v.name == "x"]
        slave.getRealOutputDerivatives(reference, [1])
    print(found[0].resources)
""")


@pytest.mark.parametrize("name", FOLDERS)
def test_folders_the_fmi_libraries_would_rewrite(host, host3, unzipped, unzipped3, tmp_path, name):
    """Both FMUs extracted below a folder whose name has '%', '%20', a space or non-ASCII letters run through FMPy
    and through the C hosts with the results of a plain folder; the slave gets the folder's path byte for byte."""
    for fmi, (folder, c_host) in {2: (unzipped[0], host), 3: (unzipped3[0], host3)}.items():
        plain = copy_of(folder, tmp_path / f"plain{fmi}")
        odd = copy_of(folder, tmp_path / name / f"fmu{fmi}")
        runs = [subprocess.run([sys.executable, "-c", FMPY_RUN, str(where)], capture_output=True, text=True,
                               timeout=120) for where in (plain, odd)]
        assert [r.returncode for r in runs] == [0, 0], runs[1].stderr[-2000:]
        assert runs[1].stdout.split("x")[-1] == runs[0].stdout.split("x")[-1]
        in_c = [run_host(c_host, where, "run", 2.0, 0.5, STUCK) for where in (plain, odd)]
        assert [r.returncode for r in in_c] == [0, 0] and in_c[1].completed, in_c[1].lines[-3:]
        assert in_c[1].series("x") == in_c[0].series("x")
        folder_seen = subprocess.run([sys.executable, "-c", SLAVE_FOLDER, str(odd), str(fmi)], capture_output=True,
                                     text=True, timeout=120)
        assert folder_seen.returncode == 0, folder_seen.stderr[-2000:]
        assert folder_seen.stdout.splitlines()[-1] == str(odd / "resources") + ("/" if fmi == 3 else "")


SIGINT_HOST = textwrap.dedent("""
    import sys
    import fmpy
    from fmpy.fmi2 import FMU2Slave
    folder = sys.argv[1]
    description = fmpy.read_model_description(folder)
    slave = FMU2Slave(guid=description.guid, unzipDirectory=folder,
                      modelIdentifier=description.coSimulation.modelIdentifier)
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    drive = [v.valueReference for v in description.modelVariables if v.name == "v_drive"]
    t, h = 0.0, 0.01
    print("stepping", flush=True)
    try:
        while True:
            slave.setReal(drive, [0.1])  # the slave's Python code runs in PythonFMU's calls
            slave.doStep(t, h)
            t += h
    except KeyboardInterrupt:
        print("interrupted in the host at t =", t, flush=True)
        sys.exit(7)
    except Exception as failure:  # FMPy raises a plain Exception for a failed FMI call
        print("FMU error", failure, flush=True)
        sys.exit(3)
""")


def test_ctrl_c_while_the_model_steps_reaches_the_host_not_the_model(unzipped):
    """A Python host (FMPy) steps the FMU in a loop and gets SIGINT at random moments: each run ends with a
    KeyboardInterrupt in the host's own code (exit 7), never as an FMU error status ("[doStep]
    KeyboardInterrupt()", exit 3)."""
    outcomes = []
    for k in range(RUNS["sigint"]):
        env = dict(os.environ, SBF_FAST_PATH=str(k % 2))  # steps through the fast path and through PythonFMU
        child = subprocess.Popen([sys.executable, "-c", SIGINT_HOST, str(unzipped[0])], stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True, env=env)
        assert child.stdout.readline().strip() == "stepping"
        time.sleep(0.05 + 0.037 * (k % 10))
        child.send_signal(signal.SIGINT)
        try:
            out, err = child.communicate(timeout=60)
        finally:  # a host that the signal did not stop fails the test and is not left stepping
            if child.poll() is None:
                child.kill()
                child.wait()
        outcomes.append((child.returncode, out.strip(), err[-300:]))
    assert [code for code, _, _ in outcomes] == [7] * RUNS["sigint"], outcomes
    assert not any("KeyboardInterrupt()" in err or "FMU error" in out for _, out, err in outcomes)
