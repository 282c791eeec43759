"""The friction laws of SPEC section 2 as compiled kernels over flat parameter rows.

A block's kinetic law is its code (1..5) and a row of parameters in the order of :data:`KINETIC_PARAMETERS`
(unused places 0); its static law likewise (:data:`STATIC_PARAMETERS`). The kernels read block ``i``'s row in place,
``par[i, at + k]`` for its parameter ``k`` (no array view is made in the hot loop). Kinetic: ``F_K(u)`` (N) for the sliding
speed ``u = |v_rel| >= 0`` (m/s) and its slope (N s/m). Static: ``F_S(t)`` (N) after sticking ``t >= 0`` s and its
rate (N/s).
"""

import math

from .jit import njit

#: kinetic law code: the names of its parameters, in the order of a block's row
KINETIC_PARAMETERS = {1: ("F0",), 2: ("F0", "gamma"), 3: ("F0", "F_stribeck", "v_stribeck", "delta", "gamma"),
                      4: ("gamma1", "gamma2", "v_tilde", "dv"), 5: ("F0", "sigma", "alpha")}
#: static law code: the names of its parameters, in the order of a block's row
STATIC_PARAMETERS = {1: ("F0",), 2: ("F0", "A", "tau"), 3: ("F0", "F_inf", "tau"), 4: ("F0", "F_inf", "tau", "n")}
KINETIC_WIDTH = 5
STATIC_WIDTH = 4


@njit
def force_of(code, p0, p1, p2, p3, p4, u):
    """``F_K(u)`` (N) of the kinetic law ``code`` with the parameters ``p0 .. p4`` (a row), ``u >= 0`` (m/s)."""
    if code == 1:
        return p0
    if code == 2:
        return p0 + p1 * u
    if code == 3:
        s = u / p2
        return p0 + p1 * (math.exp(-s) if p3 == 1.0 else math.exp(-math.pow(s, p3))) + p4 * u
    if code == 4:
        w = u - p2
        return 0.5 * u * (p0 + p1 + (p1 - p0) * w / math.sqrt(p3 * p3 + w * w))
    rest = 1.0 - p1
    return p0 * rest / (1.0 + 2.0 * p2 * u / rest)


@njit
def slope_of(code, p0, p1, p2, p3, p4, u):
    """``dF_K/du`` (N s/m) of the kinetic law ``code`` with the parameters ``p0 .. p4`` at ``u >= 0`` (m/s)."""
    if code == 1:
        return 0.0
    if code == 2:
        return p1
    if code == 3:
        s = u / p2
        return p4 - p1 * p3 * math.pow(s, p3 - 1.0) * math.exp(-math.pow(s, p3)) / p2
    if code == 4:
        w = u - p2
        r = math.sqrt(p3 * p3 + w * w)
        return 0.5 * (p0 + p1) + 0.5 * (p1 - p0) * (w / r + u * p3 * p3 / (r * r * r))
    weakening = 1.0 + 2.0 * p2 * u / (1.0 - p1)
    return -2.0 * p2 * p0 / (weakening * weakening)


@njit
def friction_of(code, p0, p1, p2, p3, p4, u):
    """``F_K(u)`` (N) for ``u >= 0``; for ``u < 0`` its tangent at 0. Only a Runge-Kutta stage past a ``v_rel = 0``
    crossing sees ``u < 0``: the C1 continuation keeps the step smooth and is never part of the solution."""
    if u >= 0.0:
        return force_of(code, p0, p1, p2, p3, p4, u)
    return force_of(code, p0, p1, p2, p3, p4, 0.0) + slope_of(code, p0, p1, p2, p3, p4, 0.0) * u


@njit
def kinetic_force(code, par, i, at, u):
    """:func:`force_of` with block ``i``'s parameters ``par[i, at:at + 5]``."""
    return force_of(code, par[i, at], par[i, at + 1], par[i, at + 2], par[i, at + 3], par[i, at + 4], u)


@njit
def static_force(code, par, i, at, t):
    """``F_S(t)`` (N) of the static law ``code`` with the parameters ``par[i, at:]`` after sticking ``t >= 0`` s."""
    p = (par[i, at], par[i, at + 1], par[i, at + 2], par[i, at + 3])
    if code == 1:
        return p[0]
    if code == 2:
        return p[0] + p[1] * math.log1p(t / p[2])
    if code == 3:
        return p[0] - (p[1] - p[0]) * math.expm1(-t / p[2])
    s = t / p[2]
    if s > 1.0:  # t^n / (tau^n + t^n) = 1 / (1 + s^-n): no overflow for large s
        return p[0] + (p[1] - p[0]) / (1.0 + math.pow(s, -p[3]))
    q = math.pow(s, p[3])
    return p[0] + (p[1] - p[0]) * q / (1.0 + q)


@njit
def static_rate(code, par, i, at, t):
    """``dF_S/dt`` (N/s) of the static law ``code`` with the parameters ``par[i, at:]`` after sticking ``t >= 0`` s."""
    p = (par[i, at], par[i, at + 1], par[i, at + 2], par[i, at + 3])
    if code == 1:
        return 0.0
    if code == 2:
        return p[1] / (p[2] + t)
    if code == 3:
        return (p[1] - p[0]) / p[2] * math.exp(-t / p[2])
    jump, n, s = p[1] - p[0], p[3], t / p[2]
    if jump == 0.0:
        return 0.0
    if s == 0.0:
        return 0.0 if n > 1.0 else jump / p[2] if n == 1.0 else math.copysign(math.inf, jump)
    if s > 1.0:  # s^(n-1) / (1 + s^n)^2 = s^(-n-1) / (1 + s^-n)^2
        q = math.pow(s, -n)
        return jump * (n / p[2]) * (q / s) / ((1.0 + q) * (1.0 + q))
    q = math.pow(s, n)
    return jump * (n / p[2]) * math.pow(s, n - 1.0) / ((1.0 + q) * (1.0 + q))


@njit
def static_bend(code, par, i, at):
    """The stick time (s) where ``F_S''`` changes sign (the sigmoid law with ``n > 1``), else -1."""
    p = (par[i, at], par[i, at + 1], par[i, at + 2], par[i, at + 3])
    if code != 4 or p[3] <= 1.0 or p[1] == p[0]:
        return -1.0
    return p[2] * math.pow((p[3] - 1.0) / (p[3] + 1.0), 1.0 / p[3])
