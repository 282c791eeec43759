"""Kinetic friction as vectorized functions, and its higher derivatives.

The core laws (:mod:`stickslip.core.laws`) are scalar (pure ``math``, bundled
into the FMU). The analysis integrates whole batches of slips at once, so it
needs ``F_K(u)`` and ``F_K'(u)`` on numpy arrays: :func:`vectorized` returns
them for the five coded laws in closed form (SPEC section 2's formulas, as in the
core; ``tests/test_law_formulas.py`` pins both, and the continuation below 0, to
SPEC) and wraps any other law (``CallableKinetic``) with :func:`numpy.vectorize`.

The normal form of the Hopf points needs ``F_K''`` and ``F_K'''``.
:func:`derivatives` gets them by high-order central differences of the law's
own ``slope`` (so it works for every law, callables included):

    F''(u)  ~ [8 (s(u+h) - s(u-h)) - (s(u+2h) - s(u-2h))] / (12 h)        (error O(h^4))
    F'''(u) ~ [-s(u+2h) + 16 s(u+h) - 30 s(u) + 16 s(u-h) - s(u-2h)] / (12 h^2)

with ``s = slope``; the step ``h`` is chosen from a ladder by Richardson
consistency (the step whose estimate agrees best with the estimate at half the
step), which balances truncation against rounding (``eps / h^2``).

Outside the slip side (``u < 0``, only probed by the smooth continuation of a
slip past ``v_rel = 0``, see :mod:`.flow`) ``F_K`` is continued by its tangent
at 0, exactly as the core's Runge-Kutta stages do.
"""

import math

import numpy as np

from ..core.laws import CarlsonLanger, Coulomb, Lubricated, Stribeck, Viscous


def _coulomb(law):
    F0 = law.F0
    return (lambda u: np.full(np.shape(u), F0)), (lambda u: np.zeros(np.shape(u)))


def _viscous(law):
    F0, g = law.F0, law.gamma
    return (lambda u: F0 + g * u), (lambda u: np.full(np.shape(u), g))


def _stribeck(law):
    F0, Fs, vs, d, g = law.F0, law.F_stribeck, law.v_stribeck, law.delta, law.gamma

    def force(u):
        return F0 + Fs * np.exp(-((np.maximum(u, 0.0) / vs) ** d)) + g * u

    def slope(u):
        s = np.maximum(u, 0.0) / vs
        if d == 1.0:
            return g - Fs * np.exp(-s) / vs
        return g - Fs * d * s ** (d - 1.0) * np.exp(-(s**d)) / vs

    return force, slope


def _lubricated(law):
    g1, g2, vt, dv = law.gamma1, law.gamma2, law.v_tilde, law.dv
    mean, half = 0.5 * (g1 + g2), 0.5 * (g2 - g1)

    def force(u):
        w = u - vt
        return u * (mean + half * w / np.hypot(dv, w))

    def slope(u):
        w = u - vt
        s = np.hypot(dv, w)
        return mean + half * (w / s + u * dv * dv / (s * s * s))

    return force, slope


def _carlson_langer(law):
    F0, drop, alpha = law.F0, 1.0 - law.sigma, law.alpha

    def force(u):
        return F0 * drop / (1.0 + 2.0 * alpha * u / drop)

    def slope(u):
        return -2.0 * alpha * F0 / (1.0 + 2.0 * alpha * u / drop) ** 2

    return force, slope


_EXACT = {Coulomb: _coulomb, Viscous: _viscous, Stribeck: _stribeck, Lubricated: _lubricated,
          CarlsonLanger: _carlson_langer}


def vectorized(law):
    """``(force, slope)``: numpy functions of ``u >= 0`` for a kinetic law."""
    make = _EXACT.get(type(law))
    if make is not None:
        return make(law)
    return np.vectorize(law.force, otypes=[float]), np.vectorize(law.slope, otypes=[float])


class Kinetic:
    """A kinetic law ready for batches: ``F(u)``, ``dF(u)`` continued by the tangent below ``u = 0``."""

    def __init__(self, law):
        self.law = law
        self._force, self._slope = vectorized(law)
        self.f0 = float(law.force(0.0))
        self.s0 = float(law.slope(0.0))
        self.affine = law.affine()

    def force(self, u):
        u = np.asarray(u, float)
        if np.all(u >= 0.0):
            return self._force(u)
        up = np.maximum(u, 0.0)
        return np.where(u >= 0.0, self._force(up), self.f0 + self.s0 * u)

    def slope(self, u):
        u = np.asarray(u, float)
        if np.all(u >= 0.0):
            return self._slope(u)
        return np.where(u >= 0.0, self._slope(np.maximum(u, 0.0)), self.s0)


# ----------------------------------------------------------------------
# higher derivatives by central differences of the slope
# ----------------------------------------------------------------------


def _second(s, u, h):
    return (8.0 * (s(u + h) - s(u - h)) - (s(u + 2 * h) - s(u - 2 * h))) / (12.0 * h)


def _third(s, u, h):
    return (-s(u + 2 * h) + 16.0 * s(u + h) - 30.0 * s(u) + 16.0 * s(u - h) - s(u - 2 * h)) / (12.0 * h * h)


def _richardson(estimate, s, u, steps):
    """The estimate at the step of the ladder whose value changes least when the step is halved."""
    values = [estimate(s, u, h) for h in steps]
    best, best_change = values[0], math.inf
    for k in range(len(values) - 1):
        change = abs(values[k] - values[k + 1])
        if change < best_change:
            best, best_change = values[k + 1], change
    return best


def derivatives(law, u, scale=None):
    """``(F_K'(u), F_K''(u), F_K'''(u))`` at ``u > 0`` (m/s) by central differences of ``slope``.

    ``scale`` (m/s) bounds the steps from above (default ``u``); steps stay
    below ``u/2`` so the stencil never leaves the slip side.
    """
    u = float(u)
    if u <= 0.0:
        raise ValueError("derivatives of F_K are taken at u > 0")
    top = min(0.2 * (scale if scale is not None else u), 0.45 * u)
    steps = [top * 0.5**k for k in range(14)]
    s = law.slope
    return float(s(u)), _richardson(_second, s, u, steps), _richardson(_third, s, u, steps)


def extrema(law, u_max, u_min=0.0, n=4000):
    """Extrema of ``F_K`` on ``(u_min, u_max]``: ``[(u, "max" or "min"), ...]`` (zeros of the slope).

    The slope is sampled on a grid fine near 0 and uniform elsewhere; each sign
    change is refined by Brent's method to machine precision.
    """
    from scipy.optimize import brentq

    if u_max <= u_min:
        return []
    grid = np.unique(np.concatenate([
        np.linspace(u_min, u_max, n),
        u_min + (u_max - u_min) * np.geomspace(1e-7, 1.0, n // 4),
    ]))
    grid = grid[grid > 0.0] if u_min <= 0.0 else grid
    slope = np.array([law.slope(float(u)) for u in grid])
    found = []
    for i in np.flatnonzero(np.sign(slope[:-1]) * np.sign(slope[1:]) < 0.0):
        u = brentq(law.slope, grid[i], grid[i + 1], xtol=1e-15, rtol=1e-15)
        found.append((u, "max" if slope[i] > 0.0 else "min"))
    for i in np.flatnonzero(slope[1:-1] == 0.0) + 1:
        if slope[i - 1] * slope[i + 1] < 0.0:
            found.append((float(grid[i]), "max" if slope[i - 1] > 0.0 else "min"))
    return sorted(found)
