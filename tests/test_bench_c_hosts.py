"""``stickslip bench-c-hosts`` (issue 21's benchmarks): the compiled floor FMU, the timing of child processes,
the hosts' command lines, ours in our C host against the reference, the peer's parameters against the
Modelica model, matching tolerances, the report. The benchmark's inputs (the Dymola peer, fmusim) are not
needed: they are stood in for or left out. No test measures speed."""

import argparse
import json
import sys
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, fmi2Error

from stickslip.bench import c_hosts, dymola_peer, fmus
from stickslip.bench.c_floor import ensure_c_floor_fmu
from stickslip.bench.c_hosts_report import markdown, write
from stickslip.bench.matched_error import OUR_RTOLS, loosest_rtol
from stickslip.bench.process_timing import ChildFailed, Timings, slope, startup, timed_child
from stickslip.bench.scenes import SCENES
from stickslip.bench.state_costs import CALLS as STATE_CALLS
from stickslip.bench.state_costs import FLOOR as STATE_FLOOR
from stickslip.cli.bench import add_c_hosts_parser
from stickslip.hosts.c_host import run_host

import machine_needs


@pytest.fixture(scope="module")
def c_floor(tmp_path_factory):
    machine_needs.c_compiler("the compiled floor FMU")
    return ensure_c_floor_fmu(tmp_path_factory.mktemp("c_floor"))


def test_c_floor_is_a_valid_fmu_whose_output_stays_and_whose_input_holds(c_floor):
    result = fmpy.simulate_fmu(str(c_floor), stop_time=1.0, output_interval=0.1, start_values={"u": 2.5},
                               output=["x", "u"], validate=True)  # FMPy checks the model description
    assert len(result) == 11 and np.all(result["x"] == 0.0) and np.all(result["u"] == 2.5)


def test_c_floor_states_restore_its_variables_and_refuse_bytes_of_another_size(c_floor, tmp_path):
    folder = c_hosts.extract(c_floor, tmp_path)
    description = fmpy.read_model_description(str(folder))
    assert description.coSimulation.canGetAndSetFMUstate and description.coSimulation.canSerializeFMUstate
    fmu = FMU2Slave(guid=description.guid, unzipDirectory=str(folder), modelIdentifier="CFloor")
    fmu.instantiate()
    fmu.setReal([1], [2.5])
    state = fmu.getFMUstate()
    fmu.setReal([1], [-4.0])
    fmu.setFMUstate(state)
    assert fmu.getReal([1]) == [2.5]
    data = fmu.serializeFMUstate(state)
    assert len(data) == 614  # a serialized state of SpringBlockFriction.fmu where state_costs measures it
    fmu.setReal([1], [-4.0])
    copy = fmu.deSerializeFMUstate(data)
    fmu.setFMUstate(copy)
    assert fmu.getReal([1]) == [2.5] and fmu.serializeFMUstate(copy) == data
    with pytest.raises(FMICallException, match="fmi2DeSerializeFMUstate") as refused:
        fmu.deSerializeFMUstate(data[:-1])
    assert refused.value.status == fmi2Error
    for saved in (state, copy):
        fmu.freeFMUstate(saved)
    fmu.freeInstance()


def test_c_floor_runs_in_our_c_host(c_floor, host, tmp_path):
    folder = c_hosts.extract(c_floor, tmp_path)
    run = run_host(host, folder, "run", 1.0, 0.25)
    assert run.completed and run.series("x") == ([0.0, 0.25, 0.5, 0.75, 1.0], [0.0] * 5)


def test_ours_in_our_c_host_meets_the_scenario_tolerance_against_the_reference(fmu_path, host, tmp_path):
    scene = SCENES["msl-pendulum"]
    ours = c_hosts.Subject("ours", fmu_path, "x", scene.start_values(1e-10))
    assert c_hosts.scene_error(c_hosts.CHost(host, tmp_path), ours, scene) <= 2e-8  # msl-pendulum.toml's max_abs_dx


def test_timed_child_reports_a_failing_child_with_its_exit_code_and_output():
    wall, cpu, out = timed_child([sys.executable, "-c", "print('fine')"])
    assert out == "fine\n" and wall > 0 and cpu >= 0
    with pytest.raises(ChildFailed, match="exited with 3: boom"):
        timed_child([sys.executable, "-c", "import sys; print('boom'); sys.exit(3)"])


def test_per_step_cost_is_the_slope_of_the_medians_and_start_up_the_short_run():
    short = Timings(wall=[0.09, 0.1, 0.5], cpu=[0.08, 0.08, 0.08])
    long = Timings(wall=[0.6, 0.61, 0.59], cpu=[0.28, 0.3, 0.29])
    assert slope(short, long, 1, 50_001) == pytest.approx({"wall_us": 10.0, "cpu_us": 4.2})
    assert startup(short, Timings([0.02], [0.01])) == pytest.approx({"wall_ms": 120.0, "cpu_ms": 90.0})


