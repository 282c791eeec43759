"""scripts/omsimulator_me.py without OMSimulator (which CI cannot get): the SSP is a strongly coupled system of the
block with the scene's start values, and a fake result file in OMSimulator's layout (grid rows and an event row
at each event's left limit) is compared with the reference giving the offsets put in."""

import sys
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import numpy as np
import pytest
from oms_results import write_result

from stickslip.suite.compare import FMU_COUNTERS, transition_kind
from stickslip.suite.runner import reference_on
from stickslip.systems.ssp import NAMESPACES

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))
import omsimulator_me as oms_me  # noqa: E402  (a script beside omsimulator_chain.py, which it imports)

OMS = "{https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd}"
SSD = "{" + NAMESPACES["ssd"] + "}"
SSV = "{" + NAMESPACES["ssv"] + "}"
SOLVER = {"relativeTolerance": 1e-10, "initialStepSize": 1e-6, "minimumStepSize": 1e-12, "maximumStepSize": 1.0}


def test_the_ssp_is_a_strongly_coupled_system_of_the_block_with_the_scenes_start_values(tmp_path, fmu_path):
    sc = oms_me.scene("stick-slip", 2000.0, 1.0)
    ssp = oms_me.write_ssp(sc, SOLVER, fmu_path, tmp_path / "s.ssp")
    with zipfile.ZipFile(ssp) as archive:
        root = ET.fromstring(archive.read("SystemStructure.ssd"))
        values = ET.fromstring(archive.read("resources/b1.ssv"))
        assert archive.read("resources/SpringBlockFriction.fmu") == Path(fmu_path).read_bytes()
    # OMSimulator makes a system strongly coupled when its SimulationInformation names a VariableStepSolver
    solver = root.find(f"{SSD}System/{SSD}Annotations//{OMS}SimulationInformation/{OMS}VariableStepSolver")
    assert solver.attrib == {"description": "cvode", **{k: repr(v) for k, v in SOLVER.items()}}
    assert root.find(f"{SSD}DefaultExperiment").get("stopTime") == "2000.0"
    (component,) = root.find(f"{SSD}System/{SSD}Elements")
    assert component.get("source") == "resources/SpringBlockFriction.fmu"
    assert component.find(f"{SSD}ParameterBindings/{SSD}ParameterBinding").get("source") == "resources/b1.ssv"
    assert [c.get("name") for c in component.find(f"{SSD}Connectors")] == list(oms_me.OUTPUTS)
    given = {p.get("name"): p[0].get("value") for p in values.iter(f"{SSV}Parameter")}
    assert {k: given[k] for k in ("x_start", "v_start", "v_drive", "F_ext", "M", "kinetic.gamma1")} == {
        "x_start": "1.0", "v_start": "0.1", "v_drive": "0.1", "F_ext": "0.0", "M": "40.0", "kinetic.gamma1": "3.0"}


def _fake_run(sc, dx, dt_event):
    """OMSimulator's columns of the block on scene ``sc`` as the reference has it, ``x`` off by ``dx`` (m) and the
    events' times by ``dt_event`` (s): a row at each grid time and one at each event's left limit."""
    grid = np.linspace(0.0, sc.stop_time, round(sc.stop_time / sc.output_interval) + 1)
    events = reference_on(sc, grid).events
    t = np.sort(np.concatenate([grid, [e.t for e in events if 0.0 < e.t < sc.stop_time]]))
    left = np.isin(t, [e.t for e in events]) & (t > 0)
    ref = reference_on(sc, t)
    done = [[e for e in events if e.t < time or (e.t == time and not at_event)] for time, at_event in zip(t, left)]
    kinds = [[transition_kind(e.mode_before, e.mode_after) for e in past] for past in done]
    columns = {"x": ref.x + dx, "v": ref.v, "mode": ref.mode, "n_events": [len(past) for past in done],
               "t_last_event": [past[-1].t + dt_event if past else 0.0 for past in done]}
    columns.update({name: [k.count(kind) for k in kinds] for kind, name in FMU_COUNTERS.items()})
    return t, {f"m.m.b1.{name}": values for name, values in columns.items()}


@pytest.mark.parametrize("dt_event", [0.0, 1e-4])
def test_the_comparison_gives_the_offsets_put_into_the_result_file(tmp_path, dt_event):
    sc = oms_me.scene("stick-slip", 200.0, 1.0)
    t, columns = _fake_run(sc, 1e-3, dt_event)
    write_result(tmp_path / "r.mat", t, columns)
    numbers = oms_me.measure(sc, oms_me.block_signals(oms_me.read_mat(tmp_path / "r.mat")))
    reference = reference_on(sc, np.arange(201.0))
    assert numbers["max_abs_dx"] == pytest.approx(1e-3, abs=1e-12)
    assert numbers["relative"] == pytest.approx(1e-3 / (0.5 * np.ptp(reference.x)), rel=1e-9)
    assert numbers["events"] == numbers["reference_events"] == len(reference.events) > 5
    assert numbers["match"].n_unmatched == 0 and numbers["match"].n_matched == len(reference.events)
    assert numbers["match"].max_time_error == pytest.approx(dt_event, abs=1e-9)


def test_a_grid_time_without_a_row_is_named():
    assert oms_me.grid_rows(np.array([0.0, 0.5, 1.0, 1.0, 2.0]), np.array([0.0, 1.0, 2.0])).tolist() == [0, 3, 4]
    with pytest.raises(RuntimeError, match=r"no row at t = 2.0 s \(last row at 1.5 s\)"):
        oms_me.grid_rows(np.array([0.0, 1.0, 1.5]), np.array([0.0, 1.0, 2.0]))


def test_omsimulators_warnings_and_errors_are_counted():
    text = ("info:    Final Statistics for 'm.m':\n         NumSteps = 153 NumRhsEvals  = 178\n"
            "warning: Bad return code at time 12.000000\ninfo:    1 warnings\ninfo:    2 errors\n")
    assert oms_me.diagnostics(text) == {"warnings": 1, "errors": 2}
    assert oms_me.diagnostics("info:    Result file: x.mat (bufferSize=1)\n") == {"warnings": 0, "errors": 0}


@pytest.mark.parametrize("argv, message", [
    (["--scenes", "stick-slip,sliding"], "--scenes: 'sliding': allowed are ['stick-slip', 'from-rest']"),
    (["--tolerance", "0"], "--tolerance: '0': allowed is a finite number > 0"),
    (["--stop-time", "10.5"], "--stop-time 10.5: allowed is a whole number of --interval (1.0 s)")])
def test_bad_options_are_refused_with_the_allowed_values(capsys, argv, message):
    with pytest.raises(SystemExit) as refused:
        oms_me.parse(["OMSimulator", *argv])
    assert refused.value.code == 2 and message in capsys.readouterr().err
