"""Input signals ``v_drive`` (m/s) and ``F_ext`` (N): the FMPy input table and what the FMU sees.

A signal is piecewise linear through its points, held constant before the first
and after the last point; a time given twice is a step. FMPy (2.0 co-simulation,
``fmpy.simulation.simulateCS``) samples the table at every communication point
(the value after a step at that time), holds it during ``doStep``, and inserts a
communication point at every step of the table. :func:`applied_inputs` and
:func:`zoh_breakpoints` reproduce that loop (bit for bit: the test drives the FMU
through FMPy and compares), so the reference integrates the same
piecewise-constant inputs as the FMU.
"""

from math import isclose

import numpy as np

from ..fmu.variables import INPUTS as INPUT_NAMES  # ("v_drive", "F_ext"), from the variable table


class Signal:
    """A piecewise-linear signal with steps, from points ``[(t, value), ...]`` sorted by ``t``."""

    def __init__(self, points):
        self.t = np.array([p[0] for p in points], dtype=float)
        self.value = np.array([p[1] for p in points], dtype=float)

    @classmethod
    def constant(cls, value):
        return cls([(0.0, value)])

    def left(self, time):
        """Value just before ``time`` (before a step there)."""
        i = np.searchsorted(self.t, time, side="left")
        if i == len(self.t) or self.t[i] == time:
            return self.value[min(i, len(self.t) - 1)]
        return self._between(i - 1, time) if i > 0 else self.value[0]

    def right(self, time):
        """Value at and just after ``time`` (after a step there)."""
        i = np.searchsorted(self.t, time, side="right") - 1
        if i < 0:
            return self.value[0]
        return self._between(i, time) if i + 1 < len(self.t) else self.value[-1]

    def breaks(self):
        """The signal's point times (s), each once."""
        return np.unique(self.t)

    def _between(self, i, time):
        t0, t1 = self.t[i], self.t[i + 1]
        w = (time - t0) / (t1 - t0)
        return (1.0 - w) * self.value[i] + w * self.value[i + 1]


def input_table(signals, start_time, stop_time):
    """FMPy input table (structured array: ``time``, ``v_drive``, ``F_ext``) for ``signals``.

    ``signals`` maps each name of :data:`INPUT_NAMES` to a :class:`Signal`. The
    table has a row at every point of either signal within the run and two rows
    (before, after) where either signal steps. Constant inputs give a single row,
    which FMPy applies exactly (interpolating between equal rows may round).
    """
    dtype = [("time", np.float64)] + [(name, np.float64) for name in INPUT_NAMES]
    if all(len(signal.t) == 1 for signal in signals.values()):
        return np.array([(start_time, *(signals[name].value[0] for name in INPUT_NAMES))], dtype=dtype)
    times = {start_time, stop_time}
    for signal in signals.values():
        times.update(t for t in signal.breaks() if start_time < t < stop_time)
    rows = []
    for t in sorted(times):
        before = tuple(signals[name].left(t) for name in INPUT_NAMES)
        after = tuple(signals[name].right(t) for name in INPUT_NAMES)
        if before != after and t > start_time:
            rows.append((t, *before))
        rows.append((t, *after))
    return np.array(rows, dtype=dtype)


def communication_points(table, start_time, stop_time, output_interval):
    """The communication points (s) of FMPy's co-simulation loop with this input table.

    Reproduces ``simulateCS`` for an FMU that handles variable step sizes: a
    regular grid ``start + k * output_interval`` plus every step time of the table.
    """
    t_events = list(np.unique(table["time"][:-1][np.diff(table["time"]) == 0])) + [float("inf")]
    points = [start_time]
    time, n_steps = start_time, 0
    while not (time > stop_time or isclose(time, stop_time)):
        next_regular = start_time + (n_steps + 1) * output_interval
        next_event = next(t for t in t_events if t > time and not isclose(t, time))
        point = next_regular
        if point > next_event and not isclose(point, next_event):
            point = next_event
        if point > stop_time and not isclose(point, stop_time):
            point = stop_time
        time = point
        points.append(time)
        if isclose(time, next_regular):
            n_steps += 1
    return np.array(points)


def applied_inputs(table, times):
    """Inputs FMPy applies at each communication point: rows ``(v_drive, F_ext)``, see :func:`sampled_row`."""
    values = np.stack([table[name] for name in INPUT_NAMES], axis=1)
    return np.array([sampled_row(table["time"], values, t) for t in times])


def sampled_row(table_times, rows, time):
    """The row of input values FMPy applies at ``time`` (s) from a table (``rows[i]`` at ``table_times[i]``).

    Held before the first and after the last time; at a step (a time listed
    twice, or within FMPy's ``math.isclose``) the value after it, i.e. at the
    last copy of that time; elsewhere linear between the neighbouring rows, as
    ``w0 v0 + w1 v1`` with ``w0 = (t1 - time)/(t1 - t0)``, ``w1 = 1 - w0``
    (FMPy's weights, so the same doubles).
    """
    if len(table_times) < 2 or time <= table_times[0]:
        return rows[0]
    if time > table_times[-1]:
        return rows[-1]
    i = int(np.searchsorted(table_times, time))  # the first row at or after time
    at_step = isclose(time, table_times[i]) and i + 1 < len(table_times) and isclose(table_times[i],
                                                                                     table_times[i + 1])
    if at_step:
        while i + 1 < len(table_times) and isclose(table_times[i], table_times[i + 1]):
            i += 1
        return rows[i]
    t0, t1 = table_times[i - 1], table_times[i]
    w0 = (t1 - time) / (t1 - t0)
    w1 = 1 - w0
    return w0 * rows[i - 1] + w1 * rows[i]


def zoh_breakpoints(table, start_time, stop_time, output_interval):
    """Zero-order-hold breakpoints ``[(t_k, v_drive_k, F_ext_k), ...]`` the FMU integrates.

    Holds on ``[t_k, t_{k+1})``; the first ``t_k`` is ``start_time``; only the
    points where a value changes are kept.
    """
    times = communication_points(table, start_time, stop_time, output_interval)[:-1]
    breakpoints = []
    for t, (v_drive, F_ext) in zip(times, applied_inputs(table, times)):
        if not breakpoints or (v_drive, F_ext) != breakpoints[-1][1:]:
            breakpoints.append((float(t), float(v_drive), float(F_ext)))
    return breakpoints



def held_input_table(breakpoints, stop_time):
    """FMPy input table that holds each of ``breakpoints`` ``[(t, v_drive, F_ext), ...]`` until the next (a step
    there) and the last until ``stop_time``: the inputs of a model-exchange run that sees exactly what a
    co-simulation holds."""
    rows = [(breakpoints[0][0], *breakpoints[0][1:])]
    for (_, *before), (t, *after) in zip(breakpoints, breakpoints[1:]):
        rows += [(t, *before), (t, *after)]
    rows.append((stop_time, *breakpoints[-1][1:]))
    return np.array(rows, dtype=[("time", np.float64)] + [(name, np.float64) for name in INPUT_NAMES])
