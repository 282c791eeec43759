"""The chain engine's driver (compiled): steps, events and output of one chunk of a run.

:func:`advance` runs from ``clock[T_NOW]`` until the stop time, the chunk's step budget or full output buffers, and
returns the status (:data:`RUNNING`: call again after emptying the buffers; :data:`DONE`; negative: failed). While
every block sticks the chain moves with the surface in closed form up to the first breakaway; otherwise the slipping
blocks are stepped (:mod:`.stepper`), each step's indicators of the slipping blocks and of their stuck neighbours
are scanned (:mod:`.events`), and a stuck block whose neighbours all stick breaks at its precomputed time
(:mod:`.stuck`). An event ends the step there: the state at the event comes from a true step to its time, corrected
once by Newton's rule on the indicator; the event is applied and any event it causes at the same instant follows.
"""

import math

from .arrays import (C_ACT, C_ALL_EVENTS, C_BUDGET, C_DENSE, C_EVENTS, C_GRID, C_INSTANT, C_MON, C_QUIET,
                     C_REJECTED, C_ROWS, C_STATUS, C_STEPS, OVERSHOOT, SLIP, STICK, T_EVENT, T_GRID, T_NOW, T_QUIET,
                     T_STEP, T_STOP)
from .events import indicator, leaves_zero, may_cross, scan_step
from .jit import njit
from .laws import static_force
from .stepper import coupling_force, dense, dense_state, position, rates, step
from .stuck import quiet_break

RUNNING, DONE, FAILED_EVENTS, FAILED_STEP = 0, 1, -1, -2
#: more mode changes than this at one instant are an error (an event chain that does not end)
MAX_EVENTS_PER_INSTANT = 1000


@njit
def start(ch, bl, wk, out, clock, count):
    """Each block's mode at the start time (stuck if ``v = v_drive`` and ``F_S(0)`` holds, else the sign of
    ``v_rel``), the lists, the breakaway times, the first stage and any event at once."""
    t = clock[T_NOW]
    for i in range(ch.M.size):
        bl.x_stuck[i], bl.t_stuck[i] = bl.x[i], t
        bl.mode[i] = 0
    for i in range(ch.M.size):
        bl.mode[i] = _initial_mode(ch, bl, i, t)
    for i in range(ch.M.size):
        if bl.mode[i] == 0:
            bl.v[i] = ch.v_drive
        else:
            bl.t_stuck[i] = math.nan
    _rebuild(ch, bl, wk, count)
    _refresh_breaks(ch, bl, wk, clock, count, 0, ch.M.size - 1)
    _settle(ch, bl, wk, out, clock, count, -1, t)


@njit
def _initial_mode(ch, bl, i, t):
    v_rel = ch.v_drive - bl.v[i]
    if v_rel != 0.0:
        return 1 if v_rel > 0.0 else -1
    h = ch.kappa[i] * bl.x[i] - coupling_force(ch, bl, bl.x, i, t)
    if static_force(ch.sta_law[i], ch.sta[i], 0.0) - abs(h) >= 0.0:
        return 0
    return 1 if h > 0.0 else -1


@njit
def _rebuild(ch, bl, wk, count):
    """The lists of slipping blocks and of stuck blocks with a slipping neighbour."""
    n, nact, nmon = ch.M.size, 0, 0
    for i in range(n):
        if bl.mode[i] != 0:
            wk.act[nact] = i
            nact += 1
        elif (i > 0 and bl.mode[i - 1] != 0) or (i < n - 1 and bl.mode[i + 1] != 0):
            wk.mon[nmon] = i
            nmon += 1
    count[C_ACT], count[C_MON] = nact, nmon


