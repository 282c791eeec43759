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
                     C_REJECTED, C_ROWS, C_STATUS, C_STEPS, D0, D1, E0, E1, H_MAX, KAPPA, OVERSHOOT, RISING, RTOL,
                     SLIP, STA, STICK, T_BREAK, T_EVENT, T_GRID, T_NOW, T_QUIET, T_STEP, T_STOP, T_STUCK, V_DRIVE,
                     X_STUCK)
from .events import indicator, leaves_zero, may_cross, scan_step
from .jit import njit
from .laws import static_force
from .stepper import coupling_force, dense, dense_state, position, rates, step
from .stuck import quiet_break

RUNNING, DONE, FAILED_EVENTS, FAILED_STEP = 0, 1, -1, -2
#: more mode changes than this at one instant are an error (an event chain that does not end)
MAX_EVENTS_PER_INSTANT = 1000
#: step size control: the next step is ``h SAFETY err^(-1/8)``, within ``[SHRINK_MOST, GROW_MOST]`` times ``h``
SAFETY, SHRINK_MOST, GROW_MOST = 0.8, 0.2, 2.5


@njit
def start(ch, bl, wk, out, clock, count):
    """Each block's mode at the start time (stuck if ``v = v_drive`` and ``F_S(0)`` holds, else the sign of
    ``v_rel``), the lists, the breakaway times, the first stage and any event at once."""
    par, law = ch
    mode, x, v, blk = bl
    t, vd = clock[T_NOW], clock[V_DRIVE]
    for i in range(mode.size):
        blk[i, X_STUCK], blk[i, T_STUCK] = x[i], t
        mode[i] = 0
    for i in range(mode.size):
        mode[i] = _initial_mode(par, law, mode, blk, vd, x, v, i, t)
    for i in range(mode.size):
        if mode[i] == 0:
            v[i] = vd
        else:
            blk[i, T_STUCK] = math.nan
    _rebuild(mode, wk.act, wk.mon, count)
    _refresh_breaks(ch, bl, wk, clock, count, 0, mode.size - 1)
    _settle(ch, bl, wk, out, clock, count, -1, t)


@njit
def _initial_mode(par, law, mode, blk, vd, x, v, i, t):
    v_rel = vd - v[i]
    if v_rel != 0.0:
        return 1 if v_rel > 0.0 else -1
    h = par[i, KAPPA] * x[i] - coupling_force(par, mode, blk, vd, x, i, t)
    if static_force(law[i, 1], par, i, STA, 0.0) - abs(h) >= 0.0:
        return 0
    return 1 if h > 0.0 else -1


@njit
def _rebuild(mode, act, mon, count):
    """The lists of slipping blocks and of stuck blocks with a slipping neighbour."""
    n, nact, nmon = mode.size, 0, 0
    for i in range(n):
        if mode[i] != 0:
            act[nact] = i
            nact += 1
        elif (i > 0 and mode[i - 1] != 0) or (i < n - 1 and mode[i + 1] != 0):
            mon[nmon] = i
            nmon += 1
    count[C_ACT], count[C_MON] = nact, nmon


@njit
def _refresh_breaks(ch, bl, wk, clock, count, lo, hi):
    """Breakaway times of the blocks ``lo .. hi`` (those stuck with stuck neighbours; inf for the others), then the
    earliest of all into ``clock[T_QUIET]`` and its block into ``count[C_QUIET]``."""
    mode, blk = bl.mode, bl.blk
    n, t = mode.size, clock[T_NOW]
    for j in range(max(lo, 0), min(hi, n - 1) + 1):
        quiet = mode[j] == 0 and (j == 0 or mode[j - 1] == 0) and (j == n - 1 or mode[j + 1] == 0)
        blk[j, T_BREAK] = quiet_break(ch, bl, wk, clock[V_DRIVE], j, t, clock[T_STOP]) if quiet else math.inf
    first = 0
    for j in range(1, n):
        if blk[j, T_BREAK] < blk[first, T_BREAK]:
            first = j
    clock[T_QUIET], count[C_QUIET] = blk[first, T_BREAK], first


