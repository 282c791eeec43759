"""The FMUs in third-party engines from the package registries: ecos (``ecospy``) and the FMU Manipulation Toolbox
(``fmu-manipulation-toolbox``: ``fmutool -check`` and its FMU container run under FMPy). libcosim is in
test_importers.py.

Each engine runs in a child process with a time limit (``engine_child.py``), the elmer-fig3-v0.1 scene with a
fixed step equal to its output interval, compared with FMPy driving our FMU; and the invalid-parameter case
(M = -1 kg), where the test states what the user of the engine sees. An engine that cannot run on the machine
skips the test, saying what is missing.
"""

import ctypes.util
import importlib.util
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from stickslip.hosts.fmpy_host import run_fmu
from stickslip.stress.session import FmuSession
from stickslip.suite.scenario import load_scenario

from engine_child import RESULT_MARK

SCENE = load_scenario(Path(__file__).resolve().parents[1] / "scenarios" / "elmer-fig3-v0.1.toml")
START = SCENE.start_values()
STEPS = round(SCENE.stop_time / SCENE.output_interval)
BAD = dict(START, M=-1.0, x_start=0.5)
BAD_MASS = "M = -1.0 kg is out of range: allowed is a finite value in (0, inf)"
CHILD = Path(__file__).with_name("engine_child.py")
TIMEOUT = 120  # s, for one engine run (measured: under 2 s each)


def run_engine(engine, fmu, start, env=None, **spec):
    """``(result or None, output)`` of ``engine_child.py ENGINE`` on the scene's step; ``output`` is the child's
    stdout and stderr together (the engine's log)."""
    spec = {"fmu": str(fmu), "start": start, "step": SCENE.output_interval, "steps": STEPS, **spec}
    proc = subprocess.run([sys.executable, str(CHILD), engine], input=json.dumps(spec), capture_output=True,
                          text=True, timeout=TIMEOUT, env=env)
    lines = [line for line in proc.stdout.splitlines() if line.startswith(RESULT_MARK)]
    output = proc.stdout + proc.stderr
    assert proc.returncode == 0, f"{engine} child exited with {proc.returncode}: {output[-2000:]}"
    return json.loads(lines[0][len(RESULT_MARK):]), output


def fmpy_at(fmu, start, engine):
    """``{"x": [m], "n_events": [...]}`` of FMPy driving ``fmu`` with ``doStep(t, h)``, h the scene's output
    interval, at the communication points t of the ``engine`` result (0 and its times but the last), read after
    each step. ``fmpy.simulate_fmu`` differs: it steps from t = k h to (k + 1) h, so its h varies by rounding."""
    points = [0.0] + engine["time"][:-1]
    out = {"x": [], "n_events": []}
    with FmuSession(str(fmu)) as session:
        instance = session.new_instance("reference")
        instance.set_values(start)
        instance.enter_initialization(0.0)
        instance.exit_initialization()
        for t in points:
            instance.call(instance.fmu.doStep, t, SCENE.output_interval)
            row = instance.read()
            out["x"].append(row["x"])
            out["n_events"].append(row["n_events"])
        instance.free()
    return out


@pytest.fixture(scope="module")
def fmpy_run(fmu_path):
    """FMPy's run of the scene (``fmpy.simulate_fmu``: doStep at t = k h), without the sample at t = 0."""
    result = run_fmu(fmu_path, START, SCENE.stop_time, SCENE.output_interval, outputs=["x", "n_events"])
    return {"time": result["time"][1:], "x": result["x"][1:], "n_events": result["n_events"][1:]}


# ---------------------------------------------------------------------------
# ecos
# ---------------------------------------------------------------------------


