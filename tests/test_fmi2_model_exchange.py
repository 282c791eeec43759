"""FMI 2 model exchange of SpringBlockFriction.fmu (answered by the FMU's C loader through the slave, with the FMI 3
FMU's model exchange) under FMPy's CVode: against the independent reference, against the FMI 3 FMU's model
exchange, through the scenario suite, and the refusals of a bad parameter.
"""

from pathlib import Path

import numpy as np
import pytest
from fmpy import simulate_fmu

from stickslip.hosts.fmpy_host import FmuCallError, run_fmu
from stickslip.reference import parameters_from_values, simulate_reference
from stickslip.suite.runner import interface_of, simulate
from stickslip.suite.scenario import load_scenario

SCENARIO_DIR = Path(__file__).resolve().parents[1] / "scenarios"
RTOL = 1e-10  # CVode's relative tolerance
STOP = 2000.0  # s
SCENE = load_scenario(SCENARIO_DIR / "elmer-fig3-v0.1.toml")
# elmer-fig3 at v_drive 0.1 m/s: stick-slip from x_start 1 m, v_start 0.1 m/s (91 events over 2000 s); and from rest
# (v_start 0), where the block settles into steady sliding
STARTS = {"stick-slip": {"x_start": 1.0, "v_start": 0.1}, "steady sliding from rest": {"x_start": 0.0, "v_start": 0.0}}


def model_exchange(fmu_path, start):
    """FMPy's model exchange of the FMU at ``fmu_path`` with CVode at RTOL on the scene from ``start``, output every
    1 s over STOP."""
    return simulate_fmu(str(fmu_path), fmi_type="ModelExchange", solver="CVode", relative_tolerance=RTOL,
                        start_values={**SCENE.start_values(), "v_drive": 0.1, **start}, stop_time=STOP,
                        output_interval=1.0, output=["x", "v", "n_events"], record_events=False)


@pytest.fixture(scope="module")
def runs(fmu_path, fmu3_path):
    """``{scene: (FMI 2 result, FMI 3 result)}`` of :func:`model_exchange`."""
    return {name: (model_exchange(fmu_path, start), model_exchange(fmu3_path, start))
            for name, start in STARTS.items()}


@pytest.mark.parametrize("name", STARTS)
def test_fmpy_runs_fmi2_model_exchange_within_1e_6_of_the_amplitude(runs, name):
    """The whole run without a solver failure (FMPy raises on one), x within 1e-6 of the amplitude of the
    reference (half its range of x) at every output point (measured: 2.3e-7 stick-slip, 1.9e-8 steady sliding)."""
    result, _ = runs[name]
    start = STARTS[name]
    assert result["time"][-1] == STOP and len(result) == STOP + 1
    ref = simulate_reference(parameters_from_values(SCENE.law_values), start["x_start"], start["v_start"],
                             [(0.0, 0.1, 0.0)], result["time"], rtol=3e-14)
    amplitude = 0.5 * np.ptp(ref.x)
    assert np.abs(result["x"] - ref.x).max() <= 1e-6 * amplitude
    events = ref.events  # the start's breakaway (stick-slip) included: the initial event iteration's
    assert result["n_events"][-1] == len(events) and (len(events) > 80 if name == "stick-slip" else not events)
    if name != "stick-slip":  # it slides steadily at the end
        assert abs(result["x"][-1] - SCENE.params.kinetic.force(0.1) / SCENE.params.kappa) < 1e-6


@pytest.mark.parametrize("name", STARTS)
def test_the_fmi2_and_fmi3_model_exchange_give_the_same_bits(runs, name):
    """One model exchange (block_interface.ExchangeInterface) behind both FMI versions: FMPy's CVode gets the same
    states, derivatives and indicators from both, and gives the same numbers."""
    fmi2, fmi3 = runs[name]
    for field in ("time", "x", "v", "n_events"):
        assert np.array_equal(fmi2[field], fmi3[field]), field


def test_the_suite_runs_a_scenario_through_fmi2_model_exchange(fmu_path):
    """``stickslip run --fmu SpringBlockFriction.fmu --interface me``: the FMI 2 FMU's model exchange, checked
    against the scenario's [model_exchange] tolerances like the FMI 3 FMU's."""
    assert interface_of(fmu_path, "me") == "me" and interface_of(fmu_path, None) is None
    fmu, ref, _, _ = simulate(SCENE, fmu_path, "me")
    assert fmu["time"][-1] == pytest.approx(SCENE.stop_time)
    assert np.abs(fmu["x"] - ref.x).max() <= SCENE.model_exchange.tolerance.max_abs_dx


def test_a_bad_parameter_is_refused_with_its_name_and_range(fmu_path):
    """M = -1 kg: fmi2ExitInitializationMode of a model-exchange instance returns fmi2Error with a message naming M
    and its allowed range."""
    with pytest.raises(FmuCallError) as refused:
        run_fmu(fmu_path, {"M": -1.0}, 10.0, 1.0, "me")
    assert refused.value.status == 3 and refused.value.function == "fmi2ExitInitializationMode"
    assert any("M = -1.0 kg is out of range" in m and "allowed" in m for m in refused.value.messages), refused.value

