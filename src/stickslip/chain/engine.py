"""The chain engine's entry point: :func:`run_chain` runs a :class:`~.spec.ChainSpec` in compiled chunks and streams
the output into a sink (:mod:`.output`).

The kernels (:mod:`.kernel`) return control every :data:`CHUNK_STEPS` steps, or when their buffers of grid rows
(:data:`ROW_BYTES` in all) or events (:data:`EVENT_BUFFER`) fill: the sink takes the batch, ``progress(t)`` is called,
and a KeyboardInterrupt there leaves the sink's files complete up to the last chunk. Memory stays flat over any run
length. The first run in a process compiles the kernels (or loads them from numba's cache): that time is reported
apart (:attr:`ChainRunSummary.compile_time`).
"""

import math
import time
from dataclasses import dataclass

import numpy as np

from . import jit
from .arrays import (ATOL_V, ATOL_X, BLK_WIDTH, C_ACT, C_ALL_EVENTS, C_BUDGET, C_DENSE, C_EVENTS, C_REJECTED,
                     C_ROWS, C_STEPS, H_MAX, K_LEFT, K_RIGHT, KAPPA, KIN, M, PAR_WIDTH, RTOL, STA, T_BREAK, T_GRID,
                     T_NOW, T_QUIET, T_STEP, T_STOP, T_STUCK, V_DRIVE, X_STUCK, Blocks, Chain, out_arrays,
                     work_arrays)
from .kernel import DONE, FAILED_EVENTS, MAX_EVENTS_PER_INSTANT, advance, start
from .spec import ChainSpec

#: steps of the slipping blocks per chunk (compiled; a hundredth of that as plain Python)
CHUNK_STEPS = 20000
#: bytes of the buffer of grid rows, and the number of events buffered
ROW_BYTES = 1 << 21
EVENT_BUFFER = 1 << 13
#: the longest step as a fraction of the chain's shortest free period
STEP_PER_PERIOD = 0.125
_compiled = []


class ChainRunError(RuntimeError):
    """The engine could not go on (an event chain that does not end, a step size that vanished)."""


@dataclass
class ChainRunSummary:
    """What a run did: ``t_end`` (s, the time reached), ``steps`` and ``rejected_steps`` of the slipping blocks,
    ``dense_outputs`` built, ``events`` (block events in all), ``wall_time`` (s, the run without compiling) and
    ``compile_time`` (s, compiling or loading the kernels on the first run in the process, else 0), ``compiled``
    (False: plain Python), ``rtol``; over the grid rows, each block's ``x_min`` and ``x_max`` (m; NaN without a
    grid); the final state ``x`` (m), ``v`` (m/s), ``mode``."""

    t_end: float
    steps: int
    rejected_steps: int
    dense_outputs: int
    events: int
    wall_time: float
    compile_time: float
    compiled: bool
    rtol: float
    x_min: np.ndarray
    x_max: np.ndarray
    x: np.ndarray
    v: np.ndarray
    mode: np.ndarray

    @property
    def amplitude(self):
        """The largest range ``max x - min x`` of any block over the grid (m)."""
        return float(np.max(self.x_max - self.x_min))


def run_chain(spec, stop_time, *, rtol=1e-10, output_interval=None, sink=None, progress=None):
    """Integrate the chain ``spec`` from 0 to ``stop_time`` (s) at the relative tolerance ``rtol``; grid rows every
    ``output_interval`` s (None: none) and every block event go to ``sink`` (closed at the end, also on an error or
    KeyboardInterrupt); ``progress(t)`` is called with the time reached after each chunk. Returns a
    :class:`ChainRunSummary`."""
    if not isinstance(spec, ChainSpec):
        raise TypeError(f"spec must be a ChainSpec, got {type(spec).__name__}")
    _check("stop_time", stop_time, "s", low=0.0)
    _check("rtol", rtol, "", low=1e-14, high=1e-2, closed=True)
    if output_interval is not None:
        _check("output_interval", output_interval, "s", low=0.0)
    jit.say_if_plain()
    compile_time = warm_up()
    try:
        run = _Run(spec, float(stop_time), float(rtol), output_interval or 0.0)
        run.go(sink, progress or (lambda t: None))
    finally:
        if sink is not None:
            sink.close()
    return run.summary(compile_time)


def _check(name, value, unit, low, high=math.inf, closed=False):
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if not (ok and (low <= value if closed else low < value) and value <= high):
        bracket = "[" if closed else "("
        raise ValueError(f"{name} = {value!r} {unit}: allowed is a finite value in {bracket}{low:g}, {high:g}]")


def warm_up():
    """Compile the kernels (or load them from the cache) on a two-block chain, once per process; returns the seconds
    that took (0 after the first call or as plain Python)."""
    if _compiled or not jit.COMPILED:
        return 0.0
    begin = time.perf_counter()
    spec = ChainSpec(M=[1.0, 1.0], kappa=[1.0, 1.0], kinetic_law=[3, 2], kinetic=[[0.5, 0.4, 0.05, 1.0, 0.0],
                     [0.5, 0.1, 0, 0, 0]], static_law=[1, 2], static=[[1.0, 0, 0, 0], [1.0, 0.1, 1.0, 0]],
                     x0=[0.0, 0.9], v0=[0.01, 0.01], coupling=[1.0], v_drive=0.01)
    _Run(spec, 5.0, 1e-8, 1.0).go(None, lambda t: None)
    _compiled.append(True)
    return time.perf_counter() - begin


