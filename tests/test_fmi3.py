"""The FMI 3 FMU: the FMI 2 FMU's variables, co-simulation identical to it, model exchange against the reference."""

import shutil
import subprocess
import sys
import zipfile
from ctypes import c_double
from dataclasses import replace
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Model
from fmpy.validation import validate_fmu

from stickslip.cli import main
from stickslip.suite.compare import compare, fmu_events, reference_events
from stickslip.core import Constant, Lubricated, Parameters, Trajectory
from stickslip.fmu import ensure_fmu, is_current, source_tag
from stickslip.fmu.sources import built_tag
from stickslip.hosts.fmpy_host import FMUError, run_fmu
from stickslip.suite.inputs import Signal, held_input_table
from stickslip.reference import parameters_from_values, simulate_reference
from stickslip.suite.runner import OUTPUTS, simulate
from stickslip.suite.scenario import load_scenario

import machine_needs
from fmu_instances import instantiate3

SCENARIO_DIR = Path(__file__).resolve().parents[1] / "scenarios"
SCENARIOS = sorted(SCENARIO_DIR.glob("*.toml"))
ELMER = {"M": 40.0, "kappa": 1.0, "kinetic.law": 4, "kinetic.gamma1": 3.0, "kinetic.gamma2": 0.1,
         "kinetic.v_tilde": 0.2, "kinetic.dv": 0.05, "static.law": 1, "static.F0": 1.0}
# the FMI 3 FMU's variables beyond the FMI 2 FMU's (which has der(x) and der(v) too; its event indicators are no
# variables in FMI 2, and it takes der(F_ext) through fmi2SetRealInputDerivatives)
FMI3_ONLY = {"indicator.stick", "indicator.breakaway", "indicator.graze", "time", "der(F_ext)"}


def reals(fmu, unzipped3, names):
    return fmu.getFloat64([unzipped3[2][name].valueReference for name in names])


# ---------------------------------------------------------------------------
# the artifact
# ---------------------------------------------------------------------------


def test_fmpy_validate_reports_no_problems(fmu3_path):
    assert validate_fmu(str(fmu3_path)) == []


def test_same_variables_units_ranges_and_defaults_as_the_fmi2_fmu(fmu_path, fmu3_path):
    fmi2 = {v.name: v for v in fmpy.read_model_description(str(fmu_path)).modelVariables}
    fmi3 = {v.name: v for v in fmpy.read_model_description(str(fmu3_path)).modelVariables}
    assert set(fmi3) - set(fmi2) == FMI3_ONLY and set(fmi2) <= set(fmi3)
    for name, v2 in fmi2.items():
        v3 = fmi3[name]
        law_selector = name.endswith(".law")  # FMI 3: an Enumeration of the codes the FMI 2 Integer holds
        assert ("Enumeration" if law_selector else {"Real": "Float64", "Integer": "Int32"}[v2.type]) == v3.type, name
        for attribute in ("causality", "variability", "start", "unit", "declaredType", "min", "max", "description"):
            if law_selector and attribute == "declaredType":
                continue
            expected = getattr(v2, attribute)
            if attribute == "declaredType":
                expected = None if expected is None else expected.name
                actual = None if v3.declaredType is None else v3.declaredType.name
            else:
                actual = getattr(v3, attribute)
            assert str(actual) == str(expected), (name, attribute)


def test_ensure_fmu_fmi3_builds_only_when_the_sources_changed(tmp_path, fmu3_path):
    target = tmp_path / "SpringBlockFriction-fmi3.fmu"
    shutil.copy(fmu3_path, target)
    assert is_current(target, 3) and built_tag(target, 3) == source_tag(3)
    before = target.stat().st_mtime_ns
    assert ensure_fmu(target, 3) == target and target.stat().st_mtime_ns == before
    with zipfile.ZipFile(fmu3_path) as source, zipfile.ZipFile(target, "w") as stale:
        for item in source.infolist():
            data = source.read(item)
            stale.writestr(item, b"springblockfriction3_0000000000" if item.filename.endswith("slavemodule.txt") else data)
    assert not is_current(target, 3)
    ensure_fmu(target, 3)
    assert is_current(target, 3)