@njit
def _refresh_breaks(ch, bl, wk, clock, count, lo, hi):
    """Breakaway times of the blocks ``lo .. hi`` (those stuck with stuck neighbours; inf for the others), then the
    earliest of all into ``clock[T_QUIET]`` and its block into ``count[C_QUIET]``."""
    n, t = ch.M.size, clock[T_NOW]
    for j in range(max(lo, 0), min(hi, n - 1) + 1):
        quiet = bl.mode[j] == 0 and (j == 0 or bl.mode[j - 1] == 0) and (j == n - 1 or bl.mode[j + 1] == 0)
        bl.t_break[j] = quiet_break(ch, bl, wk, j, t, clock[T_STOP]) if quiet else math.inf
    first = 0
    for j in range(1, n):
        if bl.t_break[j] < bl.t_break[first]:
            first = j
    clock[T_QUIET], count[C_QUIET] = bl.t_break[first], first


@njit
def _apply(ch, bl, wk, out, clock, count, i, t):
    """Block ``i``'s event at time ``t``: a breakaway, or ``v_rel`` reaching 0 (stick, or overshoot where
    ``F_S(0)`` cannot hold the block); recorded in the buffers."""
    x = position(ch, bl, bl.x, i, t)
    push = coupling_force(ch, bl, bl.x, i, t) - ch.kappa[i] * x
    new = 1 if push < 0.0 else -1
    kind = SLIP
    if bl.mode[i] != 0:
        kind = OVERSHOOT
        if static_force(ch.sta_law[i], ch.sta[i], 0.0) - abs(push) >= 0.0:
            new, kind = 0, STICK
    bl.x[i], bl.v[i], bl.mode[i] = x, ch.v_drive, new
    bl.x_stuck[i], bl.t_stuck[i] = (x, t) if new == 0 else (x, math.nan)
    k = count[C_EVENTS]
    out.ev_t[k], out.ev_block[k], out.ev_kind[k], out.ev_x[k] = t, i, kind, x
    count[C_EVENTS] += 1
    count[C_ALL_EVENTS] += 1
    count[C_INSTANT] = count[C_INSTANT] + 1 if t == clock[T_EVENT] else 1
    clock[T_EVENT] = t
    _rebuild(ch, bl, wk, count)
    _refresh_breaks(ch, bl, wk, clock, count, i - 1, i + 1)


@njit
def _settle(ch, bl, wk, out, clock, count, i, t):
    """Apply block ``i``'s event at ``t`` (none if ``i < 0``), then every event it causes at the same instant; the
    first stage and the indicators at ``t`` for the next step."""
    while True:
        if i >= 0:
            _apply(ch, bl, wk, out, clock, count, i, t)
            if count[C_INSTANT] > MAX_EVENTS_PER_INSTANT:
                count[C_STATUS] = FAILED_EVENTS
                return
        rates(ch, bl, wk, count[C_ACT], t, bl.x, bl.v, 0)
        i = _event_now(ch, bl, wk, count, t)
        if i < 0 and clock[T_QUIET] <= t:
            i = count[C_QUIET]
        if i < 0:
            return


@njit
def _event_now(ch, bl, wk, count, t):
    """The first watched block whose indicator is at or below 0 at ``t`` and does not rise (its event is now), or
    -1; sets every watched block's ``e0``, ``d0`` and ``rising``."""
    for lst, size in ((wk.act, count[C_ACT]), (wk.mon, count[C_MON])):
        for q in range(size):
            i = lst[q]
            value, rate = indicator(ch, bl, i, t, bl.x, bl.v)
            wk.e0[i], wk.d0[i] = value, rate
            bl.rising[i] = True
            if value <= 0.0:
                bl.rising[i] = leaves_zero(ch, bl, i, t, value, rate)
                if not bl.rising[i]:
                    return i
    return -1