class _Run:
    """One run's arrays and the loop over its chunks."""

    def __init__(self, spec, stop_time, rtol, interval):
        n = spec.n
        par = np.zeros((n, PAR_WIDTH))
        side = np.concatenate([[0.0], spec.coupling, [0.0]])
        x_scale = spec.static[:, 0] / spec.kappa
        par[:, M], par[:, KAPPA], par[:, K_LEFT], par[:, K_RIGHT] = spec.M, spec.kappa, side[:-1], side[1:]
        par[:, ATOL_X] = rtol * x_scale
        par[:, ATOL_V] = rtol * np.maximum(abs(spec.v_drive), np.sqrt(spec.kappa / spec.M) * x_scale)
        par[:, KIN:KIN + spec.kinetic.shape[1]], par[:, STA:STA + spec.static.shape[1]] = spec.kinetic, spec.static
        self.chain = Chain(par, np.column_stack([spec.kinetic_law, spec.static_law]).astype(np.int64))
        blk = np.zeros((n, BLK_WIDTH))
        blk[:, T_BREAK] = math.inf
        self.blocks = Blocks(np.zeros(n, np.int64), spec.x0.copy(), spec.v0.copy(), blk)
        self.work = work_arrays(n)
        self.out = out_arrays(n, max(1, ROW_BYTES // (8 * n)) if interval > 0.0 else 1, EVENT_BUFFER)
        h_max = STEP_PER_PERIOD * spec.shortest_period()
        self.clock = np.zeros(9)
        self.clock[[T_NOW, T_STEP, T_QUIET, T_STOP, T_GRID, V_DRIVE, RTOL, H_MAX]] = (
            0.0, h_max / 20.0, math.inf, stop_time, interval, spec.v_drive, rtol, h_max)
        self.count = np.zeros(16, np.int64)
        self.x_min, self.x_max = np.full(n, math.inf), np.full(n, -math.inf)
        self.rtol, self.wall = rtol, 0.0

    def _call(self, kernel):
        return kernel(self.chain, self.blocks, self.work, self.out, self.clock, self.count)

    def go(self, sink, progress):
        begin = time.perf_counter()
        self._call(start)
        budget = CHUNK_STEPS if jit.COMPILED else CHUNK_STEPS // 100
        while True:
            self.count[C_BUDGET] = budget
            status = self._call(advance)
            self._hand_over(sink)
            progress(self.clock[T_NOW])
            if status == DONE:
                break
            if status < 0:
                raise ChainRunError(self._failure(status))
        self.wall = time.perf_counter() - begin

    def _hand_over(self, sink):
        """The buffered rows and events to the sink; the buffers emptied."""
        rows, events = self.count[C_ROWS], self.count[C_EVENTS]
        if rows:
            x = self.out.row_x[:rows]
            np.minimum(self.x_min, x.min(axis=0), out=self.x_min)
            np.maximum(self.x_max, x.max(axis=0), out=self.x_max)
        out = self.out
        if sink is not None and rows:
            if hasattr(sink, "states"):
                sink.states(*(a[:rows].copy() for a in (out.row_t, out.row_x, out.row_v, out.row_mode)))
            else:
                sink.positions(out.row_t[:rows].copy(), out.row_x[:rows].copy())
        if sink is not None and events:
            batch = [a[:events].copy() for a in (out.ev_t, out.ev_block, out.ev_kind, out.ev_x, out.ev_mode)]
            if hasattr(sink, "transitions"):
                sink.transitions(*batch)
            else:
                sink.events(*batch[:4])
        self.count[C_ROWS] = self.count[C_EVENTS] = 0

    def _failure(self, status):
        t = self.clock[T_NOW]
        if status == FAILED_EVENTS:
            return f"event chain at t = {t!r} s: more than {MAX_EVENTS_PER_INSTANT} mode changes at one instant"
        return f"the step size vanished at t = {t!r} s with {self.count[C_ACT]} blocks slipping"

    def summary(self, compile_time):
        bl, t, vd = self.blocks, self.clock[T_NOW], self.clock[V_DRIVE]
        x = np.where(bl.mode == 0, bl.blk[:, X_STUCK] + vd * (t - bl.blk[:, T_STUCK]), bl.x)
        empty = ~np.isfinite(self.x_min)
        return ChainRunSummary(
            t_end=t, steps=int(self.count[C_STEPS]), rejected_steps=int(self.count[C_REJECTED]),
            dense_outputs=int(self.count[C_DENSE]), events=int(self.count[C_ALL_EVENTS]), wall_time=self.wall,
            compile_time=compile_time, compiled=jit.COMPILED, rtol=self.rtol,
            x_min=np.where(empty, math.nan, self.x_min), x_max=np.where(empty, math.nan, self.x_max), x=x,
            v=np.where(bl.mode == 0, vd, bl.v), mode=bl.mode.copy())
