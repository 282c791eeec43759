"""The FMI 3 FMU's co-simulation with early return and event mode, and its output derivatives, driven the way the
Reference-FMUs' fmusim drives them (tests/early_return_runner.py, a child process, through FMPy's FMI 3 calls).

The scene is elmer-fig3's stick-slip cycle from the breakaway point (v_drive = 0.1 m/s, x_start = 1 m, v_start =
0.1 m/s, solver.rtol = 1e-12), sampled every second. With earlyReturnAllowed every stick and breakaway returns early, at the time the
independent reference integrator finds for it (within 1e-9 s); with eventModeUsed as well the event is handled in
Event Mode. Without the flags nothing changes: the FMI 3 FMU's samples and output derivatives are the FMI 2 FMU's,
bit for bit (both run the same runtime, which the flags do not touch).
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import machine_needs
from stickslip.reference import parameters_from_values, simulate_reference

RUNNER = Path(__file__).resolve().parent / "early_return_runner.py"
STOP, INTERVAL = 200.0, 1.0  # s: about 4.5 cycles of 44 s
VALUES = {"M": 40.0, "x_start": 1.0, "v_start": 0.1, "v_drive": 0.1, "kinetic.law": 4, "kinetic.gamma1": 3.0,
          "kinetic.gamma2": 0.1, "kinetic.v_tilde": 0.2, "kinetic.dv": 0.05, "solver.rtol": 1e-12}
#: s: the early returns' times against the reference's events. The stepper's event times are as precise as its
#: solver.rtol makes them (1e-10, the default: about 3e-8 s over 2000 s of this scene; 1e-12: 4e-10 s), and the
#: reference's as its rtol (1e-12 against 1e-13: 1.4e-8 s), hence 1e-12 and 1e-13 here.
EVENT_TIME = 1e-9


@pytest.fixture(scope="module", params=["fast path", "SBF_FAST_PATH=0"])
def runs(request, fmu3_path, fmu_path):
    """The runner's record, with the loader's per-step path on and off (the results do not depend on it)."""
    machine_needs.c_compiler("the FMU's loader, which answers early return, event mode and output derivatives")
    scene = json.dumps({"values": VALUES, "stop": STOP, "interval": INTERVAL})
    env = {**os.environ, **({"SBF_FAST_PATH": "0"} if request.param != "fast path" else {})}
    run = subprocess.run([sys.executable, str(RUNNER), str(fmu3_path), str(fmu_path), scene], capture_output=True,
                         text=True, timeout=600, env=env)
    assert run.returncode == 0, run.stderr[-3000:]
    return json.loads(run.stdout)


@pytest.fixture(scope="module")
def reference_events():
    return reference_event_times()


def reference_event_times():
    """The reference integrator's mode changes of the scene inside (0, STOP): times (s)."""
    params = parameters_from_values({"M": 40.0, "kappa": 1.0, "kinetic.law": "lubricated", "kinetic.gamma1": 3.0,
                                     "kinetic.gamma2": 0.1, "kinetic.v_tilde": 0.2, "kinetic.dv": 0.05,
                                     "static.law": "constant", "static.F0": 1.0})
    result = simulate_reference(params, 1.0, 0.1, [(0.0, 0.1, 0.0)], np.linspace(0.0, STOP, 201), rtol=1e-13)
    return [event.t for event in result.events if 0.0 < event.t < STOP]


def early_returns(record):
    return [last for _, returned, last in record["steps"] if returned]


def test_the_model_description_offers_event_mode_early_return_and_output_derivatives(runs):
    assert runs["capabilities"] == {"hasEventMode": True, "mightReturnEarlyFromDoStep": True,
                                    "maxOutputDerivativeOrder": 2}


@pytest.mark.parametrize("way", ["early", "event"])
def test_every_stick_and_breakaway_returns_early_at_the_reference_s_time(runs, reference_events, way):
    times = early_returns(runs[way])
    assert len(reference_events) >= 8
    assert len(times) == len(reference_events)
    assert max(abs(a - b) for a, b in zip(times, reference_events)) <= EVENT_TIME