@njit
def _emit(ch, bl, wk, out, clock, count, t0, t1, on_dense, final):
    """Grid rows at the grid times in ``[t0, t1)`` (``final``: up to ``t1`` included), slipping blocks from the
    step's dense output (``on_dense``) or their state."""
    dt, n = clock[T_GRID], ch.M.size
    if dt <= 0.0:
        return
    while count[C_ROWS] < out.row_t.size:
        g = count[C_GRID] * dt
        if g >= t1 and not (final and g <= t1 + 1e-9 * dt):
            return
        r = count[C_ROWS]
        out.row_t[r] = g
        for j in range(n):
            if bl.mode[j] == 0:
                out.row_x[r, j] = bl.x_stuck[j] + ch.v_drive * (g - bl.t_stuck[j])
            elif on_dense:
                out.row_x[r, j] = dense_state(bl, wk, j, (g - t0) / (t1 - t0))[0]
            else:
                out.row_x[r, j] = bl.x[j]
        count[C_ROWS] += 1
        count[C_GRID] += 1


@njit
def _limit(out, clock, count):
    """The latest time (s) the next step may reach: the next breakaway, the stop time, and the grid times the row
    buffer still holds."""
    limit = min(clock[T_QUIET], clock[T_STOP])
    if clock[T_GRID] > 0.0:
        limit = min(limit, (count[C_GRID] + out.row_t.size - count[C_ROWS]) * clock[T_GRID])
    return limit


@njit
def _stuck_phase(ch, bl, wk, out, clock, count):
    """Every block stuck: the chain moves with the surface up to the next breakaway."""
    t0, t1 = clock[T_NOW], _limit(out, clock, count)
    _emit(ch, bl, wk, out, clock, count, t0, t1, False, False)
    clock[T_NOW] = t1
    count[C_BUDGET] -= 1


@njit
def _accepted_step(ch, bl, wk, count, t, h, t_step):
    """An accepted step from ``t``: tries ``h`` (s), shrinks it until the error norm is <= 1; sets the next step size
    in ``t_step[0]``; returns the step taken (s), or 0 if it became too small (status set)."""
    nact = count[C_ACT]
    rejected = False
    while True:
        err = step(ch, bl, wk, nact, t, h)
        if err <= 1.0:
            break
        h *= 0.2 if not err < math.inf else max(0.2, 0.9 * err ** -0.125)
        rejected = True
        count[C_REJECTED] += 1
        if h <= 1e-14 * max(1.0, abs(t)):
            count[C_STATUS] = FAILED_STEP
            return 0.0
    grow = 10.0 if err == 0.0 else min(10.0, max(0.2, 0.9 * err ** -0.125))
    t_step[0] = h * min(grow, 1.0) if rejected else h * grow
    return h


@njit
def _find_event(ch, bl, wk, count, t, h):
    """``(time, block)`` of the first event in the step ``[t, t + h]`` just taken (``(inf, -1)`` if none): every
    watched block's indicator at the step's end into ``e1``, ``d1``; the dense output built where a block may
    cross."""
    first, block, built = math.inf, -1, False
    for lst, size in ((wk.act, count[C_ACT]), (wk.mon, count[C_MON])):
        for q in range(size):
            i = lst[q]
            if bl.mode[i] != 0:
                wk.e1[i], wk.d1[i] = bl.mode[i] * (ch.v_drive - wk.vn[i]), -bl.mode[i] * wk.kv[12, i]
            else:
                wk.e1[i], wk.d1[i] = indicator(ch, bl, i, t + h, wk.xn, wk.vn)
            if may_cross(wk.e0[i], wk.d0[i], wk.e1[i], wk.d1[i], h):
                if not built:
                    dense(ch, bl, wk, count[C_ACT], t, h)
                    count[C_DENSE] += 1
                    built = True
                hit = scan_step(ch, bl, wk, i, t, h)
                if hit < first:
                    first, block = hit, i
    return first, block, built


@njit
def _step_to_event(ch, bl, wk, count, i, t, t_event, t_end):
    """The state at block ``i``'s event by a true step from ``t`` to ``t_event`` (s), moved once by Newton's rule on
    its indicator where that moves it by less than a thousandth of the step; returns the event's time."""
    nact = count[C_ACT]
    step(ch, bl, wk, nact, t, t_event - t)
    value, rate = indicator(ch, bl, i, t_event, wk.xn, wk.vn)
    if rate != 0.0:
        moved = t_event - value / rate
        if moved != t_event and abs(moved - t_event) < 1e-3 * (t_event - t) and t < moved <= t_end:
            t_event = moved
            step(ch, bl, wk, nact, t, t_event - t)
    return t_event


