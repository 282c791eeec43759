"""The ``me`` master: every block's FMI 3 model exchange integrated together by one solver.

One model-exchange instance of ``SpringBlockFriction-fmi3.fmu`` per block (:class:`~.me_blocks.ExchangeBlocks`).
scipy's DOP853 steps all ``2N`` states at relative tolerance ``rtol`` (absolute: ``rtol`` times each state's
nominal, as FMPy does) with steps of at most a twentieth of the chain's shortest free period while a block slips
(a fiftieth of the run while all are stuck: the chain then moves with the surface and each breakaway indicator
is concave for the constant, logarithmic and saturating laws, so no dip hides between steps); every derivative
evaluation sets each block's ``F_ext`` from the current positions, so the coupling is exact. After each step the
blocks' event indicators (``indicator.stick``, ``indicator.breakaway``, ``indicator.graze``: positive while
the mode lasts, or at an extremum of ``v_rel``) are compared with their signs at the step's start; the first
sign change (checked again at that point for indicators that changed sign and back before the step's end) is
located with brentq on the step's dense output, at its far side, and every block gets an event update there.
"""

import math
import time

import numpy as np

from ..hosts.fmpy_host import FMUError
from .master import SystemResult, block_instances, checked_rtol, new_event
from .me_blocks import ExchangeBlocks

STEPS_PER_PERIOD = 20
MAX_EVENTS_PER_INSTANT = 100
_POSITIVE_WHILE_MODE_LASTS = (0, 1)  # indicators stick and breakaway; graze (2) has either sign
_EPS = 2.220446049250313e-16


class MeMaster:
    """Relative tolerance ``rtol`` of the solver (default 1e-10)."""

    NAME = "me"
    FMI_VERSION = 3
    OPTIONS = ("rtol",)

    def __init__(self, rtol=None):
        self.rtol = checked_rtol("me", rtol, default=1e-10, lowest=1e-13)

    def run(self, system, fmu_path, progress=lambda t: None):
        with block_instances(self, system, fmu_path, interface="me") as (fmu, instances):
            blocks = ExchangeBlocks(system, fmu, instances)
            blocks.initial_update()
            return _Run(system, blocks, self.rtol, progress).run()


def max_step(system):
    """A twentieth of the bound on the chain's shortest free period (:meth:`~.system_file.System.shortest_period`),
    s."""
    return system.shortest_period() / STEPS_PER_PERIOD