@njit
def _apply(ch, bl, wk, out, clock, count, i, t):
    """Block ``i``'s event at time ``t``: a breakaway, or ``v_rel`` reaching 0 (stick, or overshoot where
    ``F_S(0)`` cannot hold the block); recorded in the buffers."""
    par, law = ch
    mode, x, v, blk = bl
    vd = clock[V_DRIVE]
    xi = position(mode, blk, vd, x, i, t)
    push = coupling_force(par, mode, blk, vd, x, i, t) - par[i, KAPPA] * xi
    new = 1 if push < 0.0 else -1
    kind = SLIP
    if mode[i] != 0:
        kind = OVERSHOOT
        if static_force(law[i, 1], par, i, STA, 0.0) - abs(push) >= 0.0:
            new, kind = 0, STICK
    x[i], v[i], mode[i] = xi, vd, new
    blk[i, X_STUCK], blk[i, T_STUCK] = xi, t if new == 0 else math.nan
    k = count[C_EVENTS]
    out.ev_t[k], out.ev_block[k], out.ev_kind[k], out.ev_x[k], out.ev_mode[k] = t, i, kind, xi, new
    count[C_EVENTS] += 1
    count[C_ALL_EVENTS] += 1
    count[C_INSTANT] = count[C_INSTANT] + 1 if t == clock[T_EVENT] else 1
    clock[T_EVENT] = t
    _rebuild(mode, wk.act, wk.mon, count)
    _refresh_breaks(ch, bl, wk, clock, count, i - 1, i + 1)


@njit
def _settle(ch, bl, wk, out, clock, count, i, t):
    """Apply block ``i``'s event at ``t`` (none if ``i < 0``), then every event it causes at the same instant; the
    first stage and the indicators at ``t`` for the next step."""
    par, law = ch
    mode, x, v, blk = bl
    while True:
        if i >= 0:
            _apply(ch, bl, wk, out, clock, count, i, t)
            if count[C_INSTANT] > MAX_EVENTS_PER_INSTANT:
                count[C_STATUS] = FAILED_EVENTS
                return
        rates(par, law, mode, blk, clock[V_DRIVE], wk.act, count[C_ACT], t, x, v, wk.kx, wk.kv, 0, wk.sx, wk.sv)
        i = _event_now(ch, bl, wk, clock[V_DRIVE], count, t)
        if i < 0 and clock[T_QUIET] <= t:
            i = count[C_QUIET]
        if i < 0:
            return


@njit
def _event_now(ch, bl, wk, vd, count, t):
    """The first watched block whose indicator is at or below 0 at ``t`` and does not rise (its event is now), or
    -1; sets every watched block's ``e0``, ``d0`` and ``rising``."""
    par, law = ch
    mode, x, v, blk = bl
    for lst, size in ((wk.act, count[C_ACT]), (wk.mon, count[C_MON])):
        for q in range(size):
            i = lst[q]
            value, rate = indicator(par, law, mode, blk, vd, x, v, i, t)
            blk[i, E0], blk[i, D0], blk[i, RISING] = value, rate, 1.0
            if value <= 0.0:
                if not leaves_zero(ch, bl, vd, i, t, rate):
                    blk[i, RISING] = 0.0
                    return i
    return -1


