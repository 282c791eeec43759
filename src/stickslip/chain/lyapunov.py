"""The largest Lyapunov exponent of a chain over a run, measured by Benettin's method.

Two trajectories of the chain start ``separation`` apart in its ``2N``-dimensional state space ``(x, v)``. Every
``interval`` seconds both are stopped, the separation's growth ``g_k = |d_k| / separation`` is recorded, and the
second trajectory restarts ``separation`` away from the first along the separation's direction. The exponent is
``lambda = sum_k ln g_k / stop_time`` (1/s); its running value over the run shows how it settles, and the spread
of the sums over ten equal batches of intervals gives its standard error.

Distances are measured in each block's own scales: positions over the block's ``F_S(0) / kappa`` (m), velocities
over ``F_S(0) / kappa`` times its free angular frequency ``sqrt(kappa / M)``. A block stuck in the first trajectory
moves with the surface (``v = v_drive`` exactly): the separation's velocity component of that block is left out
(the stuck motion has no velocity freedom), so the restarted second trajectory sticks there too.

A stick-slip cycle has exponent 0 (a perturbation becomes a shift along the cycle); a chain whose slips are
chaotic has a positive one: an error of size ``e`` grows to ``e exp(lambda T)`` over a run of ``T`` seconds.
"""

import math
from dataclasses import dataclass, replace

import numpy as np

from .engine import run_chain

#: separation of the two trajectories, in the blocks' scales (module docstring)
SEPARATION = 1e-8
#: the engine's relative tolerance for the two trajectories: far below the separation
RTOL = 1e-12
#: batches of intervals whose spread gives the exponent's standard error
BATCHES = 10
#: the fewest intervals a run is cut into
MIN_INTERVALS = 4 * BATCHES


@dataclass(frozen=True)
class LyapunovEstimate:
    """The largest Lyapunov exponent ``exponent`` (1/s) over ``stop_time`` (s) and its standard error
    ``uncertainty`` (1/s); ``times`` (s) of the renormalisations and ``running`` (1/s), the estimate up to each;
    ``interval`` (s), ``separation`` and ``rtol`` as measured."""

    exponent: float
    uncertainty: float
    stop_time: float
    times: np.ndarray
    running: np.ndarray
    interval: float
    separation: float
    rtol: float

    def growth(self):
        """``exponent * stop_time``: the e-foldings of a small error over the run (negative: it shrinks)."""
        return self.exponent * self.stop_time


def default_interval(spec, stop_time):
    """The renormalisation interval (s): the longest free period ``2 pi sqrt(M / kappa)`` of a block, at most
    ``stop_time /`` :data:`MIN_INTERVALS`."""
    return min(2.0 * math.pi * float(np.max(np.sqrt(spec.M / spec.kappa))), stop_time / MIN_INTERVALS)


def state_scales(spec):
    """The scale of each of the ``2N`` states (module docstring): ``F_S(0) / kappa`` (m) of each block, then
    ``F_S(0) / kappa * sqrt(kappa / M)`` (m/s)."""
    length = spec.static[:, 0] / spec.kappa  # every static law's first parameter is F_S(0)
    return np.concatenate([length, length * np.sqrt(spec.kappa / spec.M)])


def largest_lyapunov(spec, stop_time, *, interval=None, separation=SEPARATION, rtol=RTOL, progress=None):
    """The :class:`LyapunovEstimate` of the chain ``spec`` (:class:`~.engine.ChainSpec`) from its start state over
    ``stop_time`` (s), both trajectories run by the chain engine at ``rtol``; ``interval`` (s) between
    renormalisations (default :func:`default_interval`); ``progress(t)`` is called after each interval."""
    stop_time = float(stop_time)
    if not (math.isfinite(stop_time) and stop_time > 0.0):
        raise ValueError(f"stop_time = {stop_time!r} s: allowed is a finite time > 0")
    interval = default_interval(spec, stop_time) if interval is None else float(interval)
    if not (math.isfinite(interval) and 0.0 < interval <= stop_time):
        raise ValueError(f"interval = {interval!r} s: allowed is a time in (0, stop_time = {stop_time!r}]")
    if not (math.isfinite(separation) and 0.0 < separation <= 1e-3):
        raise ValueError(f"separation = {separation!r}: allowed is (0, 1e-3] (in the blocks' scales)")
    n = spec.n
    scale = state_scales(spec)
    first = np.concatenate([spec.x0, spec.v0]).astype(float)
    direction = np.concatenate([np.ones(n), np.zeros(n)]) / math.sqrt(n)
    second = first + separation * direction * scale
    count = max(1, round(stop_time / interval))
    logs = np.empty(count)
    for k in range(count):
        duration = stop_time * (k + 1) / count - stop_time * k / count
        first, stuck = advance(spec, first, duration, rtol)
        second, _ = advance(spec, second, duration, rtol)
        d = (second - first) / scale
        d[n:][stuck] = 0.0
        size = float(np.linalg.norm(d))
        logs[k] = math.log(size / separation) if size > 0.0 else 0.0
        second = first + separation * (d / size if size > 0.0 else direction) * scale
        if progress is not None:
            progress(stop_time * (k + 1) / count)
    return _estimate(logs, stop_time, separation, rtol)


def _estimate(logs, stop_time, separation, rtol):
    """The estimate from the log growths ``logs`` of equal intervals over ``stop_time``."""
    count = logs.size
    times = stop_time * np.arange(1, count + 1) / count
    running = np.cumsum(logs) / times
    size = count // BATCHES
    if size:
        batches = logs[:size * BATCHES].reshape(BATCHES, size).sum(axis=1) / (size * stop_time / count)
        uncertainty = float(np.std(batches, ddof=1) / math.sqrt(BATCHES))
    else:
        uncertainty = math.inf
    return LyapunovEstimate(float(running[-1]), uncertainty, stop_time, times, running, stop_time / count,
                            separation, rtol)


def advance(spec, y, duration, rtol):
    """The state ``y = (x, v)`` of the chain ``spec`` after ``duration`` (s) from ``y`` (blocks at ``v = v_drive``
    start stuck where the contact holds them), and which blocks are stuck then."""
    n = spec.n
    run = run_chain(replace(spec, x0=y[:n], v0=y[n:]), duration, rtol=rtol)
    return np.concatenate([run.x, run.v]), run.mode == 0
