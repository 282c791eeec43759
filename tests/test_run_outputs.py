"""What ``stickslip run`` writes, against numbers computed here (issue 22): the report's columns from an FMPy run
of the FMU and the independent reference run in this file, the CSV's columns by name against that FMPy run, and
the arrays one figure plots.

The scenarios' errors differ from column to column by far more than the three significant digits printed
(stribeck-fext-constant: max |dx| 4.7e-9 m, max |dv| 6.6e-9 m/s, final |dx| 4.8e-10 m, event dt 8.0e-9 s;
elmer-fig3-fext-step, an F_ext step at 130 s: 1.4e-8, 2.8e-9, 6.8e-9, 1.3e-7), so a column swapped or
mislabelled fails.
"""

import csv
from pathlib import Path

import fmpy
import numpy as np
import pytest

from stickslip.cli import main
from stickslip.reference import parameters_from_values, simulate_reference
from stickslip.suite.scenario import load_scenario
from stickslip.suite.scenario_plots import plot_scenario

SCENARIO_DIR = Path(__file__).resolve().parents[1] / "scenarios"
NAMES = ("stribeck-fext-constant", "elmer-fig3-fext-step")
COUNTERS = {"n_stick_events": "stick", "n_slip_events": "slip", "n_overshoots": "overshoot"}
#: the report prints errors with three significant digits
PRINTED = 5e-3


def _columns(fmu_path):
    """The CSV's columns as docs/scenarios.md gives them: time, the FMU's outputs in the order the model
    description declares them, then the inputs v_drive and F_ext."""
    description = fmpy.read_model_description(str(fmu_path))
    return ["time"] + [v.name for v in description.modelVariables if v.causality == "output"] + ["v_drive", "F_ext"]


def _fmpy_run(fmu_path, scenario, columns):
    """The scenario through ``fmpy.simulate_fmu`` directly (not the suite's host), recording ``columns``."""
    return fmpy.simulate_fmu(str(fmu_path), start_values=scenario.start_values(), stop_time=scenario.stop_time,
                             output_interval=scenario.output_interval, input=scenario.input_table(),
                             output=columns[1:])


def _reference(scenario, times):
    """The independent reference of ``scenario`` on ``times`` (s), with the scenario file's inputs."""
    return simulate_reference(parameters_from_values(scenario.law_values), scenario.x0, scenario.v0,
                              scenario.breakpoints(), times)


def _kind(before, after):
    """The event kind of the mode change ``before -> after``."""
    return "stick" if after == 0 else ("slip" if before == 0 else "overshoot")


def _event_error(fmu, ref):
    """``(largest |t_FMU - t_ref| s over the events the FMU times exactly, number of FMU events)``.

    The FMU times an event exactly when a communication step holds one new event and ``t_last_event`` lies in
    the step; the k-th FMU event of a kind is the reference's k-th mode change of that kind (each kind must
    have as many)."""
    times = {kind: [] for kind in COUNTERS.values()}
    for i in range(1, len(fmu)):
        new = [kind for name, kind in COUNTERS.items() for _ in range(fmu[name][i] - fmu[name][i - 1])]
        timed = len(new) == 1 and fmu["time"][i - 1] < fmu["t_last_event"][i] <= fmu["time"][i]
        for kind in new:
            times[kind].append(fmu["t_last_event"][i] if timed else None)
    expected = {kind: [] for kind in COUNTERS.values()}
    for event in ref.events:
        if event.mode_before != event.mode_after:
            expected[_kind(event.mode_before, event.mode_after)].append(event.t)
    assert {k: len(v) for k, v in times.items()} == {k: len(v) for k, v in expected.items()}
    errors = [abs(t - t_ref) for kind in times for t, t_ref in zip(times[kind], expected[kind]) if t is not None]
    return max(errors), sum(len(v) for v in times.values())


def _report_rows(text):
    """``{scenario: {column: cell}}`` of report.md's summary table."""
    lines = [line for line in text.splitlines() if line.startswith("|")]
    header = [cell.strip() for cell in lines[0].strip("|").split("|")]
    rows = [[cell.strip() for cell in line.strip("|").split("|")] for line in lines[2:]]
    return {row[0]: dict(zip(header, row)) for row in rows}


@pytest.fixture(scope="module")
def written(fmu_path, tmp_path_factory):
    """The folder ``stickslip run`` wrote for :data:`NAMES` (exit status 0)."""
    out = tmp_path_factory.mktemp("run") / "out"
    paths = [str(SCENARIO_DIR / f"{name}.toml") for name in NAMES]
    assert main(["run", *paths, "--out", str(out), "--jobs", "1", "--fmu", str(fmu_path)]) == 0
    return out


@pytest.fixture(scope="module")
def runs(fmu_path):
    """``{name: (scenario, FMPy result, reference on its grid)}``, all computed here."""
    columns = _columns(fmu_path)
    out = {}
    for name in NAMES:
        scenario = load_scenario(SCENARIO_DIR / f"{name}.toml")
        fmu = _fmpy_run(fmu_path, scenario, columns)
        out[name] = (scenario, fmu, _reference(scenario, fmu["time"]))
    return out


