"""Model exchange of the FMI 3 FMU driven by our C host (``host3.c``, modes "me-run" and "me-bad"), as a C
simulator would: fmi3InstantiateModelExchange, the event iteration, then RK4 of its own with state events
located on the indicators, Event Mode at each, against the independent reference integrator.

Each run is a child process (see ``tests/test_c_host.py``); the host is conftest's ``host3``. The reference
runs at rtol 3e-14 (scipy's floor 2.2e-14, rounded up), so that the errors measured below are the host's RK4
and event location, not its own.
"""

from pathlib import Path

import numpy as np
import pytest

from stickslip.hosts.c_host import run_host
from stickslip.reference import parameters_from_values, simulate_reference
from stickslip.suite.scenario import load_scenario

SCENARIO_DIR = Path(__file__).resolve().parents[1] / "scenarios"
REFERENCE_RTOL = 3e-14
BAD_MASS = "M = -1.0 kg is out of range: allowed is a finite value in (0, inf)"

# scene, RK4 step (s), bounds on max |x - x_ref| (m) and on max |t_event - t_event_ref| (s); measured with
# the event time tolerance of host3.c (1e-14 s, relative beyond 1 s): elmer-fig3 9.3e-13 m and 4.2e-12 s,
# stribeck with F_ext 5.4e-11 m and 4.5e-9 s (its sticks are reached slowly: a small v_rel error is a larger
# time error; 1.5e-8 m and 5.3e-8 s at a step of 0.01 s), aging 4.4e-11 m and 7.7e-11 s.
SCENES = [
    pytest.param("elmer-fig3-v0.1", 0.005, 5e-11, 2e-10, id="elmer-fig3-stick-slip"),
    pytest.param("stribeck-fext-constant", 0.0025, 3e-9, 2e-7, id="F_ext"),
    pytest.param("aging-logarithmic", 0.005, 2e-9, 4e-9, id="aging"),
]


def start_values(scene):
    """The scene's start values with its inputs, constant in these scenes (set before initialization)."""
    (_, v_drive, F_ext), = scene.breakpoints()
    return {**scene.start_values(), "v_drive": v_drive, "F_ext": F_ext}


def run_me(host3, unzipped3, mode, scene, stop, rk4_step, settings):
    """The host's run of ``mode``, printing ``n_events`` after each state event ("e" lines)."""
    folder, _, variables = unzipped3
    env = {"HOST_ME_STEP": repr(rk4_step), "HOST_ME_COUNTER": str(variables["n_events"].valueReference)}
    run = run_host(host3, folder, mode, stop, scene.output_interval, settings, env=env)
    assert run.completed, f"host exit {run.returncode}: {run.lines[-3:]} {run.logs} {run.stderr[-2000:]}"
    return run


def check_against_reference(run, scene, max_dx, max_dt):
    """``x`` at the output points and the times of the mode changes (where ``n_events`` rose) against the
    reference's; returns the reference's events."""
    times, x = run.series("x")
    ref = simulate_reference(parameters_from_values(scene.law_values), scene.x0, scene.v0, scene.breakpoints(),
                             times, rtol=REFERENCE_RTOL)
    assert np.abs(np.array(x) - ref.x).max() <= max_dx
    event_times, counts = run.series("e")
    rises = np.diff([0.0, *counts])
    assert set(rises) <= {0.0, 1.0}  # one mode change at most per state event
    changes = [t for t, rise in zip(event_times, rises) if rise]
    assert len(changes) == len(ref.events)
    assert np.abs(np.array(changes) - [e.t for e in ref.events]).max() <= max_dt
    return ref.events


@pytest.mark.parametrize("name, rk4_step, max_dx, max_dt", SCENES)
def test_model_exchange_in_the_c_host_follows_the_reference(host3, unzipped3, name, rk4_step, max_dx, max_dt):
    scene = load_scenario(SCENARIO_DIR / f"{name}.toml")
    run = run_me(host3, unzipped3, "me-run", scene, scene.stop_time, rk4_step, start_values(scene))
    assert len(run.series("x")[0]) == round(scene.stop_time / scene.output_interval) + 1
    kinds = [e.kind for e in check_against_reference(run, scene, max_dx, max_dt)]
    assert kinds.count("stick") >= 6 and kinds.count("slip") >= 6  # the scene's stick-slip cycle
    assert run.logs == []  # logging off and nothing wrong


def test_model_exchange_bad_parameter_is_logged_by_name_and_the_host_goes_on(host3, unzipped3):
    """M = -1 fails fmi3ExitInitializationMode of a model-exchange instance with fmi3Error and a message naming
    it; the host frees it, and a new instance (valid M) runs elmer-fig3's first 45 s (stuck until x = F_S/kappa
    = 1 m at t = 10 s, a slip, a stick at 39.3 s) like the reference."""
    scene = load_scenario(SCENARIO_DIR / "elmer-fig3-v0.1.toml")
    settings = [*start_values(scene).items(), ("M", -1.0)]  # the second instance gets all but the last
    run = run_me(host3, unzipped3, "me-bad", scene, 45.0, 0.005, settings)
    assert int(run.value("status")[1]) == 3  # fmi3Error
    assert [(status, instance) for status, instance, _ in run.logs] == [(3, "bad")]
    assert BAD_MASS in run.logs[0][2]
    events = check_against_reference(run, scene, 5e-11, 2e-10)
    assert [e.kind for e in events] == ["slip", "stick"]