class _FakeHost:
    """Runs a do-nothing Python child per run and records the (subject, steps) of each run in order."""

    name = "fake"

    def __init__(self):
        self.calls = []

    def command(self, subject, stop_time, step):
        self.calls.append((subject.name, round(stop_time / step)))
        return [sys.executable, "-c", "print('cpu_us_per_step 1.5')"]

    def env(self):
        return None

    def extra_startup(self, subject):
        return (0.25, 0.125)


def test_measure_alternates_the_fmus_in_every_round_with_both_run_lengths():
    host = _FakeHost()
    subjects = [c_hosts.Subject("a", Path("a.fmu")), c_hosts.Subject("b", Path("b.fmu"))]
    records = c_hosts.measure(host, subjects, 0.01, 200, repeats=2, progress=lambda _: None)
    assert host.calls == [("a", 1), ("a", 200), ("b", 1), ("b", 200)] * 2
    for record in records.values():
        assert len(record["times_s"]["long"]["wall"]) == 2 and record["in_host_cpu_us"] == 1.5
        assert record["startup"]["wall_ms"] >= 250.0  # the extraction's 0.25 s is part of the start-up


def test_fmusim_command_reads_one_output_at_the_step_with_the_start_values(tmp_path):
    subject = c_hosts.Subject("ours", Path("/f/Ours.fmu"), "x", {"solver.rtol": 1e-8, "M": 1.0})
    command = c_hosts.Fmusim("/bin/fmusim", tmp_path).command(subject, 500.0, 0.01)
    assert command[:9] == ["/bin/fmusim", "--interface-type", "cs", "--stop-time", "500.0", "--output-interval",
                           "0.01", "--output-variable", "x"]
    assert command[9:15] == ["--start-value", "solver.rtol", "1e-08", "--start-value", "M", "1.0"]
    assert command[-1] == "/f/Ours.fmu"


#: SpringFrictionPendulum1D.mo (FMIZoo.jl): fricScale = 20, F_prop = 1/fricScale, F_Coulomb = 5/fricScale,
#: F_Stribeck = 10/fricScale, fexp = 2, m = 1, spring c = 10 with s_rel0 = 1 from a fixed flange at 0, s0 = 0.5
MODELICA_VALUES = {"mass.m": 1.0, "spring.c": 10.0, "mass.s": 0.5, "fixed.s0": 0.0, "spring.s_rel0": 1.0,
                   "mass.v": 0.0, "mass.F_Coulomb": 5 / 20, "mass.F_Stribeck": 10 / 20, "mass.fexp": 2.0,
                   "mass.F_prop": 1 / 20}


def test_msl_pendulum_scene_is_the_modelica_model_and_a_changed_peer_is_named(monkeypatch):
    scene = SCENES["msl-pendulum"]
    monkeypatch.setattr(dymola_peer, "peer_values", lambda path: dict(MODELICA_VALUES))
    assert dymola_peer.mismatches("peer.fmu", scene) == []
    assert dymola_peer.subject("peer.fmu").offset == 1.0
    monkeypatch.setattr(dymola_peer, "peer_values", lambda path: {**MODELICA_VALUES, "spring.c": 11.0})
    assert dymola_peer.mismatches("peer.fmu", scene) == [("kappa", 10.0, 11.0)]


def test_loosest_rtol_is_the_first_reaching_the_target_else_the_most_accurate_tried():
    asked = []

    def error_at(rtol):
        asked.append(rtol)
        return max(10 * rtol, 3e-12)

    assert loosest_rtol(error_at, 1e-7) == (1e-8, 1e-7) and asked == list(OUR_RTOLS[:5])
    assert loosest_rtol(error_at, 1e-15) == (1e-13, 3e-12)


def _made_up_results():
    def record(per_step_us, startup_ms):
        return {"per_step": {"wall_us": per_step_us, "cpu_us": per_step_us}, "in_host_cpu_us": None,
                "startup": {"wall_ms": startup_ms, "cpu_ms": startup_ms}}

    row = {"peer_tolerance": 1e-6, "peer_error": 1e-5, "our_rtol": 1e-6, "our_error": 1e-6, "peer_wall_ms": 2.0,
           "peer_cpu_ms": 2.0, "our_wall_ms": 3.0, "our_cpu_ms": 3.0, "ratio_wall": 1.5, "ratio_cpu": 1.5}
    return {"meta": {"date": "today", "machine": "m", "load_start": [1.5, 1, 1], "load_end": [2.5, 2, 2],
                     "steps": 50_000, "step": 0.01, "repeats": 5},
            "matched": {"peer_error": {"C host": 2e-4}, "our_rtol": 1e-4, "our_error": {"C host": 4e-5}},
            "hosts": {"C host": {"ours": record(4.0, 90.0), "peer (Dymola)": record(2.0, 80.0),
                                 "PythonFMU floor": record(1.6, 70.0), "C floor": record(0.5, 2.0)}},
            "fmpy": [row], "dense_grid": [row], "dense_grid_tuned": [{**row, "peer_tolerance": 1e-11}],
            "one_step": {"fmu": {"wall_ms": 6.0, "cpu_ms": 6.0}, "floor": {"wall_ms": 5.0, "cpu_ms": 5.0},
                         "ratio_wall": 1.2, "ratio_cpu": 1.2},
            "carried_python": {"fmi2": {"size_mb": {"ours": 7.5, "without": 2.4},
                                        "fmpy_ms": {clock: {"ours": 44.0, "without": 40.0, "ratio": 1.1}
                                                    for clock in ("wall", "cpu")},
                                        "c_host_ms": {clock: {"ours": 120.0, "without": 100.0, "first": 500.0,
                                                              "ratio": 1.2} for clock in ("wall", "cpu")}}},
            "states": {"C host": {"FMI 2": dict(zip(STATE_CALLS, (0.5, 1.0, 0.75, 1.25, 20.0, 40.0))),
                                  STATE_FLOOR: dict(zip(STATE_CALLS, (0.01, 0.02, 0.01, 0.015, 0.05, 0.03)))}}}