def test_both_interfaces_states_indicators_and_state_capabilities(unzipped3):
    description = unzipped3[1]
    for interface in (description.modelExchange, description.coSimulation):
        assert interface.canGetAndSetFMUstate and interface.canSerializeFMUstate
    assert description.coSimulation.canHandleVariableCommunicationStepSize
    assert [d.variable.name for d in description.derivatives] == ["der(x)", "der(v)"]
    assert [d.variable.derivative.name for d in description.derivatives] == ["x", "v"]
    assert [e.variable.name for e in description.eventIndicators] == [
        "indicator.stick", "indicator.breakaway", "indicator.graze"]


# ---------------------------------------------------------------------------
# co-simulation: identical to the FMI 2 FMU
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("path", SCENARIOS, ids=lambda p: p.stem)
def test_co_simulation_equals_the_fmi2_fmu_bit_for_bit(path, fmu_path, fmu3_path):
    scenario = load_scenario(path)
    args = (scenario.start_values(), scenario.stop_time, scenario.output_interval)
    fmi2 = run_fmu(fmu_path, *args, input_signal=scenario.input_table(), outputs=list(OUTPUTS))
    fmi3 = run_fmu(fmu3_path, *args, "cs", input_signal=scenario.input_table(), outputs=list(OUTPUTS))
    assert np.array_equal(fmi2["time"], fmi3["time"])
    for name in OUTPUTS:
        assert np.array_equal(fmi2[name], fmi3[name]), name


def test_co_simulation_starts_at_the_start_time_and_refuses_a_first_step_elsewhere(unzipped3):
    """pythonfmu3 passes no start time; the loader hands fmi3EnterInitializationMode's to the slave: the trajectory
    starts there, and a first fmi3DoStep at another time is refused naming both times (as in FMI 2)."""
    fmu = instantiate3(unzipped3, "cs-start", {**ELMER, "v_start": 0.1}, start_time=5.0)
    try:
        rows = []
        for k in range(40):
            fmu.doStep(5.0 + k, 1.0)
            rows.append(reals(fmu, unzipped3, ("x", "v", "t_last_event")))
    finally:
        fmu.terminate()
        fmu.freeInstance()
    traj = Trajectory(Parameters(40.0, 1.0, Lubricated(), Constant(F0=1.0)), 0.0, 0.1, 0.1, 0.0, t0=5.0, rtol=1e-10)
    x, v = traj.sample([6.0 + k for k in range(40)])
    assert [row[:2] for row in rows] == [list(pair) for pair in zip(x, v)]
    assert rows[-1][2] == traj.t_last_event > 15.0  # the breakaway 10 s after the start

    late = instantiate3(unzipped3, "cs-late", {**ELMER, "v_start": 0.1})
    try:
        with pytest.raises(FMICallException):
            late.doStep(5.0, 1.0)
    finally:
        late.freeInstance()


def test_co_simulation_state_restore_and_serialization_continue_bit_for_bit(unzipped3):
    fmu = instantiate3(unzipped3, "cs-state", {**ELMER, "v_start": 0.1})
    try:
        fmu.doStep(0.0, 15.0)
        state = fmu.getFMUState()
        serialized = fmu.serializeFMUState(state)
        runs = []
        for restore in (None, lambda: fmu.setFMUState(state), lambda: fmu.setFMUState(fmu.deserializeFMUState(serialized))):
            if restore:
                restore()
            rows = []
            for k in range(30):
                fmu.doStep(15.0 + k, 1.0)
                rows.append(reals(fmu, unzipped3, ("x", "v", "t_last_event")))
            runs.append(rows)
        assert runs[0] == runs[1] == runs[2]
        fmu.freeFMUState(state)
    finally:
        fmu.terminate()
        fmu.freeInstance()


