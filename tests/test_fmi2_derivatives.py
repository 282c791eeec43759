"""The FMI 2 FMU's input and output derivatives (canInterpolateInputs, maxOutputDerivativeOrder = 2), which the C
loader answers through the slave (PythonFMU has none): a ramp of F_ext set by fmi2SetRealInputDerivatives is
followed to the closed form through the FMU, the output derivatives are those of the motion, a saved state keeps
the ramp, a force set ends it, and derivatives the block does not follow or cannot give are warned about or
refused by name. The session runs in a child process (tests/derivatives_runner.py), with the loader's fast path
on and off (SBF_FAST_PATH=0): the derivatives do not depend on it.
"""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import fmpy
import pytest

import machine_needs
from test_input_rate import RATE, ramp_motion

RUNNER = Path(__file__).resolve().parent / "derivatives_runner.py"


@pytest.fixture(scope="module", params=["fast path", "SBF_FAST_PATH=0"])
def session(request, fmu_path):
    machine_needs.c_compiler("the FMU's loader, which answers the derivative calls")
    env = {**os.environ, **({"SBF_FAST_PATH": "0"} if request.param != "fast path" else {})}
    run = subprocess.run([sys.executable, str(RUNNER), str(fmu_path)], capture_output=True, text=True, timeout=300,
                         env=env)
    assert run.returncode == 0, run.stderr[-3000:]
    return json.loads(run.stdout)


def test_the_model_description_offers_input_and_output_derivatives(session):
    assert session["canInterpolateInputs"] is True
    assert session["maxOutputDerivativeOrder"] == 2


def test_a_ramp_set_as_an_input_derivative_is_followed_to_the_closed_form(session):
    for t, x, v in session["steps"]:
        expected = (0.0, 0.0) if t < 4.0 else ramp_motion(t)
        assert abs(x - expected[0]) < 1e-12 and abs(v - expected[1]) < 1e-12, t


def test_the_output_derivatives_are_those_of_the_motion(session):
    x, v = ramp_motion(6.0)
    a = RATE * 6.0 - x - 0.5  # M a = F_ext - kappa x + F (sliding backward: F = -0.5 N)
    jerk = RATE - v  # M da/dt = dF_ext/dt - kappa v
    assert session["derivatives"] == pytest.approx([v, a, a, jerk], abs=1e-12)


def test_a_restored_state_keeps_the_ramp(session):
    assert session["restored"] == [[x, v] for _, x, v in session["steps"][50:]]


def test_a_force_set_ends_the_ramp(session):
    _, x0, v0 = session["steps"][-1]
    centre = 1.875 - 0.5  # held F_ext + F over kappa, sliding backward
    x = centre + (x0 - centre) * math.cos(0.5) + v0 * math.sin(0.5)
    v = -(x0 - centre) * math.sin(0.5) + v0 * math.cos(0.5)
    assert session["held"] == pytest.approx([x, v], abs=1e-12)


EXPECTED_CALLS = {
    "der(F_ext) of order 2": (1, "ignored der(F_ext, 2) = 1.0: the block follows F_ext to first order"),
    "der(F_ext) of order 2 again": (0, None),  # warned about once
    "der(F_ext) of order 2 = 0": (0, None),
    "der(v_drive)": (1, "ignored der(v_drive, 1) = 0.1"),
    "der(x) set": (3, "x is not an input: input derivatives are set for the inputs v_drive and F_ext"),
    "der(F_ext) NaN": (3, "der(F_ext, 1) = nan is out of range: allowed is a finite value"),
    "der(F_ext) of order 0": (3, "the order of der(F_ext) is 0: allowed is 1 or more"),
    "der(F_friction)": (3, "no derivatives of F_friction: output derivatives are given for x and v"),
    "der(x) of order 3": (3, "the order of der(x) is 3: allowed is 1 to 2 (maxOutputDerivativeOrder)"),
}


@pytest.mark.parametrize("label", EXPECTED_CALLS)
def test_derivatives_the_block_cannot_follow_are_warned_about_or_refused_by_name(session, label):
    status, text = EXPECTED_CALLS[label]
    found = {name: (got, messages) for name, got, messages in session["calls"]}
    got, messages = found[label]
    assert got == status
    assert (messages == []) if text is None else any(text in m for m in messages), messages


def test_the_outputs_declare_their_direct_dependencies(fmu_path):
    """x and F_spring depend on no input (they move only with time), v on v_drive only (a stuck block's velocity is
    the surface's); so an engine sees no algebraic loop through a chain of blocks and couplings (OMSimulator found one
    without them). The others may depend on every input (dependencies omitted)."""
    md = fmpy.read_model_description(str(fmu_path))
    dependencies = {u.variable.name: u.dependencies for u in md.outputs}
    assert dependencies["x"] == [] and dependencies["F_spring"] == []
    assert [v.name for v in dependencies["v"]] == ["v_drive"]
    assert all(dependencies[name] is None for name in dependencies if name not in ("x", "F_spring", "v"))