@njit
def _emit(bl, wk, out, clock, count, t0, t1, on_dense, final):
    """Grid rows at the grid times in ``[t0, t1)`` (``final``: up to ``t1`` included), slipping blocks from the
    step's dense output (``on_dense``) or their state."""
    mode, x, v, blk = bl
    dt, vd = clock[T_GRID], clock[V_DRIVE]
    if dt <= 0.0:
        return
    while count[C_ROWS] < out.row_t.size:
        g = count[C_GRID] * dt
        if g >= t1 and not (final and g <= t1 + 1e-9 * dt):
            return
        r = count[C_ROWS]
        out.row_t[r] = g
        for j in range(mode.size):
            out.row_mode[r, j] = mode[j]
            if mode[j] == 0:
                out.row_x[r, j], out.row_v[r, j] = blk[j, X_STUCK] + vd * (g - blk[j, T_STUCK]), vd
            elif on_dense:
                out.row_x[r, j], out.row_v[r, j] = dense_state(x, v, wk.fx, wk.fv, j, (g - t0) / (t1 - t0))
            else:
                out.row_x[r, j], out.row_v[r, j] = x[j], v[j]
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
def _stuck_phase(bl, wk, out, clock, count):
    """Every block stuck: the chain moves with the surface up to the next breakaway."""
    t0, t1 = clock[T_NOW], _limit(out, clock, count)
    _emit(bl, wk, out, clock, count, t0, t1, False, False)
    clock[T_NOW] = t1
    count[C_BUDGET] -= 1


@njit
def _true_step(ch, bl, wk, clock, count, t, h):
    """A DOP853 step of ``h`` s from ``t`` into ``wk.xn``, ``wk.vn``; its error norm."""
    par, law = ch
    mode, x, v, blk = bl
    return step(par, law, mode, blk, clock[V_DRIVE], clock[RTOL], wk.act, count[C_ACT], t, h, x, v, wk.kx, wk.kv,
                wk.sx, wk.sv, wk.xn, wk.vn)


@njit
def _accepted_step(ch, bl, wk, clock, count, t, h):
    """An accepted step from ``t``: tries ``h`` (s), shrinks it until the error norm is <= 1; returns the step taken
    (s) and the next step's size (s); the step is 0 if it became too small (status set)."""
    rejected = False
    while True:
        err = _true_step(ch, bl, wk, clock, count, t, h)
        if err <= 1.0:
            break
        h *= SHRINK_MOST if not err < math.inf else max(SHRINK_MOST, SAFETY * err ** -0.125)
        rejected = True
        count[C_REJECTED] += 1
        if h <= 1e-14 * max(1.0, abs(t)):
            count[C_STATUS] = FAILED_STEP
            return 0.0, h
    grow = GROW_MOST if err == 0.0 else min(GROW_MOST, max(SHRINK_MOST, SAFETY * err ** -0.125))
    return h, h * (min(grow, 1.0) if rejected else grow)


@njit
def _find_event(ch, bl, wk, clock, count, t, h):
    """``(time, block, dense built)`` of the first event in the step ``[t, t + h]`` just taken (block -1 if none):
    every watched block's indicator at the step's end into ``e1``, ``d1``; the dense output built where a block may
    cross."""
    par, law = ch
    mode, x, v, blk = bl
    vd = clock[V_DRIVE]
    first, block, built = math.inf, -1, False
    for lst, size in ((wk.act, count[C_ACT]), (wk.mon, count[C_MON])):
        for q in range(size):
            i = lst[q]
            if mode[i] != 0:
                blk[i, E1], blk[i, D1] = mode[i] * (vd - wk.vn[i]), -mode[i] * wk.kv[12, i]
            else:
                blk[i, E1], blk[i, D1] = indicator(par, law, mode, blk, vd, wk.xn, wk.vn, i, t + h)
            if may_cross(blk[i, E0], blk[i, D0], blk[i, E1], blk[i, D1], h):
                if not built:
                    _dense(ch, bl, wk, clock, count, t, h)
                    built = True
                hit = scan_step(ch, bl, wk, vd, i, t, h)
                if hit < first:
                    first, block = hit, i
    return first, block, built


@njit
def _dense(ch, bl, wk, clock, count, t, h):
    """The dense output of the step ``[t, t + h]`` just taken."""
    par, law = ch
    mode, x, v, blk = bl
    dense(par, law, mode, blk, clock[V_DRIVE], wk.act, count[C_ACT], t, h, x, v, wk.kx, wk.kv, wk.sx, wk.sv, wk.xn,
          wk.vn, wk.fx, wk.fv)
    count[C_DENSE] += 1