def ecos_environment():
    """The environment of an ecos child: ecospy's ``libecosc.so`` needs ``libtbb.so.12``, from Debian's
    ``libtbb12`` or else from PyPI's ``tbb`` wheel (in this environment's ``lib/``, put on LD_LIBRARY_PATH).
    Skips the test, naming what is missing."""
    if importlib.util.find_spec("ecospy") is None:
        pytest.skip("ecos needs the Python package ecospy (test extra)")
    env = dict(os.environ)
    if ctypes.util.find_library("tbb") is None:
        wheel_lib = Path(sys.prefix) / "lib"
        if not (wheel_lib / "libtbb.so.12").exists():
            pytest.skip("ecos needs libtbb.so.12: install Debian's libtbb12 or PyPI's tbb (test extra)")
        env["LD_LIBRARY_PATH"] = os.pathsep.join(filter(None, [str(wheel_lib), env.get("LD_LIBRARY_PATH")]))
    return env


def test_ecos_runs_the_scene_as_fmpy_does(fmu_path, fmpy_run):
    ecos, _ = run_engine("ecos", fmu_path, START, env=ecos_environment())
    assert ecos["ok"], ecos["error"]
    assert {"x": ecos["x"], "n_events": ecos["n_events"]} == fmpy_at(fmu_path, START, ecos)  # bit for bit
    # ecos sums its steps (t = 0.1 + 0.1 + ...): against fmpy.simulate_fmu (t = k h) the times differ by up to
    # 1.03e-11 s at 300 s and x by 1.5e-12 m (measured); the breakaway at t = 10 s exactly falls one sample later
    assert np.abs(np.array(ecos["time"]) - fmpy_run["time"]).max() <= 2e-11
    assert np.abs(np.array(ecos["x"]) - fmpy_run["x"]).max() <= 5e-12
    assert ecos["n_events"][-1] == fmpy_run["n_events"][-1] >= 10


def test_ecos_bad_parameter_is_silent_at_its_default_log_level(fmu_path):
    """ecos ignores the statuses of the FMU's calls: with M = -1 its ``init`` reports success, the run goes on to
    the stop time and every x read is 0.0 (not even x_start = 0.5: fmi2GetReal failed and ecos returns its
    default), and at ecos's default log level the user sees no message at all."""
    ecos, output = run_engine("ecos", fmu_path, BAD, env=ecos_environment())
    assert ecos["ok"] and ecos["error"] == ""
    assert len(ecos["time"]) == STEPS and set(ecos["x"]) == {0.0} and set(ecos["n_events"]) == {0}
    assert "M = -1.0" not in output and "Error" not in output


def test_ecos_bad_parameter_message_shows_at_debug_level(fmu_path):
    """At ecos's ``debug`` log level the FMU's message is there, as ecos's debug line of the failed
    fmi2ExitInitializationMode, followed by one refused fmi2DoStep per step; the run still "succeeds"."""
    ecos, output = run_engine("ecos", fmu_path, BAD, env=ecos_environment(), log_level="debug", steps=3)
    assert ecos["ok"] and ecos["x"] == [0.0] * 3
    assert f"[debug] [{fmu_path}] fmi2Error [exitInitializationMode] ParameterError('{BAD_MASS}')" in output
    assert output.count("fmi2DoStep at t = ") == 3 and "not allowed during initialization" in output