# ---------------------------------------------------------------------------
# model exchange
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("name, rtol, bound", [
    ("elmer-fig3-v0.1", 1e-9, 1e-5), ("elmer-fig3-v0.3", 1e-9, 1e-5),
    ("elmer-fig3-v0.1", 1e-8, 1e-4), ("elmer-fig3-v0.3", 1e-8, 1e-4),
])
def test_model_exchange_finds_the_reference_events_over_2000_s(name, rtol, bound, fmu3_path):
    """CVode at ``rtol``: every event of the reference in order, and max |dx| <= ``bound`` times the amplitude
    (measured at 1e-9: 2.4e-6 and 2.5e-6; at 1e-8: 3.5e-5 and 3.2e-5, the host's BDF error, linear in T:
    each slip ends with CVode's error in x, 6.9e-7 m at rtol 1e-8 and 0.1 m/s, proportional to rtol, and
    the stuck phase that follows turns it into a shift of the next breakaway by that error over v_drive)."""
    scenario = load_scenario(SCENARIO_DIR / f"{name}.toml")
    scenario = replace(scenario, stop_time=2000.0, output_interval=0.5, tail=600.0,
                       model_exchange=replace(scenario.model_exchange, rtol=rtol))
    fmu, ref, _, _ = simulate(scenario, fmu3_path, "me")
    events_fmu, events_ref = fmu_events(fmu), reference_events(ref)
    assert len(events_ref) > 80
    assert [e.kind for e in events_fmu] == [e.kind for e in events_ref]
    amplitude = 0.5 * np.ptp(ref.x)
    assert np.abs(fmu["x"] - ref.x).max() <= bound * amplitude
    comparison = compare(fmu, ref, replace(scenario, tolerance=scenario.model_exchange.tolerance))
    assert comparison.events.n_unmatched == 0
    assert comparison.attractor_fmu == comparison.attractor_ref == "stick-slip"


@pytest.mark.parametrize("v_drive", [0.0585, 0.05851])
def test_model_exchange_sees_the_shallow_dips_next_to_the_grazing_boundary(v_drive, fmu3_path):
    """Just below the stick-slip boundary 0.0585126 m/s the slip's v_rel dips below 0 for a moment and sticks.

    At rtol 1e-6 CVode steps over the dip; the graze indicator's sign change at the dip's extremum makes
    the locator find it. Measured without that indicator (same FMU, graze indicator held at 1): 2 events
    instead of 26 and continuous sliding, at both drives.
    """
    scenario = load_scenario(SCENARIO_DIR / "elmer-fig3-v0.1.toml")
    scenario = replace(scenario, signals={**scenario.signals, "v_drive": Signal.constant(v_drive)}, stop_time=600.0,
                       output_interval=0.5, model_exchange=replace(scenario.model_exchange, rtol=1e-6))
    fmu, ref, _, _ = simulate(scenario, fmu3_path, "me")
    kinds = [e.kind for e in reference_events(ref)]
    assert len(kinds) == 26 and kinds.count("stick") == 13
    assert [e.kind for e in fmu_events(fmu)] == kinds


def test_model_exchange_stuck_block_follows_an_input_jump(fmu3_path):
    inputs = held_input_table([(0.0, 0.1, 0.0), (4.0, 0.3, 0.0)], 6.0)
    start = {**ELMER, "v_start": 0.1}
    result = run_fmu(fmu3_path, start, 6.0, 0.5, "me", input_signal=inputs, outputs=["x", "v", "mode", "n_events"])
    t = result["time"]
    expected = np.where(t <= 4.0, 0.1 * t, 0.4 + 0.3 * (t - 4.0))
    # 1e-8, not 0: FMPy's root function sets the input's left limit (0.1) again at t = 4 after the event,
    # and CVode's first derivative after its restart there sees it
    assert np.allclose(result["x"], expected, rtol=0.0, atol=1e-7)
    assert np.all(result["mode"] == 0) and np.all(result["n_events"] == 0)
    assert np.all(result["v"][t > 4.0] == 0.3)


