"""The ``zoh`` master: fixed communication step, inputs held over it, as co-simulation engines do.

One FMI 2 co-simulation instance of ``SpringBlockFriction.fmu`` per block (FMPy, through
:mod:`stickslip.hosts.fmpy_host`: extracted once). At each communication point ``t_k = k h`` every block's
``F_ext`` is set from the positions all blocks had at ``t_k`` (SPEC section 5) and held while each block
steps to ``t_(k+1)`` with its own exact stepper (a Jacobi scheme: no block sees another's new position
within a step). Holding the coupling force is first order in ``h``: the measured error on the 2-block
chain is in benchmarks/README.md. Each block reports its events through ``n_events`` and
``t_last_event``: one event within a step is known with its exact time, more only by count.

With ``engine`` (``fmpy``, ``libcosim``, ``ecos``) the master writes the system as an SSP file instead, the
coupling springs as coupling FMUs, and an engine steps it (:mod:`.engines`: the force then reaches a block one
step later than here).
"""

import math
import time

import numpy as np

from ..hosts.fmpy_host import FMUError
from ..hosts.run_limits import too_many_steps
from .engines import INTEGERS, REALS, run_ssp
from .master import SystemResult, block_instances, read_values, references, step_events
from .names import ENGINES



class ZohMaster:
    """Fixed step ``step`` (s; default: the system's output interval, which must be a whole multiple of it)."""

    NAME = "zoh"
    FMI_VERSION = 2
    OPTIONS = ("step", "engine")

    def __init__(self, step=None, engine=None):
        if step is not None and not (math.isfinite(step) and step > 0.0):
            raise FMUError(f"zoh: step = {step!r} s: allowed is a finite step > 0")
        if engine is not None and engine not in ENGINES:
            raise FMUError(f"zoh: engine = {engine!r}: allowed is one of {list(ENGINES)}")
        self.step, self.engine = step, engine

    def _grid(self, system):
        """``(h, steps per output)``: the step and the number of steps between output points."""
        h = self.step or system.output_interval
        ratio = system.output_interval / h
        per_output = round(ratio)
        if per_output < 1 or abs(ratio - per_output) > 1e-9 * ratio:
            raise FMUError(f"zoh: step = {h!r} s: allowed is output_interval ({system.output_interval!r} s) "
                           f"divided by a whole number")
        why = too_many_steps(system.stop_time, h, system.n)
        if why:
            raise FMUError(f"zoh: step = {h!r} s: {why}")
        return h, per_output

    def run(self, system, fmu_path, progress=lambda t: None):
        h, per_output = self._grid(system)
        grid = np.asarray(system.times())
        with block_instances(self, system, fmu_path) as (fmu, blocks):
            run = _Run(system, fmu, blocks, h, per_output, grid)
            if self.engine is None:
                return run.run(progress)
            first = run.read()
        start = time.perf_counter()
        rows = run_ssp(self.engine, system, h, fmu_path)
        progress(system.stop_time)
        return run.from_rows(first, rows, time.perf_counter() - start, self.engine)


class _Run:
    """One co-simulation: the instances, the samples taken and the events seen."""

    def __init__(self, system, fmu, blocks, h, per_output, grid):
        self.system, self.blocks, self.h, self.per_output, self.grid = system, blocks, h, per_output, grid
        self.reals, self.integers = references(fmu, REALS), references(fmu, INTEGERS)
        self.F_ext = references(fmu, ("F_ext",))
        self.rows, self.events, self.complete = [], [], True

    def read(self):
        """``(x, v, t_last_event, mode, n_events)`` of every block, each a list over blocks."""
        return read_values(self.blocks, self.reals, self.integers)

    def run(self, progress):
        start = time.perf_counter()
        x, v, _, mode, count = self.read()
        self.rows.append((x, v, mode))
        t, k, n_steps = 0.0, 0, round((self.grid[-1] - self.grid[0]) / self.h)
        for k in range(1, n_steps + 1):
            target = self.grid[0] + k * self.h if k < n_steps else float(self.grid[-1])
            for block, F in zip(self.blocks, self.system.forces(x)):
                block.call(block.fmu.setReal, self.F_ext, [F])
                block.call(block.fmu.doStep, t, target - t)
            t = t + (target - t)  # the FMU's own new time
            values = self.read()
            x = values[0]
            mode, count = self.sample(k, n_steps, values, mode, count)
            if k % self.per_output == 0:
                progress(t)
        return self.result(count, n_steps, time.perf_counter() - start, {"step (s)": self.h})

    def sample(self, k, n_steps, values, mode, count):
        """Record the events of step ``k`` (1-based) and the row if it ends on the output grid; the new
        ``(mode, n_events)``. ``values``: ``(x, v, t_last_event, mode, n_events)`` after the step."""
        x, v, t_last, new_mode, new_count = values
        self._events(t_last, mode, new_mode, count, new_count)
        if k % self.per_output == 0 or k == n_steps:
            self.rows.append((x, v, new_mode))
        return new_mode, new_count

    def result(self, count, n_steps, wall_time, settings, instances=None):
        """The :class:`SystemResult` of the rows and events recorded; ``instances``: FMU instances stepped (default:
        one per block)."""
        xs, vs, modes = (np.array(column) for column in zip(*self.rows))
        stepped = instances or len(self.blocks)
        return SystemResult(ZohMaster.NAME, self.grid[:len(xs)].copy(), xs, vs, modes, self.events, self.complete,
                            np.array(count), wall_time, settings,
                            {"communication steps": n_steps, "doStep calls": n_steps * stepped})

    def from_rows(self, first, rows, wall_time, engine):
        """The result of an engine's ``rows`` (:func:`.engines.run_ssp`; ``first``: the values at t = 0)."""
        x, v, _, mode, count = first
        self.rows.append((x, v, mode))
        columns = [rows[name] for name in REALS + INTEGERS]
        n_steps = len(columns[0])
        for k, values in enumerate(zip(*columns), start=1):
            mode, count = self.sample(k, n_steps, [list(column) for column in values], mode, count)
        settings = {"step (s)": self.h, "engine": f"{engine} (SSP: blocks and coupling FMUs)"}
        return self.result(count, n_steps, wall_time, settings, instances=2 * len(self.blocks))  # and couplings

    def _events(self, t_last, mode, new_mode, count, new_count):
        """Record the events of the last step."""
        events, complete = step_events(t_last, mode, new_mode, count, new_count)
        self.events += events
        self.complete = self.complete and complete
