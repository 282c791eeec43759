"""Attractor of a long run: continuous sliding, oscillatory sliding, stick-slip or rest, with its measures.

:func:`classify_run` simulates with the exact core stepper
(:class:`stickslip.core.Trajectory`) and samples it finely; every mode change
is timed exactly (the trajectory's ``t_last_event`` when a sample interval holds
a single event). :func:`classify_samples` classifies sampled data of any origin
(an FMU result, the reference) from the last ``tail`` seconds:

- ``rest``: the surface and the block are still;
- ``stick-slip``: at least two sticks in the tail; the period is the smallest
  repeat of the stick pattern (stick positions repeat after ``k`` sticks, so
  period-doubled cycles of an aging map are recognized; ``NaN`` if the sticks
  never repeat, i.e. chaotic stick-slip);
- otherwise sliding: ``continuous-sliding`` when the velocity oscillation has
  died out or still shrinks, ``oscillatory-sliding`` when it persists (its
  period from the upward crossings of the mean velocity).

Reported with it: ``x_max, x_min`` (amplitude), ``v_min, v_max``, the stick
fraction, whether the cycle overshoots (passes ``v_rel = 0`` without sticking)
and the number of sticks in the tail.
"""

import math
from dataclasses import dataclass

import numpy as np

from ..core import Trajectory
from ..core.model import STUCK

#: A sliding oscillation whose velocity range shrinks by more than this factor from the
#: first to the second half of the tail is decaying onto continuous sliding.
DECAY_RATIO = 0.9
KINDS = ("continuous-sliding", "oscillatory-sliding", "stick-slip", "rest", "undetermined")


@dataclass(frozen=True)
class Attractor:
    """The attractor a run settles on, measured over the tail of the run.

    ``period`` (s; NaN for continuous sliding, rest, aperiodic stick-slip),
    ``x_max, x_min`` (m), ``v_min, v_max`` (m/s), ``stick_fraction`` (share of
    the tail spent stuck), ``overshoots`` (the tail has slips that pass
    ``v_rel = 0`` without sticking), ``n_sticks`` (sticks in the tail),
    ``repeat``: sticks per period of a stick-slip cycle (1 for a simple cycle,
    0 when aperiodic).
    """

    kind: str
    period: float
    x_max: float
    x_min: float
    v_min: float
    v_max: float
    stick_fraction: float
    overshoots: bool
    n_sticks: int
    repeat: int = 1

    @property
    def amplitude(self):
        """Half the peak-to-peak position range (m)."""
        return 0.5 * (self.x_max - self.x_min)


def classify_samples(t, x, v, v_drive, mode, tail, stick_times=(), stick_positions=(), overshoot_times=(),
                     breakaway_times=()):
    """Classify sampled data ``t, x, v, v_drive, mode`` (arrays) from its last ``tail`` s.

    Exact event times (``stick_times`` with their ``stick_positions``, and
    ``overshoot_times``, ``breakaway_times``) sharpen the period and the stick
    fraction; without them sticks are read from the sampled ``mode``.
    """
    t, x, v = np.asarray(t, float), np.asarray(x, float), np.asarray(v, float)
    v_drive, mode = np.broadcast_to(np.asarray(v_drive, float), t.shape), np.asarray(mode)
    t_from = t[-1] - tail
    in_tail = t >= t_from
    late = t >= t[-1] - tail / 2
    early = in_tail & ~late
    xs, vs = x[in_tail], v[in_tail]
    measures = dict(x_max=float(xs.max()), x_min=float(xs.min()), v_min=float(vs.min()), v_max=float(vs.max()))
    speed = max(np.abs(v_drive[in_tail]).max(), np.abs(vs).max())
    still = 1e-9 + 1e-6 * speed
    stuck = mode[in_tail] == STUCK
    stick_fraction = float(stuck.mean())
    if not len(stick_times):
        starts = np.flatnonzero((mode[1:] == STUCK) & (mode[:-1] != STUCK)) + 1
        stick_times, stick_positions = t[starts], x[starts]
    stick_times, stick_positions = np.asarray(stick_times, float), np.asarray(stick_positions, float)
    sel = stick_times >= t_from
    ticks, xticks = stick_times[sel], stick_positions[sel]
    overs = bool(np.any(np.asarray(overshoot_times, float) >= t_from)) if len(overshoot_times) else bool(
        np.any((mode[in_tail][1:] * mode[in_tail][:-1]) < 0))
    if abs(v_drive[-1]) <= still and np.abs(v[late]).max() <= still:
        return Attractor("rest", math.nan, stick_fraction=stick_fraction, overshoots=False, n_sticks=len(ticks),
                         repeat=0, **measures)
    if len(ticks) >= 2:
        period, repeat = _stick_period(ticks, xticks, measures["x_max"] - measures["x_min"])
        if len(breakaway_times):
            stick_fraction = _stuck_share(ticks, np.asarray(breakaway_times, float))
        return Attractor("stick-slip", period, stick_fraction=stick_fraction, overshoots=overs,
                         n_sticks=len(ticks), repeat=repeat, **measures)
    if len(ticks) == 1 or abs(v[late].mean()) > 0.5 * abs(v_drive[-1]):
        return Attractor("undetermined", math.nan, stick_fraction=stick_fraction, overshoots=overs,
                         n_sticks=len(ticks), repeat=0, **measures)
    spread_early, spread_late = np.ptp(v[early]), np.ptp(v[late])
    if spread_late <= still or spread_late < DECAY_RATIO * spread_early:
        return Attractor("continuous-sliding", math.nan, stick_fraction=0.0, overshoots=False, n_sticks=0,
                         repeat=0, **measures)
    return Attractor("oscillatory-sliding", _crossing_period(t[in_tail], vs), stick_fraction=0.0,
                     overshoots=overs, n_sticks=0, repeat=0, **measures)