def test_model_exchange_slipping_block_keeps_its_velocity_through_an_input_jump(fmu3_path):
    """A jump of v_drive across v reverses the slip direction without a stick (SPEC: the mode follows v_rel)."""
    start = {"M": 1.0, "kappa": 1.0, "kinetic.F0": 0.5, "static.F0": 1.0, "x_start": 0.0, "v_start": 0.0}
    inputs = held_input_table([(0.0, 1.0, 0.0), (0.1, -1.0, 0.0)], 0.2)
    outputs = ["x", "v", "mode", "n_events", "n_overshoots", "n_stick_events"]
    result = run_fmu(fmu3_path, start, 0.2, 0.05, "me", input_signal=inputs, outputs=outputs, rtol=1e-10)
    laws = {"M": 1.0, "kappa": 1.0, "kinetic.law": "coulomb", "kinetic.F0": 0.5, "static.law": "constant",
            "static.F0": 1.0}
    ref = simulate_reference(parameters_from_values(laws), 0.0, 0.0,
                             [(0.0, 1.0, 0.0), (0.1, -1.0, 0.0)], result["time"])
    assert np.all(result["mode"][result["time"] > 0.1] == -1)
    assert result["n_overshoots"][-1] == 1 and result["n_stick_events"][-1] == 0
    assert [e.kind for e in reference_events(ref)] == ["overshoot"]
    assert np.abs(result["x"] - ref.x).max() < 1e-9 and np.abs(result["v"] - ref.v).max() < 1e-8


@pytest.mark.parametrize("interface", ["cs", "me"])
def test_bad_parameter_is_named(interface, fmu3_path):
    with pytest.raises(FMUError, match=r"M = -1\.0 kg is out of range"):
        run_fmu(fmu3_path, {"M": -1.0}, 1.0, 0.5, interface)
    assert np.isfinite(run_fmu(fmu3_path, {}, 1.0, 0.5, interface)["x"]).all()  # the process goes on


def test_model_exchange_nan_input_names_the_input(fmu3_path):
    inputs = held_input_table([(0.0, 0.1, 0.0), (0.5, float("nan"), 0.0)], 1.0)
    with pytest.raises(FMUError, match=r"v_drive = nan m/s is out of range"):
        run_fmu(fmu3_path, {}, 1.0, 0.25, "me", input_signal=inputs)


def test_model_exchange_state_restore_and_serialization(unzipped3):
    fmu = instantiate3(unzipped3, "me-state", {**ELMER, "v_start": 0.1}, FMU3Model)
    try:
        fmu.updateDiscreteStates()
        fmu.enterContinuousTimeMode()
        states, derivatives = (c_double * 2)(), (c_double * 2)()
        fmu.setTime(12.0)
        fmu.setContinuousStates((c_double * 2)(1.2, 0.1), 2)
        fmu.enterEventMode()
        fmu.updateDiscreteStates()  # z_slip < 0: breaks away
        fmu.enterContinuousTimeMode()
        state = fmu.getFMUState()
        serialized = fmu.serializeFMUState(state)

        def snapshot():
            fmu.getContinuousStates(states, 2)
            fmu.getContinuousStateDerivatives(derivatives, 2)
            return list(states), list(derivatives), fmu.getInt32([unzipped3[2]["mode"].valueReference])

        before = snapshot()
        assert before[2] == [1]
        fmu.setTime(30.0)
        fmu.setContinuousStates((c_double * 2)(-0.3, 0.1), 2)  # the spring pushes: the slip arrives at v_rel = 0
        fmu.enterEventMode()
        fmu.updateDiscreteStates()  # v = v_drive: sticks
        assert snapshot()[2] == [0]
        fmu.setFMUState(state)
        assert snapshot() == before
        fmu.setFMUState(fmu.deserializeFMUState(serialized))
        assert snapshot() == before
        fmu.freeFMUState(state)
    finally:
        fmu.terminate()
        fmu.freeInstance()


# ---------------------------------------------------------------------------
# the command line
# ---------------------------------------------------------------------------


