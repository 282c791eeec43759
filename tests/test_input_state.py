"""Inputs and the FMU's time through the real FMUs (FMI 2 with the loader's fast path on and off, FMI 3): an FMU
state holds every input the next step uses, an input out of range is refused when it is set (all or nothing, the
instance going on with the old value), and fmi2LastSuccessfulTime is always the time the FMU is at.

Each FMU runs in a child process (tests/input_state_runner.py); its exit status is asserted.
"""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

import machine_needs
from test_input_rate import ramp_motion

RUNNER = Path(__file__).resolve().parent / "input_state_runner.py"
ERROR = 3  # fmi2Error, fmi3Error


@pytest.fixture(scope="module", params=["FMI 2", "FMI 2, SBF_FAST_PATH=0", "FMI 3"])
def session(request, fmu_path, fmu3_path):
    machine_needs.c_compiler("the FMU's loader")
    path = fmu3_path if request.param == "FMI 3" else fmu_path
    env = {**os.environ, **({"SBF_FAST_PATH": "0"} if "SBF_FAST_PATH" in request.param else {})}
    run = subprocess.run([sys.executable, str(RUNNER), str(path)], capture_output=True, text=True, timeout=600,
                         env=env)
    assert run.returncode == 0, run.stderr[-3000:]
    return json.loads(run.stdout.splitlines()[-1])


def closed_form(name, t):
    """``(x, v)`` at ``t`` s of the block at rest at x = 0 on a still surface (Coulomb F_K = 0.5 N, F_S = 1 N,
    M = kappa = 1), the input ``name`` set at 1 s: F_ext = 1.5 N breaks it away, x = 1 - cos(t - 1) until it sticks
    at x = 2 m (holding 0.5 N); v_drive = 0.1 m/s carries it; der(F_ext) = 0.25 N/s ramps the force from 1 s."""
    tau = t - 1.0
    if name == "F_ext":
        return (1.0 - math.cos(tau), math.sin(tau)) if tau <= math.pi else (2.0, 0.0)
    if name == "v_drive":
        return 0.1 * tau, 0.1
    return ramp_motion(tau) if tau >= 4.0 else (0.0, 0.0)


@pytest.mark.parametrize("name", ["F_ext", "v_drive", "der(F_ext)"])
def test_a_restored_state_steps_with_the_input_it_was_saved_with(session, name):
    """Set the input, get the FMU state, change the input, restore the state, step: the instance reports the
    saved input and steps with it, bit for bit as a run that never changed it, and as the closed form (before,
    the pending input was not in the state: x stayed 0 where 2 m is right, and 0 where 0.5 m is)."""
    if name not in session["restore"]:
        pytest.skip("FMI 3 co-simulation has no input derivatives")
    case = session["restore"][name]
    if name != "der(F_ext)":
        assert case["reported"] == {"F_ext": 1.5, "v_drive": 0.1}[name]
    assert case["restored"] == case["unchanged"]
    for t, x, v in case["restored"]:
        assert (x, v) == pytest.approx(closed_form(name, t), abs=1e-12), t
    assert case["restored"][-1][1] == pytest.approx({"F_ext": 2.0, "v_drive": 0.5, "der(F_ext)": 0.2694811}[name])


REFUSED = {  # label: (the variable the message names, the range it states)
    "F_ext = nan": ("F_ext = nan N", "allowed is a finite value"),
    "F_ext = inf": ("F_ext = inf N", "allowed is a finite value"),
    "F_ext = 1e+151": ("|F_ext| = 1e+151 N", "allowed is at most 1e+150 N"),
    "v_drive = nan": ("v_drive = nan m/s", "allowed is a finite value"),
    "v_drive = -inf": ("v_drive = -inf m/s", "allowed is a finite value"),
    "v_drive = 1e+151": ("v_drive = 1e+151 m/s", "allowed is at most 1e+150 N"),
    "F_ext = 0.3 with v_drive = nan": ("v_drive = nan m/s", "allowed is a finite value"),
    "der(F_ext) = 1e+151": ("der(F_ext) = 1e+151 N/s", "allowed is at most 1e+150 N"),
    "der(F_ext) = 1e+300": ("der(F_ext) = 1e+300 N/s", "allowed is at most 1e+150 N"),
    "der(F_ext) = 1.0 with der(x)": ("x is not an input", "input derivatives are set for the inputs v_drive and F_ext"),
}


@pytest.mark.parametrize("label", REFUSED)
def test_an_input_out_of_range_is_refused_when_it_is_set_and_the_instance_goes_on(session, label):
    """fmi2SetReal, fmi3SetFloat64 and fmi2SetRealInputDerivatives refuse an input out of range with the error
    status and a message naming it and its range, all or nothing (a mixed call takes none of its values); the
    instance keeps its inputs (v_drive 0.1 m/s, F_ext 0, no der(F_ext)) and steps on with them: the carried block
    is stuck at x = 0.1 t at 5 s (before: fmi2OK, then every step failed; the mixed derivative call applied
    der(F_ext) and the block broke away)."""
    if label not in session["refused"]:
        pytest.skip("FMI 3 co-simulation has no input derivatives")
    case = session["refused"][label]
    (status, messages), (variable, allowed) = case["call"], REFUSED[label]
    assert status == ERROR and any(variable in m and allowed in m for m in messages), messages
    assert case["inputs"] == [0.1, 0.0]
    assert case["x"] == pytest.approx(0.5, abs=1e-14) and case["mode"] == 0


def test_fmi2_last_successful_time_is_where_the_fmu_is(session):
    """After restoring a state saved at 4.5 s (from 5 s), after a reset and a new initialization at 2 s (and a step
    from there), after a refused step that stopped part of the way: fmi2LastSuccessfulTime is the FMU's time, the
    one the next step must start from (before: 5.0, 6.0 and the last successful step's end). FMI 3: fmi3DoStep's
    lastSuccessfulTime after such a refused step."""
    if "time" not in session:
        case = session["failed_step_time"]
        assert case["refused step"][0] == ERROR and "stopped at t = " in case["refused step"][1][0]
        assert 10.0 < case["reached"] < 1e16 and case["step from there"] == [0, []]
        return
    time = session["time"]
    assert time["before restore"] == 5.0 and time["restored at 4.5"] == 4.5
    assert time["reset, initialized at 2"] == 2.0 and time["stepped to 2.5"] == 2.5
    (status, [message]), reached = time["refused step"], time["after the refused step"]
    assert status == ERROR and f"stopped at t = {reached!r} s" in message
    assert 10.0 < reached < 1e16 and time["step from there"] == [0, []]
    assert time["step from 0.001"][0] == ERROR