@njit
def _slip_step(ch, bl, wk, out, clock, count):
    """One step of the slipping blocks up to the first event in it (applied) or its end."""
    t, limit = clock[T_NOW], _limit(out, clock, count)
    h = min(clock[T_STEP], ch.h_max)
    clipped = t + h >= limit
    if clipped:
        h = limit - t
    before = clock[T_STEP]
    t_step = clock[T_STEP:T_STEP + 1]
    taken = _accepted_step(ch, bl, wk, count, t, h, t_step)
    if count[C_STATUS] != RUNNING:
        return
    if clipped and taken == h:
        t_step[0] = max(t_step[0], before)  # a step cut short by the limit says nothing of the next one
    t1 = limit if clipped and taken == h else t + taken
    count[C_STEPS] += 1
    count[C_BUDGET] -= 1
    rates(ch, bl, wk, count[C_ACT], t1, wk.xn, wk.vn, 12)
    hit, block, built = _find_event(ch, bl, wk, count, t, t1 - t)
    if block < 0 and t1 == clock[T_QUIET]:
        hit, block = t1, count[C_QUIET]
    if block >= 0 and hit < t1:
        t1 = _step_to_event(ch, bl, wk, count, block, t, hit, t1)
        built = False
    _finish_step(ch, bl, wk, out, clock, count, t, t1, built)
    if block >= 0:
        _settle(ch, bl, wk, out, clock, count, block, t1)


@njit
def _finish_step(ch, bl, wk, out, clock, count, t, t1, built):
    """The grid rows in ``[t, t1)`` (from the step's dense output), then the step's end as the new state."""
    if clock[T_GRID] > 0.0 and count[C_GRID] * clock[T_GRID] < t1:
        if not built:
            rates(ch, bl, wk, count[C_ACT], t1, wk.xn, wk.vn, 12)
            dense(ch, bl, wk, count[C_ACT], t, t1 - t)
            count[C_DENSE] += 1
        _emit(ch, bl, wk, out, clock, count, t, t1, True, False)
    for q in range(count[C_ACT]):
        i = wk.act[q]
        bl.x[i], bl.v[i] = wk.xn[i], wk.vn[i]
        wk.kx[0, i], wk.kv[0, i] = wk.kx[12, i], wk.kv[12, i]
    for lst, size in ((wk.act, count[C_ACT]), (wk.mon, count[C_MON])):
        for q in range(size):
            wk.e0[lst[q]], wk.d0[lst[q]] = wk.e1[lst[q]], wk.d1[lst[q]]
    clock[T_NOW] = t1


@njit
def advance(ch, bl, wk, out, clock, count):
    """Run until the stop time (then the last grid row), the step budget ``count[C_BUDGET]`` is spent or the event
    buffer is nearly full; returns ``count[C_STATUS]``."""
    while count[C_STATUS] == RUNNING:
        t = clock[T_NOW]
        if t >= clock[T_STOP]:
            _emit(ch, bl, wk, out, clock, count, t, t, False, True)
            if count[C_ROWS] < out.row_t.size:
                count[C_STATUS] = DONE
            break
        if count[C_BUDGET] <= 0 or count[C_EVENTS] > out.ev_t.size - MAX_EVENTS_PER_INSTANT - 8:
            break
        if clock[T_GRID] > 0.0 and count[C_ROWS] >= out.row_t.size:
            break
        if clock[T_QUIET] <= t:
            _settle(ch, bl, wk, out, clock, count, count[C_QUIET], t)
        elif count[C_ACT] == 0:
            _stuck_phase(ch, bl, wk, out, clock, count)
        else:
            _slip_step(ch, bl, wk, out, clock, count)
    return count[C_STATUS]