def test_cli_runs_the_fmi3_fmu_through_both_interfaces(tmp_path, fmu_path, fmu3_path, coupling_path):
    """Both FMUs through both interfaces (the FMI 2 FMU's default: co-simulation); an FMU without model exchange
    (the coupling FMU, not even a block) is refused."""
    scenario = str(SCENARIO_DIR / "coulomb-stick-slip.toml")
    for fmu, interface in ((fmu3_path, "cs"), (fmu3_path, "me"), (fmu_path, "me")):
        out = tmp_path / f"{fmu.stem}-{interface}"
        assert main(["run", scenario, "--out", str(out), "--jobs", "1", "--fmu", str(fmu),
                     "--interface", interface]) == 0
        assert "| coulomb-stick-slip " in (out / "report.md").read_text()
    assert main(["run", scenario, "--out", str(tmp_path / "x"), "--fmu", str(coupling_path), "--interface", "me"]) == 1


def test_model_exchange_needs_the_scenarios_model_exchange_section(tmp_path, fmu3_path):
    text = (SCENARIO_DIR / "coulomb-stick-slip.toml").read_text()
    bare = tmp_path / "bare.toml"
    bare.write_text(text[:text.index("[model_exchange]")])
    assert main(["run", str(bare), "--out", str(tmp_path / "out"), "--fmu", str(fmu3_path), "--interface", "me"]) == 1


# ---------------------------------------------------------------------------
# model-exchange calls at the edges: initialization, failures, bad states
# ---------------------------------------------------------------------------

_EDGE_SCRIPT = """
import ctypes, sys
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Model
folder, case = sys.argv[1], sys.argv[2]
description = read_model_description(folder)
refs = {v.name: v.valueReference for v in description.modelVariables}
fmu = FMU3Model(guid=description.guid, unzipDirectory=folder, instanceName="edge",
                modelIdentifier=description.modelExchange.modelIdentifier)
fmu.instantiate(loggingOn=False)
fmu.enterInitializationMode(startTime=0.0)
fmu.setFloat64([refs["v_start"]], [0.3])
dx = (ctypes.c_double * 2)()
def derivatives():
    fmu.getContinuousStateDerivatives(dx, 2)
    return list(dx)
try:
    if case == "bad parameter":
        fmu.setFloat64([refs["M"]], [-1.0])
        print("derivatives", derivatives())
    else:
        during = derivatives()
        fmu.exitInitializationMode()
        fmu.enterContinuousTimeMode()
        print("same after", during == derivatives())
        if case == "nan state":
            fmu.setContinuousStates((ctypes.c_double * 2)(float("nan"), 0.3), 2)
except FMICallException as exc:
    print("status", exc.status, "then", derivatives() if case == "nan state" else "")
print("alive")
"""


def _edge(unzipped3, case):
    """Run ``_EDGE_SCRIPT``'s ``case`` in a process of its own (a crash must not take pytest down):
    ``(its stdout, stdout and stderr)``."""
    done = subprocess.run([sys.executable, "-c", _EDGE_SCRIPT, unzipped3[0], case], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0 and done.stdout.endswith("alive\n"), (done.returncode, done.stdout, done.stderr)
    return done.stdout, done.stdout + done.stderr


def test_model_exchange_derivatives_during_initialization_are_those_the_initialization_starts(unzipped3):
    out, _ = _edge(unzipped3, "initialization")
    assert "same after True" in out


def test_a_failing_derivative_call_is_an_error_naming_the_parameter_not_a_crash(unzipped3):
    """pythonfmu3 crashes the host when the slave raises in get_continuous_state_derivatives: the slave logs and
    answers NaN, the FMU's binary returns fmi3Error, and no NaN is passed on as a success."""
    machine_needs.c_compiler("the FMU's Linux loader")
    out, everything = _edge(unzipped3, "bad parameter")
    assert "status 3" in out and "derivatives" not in out
    assert "M = -1.0 kg is out of range" in everything


def test_model_exchange_rejects_a_non_finite_state_and_keeps_its_own(unzipped3):
    machine_needs.c_compiler("the FMU's Linux loader")
    out, everything = _edge(unzipped3, "nan state")
    assert "status 3" in out and "x = nan m is out of range" in everything
    then = [float(v) for v in out.split("then [")[1].split("]")[0].split(",")]
    assert np.isfinite(then).all()
