"""DOP853 steps of the slipping blocks only, and the step's dense output (compiled kernels).

The state integrated is ``(x_i, v_i)`` of every slipping block ``i`` (the list ``act``); a stuck neighbour enters
through its closed form ``x_stuck + v_drive (t - t_stuck)``. A slipping block in mode ``m`` accelerates as
``M dv/dt = F_ext - kappa x + m F_K(m v_rel)`` (SPEC section 1) with the coupling force
``F_ext_i = k_left (x_(i-1) - x_i) + k_right (x_(i+1) - x_i)`` (N, along +x). Coefficients: Hairer's ``dop853.f``
(:mod:`stickslip.analysis.dop853_tableau`); error estimate as there, its norm the root of the sum of squares over
the slipping states (not their mean: a step is as accurate whether one block slips or a hundred), each scaled by
``atol + rtol |y|``. Array names as :mod:`.arrays`.
"""

import math

import numpy as np

from ..analysis.dop853_tableau import A, A_DENSE, B, C, C_DENSE, D, E3, E5
from .arrays import ATOL_V, ATOL_X, K_LEFT, K_RIGHT, KAPPA, KIN, M, T_STUCK, X_STUCK
from .jit import njit
from .laws import friction_of

_A = np.ascontiguousarray(A)
_B, _C, _E3, _E5 = B.copy(), C.copy(), E3.copy(), E5.copy()
_AD, _CD, _D = np.ascontiguousarray(A_DENSE), C_DENSE.copy(), np.ascontiguousarray(D)


@njit
def place(stuck, x_stuck, t_stuck, x, vd, t):
    """A block's position (m) at time ``t`` (s) from scalars: its closed form if ``stuck``, else ``x``."""
    return x_stuck + vd * (t - t_stuck) if stuck else x


@njit
def position(mode, blk, vd, xs, j, t):
    """Block ``j``'s position (m) at time ``t`` (s): ``xs[j]`` while it slips, its closed form while stuck."""
    return place(mode[j] == 0, blk[j, X_STUCK], blk[j, T_STUCK], xs[j], vd, t)


@njit
def velocity(mode, vd, vs, j):
    """Block ``j``'s velocity (m/s): ``vs[j]`` while it slips, ``v_drive`` while stuck."""
    return vd if mode[j] == 0 else vs[j]


@njit
def coupling_force(par, mode, blk, vd, xs, i, t):
    """``F_ext`` (N) of block ``i`` at time ``t`` with the slipping blocks at ``xs`` (m)."""
    xi = position(mode, blk, vd, xs, i, t)
    f = 0.0
    if i > 0:
        f += par[i, K_LEFT] * (position(mode, blk, vd, xs, i - 1, t) - xi)
    if i < mode.size - 1:
        f += par[i, K_RIGHT] * (position(mode, blk, vd, xs, i + 1, t) - xi)
    return f


@njit
def coupling_rate(par, mode, vd, vs, i):
    """``dF_ext/dt`` (N/s) of block ``i`` with the slipping blocks at velocities ``vs`` (m/s)."""
    vi = velocity(mode, vd, vs, i)
    f = 0.0
    if i > 0:
        f += par[i, K_LEFT] * (velocity(mode, vd, vs, i - 1) - vi)
    if i < mode.size - 1:
        f += par[i, K_RIGHT] * (velocity(mode, vd, vs, i + 1) - vi)
    return f


@njit
def acceleration(par, law, mode, blk, vd, xs, vs, i, t):
    """``dv/dt`` (m/s^2) of the slipping block ``i`` at time ``t``."""
    m = mode[i]
    F = coupling_force(par, mode, blk, vd, xs, i, t)
    return slip_acceleration(par, law, i, m, F, xs[i], m * (vd - vs[i]))


@njit
def slip_acceleration(par, law, i, m, F, x, u):
    """``(F - kappa x + m F_K(u)) / M`` (m/s^2): block ``i`` slipping in mode ``m`` at ``x`` (m) with the coupling
    force ``F`` (N) and the sliding speed ``u = m v_rel`` (m/s)."""
    friction = friction_of(law[i, 0], par[i, KIN], par[i, KIN + 1], par[i, KIN + 2], par[i, KIN + 3],
                           par[i, KIN + 4], u)
    return (F - par[i, KAPPA] * x + m * friction) / par[i, M]