@njit
def _step_to_event(ch, bl, wk, clock, count, i, t, t_event, t_end):
    """The state at block ``i``'s event by a true step from ``t`` to ``t_event`` (s), moved once by Newton's rule on
    its indicator where that moves it by less than a thousandth of the step; returns the event's time."""
    par, law = ch
    mode, x, v, blk = bl
    _true_step(ch, bl, wk, clock, count, t, t_event - t)
    value, rate = indicator(par, law, mode, blk, clock[V_DRIVE], wk.xn, wk.vn, i, t_event)
    if rate != 0.0:
        moved = t_event - value / rate
        if moved != t_event and abs(moved - t_event) < 1e-3 * (t_event - t) and t < moved <= t_end:
            t_event = moved
            _true_step(ch, bl, wk, clock, count, t, t_event - t)
    return t_event


@njit
def _slip_step(ch, bl, wk, out, clock, count):
    """One step of the slipping blocks up to the first event in it (applied) or its end."""
    par, law = ch
    mode, x, v, blk = bl
    t, limit = clock[T_NOW], _limit(out, clock, count)
    h = min(clock[T_STEP], clock[H_MAX])
    clipped = t + h >= limit
    if clipped:
        h = limit - t
    taken, h_next = _accepted_step(ch, bl, wk, clock, count, t, h)
    if count[C_STATUS] != RUNNING:
        return
    cut = clipped and taken == h
    clock[T_STEP] = max(h_next, clock[T_STEP]) if cut else h_next  # a step cut short says nothing of the next one
    t1 = limit if cut else t + taken
    count[C_STEPS] += 1
    count[C_BUDGET] -= 1
    rates(par, law, mode, blk, clock[V_DRIVE], wk.act, count[C_ACT], t1, wk.xn, wk.vn, wk.kx, wk.kv, 12, wk.sx,
          wk.sv)
    hit, block, built = _find_event(ch, bl, wk, clock, count, t, t1 - t)
    if block < 0 and t1 == clock[T_QUIET]:
        hit, block = t1, count[C_QUIET]
    if block >= 0 and hit < t1:
        t1 = _step_to_event(ch, bl, wk, clock, count, block, t, hit, t1)
        built = False
    _finish_step(ch, bl, wk, out, clock, count, t, t1, built)
    if block >= 0:
        _settle(ch, bl, wk, out, clock, count, block, t1)


@njit
def _finish_step(ch, bl, wk, out, clock, count, t, t1, built):
    """The grid rows in ``[t, t1)`` (from the step's dense output), then the step's end as the new state."""
    par, law = ch
    mode, x, v, blk = bl
    if clock[T_GRID] > 0.0 and count[C_GRID] * clock[T_GRID] < t1:
        if not built:
            rates(par, law, mode, blk, clock[V_DRIVE], wk.act, count[C_ACT], t1, wk.xn, wk.vn, wk.kx, wk.kv, 12,
                  wk.sx, wk.sv)
            _dense(ch, bl, wk, clock, count, t, t1 - t)
        _emit(bl, wk, out, clock, count, t, t1, True, False)
    for q in range(count[C_ACT]):
        i = wk.act[q]
        x[i], v[i] = wk.xn[i], wk.vn[i]
        wk.kx[0, i], wk.kv[0, i] = wk.kx[12, i], wk.kv[12, i]
    for lst, size in ((wk.act, count[C_ACT]), (wk.mon, count[C_MON])):
        for q in range(size):
            blk[lst[q], E0], blk[lst[q], D0] = blk[lst[q], E1], blk[lst[q], D1]
    clock[T_NOW] = t1


@njit
def advance(ch, bl, wk, out, clock, count):
    """Run until the stop time (then the last grid row), the step budget ``count[C_BUDGET]`` is spent or the event
    buffer is nearly full; returns ``count[C_STATUS]``."""
    while count[C_STATUS] == RUNNING:
        t = clock[T_NOW]
        if t >= clock[T_STOP]:
            _emit(bl, wk, out, clock, count, t, t, False, True)
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
            _stuck_phase(bl, wk, out, clock, count)
        else:
            _slip_step(ch, bl, wk, out, clock, count)
    return count[C_STATUS]
