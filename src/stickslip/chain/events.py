"""Event indicators of the blocks and their first zero in a step (compiled kernels), graze-proof.

Indicator of block ``i`` (SPEC section 1): slipping in mode ``m``, ``e = m v_rel`` (m/s) with rate
``de/dt = -m dv/dt``; stuck, ``g = z_slip = F_S(t - t_stuck) - |kappa x - F_ext|`` (N) with rate
``dg/dt = F_S'(t_stick) - sign(kappa x - F_ext) (kappa v_drive - dF_ext/dt)``. Each reaches 0 at the block's event.
A step's indicators are sampled on its dense output with their rates, so that a dip between two positive samples
(a graze: the rate going from - to +) is located and counts if its minimum is <= 0; zeros are found to machine
precision by a bracketing root search.
"""

import math

from .arrays import SAMPLES
from .jit import njit
from .laws import kinetic_force, static_force, static_rate
from .stepper import acceleration, coupling_force, coupling_rate, dense_state

_EPS = 2.220446049250313e-16


@njit
def indicator(ch, bl, i, t, xs, vs):
    """``(value, rate)`` of block ``i``'s indicator at time ``t`` (s), slipping blocks at ``xs`` (m), ``vs`` (m/s)."""
    m = bl.mode[i]
    if m != 0:
        return m * (ch.v_drive - vs[i]), -m * acceleration(ch, bl, i, t, xs, vs)
    t_stick = t - bl.t_stuck[i]
    h = ch.kappa[i] * (bl.x_stuck[i] + ch.v_drive * t_stick) - coupling_force(ch, bl, xs, i, t)
    sign = 1.0 if h > 0.0 else -1.0 if h < 0.0 else 0.0
    rate = static_rate(ch.sta_law[i], ch.sta[i], t_stick)
    rate -= sign * (ch.kappa[i] * ch.v_drive - coupling_rate(ch, bl, vs, i))
    return static_force(ch.sta_law[i], ch.sta[i], t_stick) - abs(h), rate


@njit
def indicator_at(ch, bl, wk, i, t, t0, h, on_dense):
    """:func:`indicator` of block ``i`` at time ``t`` inside the step ``[t0, t0 + h]``: the slipping blocks from the
    step's dense output (``on_dense``), or all blocks stuck (closed forms)."""
    if not on_dense:
        return indicator(ch, bl, i, t, bl.x, bl.v)
    theta = (t - t0) / h
    for j in range(max(i - 1, 0), min(i + 2, ch.M.size)):
        if bl.mode[j] != 0:
            wk.sx[j], wk.sv[j] = dense_state(bl, wk, j, theta)
    return indicator(ch, bl, i, t, wk.sx, wk.sv)


@njit
def _component(ch, bl, wk, i, t, t0, h, on_dense, which):
    value, rate = indicator_at(ch, bl, wk, i, t, t0, h, on_dense)
    return value if which == 0 else rate


@njit
def root(ch, bl, wk, i, t0, h, on_dense, which, a, fa, b, fb):
    """A zero in ``[a, b]`` (s) of block ``i``'s indicator (``which`` 0) or its rate (1), whose values at the ends
    ``fa``, ``fb`` differ in sign, to machine precision (Illinois steps, every third one a bisection); ``b`` if
    ``fb == 0`` or the signs agree (the zero is there to rounding)."""
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
        fc = _component(ch, bl, wk, i, c, t0, h, on_dense, which)
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
def first_zero(ch, bl, wk, i, t0, h, on_dense, n, rising):
    """First time (s) in the samples ``wk.sample_t[:n + 1]`` (values ``sample_f``, rates ``sample_d``) at which block
    ``i``'s indicator comes down to 0, or inf. If it starts at or below 0 it is leaving 0: ``rising`` says it is known
    to rise (values <= 0 before it is positive are rounding, a maximum <= 0 before that is the zero), else a negative
    value means it never rose and the zero is the start."""
    s, fs, ds = wk.sample_t, wk.sample_f, wk.sample_d
    start = 0
    if fs[0] <= 0.0:
        first = -1
        for k in range(1, n + 1):
            if fs[k] > 0.0:
                first = k
                break
        last = first - 1 if first > 0 else n
        for k in range(last):
            if ds[k] > 0.0 and ds[k + 1] <= 0.0:
                peak = root(ch, bl, wk, i, t0, h, on_dense, 1, s[k], ds[k], s[k + 1], ds[k + 1])
                value = _component(ch, bl, wk, i, peak, t0, h, on_dense, 0)
                if value > 0.0:
                    return root(ch, bl, wk, i, t0, h, on_dense, 0, peak, value, s[k + 1], fs[k + 1])
                if rising:
                    return peak
            if not rising and fs[k + 1] < 0.0:
                return s[0]
        if first < 0:
            return math.inf
        start = first
    for k in range(start, n):
        if fs[k + 1] <= 0.0:
            return root(ch, bl, wk, i, t0, h, on_dense, 0, s[k], fs[k], s[k + 1], fs[k + 1])
        if ds[k] < 0.0 and ds[k + 1] > 0.0:
            low = root(ch, bl, wk, i, t0, h, on_dense, 1, s[k], ds[k], s[k + 1], ds[k + 1])
            value = _component(ch, bl, wk, i, low, t0, h, on_dense, 0)
            if value <= 0.0:
                return root(ch, bl, wk, i, t0, h, on_dense, 0, s[k], fs[k], low, value)
    return math.inf


@njit
def scan_step(ch, bl, wk, i, t0, h):
    """First zero (s) of block ``i``'s indicator in the step ``[t0, t0 + h]`` on its dense output, or inf; the ends
    are ``e0``, ``d0`` and ``e1``, ``d1``."""
    for k in range(SAMPLES + 1):
        t = t0 + h * k / SAMPLES
        wk.sample_t[k] = t
        if k == 0:
            wk.sample_f[k], wk.sample_d[k] = wk.e0[i], wk.d0[i]
        elif k == SAMPLES:
            wk.sample_t[k] = t0 + h
            wk.sample_f[k], wk.sample_d[k] = wk.e1[i], wk.d1[i]
        else:
            wk.sample_f[k], wk.sample_d[k] = indicator_at(ch, bl, wk, i, t, t0, h, True)
    return first_zero(ch, bl, wk, i, t0, h, True, SAMPLES, bl.rising[i])


@njit
def leaves_zero(ch, bl, i, t, value, rate):
    """Whether block ``i``'s indicator, at ``value <= 0`` with ``rate`` at time ``t``, rises (else its event is
    now). For a slip starting at ``v_rel = 0`` with ``dv/dt`` zero to rounding, the second derivative
    ``m (kappa v_drive - dF_ext/dt) / M`` decides."""
    m = bl.mode[i]
    if m != 0:
        x = bl.x[i]
        F = coupling_force(ch, bl, bl.x, i, t)
        scale = max(abs(ch.kappa[i] * x), abs(F), kinetic_force(ch.kin_law[i], ch.kin[i], 0.0),
                    static_force(ch.sta_law[i], ch.sta[i], 0.0))
        if abs(ch.M[i] * rate) <= 16.0 * _EPS * scale:
            rate = m * (ch.kappa[i] * ch.v_drive - coupling_rate(ch, bl, bl.v, i)) / ch.M[i]
    return rate > 0.0
