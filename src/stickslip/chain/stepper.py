"""DOP853 steps of the slipping blocks only, and the step's dense output (compiled kernels).

The state integrated is ``(x_i, v_i)`` of every slipping block ``i`` (``Work.act``); a stuck neighbour enters
through its closed form ``x_stuck + v_drive (t - t_stuck)``. A slipping block in mode ``m`` accelerates as
``M dv/dt = F_ext - kappa x + m F_K(m v_rel)`` (SPEC section 1) with the coupling force
``F_ext_i = k_left (x_(i-1) - x_i) + k_right (x_(i+1) - x_i)`` (N, along +x). Coefficients: Hairer's ``dop853.f``
(:mod:`stickslip.analysis.dop853_tableau`); error norm and step control as there.
"""

import math

import numpy as np

from ..analysis.dop853_tableau import A, A_DENSE, B, C, C_DENSE, D, E3, E5
from .jit import njit
from .laws import friction

_A = np.ascontiguousarray(A)
_B, _C, _E3, _E5 = B.copy(), C.copy(), E3.copy(), E5.copy()
_AD, _CD, _D = np.ascontiguousarray(A_DENSE), C_DENSE.copy(), np.ascontiguousarray(D)


@njit
def position(ch, bl, xs, j, t):
    """Block ``j``'s position (m) at time ``t`` (s): ``xs[j]`` while it slips, its closed form while stuck."""
    if bl.mode[j] == 0:
        return bl.x_stuck[j] + ch.v_drive * (t - bl.t_stuck[j])
    return xs[j]


@njit
def velocity(ch, bl, vs, j):
    """Block ``j``'s velocity (m/s): ``vs[j]`` while it slips, ``v_drive`` while stuck."""
    return ch.v_drive if bl.mode[j] == 0 else vs[j]


@njit
def coupling_force(ch, bl, xs, i, t):
    """``F_ext`` (N) of block ``i`` at time ``t`` with the slipping blocks at ``xs`` (m)."""
    xi = position(ch, bl, xs, i, t)
    f = 0.0
    if i > 0:
        f += ch.k_left[i] * (position(ch, bl, xs, i - 1, t) - xi)
    if i < ch.M.size - 1:
        f += ch.k_right[i] * (position(ch, bl, xs, i + 1, t) - xi)
    return f


@njit
def coupling_rate(ch, bl, vs, i):
    """``dF_ext/dt`` (N/s) of block ``i`` with the slipping blocks at velocities ``vs`` (m/s)."""
    vi = velocity(ch, bl, vs, i)
    f = 0.0
    if i > 0:
        f += ch.k_left[i] * (velocity(ch, bl, vs, i - 1) - vi)
    if i < ch.M.size - 1:
        f += ch.k_right[i] * (velocity(ch, bl, vs, i + 1) - vi)
    return f


@njit
def acceleration(ch, bl, i, t, xs, vs):
    """``dv/dt`` (m/s^2) of the slipping block ``i`` at time ``t``."""
    m = bl.mode[i]
    u = m * (ch.v_drive - vs[i])
    F = coupling_force(ch, bl, xs, i, t)
    return (F - ch.kappa[i] * xs[i] + m * friction(ch.kin_law[i], ch.kin[i], u)) / ch.M[i]


@njit
def rates(ch, bl, wk, nact, t, xs, vs, s):
    """Stage ``s``: ``kx[s] = v`` and ``kv[s] = dv/dt`` of the ``nact`` slipping blocks at ``(t, xs, vs)``."""
    for q in range(nact):
        i = wk.act[q]
        wk.kx[s, i] = vs[i]
        wk.kv[s, i] = acceleration(ch, bl, i, t, xs, vs)


@njit
def _stage_state(wk, nact, x, v, h, a, s):
    """``sx, sv = x, v + h sum_j a[s, j] k_j`` over the slipping blocks."""
    for q in range(nact):
        i = wk.act[q]
        dx = 0.0
        dv = 0.0
        for j in range(s):
            c = a[s, j]
            if c != 0.0:
                dx += c * wk.kx[j, i]
                dv += c * wk.kv[j, i]
        wk.sx[i] = x[i] + h * dx
        wk.sv[i] = v[i] + h * dv


@njit
def step(ch, bl, wk, nact, t, h):
    """One DOP853 step of length ``h`` (s) from ``t`` (state ``bl.x``, ``bl.v``, stage ``k_1`` in ``kx[0]``,
    ``kv[0]``) into ``xn``, ``vn``; returns its error norm (accept if <= 1)."""
    for s in range(1, 12):
        _stage_state(wk, nact, bl.x, bl.v, h, _A, s)
        rates(ch, bl, wk, nact, t + _C[s] * h, wk.sx, wk.sv, s)
    e5 = 0.0
    e3 = 0.0
    for q in range(nact):
        i = wk.act[q]
        for k, y, yn, atol in ((wk.kx, bl.x, wk.xn, ch.atol_x), (wk.kv, bl.v, wk.vn, ch.atol_v)):
            dy = 0.0
            s5 = 0.0
            s3 = 0.0
            for j in range(12):
                dy += _B[j] * k[j, i]
                s5 += _E5[j] * k[j, i]
                s3 += _E3[j] * k[j, i]
            yn[i] = y[i] + h * dy
            scale = atol[i] + ch.rtol * max(abs(y[i]), abs(yn[i]))
            e5 += (s5 / scale) ** 2
            e3 += (s3 / scale) ** 2
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * 2.0 * nact)


@njit
def dense(ch, bl, wk, nact, t, h):
    """The dense output of the step just taken (``k_13 = f(t + h, y1)`` in ``kx[12]``, ``kv[12]``): its three extra
    stages and the rows ``fx``, ``fv`` that :func:`dense_state` reads."""
    for r in range(3):
        s = 13 + r
        for q in range(nact):
            i = wk.act[q]
            dx = 0.0
            dv = 0.0
            for j in range(s):
                c = _AD[r, j]
                if c != 0.0:
                    dx += c * wk.kx[j, i]
                    dv += c * wk.kv[j, i]
            wk.sx[i] = bl.x[i] + h * dx
            wk.sv[i] = bl.v[i] + h * dv
        rates(ch, bl, wk, nact, t + _CD[r] * h, wk.sx, wk.sv, s)
    for q in range(nact):
        i = wk.act[q]
        for k, y, yn, f in ((wk.kx, bl.x, wk.xn, wk.fx), (wk.kv, bl.v, wk.vn, wk.fv)):
            dy = yn[i] - y[i]
            f[0, i] = dy
            f[1, i] = h * k[0, i] - dy
            f[2, i] = 2.0 * dy - h * (k[12, i] + k[0, i])
            for r in range(4):
                acc = 0.0
                for j in range(16):
                    c = _D[r, j]
                    if c != 0.0:
                        acc += c * k[j, i]
                f[3 + r, i] = h * acc


@njit
def dense_state(bl, wk, i, theta):
    """``(x, v)`` of the slipping block ``i`` at the fraction ``theta`` of the step (from its dense output)."""
    x = 0.0
    v = 0.0
    for r in range(6, -1, -1):
        x += wk.fx[r, i]
        v += wk.fv[r, i]
        w = theta if (6 - r) % 2 == 0 else 1.0 - theta
        x *= w
        v *= w
    return bl.x[i] + x, bl.v[i] + v
