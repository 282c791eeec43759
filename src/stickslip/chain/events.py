"""Event indicators of the blocks and their first zero in a step (compiled kernels), graze-proof.

Indicator of block ``i`` (SPEC section 1): slipping in mode ``m``, ``e = m v_rel`` (m/s) with rate
``de/dt = -m dv/dt``; stuck, ``g = z_slip = F_S(t - t_stuck) - |kappa x - F_ext|`` (N) with rate
``dg/dt = F_S'(t_stick) - sign(kappa x - F_ext) (kappa v_drive - dF_ext/dt)``. Each reaches 0 at the block's event.
A step's indicators are sampled on its dense output with their rates, so that a dip between two positive samples
(a graze: the rate going from - to +) is located and counts if its minimum is <= 0; zeros are found to machine
precision by a bracketing root search. Array names as :mod:`.arrays`; ``vd`` is ``v_drive`` (m/s).
"""

import math

from .arrays import D0, D1, E0, E1, KAPPA, KIN, M, RISING, SAMPLES, STA, T_STUCK, X_STUCK
from .jit import njit
from .laws import kinetic_force, static_force, static_rate
from .stepper import acceleration, coupling_force, coupling_rate, dense_state

_EPS = 2.220446049250313e-16


@njit
def indicator(par, law, mode, blk, vd, xs, vs, i, t):
    """``(value, rate)`` of block ``i``'s indicator at time ``t`` (s), slipping blocks at ``xs`` (m), ``vs`` (m/s)."""
    m = mode[i]
    if m != 0:
        return m * (vd - vs[i]), -m * acceleration(par, law, mode, blk, vd, xs, vs, i, t)
    t_stick = t - blk[i, T_STUCK]
    h = par[i, KAPPA] * (blk[i, X_STUCK] + vd * t_stick) - coupling_force(par, mode, blk, vd, xs, i, t)
    sign = 1.0 if h > 0.0 else -1.0 if h < 0.0 else 0.0
    rate = static_rate(law[i, 1], par, i, STA, t_stick)
    rate -= sign * (par[i, KAPPA] * vd - coupling_rate(par, mode, vd, vs, i))
    return static_force(law[i, 1], par, i, STA, t_stick) - abs(h), rate


@njit
def indicator_at(par, law, mode, x, v, blk, fx, fv, sx, sv, vd, i, t, t0, h, on_dense):
    """:func:`indicator` of block ``i`` at time ``t`` inside the step ``[t0, t0 + h]`` that starts at ``x``, ``v``:
    the slipping blocks from the step's dense output rows ``fx``, ``fv`` (``on_dense``; ``sx``, ``sv`` take their
    states), or all blocks stuck (closed forms)."""
    if not on_dense:
        return indicator(par, law, mode, blk, vd, x, v, i, t)
    theta = (t - t0) / h
    for j in range(max(i - 1, 0), min(i + 2, mode.size)):
        if mode[j] != 0:
            sx[j], sv[j] = dense_state(x, v, fx, fv, j, theta)
    return indicator(par, law, mode, blk, vd, sx, sv, i, t)


@njit
def root(par, law, mode, x, v, blk, fx, fv, sx, sv, vd, i, t0, h, on_dense, which, a, fa, b, fb):
    """A zero in ``[a, b]`` (s) of block ``i``'s indicator (``which`` 0) or its rate (1) (:func:`indicator_at`),
    whose values at the ends ``fa``, ``fb`` differ in sign, to machine precision (Illinois steps, every third one a
    bisection); ``b`` if ``fb == 0`` or the signs agree (the zero is there to rounding)."""
    if fb == 0.0 or fa * fb > 0.0:
        return b
    if fa == 0.0:
        return a
    side = 0
    for k in range(400):
        if b - a <= 2.0 * _EPS * (abs(a) + abs(b)) + 1e-300:
            break
        c = 0.5 * (a + b) if k % 3 == 2 else (a * fb - b * fa) / (fb - fa)
        if not a < c < b:
            c = 0.5 * (a + b)
        fc = indicator_at(par, law, mode, x, v, blk, fx, fv, sx, sv, vd, i, c, t0, h, on_dense)[which]
        if fc == 0.0:
            return c
        if (fc > 0.0) == (fb > 0.0):
            b, fb = c, fc
            if side == -1:
                fa *= 0.5
            side = -1
        else:
            a, fa = c, fc
            if side == 1:
                fb *= 0.5
            side = 1
    return b


@njit
def may_cross(e0, d0, e1, d1, h):
    """Whether an indicator with values ``e0``, ``e1`` and rates ``d0``, ``d1`` at the ends of a step of ``h`` s may
    reach 0 inside it: unless both ends are positive by more than four times the largest bend of the cubic through
    them (the bend is at most ``(|h d0 - de| + |h d1 - de|) / 4``, ``de = e1 - e0``), the step is scanned."""
    if e0 <= 0.0 or e1 <= 0.0:
        return True
    de = e1 - e0
    return min(e0, e1) <= abs(h * d0 - de) + abs(h * d1 - de)


