"""Input signals: the FMPy table, and the zero-order-hold breakpoints equal what FMPy applies to the FMU."""

import numpy as np
import pytest

from stickslip.hosts.fmpy_host import run_fmu
from stickslip.suite.inputs import Signal, applied_inputs, communication_points, input_table, zoh_breakpoints

RAMP_STEP = {
    # ramp, hold, a step at a time off the output grid, then a ramp down
    "v_drive": Signal([(0.0, 0.0), (1.0, 0.3), (2.0, 0.3), (2.33, 0.3), (2.33, 0.05), (4.0, 0.0)]),
    # a step and a ramp at other times than v_drive's
    "F_ext": Signal([(0.0, 0.0), (1.57, 0.0), (1.57, 0.2), (3.0, -0.1)]),
}
START, STOP, INTERVAL = 0.0, 5.0, 0.1


def hold(breakpoints, times):
    """The zero-order-hold inputs at ``times``: rows (v_drive, F_ext)."""
    i = np.searchsorted([b[0] for b in breakpoints], times, side="right") - 1
    return np.array([b[1:] for b in breakpoints])[i]


COULOMB = {"M": 1.0, "kappa": 1.0, "x_start": 0.0, "v_start": 0.0, "kinetic.law": 1, "kinetic.F0": 0.5,
           "static.law": 1, "static.F0": 1.0}


def test_signal_is_linear_between_points_held_outside_and_steps_at_repeated_times():
    s = RAMP_STEP["v_drive"]
    assert s.left(-1.0) == s.right(-1.0) == 0.0
    assert s.right(0.5) == pytest.approx(0.15)
    assert (s.left(2.33), s.right(2.33)) == (0.3, 0.05)
    assert s.left(9.0) == s.right(9.0) == 0.0
    assert Signal.constant(0.7).right(3.0) == 0.7


def test_table_has_two_rows_at_each_step_and_one_row_for_constant_inputs():
    table = input_table(RAMP_STEP, START, STOP)
    assert list(table["time"]) == [0.0, 1.0, 1.57, 1.57, 2.0, 2.33, 2.33, 3.0, 4.0, 5.0]
    assert list(table["F_ext"][2:4]) == [0.0, 0.2]
    assert list(table["v_drive"][5:7]) == [0.3, 0.05]
    constant = input_table({"v_drive": Signal.constant(0.1), "F_ext": Signal.constant(0.0)}, START, STOP)
    assert constant.tolist() == [(0.0, 0.1, 0.0)]


def test_breakpoints_hold_on_the_communication_grid_including_step_times():
    table = input_table(RAMP_STEP, START, STOP)
    points = communication_points(table, START, STOP, INTERVAL)
    assert 2.33 in points and 1.57 in points
    breakpoints = zoh_breakpoints(table, START, STOP, INTERVAL)
    assert breakpoints[0][0] == START
    assert all(b[0] in points for b in breakpoints)
    assert hold(breakpoints, [2.32, 2.33])[:, 0].tolist() == pytest.approx([0.3, 0.05], abs=1e-15)
    assert hold(breakpoints, [1.56, 1.57])[:, 1].tolist() == pytest.approx([0.0, 0.2], abs=1e-15)


#: a table by hand: held before its first row (0.35 s), a step on a communication point (1 s), a time listed
#: three times (2.5 s: the value at its last copy counts), a ramp, and held after its last row (4.2 s)
EDGES = np.array([(0.35, 0.2, 0.0), (1.0, 0.1, 0.0), (1.0, 0.3, 0.1), (2.5, 0.3, 0.1), (2.5, 0.0, 0.3),
                  (2.5, 0.15, -0.2), (4.2, 0.05, 0.0)],
                 dtype=[("time", np.float64), ("v_drive", np.float64), ("F_ext", np.float64)])


@pytest.mark.parametrize("table", [input_table(RAMP_STEP, START, STOP), EDGES], ids=["ramp-step", "edges"])
def test_fmu_sees_exactly_the_breakpoints(fmu_path, table):
    """FMPy records each communication point after the step: the inputs held during that step, bit for bit
    what :func:`applied_inputs` says (FMPy's ``simulate_fmu``, its public API, against ours)."""
    result = run_fmu(fmu_path, COULOMB, STOP, INTERVAL, input_signal=table, outputs=["v_drive", "F_ext"])
    t = result["time"]
    assert np.array_equal(t, communication_points(table, START, STOP, INTERVAL))
    held = hold(zoh_breakpoints(table, START, STOP, INTERVAL), t[:-1])
    assert np.array_equal(result["v_drive"][1:], held[:, 0])
    assert np.array_equal(result["F_ext"][1:], held[:, 1])


def test_applied_inputs_hold_outside_the_table_take_the_last_copy_at_a_step_and_interpolate_between():
    times = [0.0, 0.35, 0.5, 1.0, 1.5, 2.5, 3.35, 4.2, 9.0]
    w0 = (1.0 - 0.5) / (1.0 - 0.35)
    expected = [(0.2, 0.0), (0.2, 0.0), (w0 * 0.2 + (1 - w0) * 0.1, 0.0), (0.3, 0.1), (0.3, 0.1), (0.15, -0.2),
                (0.5 * 0.15 + 0.5 * 0.05, -0.1), (0.05, 0.0), (0.05, 0.0)]
    assert applied_inputs(EDGES, times) == pytest.approx(np.array(expected), rel=1e-15, abs=1e-17)
    assert applied_inputs(EDGES[:1], times).tolist() == [[0.2, 0.0]] * len(times)