@njit
def stage(par, law, mode, blk, vd, act, nact, t, h, x, v, kx, kv, a, row, terms, s, sx, sv):
    """Stage ``s`` at time ``t`` (s): the slipping blocks' states ``sx, sv = x, v + h sum_(j < terms) a[row, j] k_j``,
    then ``kx[s] = sv`` and ``kv[s] = dv/dt`` there. The hot loop: the coupling force is summed here (as
    :func:`coupling_force` does) and the helpers take scalars, as each array passed costs a reference count."""
    for q in range(nact):
        i = act[q]
        dx = 0.0
        dv = 0.0
        for j in range(terms):
            c = a[row, j]
            if c != 0.0:
                dx += c * kx[j, i]
                dv += c * kv[j, i]
        sx[i] = x[i] + h * dx
        sv[i] = v[i] + h * dv
    last = mode.size - 1
    for q in range(nact):
        i = act[q]
        xi = sx[i]
        f = 0.0
        if i > 0:
            j = i - 1
            f += par[i, K_LEFT] * (place(mode[j] == 0, blk[j, X_STUCK], blk[j, T_STUCK], sx[j], vd, t) - xi)
        if i < last:
            j = i + 1
            f += par[i, K_RIGHT] * (place(mode[j] == 0, blk[j, X_STUCK], blk[j, T_STUCK], sx[j], vd, t) - xi)
        kx[s, i] = sv[i]
        kv[s, i] = slip_acceleration(par, law, i, mode[i], f, xi, mode[i] * (vd - sv[i]))


@njit
def rates(par, law, mode, blk, vd, act, nact, t, xs, vs, kx, kv, s, sx, sv):
    """``kx[s] = v`` and ``kv[s] = dv/dt`` of the slipping blocks at ``(t, xs, vs)`` (:func:`stage` with no terms;
    ``sx``, ``sv`` take a copy of their states)."""
    stage(par, law, mode, blk, vd, act, nact, t, 0.0, xs, vs, kx, kv, _A, 0, 0, s, sx, sv)


@njit
def step(par, law, mode, blk, vd, rtol, act, nact, t, h, x, v, kx, kv, sx, sv, xn, vn):
    """One DOP853 step of length ``h`` (s) from ``t`` (state ``x``, ``v``, stage ``k_1`` in ``kx[0]``, ``kv[0]``)
    into ``xn``, ``vn``; returns its error norm (accept if <= 1)."""
    for s in range(1, 12):
        stage(par, law, mode, blk, vd, act, nact, t + _C[s] * h, h, x, v, kx, kv, _A, s, s, s, sx, sv)
    e5 = 0.0
    e3 = 0.0
    for q in range(nact):
        i = act[q]
        dx, x5, x3, dv, v5, v3 = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        for j in range(12):
            dx += _B[j] * kx[j, i]
            x5 += _E5[j] * kx[j, i]
            x3 += _E3[j] * kx[j, i]
            dv += _B[j] * kv[j, i]
            v5 += _E5[j] * kv[j, i]
            v3 += _E3[j] * kv[j, i]
        xn[i] = x[i] + h * dx
        vn[i] = v[i] + h * dv
        sx_ = par[i, ATOL_X] + rtol * max(abs(x[i]), abs(xn[i]))
        sv_ = par[i, ATOL_V] + rtol * max(abs(v[i]), abs(vn[i]))
        e5 += (x5 / sx_) ** 2 + (v5 / sv_) ** 2
        e3 += (x3 / sx_) ** 2 + (v3 / sv_) ** 2
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    return abs(h) * e5 / math.sqrt(e5 + 0.01 * e3)  # summed over the states, not averaged: as tight for N blocks


@njit
def dense(par, law, mode, blk, vd, act, nact, t, h, x, v, kx, kv, sx, sv, xn, vn, fx, fv):
    """The dense output of the step just taken (``k_13 = f(t + h, y1)`` in ``kx[12]``, ``kv[12]``): its three extra
    stages and the rows ``fx``, ``fv`` that :func:`dense_state` reads."""
    for r in range(3):
        stage(par, law, mode, blk, vd, act, nact, t + _CD[r] * h, h, x, v, kx, kv, _AD, r, 13 + r, 13 + r, sx, sv)
    for q in range(nact):
        i = act[q]
        _dense_rows(kx, x, xn, fx, h, i)
        _dense_rows(kv, v, vn, fv, h, i)


@njit
def _dense_rows(k, y, yn, f, h, i):
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
def dense_state(x, v, fx, fv, i, theta):
    """``(x, v)`` of the slipping block ``i`` at the fraction ``theta`` of the step (from its dense output rows
    ``fx``, ``fv`` over the step's start ``x``, ``v``)."""
    px = 0.0
    pv = 0.0
    for r in range(6, -1, -1):
        px += fx[r, i]
        pv += fv[r, i]
        w = theta if (6 - r) % 2 == 0 else 1.0 - theta
        px *= w
        pv *= w
    return x[i] + px, v[i] + pv