def test_ecos_command_line_runs_from_a_copy_with_the_run_bit(fmu_path, tmp_path):
    """ecospy ships its ``ecos`` command without the run bit: a copy with it (and libtbb.so.12 found) simulates
    the FMU at its default start values; its CSV holds 6 decimals, so x agrees with FMPy to 5e-7 m."""
    env = ecos_environment()
    shipped = Path(importlib.util.find_spec("ecospy").origin).parent / "binaries" / "ecos"
    assert not os.access(shipped, os.X_OK)  # as ecospy 0.7.2 installs it
    command = tmp_path / "ecos"
    shutil.copy(shipped, command)
    command.chmod(0o755)
    proc = subprocess.run([str(command), "simulate", "--path", str(fmu_path), "--stepSize",
                           str(SCENE.output_interval), "--stopTime", "20"], capture_output=True, text=True,
                          timeout=TIMEOUT, env=env, cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout[-1000:] + proc.stderr[-1000:]
    table = np.genfromtxt(tmp_path / "SpringBlockFriction.csv", delimiter=",", names=True, deletechars="")
    x = table["instance::x[REAL]"][1:]
    reference = fmpy_at(fmu_path, {}, {"time": [SCENE.output_interval * (k + 1) for k in range(len(x))]})
    assert len(x) == 199 and np.abs(x - reference["x"]).max() <= 5e-7  # ecos writes no row at the stop time


# ---------------------------------------------------------------------------
# FMU Manipulation Toolbox: fmutool -check, FMU container
# ---------------------------------------------------------------------------


def toolbox_command(name):
    """The path of the FMU Manipulation Toolbox's command ``name`` beside this Python; skips if it is missing."""
    if importlib.util.find_spec("fmu_manipulation_toolbox") is None:
        pytest.skip("needs the Python package fmu-manipulation-toolbox (test extra)")
    path = Path(sys.executable).parent / name
    if not path.exists():
        pytest.skip(f"fmu-manipulation-toolbox's command {name} is not beside {sys.executable}")
    return str(path)


@pytest.mark.parametrize("version", [2, 3])
def test_fmutool_check_finds_no_error(fmu_path, fmu3_path, version):
    fmu = fmu_path if version == 2 else fmu3_path
    proc = subprocess.run([toolbox_command("fmutool"), "-input", str(fmu), "-check"], capture_output=True,
                          text=True, timeout=TIMEOUT)
    output = proc.stdout + proc.stderr
    assert proc.returncode == 0, output
    assert f"This FMU seems to be compliant with FMI-{version}.0." in output
    assert f"No semantic error against the FMI-{version} standard." in output


def make_container(fmu_path, folder, start):
    """A container FMU (fmucontainer, step = the scene's output interval) holding our FMI 2 FMU with the start
    values ``start`` (START rules: the container exposes the inputs and outputs, not the parameters)."""
    folder.mkdir()
    shutil.copy(fmu_path, folder / "SpringBlockFriction.fmu")
    rows = ["rule;from_fmu;from_port;to_fmu;to_port", "FMU;SpringBlockFriction.fmu;;;"]
    rows += [f"START;SpringBlockFriction.fmu;{name};{value!r};" for name, value in start.items()]
    (folder / "box.csv").write_text("\n".join(rows) + "\n")
    proc = subprocess.run([toolbox_command("fmucontainer"), "-fmu-directory", str(folder),
                           "-container", f"box.csv:{SCENE.output_interval}"], capture_output=True, text=True,
                          timeout=TIMEOUT, cwd=folder)
    assert proc.returncode == 0 and (folder / "box.fmu").exists(), proc.stdout + proc.stderr
    return folder / "box.fmu"


def test_fmu_container_under_fmpy_runs_the_scene_as_our_fmu_does(fmu_path, fmpy_run, tmp_path):
    box, _ = run_engine("fmpy", make_container(fmu_path, tmp_path / "box", START), {})
    assert box["ok"], box["error"]
    assert box["time"] == fmpy_run["time"].tolist()  # FMPy's own grid
    # the container steps our FMU by its own fixed h at FMPy's points t = k h: bit for bit with FMPy doing the same
    assert {"x": box["x"], "n_events": box["n_events"]} == fmpy_at(fmu_path, START, box)
    # fmpy.simulate_fmu steps from k h to (k + 1) h: x differs by 8.7e-15 m at most (measured)
    assert np.abs(np.array(box["x"]) - fmpy_run["x"]).max() <= 1e-13
    assert box["n_events"] == fmpy_run["n_events"].tolist() and box["n_events"][-1] >= 10


def test_fmu_container_bad_parameter_fails_naming_it(fmu_path, tmp_path):
    """The container passes the FMU's failure and message on: FMPy prints the message with the embedded FMU's
    name and raises (the container also logs "[ERROR] Solver configure...." on every run, good ones too)."""
    box, output = run_engine("fmpy", make_container(fmu_path, tmp_path / "box", BAD), {}, steps=3)
    assert not box["ok"] and box["error"] == "fmi2ExitInitializationMode failed with status 3 (error)."
    assert f"[ERROR] SpringBlockFriction.fmu: [exitInitializationMode] ParameterError('{BAD_MASS}')" in output