@njit
def first_zero(par, law, mode, x, v, blk, fx, fv, sx, sv, vd, i, t0, h, on_dense, smp, n, rising):
    """First time (s) in the samples ``smp[:, :n + 1]`` (times, values, rates) at which block ``i``'s indicator
    (:func:`indicator_at`) comes down to 0, or inf. If it starts at or below 0 it is leaving 0: ``rising`` says it is
    known to rise (values <= 0 before it is positive are rounding, a maximum <= 0 before that is the zero), else a
    negative value means it never rose and the zero is the start."""
    s, fs, ds = smp[0], smp[1], smp[2]
    start = 0
    if fs[0] <= 0.0:
        first = -1
        for k in range(1, n + 1):
            if fs[k] > 0.0:
                first = k
                break
        for k in range(first - 1 if first > 0 else n):
            if ds[k] > 0.0 and ds[k + 1] <= 0.0:
                peak = root(par, law, mode, x, v, blk, fx, fv, sx, sv, vd, i, t0, h, on_dense, 1,
                            s[k], ds[k], s[k + 1], ds[k + 1])
                top = indicator_at(par, law, mode, x, v, blk, fx, fv, sx, sv, vd, i, peak, t0, h, on_dense)[0]
                if top > 0.0:
                    return root(par, law, mode, x, v, blk, fx, fv, sx, sv, vd, i, t0, h, on_dense, 0,
                                peak, top, s[k + 1], fs[k + 1])
                if rising:
                    return peak
            if not rising and fs[k + 1] < 0.0:
                return s[0]
        if first < 0:
            return math.inf
        start = first
    for k in range(start, n):
        if fs[k + 1] <= 0.0:
            return root(par, law, mode, x, v, blk, fx, fv, sx, sv, vd, i, t0, h, on_dense, 0,
                        s[k], fs[k], s[k + 1], fs[k + 1])
        if ds[k] < 0.0 and ds[k + 1] > 0.0:
            low = root(par, law, mode, x, v, blk, fx, fv, sx, sv, vd, i, t0, h, on_dense, 1,
                       s[k], ds[k], s[k + 1], ds[k + 1])
            bottom = indicator_at(par, law, mode, x, v, blk, fx, fv, sx, sv, vd, i, low, t0, h, on_dense)[0]
            if bottom <= 0.0:
                return root(par, law, mode, x, v, blk, fx, fv, sx, sv, vd, i, t0, h, on_dense, 0,
                            s[k], fs[k], low, bottom)
    return math.inf


@njit
def scan_step(ch, bl, wk, vd, i, t0, h):
    """First zero (s) of block ``i``'s indicator in the step ``[t0, t0 + h]`` on its dense output, or inf; the ends
    are its ``e0``, ``d0`` and ``e1``, ``d1``."""
    par, law = ch
    mode, x, v, blk = bl
    fx, fv, sx, sv, smp = wk.fx, wk.fv, wk.sx, wk.sv, wk.smp
    smp[0, 0], smp[1, 0], smp[2, 0] = t0, blk[i, E0], blk[i, D0]
    for k in range(1, SAMPLES):
        t = t0 + h * k / SAMPLES
        smp[0, k] = t
        smp[1, k], smp[2, k] = indicator_at(par, law, mode, x, v, blk, fx, fv, sx, sv, vd, i, t, t0, h, True)
    smp[0, SAMPLES], smp[1, SAMPLES], smp[2, SAMPLES] = t0 + h, blk[i, E1], blk[i, D1]
    return first_zero(par, law, mode, x, v, blk, fx, fv, sx, sv, vd, i, t0, h, True, smp, SAMPLES,
                      blk[i, RISING] > 0.0)


@njit
def leaves_zero(ch, bl, vd, i, t, rate):
    """Whether block ``i``'s indicator, at or below 0 with ``rate`` at time ``t``, rises (else its event is now).
    For a slip starting at ``v_rel = 0`` with ``dv/dt`` zero to rounding, the second derivative
    ``m (kappa v_drive - dF_ext/dt) / M`` decides."""
    par, law = ch
    mode, x, v, blk = bl
    m = mode[i]
    if m != 0:
        F = coupling_force(par, mode, blk, vd, x, i, t)
        scale = max(abs(par[i, KAPPA] * x[i]), abs(F), kinetic_force(law[i, 0], par, i, KIN, 0.0),
                    static_force(law[i, 1], par, i, STA, 0.0))
        if abs(par[i, M] * rate) <= 16.0 * _EPS * scale:
            rate = m * (par[i, KAPPA] * vd - coupling_rate(par, mode, vd, v, i)) / par[i, M]
    return rate > 0.0