@pytest.mark.parametrize("name", NAMES)
def test_the_csv_holds_the_fmus_outputs_by_name(written, runs, fmu_path, name):
    _, fmu, _ = runs[name]
    with open(written / f"{name}.csv", newline="") as file:
        header, *rows = list(csv.reader(file))
    assert header == _columns(fmu_path)
    table = np.array(rows, dtype=float)
    assert table.shape == (len(fmu), len(header))
    for k, column in enumerate(header):
        np.testing.assert_array_equal(table[:, k], fmu[column], err_msg=column)  # every digit: str() round-trips


@pytest.mark.parametrize("name", NAMES)
def test_the_report_states_the_errors_computed_here_in_their_columns(written, runs, name):
    scenario, fmu, ref = runs[name]
    row = _report_rows((written / "report.md").read_text())[name]
    dx = np.abs(fmu["x"] - ref.x)
    steps = [t for t, _, _ in scenario.breakpoints()[1:]]  # v is compared away from the input steps
    dv = np.abs(fmu["v"] - ref.v)[~np.isin(fmu["time"], steps)]
    event_dt, n_events = _event_error(fmu, ref)
    expected = {"max abs dx (m)": dx.max(), "max abs dv (m/s)": dv.max(), "final abs dx (m)": dx[-1],
                "event dt (s)": event_dt}
    assert min(expected.values()) > 0.0
    assert {column: float(row[column]) for column in expected} == {
        column: pytest.approx(value, rel=PRINTED) for column, value in expected.items()}
    assert row["events matched/unmatched"] == f"{n_events}/0" and n_events >= 10
    assert (row["attractor expected"], row["attractor found"], row["result"]) == ("stick-slip",) * 2 + ("PASS",)


def test_the_figure_plots_the_fmu_and_the_reference_where_they_say(tmp_path, runs):
    scenario, fmu, ref = runs["stribeck-fext-constant"]
    fig = plot_scenario(tmp_path / "plot.png", scenario.name, fmu, ref, scenario.tolerance.max_abs_dx)
    assert (tmp_path / "plot.png").stat().st_size > 0
    axes = {ax.get_title() or ax.get_ylabel(): ax for ax in fig.axes}
    x_t, dx_t, phase = axes[scenario.name], axes["|x_FMU - x_ref| (m)"], axes["phase portrait"]
    assert np.abs(fmu["x"] - ref.x).max() > 0.0  # the FMU's curve and the reference's differ

    def data(line):
        return np.asarray(line.get_xdata()), np.asarray(line.get_ydata())

    lines = {line.get_label(): data(line) for line in x_t.get_lines()}
    for label, (t, x) in (("FMU", (fmu["time"], fmu["x"])), ("reference", (ref.t, ref.x))):
        np.testing.assert_array_equal(lines[label][0], t, err_msg=label)
        np.testing.assert_array_equal(lines[label][1], x, err_msg=label)
    dx = np.abs(fmu["x"] - ref.x)
    (error,) = [data(line) for line in dx_t.get_lines() if line.get_linestyle() == "-"]
    np.testing.assert_array_equal(error[0], fmu["time"][dx > 0.0])
    np.testing.assert_array_equal(error[1], dx[dx > 0.0])
    solid, dashed = [data(line) for line in phase.get_lines()[:2]]
    assert [line.get_linestyle() for line in phase.get_lines()[:2]] == ["-", "--"]
    for (x, v), (x_expected, v_expected) in ((solid, (fmu["x"], fmu["v"])), (dashed, (ref.x, ref.v))):
        np.testing.assert_array_equal(x, x_expected)
        np.testing.assert_array_equal(v, v_expected)


@pytest.mark.filterwarnings("error")
def test_the_figure_of_a_run_without_any_difference_has_a_log_axis_that_holds_the_tolerance(tmp_path, fmu_path):
    """coulomb-FK-equals-FS: the FMU equals the reference at every sample, so nothing is drawn on the |dx| axis;
    its limits are set (no warning of equal limits) and hold the tolerance line."""
    scenario = load_scenario(SCENARIO_DIR / "coulomb-FK-equals-FS.toml")
    fmu = _fmpy_run(fmu_path, scenario, _columns(fmu_path))
    ref = _reference(scenario, fmu["time"])
    assert not np.any(fmu["x"] - ref.x)
    fig = plot_scenario(tmp_path / "plot.png", scenario.name, fmu, ref, scenario.tolerance.max_abs_dx)
    assert (tmp_path / "plot.png").stat().st_size > 0
    (dx_axis,) = [ax for ax in fig.axes if ax.get_ylabel() == "|x_FMU - x_ref| (m)"]
    low, high = dx_axis.get_ylim()
    assert 0.0 < low < scenario.tolerance.max_abs_dx < high