def _stick_period(times, positions, x_range):
    """Smallest ``k`` after which the stick positions repeat (to 1e-6 of the motion's range), and the period."""
    n = len(times)
    tol = 1e-6 * max(x_range, 1e-300)
    for k in range(1, n // 2 + 1):
        if np.all(np.abs(positions[k:] - positions[:-k]) <= tol):
            return float((times[-1] - times[(n - 1) % k]) / ((n - 1) // k)) if n > k else math.nan, k
    if n == 2:
        return float(times[1] - times[0]), 1
    return math.nan, 0


def _stuck_share(sticks, breakaways):
    """Share of ``[first stick, last stick]`` spent stuck, from exact stick and breakaway times."""
    stuck = 0.0
    for a in sticks[:-1]:
        later = breakaways[breakaways >= a]
        if later.size:
            stuck += min(later[0], sticks[-1]) - a
    return float(stuck / (sticks[-1] - sticks[0]))


def _crossing_period(t, v):
    """Mean time between upward crossings of the mean velocity (linear interpolation)."""
    level = 0.5 * (v.max() + v.min())
    up = np.flatnonzero((v[:-1] < level) & (v[1:] >= level))
    if up.size < 2:
        return math.nan
    tc = t[up] + (level - v[up]) * (t[up + 1] - t[up]) / (v[up + 1] - v[up])
    return float((tc[-1] - tc[0]) / (tc.size - 1))


def simulate(params, v_drive, t_end, x0=0.0, v0=None, F_ext=0.0, dt=None, rtol=1e-10):
    """Sample a run of the core stepper.

    Returns ``(t, x, v, mode, stick_times, stick_positions, overshoot_times, breakaway_times)``: the
    samples every ``dt`` (default 1/200 of the undamped period) and every event, timed exactly.
    """
    v0 = v_drive if v0 is None else v0
    period0 = 2.0 * math.pi * math.sqrt(params.M / params.kappa)
    dt = period0 / 200.0 if dt is None else dt
    traj = Trajectory(params, x0, v0, v_drive=v_drive, F_ext=F_ext, rtol=rtol)
    times = np.arange(0.0, t_end + 0.5 * dt, dt)
    xs, vs, modes = np.empty_like(times), np.empty_like(times), np.empty(times.size, int)
    sticks, stick_x, overs, slips = [], [], [], []

    def advance(traj, t_to, depth):
        """Advance to ``t_to`` recording each event exactly: an interval with several is redone finer."""
        before = (traj.n_stick_events, traj.n_overshoots, traj.n_events)
        snap = traj.snapshot() if depth < 8 else None
        t_from = traj.t
        traj.advance_to(t_to)
        d_stick, d_over, d_all = (a - b for a, b in zip((traj.n_stick_events, traj.n_overshoots, traj.n_events),
                                                        before))
        if d_all > 1 and snap is not None and t_to > t_from:
            traj = Trajectory.from_snapshot(params, snap)
            for k in range(1, 5):
                traj = advance(traj, t_from + (t_to - t_from) * k / 4.0 if k < 4 else t_to, depth + 1)
            return traj
        exact = d_all == 1
        if d_stick:
            te = traj.t_last_event if exact else t_to
            sticks.append(te)
            stick_x.append(traj.x - v_drive * (t_to - te) if traj.mode == STUCK else traj.x)
        if d_over:
            overs.append(traj.t_last_event if exact else t_to)
        if d_all - d_stick - d_over:
            slips.append(traj.t_last_event if exact else t_to)
        return traj

    for i, ti in enumerate(times):
        traj = advance(traj, ti, 0)
        xs[i], vs[i], modes[i] = traj.x, traj.v, traj.mode
    return times, xs, vs, modes, np.array(sticks), np.array(stick_x), np.array(overs), np.array(slips)


def classify_run(params, v_drive, t_end=None, x0=0.0, v0=None, F_ext=0.0, tail=None, rtol=1e-10):
    """Simulate from ``(x0, v0)`` (default: stuck at the relaxed spring) and classify the attractor.

    ``t_end`` defaults to 40 undamped periods ``2 pi sqrt(M/kappa)``, ``tail`` to a third of the run.
    """
    period0 = 2.0 * math.pi * math.sqrt(params.M / params.kappa)
    t_end = 40.0 * period0 if t_end is None else float(t_end)
    tail = t_end / 3.0 if tail is None else float(tail)
    t, x, v, mode, sticks, stick_x, overs, slips = simulate(params, v_drive, t_end, x0, v0, F_ext, rtol=rtol)
    return classify_samples(t, x, v, v_drive, mode, tail, sticks, stick_x, overs, slips)