def test_without_event_mode_the_event_is_applied_before_the_early_return(runs):
    """earlyReturnAllowed alone: no event handling asked for; the sample at the return is after the mode change
    (modes alternate 0, 1: stuck after a stick, slipping after a breakaway)."""
    record = runs["early"]
    assert not any(handling for handling, _, _ in record["steps"])
    at_events = [sample for sample in record["samples"] if sample[0] in early_returns(record)]
    assert [sample[3] for sample in at_events] == [0, 1] * (len(at_events) // 2) + [0] * (len(at_events) % 2)


def test_in_event_mode_the_event_is_applied_by_update_discrete_states(runs):
    """eventModeUsed: each early return asks for event handling; the sample there is the state before the event
    (slipping into a stick at v = v_drive, stuck before a breakaway), the one after Event Mode the state after it;
    fmi3UpdateDiscreteStates asks for nothing more."""
    record = runs["event"]
    assert all(handling == returned for handling, returned, _ in record["steps"])
    times = early_returns(record)
    pairs = [[s for s in record["samples"] if s[0] == t] for t in times]
    assert all(len(pair) == 2 for pair in pairs)
    assert [[before[3], after[3]] for before, after in pairs][:2] == [[1, 0], [0, 1]]
    assert all(after[4] == before[4] + 1 for before, after in pairs)  # n_events counts the event once
    assert all(before[1:3] == after[1:3] for before, after in pairs)  # x and v do not jump
    assert all(update == [False, False, False, False, False, 0.0] for update in record["updates"])


@pytest.mark.parametrize("way", ["early", "event"])
def test_returning_early_changes_no_result_at_the_regular_points(runs, way):
    """The steps after an early return end on the same regular points; x and v there are those of the run without
    early return (to the rounding of the shortened step's end)."""
    plain = {round(s[0], 9): s[1:] for s in runs["plain"]["samples"]}
    regular = [s for s in runs[way]["samples"] if round(s[0], 9) in plain and abs(s[0] - round(s[0])) < 1e-9]
    assert len(regular) == len(plain)
    assert max(abs(s[1] - plain[round(s[0], 9)][0]) for s in regular) <= 1e-12
    assert max(abs(s[2] - plain[round(s[0], 9)][1]) for s in regular) <= 1e-12


def test_without_the_flags_the_fmi3_fmu_gives_the_fmi2_fmu_s_results_bit_for_bit(runs):
    assert not any(returned or handling for handling, returned, _ in runs["plain"]["steps"])
    assert runs["plain"]["samples"] == runs["fmi2"]["samples"]


def test_output_derivatives_are_the_fmi2_fmu_s(runs):
    """fmi3GetOutputDerivatives of x and v, orders 1 and 2, at every regular point: the FMI 2 FMU's
    fmi2GetRealOutputDerivatives there, bit for bit; der(x) is v."""
    assert runs["plain"]["derivatives"] == runs["fmi2"]["derivatives"]
    assert [d[0] for d in runs["plain"]["derivatives"]] == [s[2] for s in runs["plain"]["samples"][1:]]


#: the README's block: stuck at x = 0 on a surface at 0.1 m/s, F_S = 1 N, kappa = 1 N/m: it breaks away at x = 1 m,
#: t = 10 s exactly, a communication point of 1 s steps
ON_A_POINT = {**{name: value for name, value in VALUES.items() if name != "solver.rtol"}, "x_start": 0.0,
              "solver.rtol": 1e-10}
BREAKAWAY = 10.0


@pytest.fixture(scope="module")
def runs_on_a_point(fmu3_path, fmu_path):
    """The runner's record of the README's block over 30 s in 1 s steps."""
    machine_needs.c_compiler("the FMU's loader, which answers early return and event mode")
    scene = json.dumps({"values": ON_A_POINT, "stop": 30.0, "interval": 1.0})
    run = subprocess.run([sys.executable, str(RUNNER), str(fmu3_path), str(fmu_path), scene], capture_output=True,
                         text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    return json.loads(run.stdout)


def test_in_event_mode_an_event_on_a_communication_point_is_handled_in_event_mode(runs_on_a_point):
    """eventModeUsed: the step that ends on the breakaway returns no early return but asks for event handling; the
    sample there is stuck (the left limit), the one after Event Mode slipping, with x and v unchanged and one event
    more. No other step asks for it."""
    record = runs_on_a_point["event"]
    assert [step for step in record["steps"] if step[0] or step[1]] == [[True, False, BREAKAWAY]]
    before, after = [sample for sample in record["samples"] if sample[0] == BREAKAWAY]
    assert (before[3], after[3]) == (0, 1)
    assert after[4] == before[4] + 1 and before[1:3] == after[1:3] == [1.0, 0.1]


def test_without_event_mode_an_event_on_a_communication_point_is_applied_in_the_step(runs_on_a_point):
    """earlyReturnAllowed alone, or no flag: the step to the breakaway applies it (slipping there), and every sample
    is the FMI 2 FMU's."""
    for way in ("early", "plain"):
        assert not any(handling or returned for handling, returned, _ in runs_on_a_point[way]["steps"])
        assert runs_on_a_point[way]["samples"] == runs_on_a_point["fmi2"]["samples"]
    assert [s[3] for s in runs_on_a_point["plain"]["samples"] if s[0] == BREAKAWAY] == [1]