class _Run:
    """One integration: the state, the indicators' signs, the samples and the events."""

    def __init__(self, system, blocks, rtol, progress):
        self.system, self.blocks, self.rtol, self.progress = system, blocks, rtol, progress
        self.grid = system.times()
        self.samples = np.empty((self.grid.size, 2 * blocks.n))
        self.modes = np.empty((self.grid.size, blocks.n), int)
        self.next_sample = 0
        self.t, self.y = 0.0, blocks.states()
        self.mode, self.count = blocks.counts()
        self.signs = self._signs()
        self.events, self.steps = [], 0
        self._instant, self._repeats = None, 0

    def _signs(self):
        """Each indicator's sign now; a zero takes the sign it has while its mode lasts (graze: unknown, 0)."""
        z = self.blocks.indicators(self.t, self.y)
        signs = np.sign(z)
        signs[:, list(_POSITIVE_WHILE_MODE_LASTS)] = np.where(z[:, list(_POSITIVE_WHILE_MODE_LASTS)] == 0.0, 1.0,
                                                               signs[:, list(_POSITIVE_WHILE_MODE_LASTS)])
        return signs

    def run(self):
        from scipy.integrate import DOP853  # here: the command's other masters do not import SciPy

        start = time.perf_counter()
        atol = self.rtol * self.blocks.nominals()
        t_end = float(self.grid[-1])
        while self.t < t_end:
            slipping = any(m != 0 for m in self.mode)  # all stuck: the indicators are concave, no dip to miss
            solver = DOP853(self.blocks.derivatives, self.t, self.y, t_end, rtol=self.rtol, atol=atol,
                            max_step=max_step(self.system) if slipping else t_end / 50.0)
            while solver.status == "running" and not self._step(solver):
                pass
            if solver.status == "failed":
                raise FMUError(f"me: the solver failed at t = {solver.t!r} s")
        self._sample_until(math.inf, lambda t: np.repeat(self.y[:, None], np.size(t), axis=1))
        _, counts = self.blocks.counts()
        xs, vs = self.samples[:, :self.blocks.n], self.samples[:, self.blocks.n:]
        return SystemResult(MeMaster.NAME, self.grid.copy(), xs, vs, self.modes, self.events, True,
                            np.array(counts), time.perf_counter() - start, {"rtol": self.rtol},
                            {"solver steps": self.steps, "derivative evaluations": self.blocks.evaluations,
                             "events": len(self.events)})

    def _step(self, solver):
        """One solver step; True if it ended at an event (applied: the solver must restart)."""
        solver.step()
        if solver.status == "failed":
            return False
        self.steps += 1
        dense, t_a, t_b = solver.dense_output(), solver.t_old, solver.t
        t_e = self._first_crossing(dense, t_a, t_b)
        t1 = t_b if t_e is None else t_e
        self._sample_until(t1, dense)
        self.t, self.y = t1, dense(t1)
        self.progress(self.t)
        if t_e is None:
            z = self.blocks.indicators(self.t, self.y)
            self.signs = np.where(z != 0.0, np.sign(z), self.signs)
            return False
        self._event()
        return True

    def _sample_until(self, t1, dense):
        """Record the grid times before ``t1`` from ``dense`` with the current modes."""
        stop = int(np.searchsorted(self.grid, t1, side="left"))
        if stop > self.next_sample:
            times = self.grid[self.next_sample:stop]
            self.samples[self.next_sample:stop] = np.asarray(dense(times)).T
            self.modes[self.next_sample:stop] = self.mode
            self.next_sample = stop

    def _crossed(self, t, y):
        """Mask ``(N, nz)`` of the indicators whose sign at ``(t, y)`` differs from their sign at the step's start."""
        z = self.blocks.indicators(t, y)
        return (self.signs != 0.0) & (z * self.signs <= 0.0)

    def _first_crossing(self, dense, t_a, t_b):
        """The time just past the first sign change of any indicator in ``[t_a, t_b]``, or None.

        The earliest located change ends the search window; indicators that changed sign by then (and back before
        ``t_b``: a dip of ``v_rel`` found through the graze indicator's extremum) are located in it again, until
        the window ends at the first change."""
        end = t_b
        crossed = self._crossed(end, dense(end))
        if not crossed.any():
            return None
        while True:
            t_e = min(self._locate(dense, t_a, end, i, k) for i, k in np.argwhere(crossed))
            if t_e >= end:
                return end
            end = t_e
            crossed = self._crossed(end, dense(end))

    def _locate(self, dense, t_a, t_b, i, k):
        """Just past the first zero of indicator ``k`` of block ``i`` in ``[t_a, t_b]``, where it has changed sign;
        ``t_a`` if it never left zero (it sits on it)."""
        sign = self.signs[i, k]

        def g(t):
            return sign * self.blocks.block_indicators(t, dense(t), i)[k]

        s = np.linspace(t_a, t_b, 5)
        gs = [g(t) for t in s]
        j = next((j for j in range(1, 5) if gs[j] <= 0.0 and max(gs[:j]) > 0.0), None)
        if j is None:
            return t_a if max(gs) <= 0.0 else t_b
        from scipy.optimize import brentq  # here, as DOP853 in run()

        xtol = 4.0 * _EPS * abs(s[j]) + 1e-300
        root = brentq(g, s[j - 1], s[j], xtol=xtol, rtol=4.0 * _EPS)
        past = min(s[j], root + 2.0 * xtol)
        return past if g(past) <= 0.0 else s[j]

    def _event(self):
        """Event update of every block at the current time; record the mode changes; restart the signs."""
        self.blocks.update(self.t, self.y)
        self.y = self.blocks.states()
        mode, count = self.blocks.counts()
        for i, (before, after) in enumerate(zip(self.mode, mode)):
            if count[i] != self.count[i]:
                self.events.append(new_event(self.t, i, before, after))
        self.mode, self.count = mode, count
        self.signs = self._signs()
        self._repeats = self._repeats + 1 if self.t == self._instant else 1
        self._instant = self.t
        if self._repeats > MAX_EVENTS_PER_INSTANT:
            raise FMUError(f"me: more than {MAX_EVENTS_PER_INSTANT} events at t = {self.t!r} s (an event chain)")