def test_report_states_the_load_and_the_ratios_of_the_same_run(tmp_path):
    results = _made_up_results()
    report = markdown(results)
    assert "at the start [1.5, 1, 1], at the end [2.5, 2, 2]" in report
    assert "| fmi2 | cpu | 7.50 / 2.40 | 44.0 / 40.0 | 1.1 | 120.0 / 100.0 | 1.2 | 500 |" in report
    tuned = report[report.index("hand-tuned DOP853"):]
    assert "| 1e-11 | 1e-05 | 2 | 2 | 1e-06 | 1e-06 | 3 | 3 | 1.5 | 1.5 |" in tuned
    # 4/2, 4/0.5, 4/1.6, 2/0.5; start-up 90/80; own cost 4 - 0.5, 2 - 0.5
    assert "| C host | 2 / 2 | 8 / 8 | 2.5 / 2.5 | 4 / 4 | 1.12 / 1.12 | 3.5, 1.5 |" in report
    # each FMU-state call over the doStep of 0.5 µs
    assert "| C host | FMI 2 | 0.5 | 2 (1 µs) | 1.5 (0.75 µs) | 2.5 (1.25 µs) | 40 (20 µs) | 80 (40 µs) |" in report
    assert "| C host | C floor, FMI 2 | 0.01 | 2 (0.02 µs) | 1 (0.01 µs) | 1.5 (0.015 µs) | 5 (0.05 µs) | 3 (0.03 µs) |" \
        in report  # the floor FMU's row, over its own doStep
    paths = write(tmp_path / "out", results)
    assert json.loads(paths[0].read_text()) == results and paths[2].stat().st_size > 0


def test_bench_c_hosts_refuses_a_missing_peer(tmp_path, capsys):
    parser = argparse.ArgumentParser()
    add_c_hosts_parser(parser.add_subparsers())
    args = parser.parse_args(["bench-c-hosts", "--peer", str(tmp_path / "none.fmu"), "--out", str(tmp_path)])
    assert args.handler(args) == 2 and "none.fmu" in capsys.readouterr().err


def test_bench_c_hosts_without_its_inputs_measures_ours_and_the_floors(tmp_path, fmu_path, fmu3_path, host,
                                                                       monkeypatch):
    machine_needs.c_compiler("the compiled floor FMU")
    monkeypatch.setattr(fmus, "BUILD_DIR", tmp_path / "build")
    parser = argparse.ArgumentParser()
    add_c_hosts_parser(parser.add_subparsers())
    args = parser.parse_args(["bench-c-hosts", "--fmu", str(fmu_path), "--fmu3", str(fmu3_path), "--out",
                              str(tmp_path / "out"), "--steps", "20", "--repeats", "1", "--state-rounds", "5",
                              "--no-carried-python"])
    assert args.handler(args) == 0
    results = json.loads((tmp_path / "out" / "c-hosts.json").read_text())
    assert set(results["hosts"]) == {"C host"}
    assert set(results["hosts"]["C host"]) == {"ours", "PythonFMU floor", "C floor"}
    assert results["matched"]["our_error"]["C host"] <= 2e-8 and "fmpy" not in results
    assert all(row["our_error"] <= row["peer_error"] for row in results["dense_grid"] + results["dense_grid_tuned"])
    assert "## One-step `simulate_fmu` of the .fmu file" in (tmp_path / "out" / "c-hosts.md").read_text()
    states = results["states"]  # every FMU-state call measured in both hosts, for both FMI versions
    assert {(host, version) for host in states for version in states[host]} == {
        (host, version) for host in ("C host", "FMPy") for version in ("FMI 2", "FMI 3", STATE_FLOOR)}
    assert all(set(costs) == set(STATE_CALLS) and min(costs.values()) > 0
               for versions in states.values() for costs in versions.values())
