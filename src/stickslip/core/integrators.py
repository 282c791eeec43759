"""One step of the slip ODE ``x' = v, v' = a(x, v)`` with an error estimate and dense output.

Two methods, both for this 2-dimensional system written out in scalars:

- ``dopri5_step``: Dormand-Prince 5(4) (Dormand & Prince 1980), with Hairer's
  4th-order continuous extension; for non-stiff slip.
- ``rosenbrock_step``: the L-stable Rosenbrock 2(3) pair of Shampine & Reichelt
  (1997), with its 2nd-order continuous extension; for stiff (strongly
  overdamped) slip, using the analytic Jacobian ``[[0, 1], [da/dx, da/dv]]``.

Both return a :class:`Step` whose dense output is a polynomial in the step
fraction ``theta`` for each component.
"""

from __future__ import annotations  # annotations stay unevaluated: the FMU runs on CPython 3.8+

import math
from typing import Final

from .model import SlipAccelerator


class Step:
    """Result of one step of size ``h``: end state, error estimate, dense-output polynomials."""

    __slots__ = ("h", "x1", "v1", "err_x", "err_v", "cx", "cv", "order")
    h: float
    x1: float
    v1: float
    err_x: float
    err_v: float
    cx: list[float]
    cv: list[float]
    order: int

    def __init__(self, h: float, x1: float, v1: float, err_x: float, err_v: float, cx: list[float],
                 cv: list[float], order: int) -> None:
        self.h, self.x1, self.v1 = h, x1, v1
        self.err_x, self.err_v = err_x, err_v
        self.cx, self.cv = cx, cv
        self.order = order  # order of the error estimate's leading term, for step-size control


# Dormand-Prince 5(4) tableau.
_C2: Final = 1 / 5
_C3: Final = 3 / 10
_C4: Final = 4 / 5
_C5: Final = 8 / 9
_A21: Final = 1 / 5
_A31: Final = 3 / 40
_A32: Final = 9 / 40
_A41: Final = 44 / 45
_A42: Final = -56 / 15
_A43: Final = 32 / 9
_A51: Final = 19372 / 6561
_A52: Final = -25360 / 2187
_A53: Final = 64448 / 6561
_A54: Final = -212 / 729
_A61: Final = 9017 / 3168
_A62: Final = -355 / 33
_A63: Final = 46732 / 5247
_A64: Final = 49 / 176
_A65: Final = -5103 / 18656
_B1: Final = 35 / 384
_B3: Final = 500 / 1113
_B4: Final = 125 / 192
_B5: Final = -2187 / 6784
_B6: Final = 11 / 84
_E1: Final = 71 / 57600
_E3: Final = -71 / 16695
_E4: Final = 71 / 1920
_E5: Final = -17253 / 339200
_E6: Final = 22 / 525
_E7: Final = -1 / 40
_D1: Final = -12715105075 / 11282082432
_D3: Final = 87487479700 / 32700410799
_D4: Final = -10690763975 / 1880347072
_D5: Final = 701980252875 / 199316789632
_D6: Final = -1453857185 / 822651844
_D7: Final = 69997945 / 29380423


def dopri5_step(accel: SlipAccelerator, x0: float, v0: float, a0: float, h: float) -> Step:
    """One Dormand-Prince step from ``(x0, v0)`` with ``a0 = accel.at(x0, v0)``."""
    # stage velocities (slopes of x) and accelerations (slopes of v)
    u1, w1 = v0, a0
    u2 = v0 + h * _A21 * w1
    w2 = accel.at(x0 + h * _A21 * u1, u2)
    u3 = v0 + h * (_A31 * w1 + _A32 * w2)
    w3 = accel.at(x0 + h * (_A31 * u1 + _A32 * u2), u3)
    u4 = v0 + h * (_A41 * w1 + _A42 * w2 + _A43 * w3)
    w4 = accel.at(x0 + h * (_A41 * u1 + _A42 * u2 + _A43 * u3), u4)
    u5 = v0 + h * (_A51 * w1 + _A52 * w2 + _A53 * w3 + _A54 * w4)
    w5 = accel.at(x0 + h * (_A51 * u1 + _A52 * u2 + _A53 * u3 + _A54 * u4), u5)
    u6 = v0 + h * (_A61 * w1 + _A62 * w2 + _A63 * w3 + _A64 * w4 + _A65 * w5)
    w6 = accel.at(x0 + h * (_A61 * u1 + _A62 * u2 + _A63 * u3 + _A64 * u4 + _A65 * u5), u6)
    x1 = x0 + h * (_B1 * u1 + _B3 * u3 + _B4 * u4 + _B5 * u5 + _B6 * u6)
    v1 = v0 + h * (_B1 * w1 + _B3 * w3 + _B4 * w4 + _B5 * w5 + _B6 * w6)
    u7, w7 = v1, accel.at(x1, v1)
    err_x = h * (_E1 * u1 + _E3 * u3 + _E4 * u4 + _E5 * u5 + _E6 * u6 + _E7 * u7)
    err_v = h * (_E1 * w1 + _E3 * w3 + _E4 * w4 + _E5 * w5 + _E6 * w6 + _E7 * w7)
    dx = h * (_D1 * u1 + _D3 * u3 + _D4 * u4 + _D5 * u5 + _D6 * u6 + _D7 * u7)
    dv = h * (_D1 * w1 + _D3 * w3 + _D4 * w4 + _D5 * w5 + _D6 * w6 + _D7 * w7)
    cx = _dopri_dense(x0, x1, h * u1, h * u7, dx)
    cv = _dopri_dense(v0, v1, h * w1, h * w7, dv)
    return Step(h, x1, v1, err_x, err_v, cx, cv, 5)


def _dopri_dense(y0: float, y1: float, hf0: float, hf1: float, d: float) -> list[float]:
    """Monomial coefficients of Hairer's continuous extension
    ``y0 + th (r2 + (1-th)(r3 + th (r4 + (1-th) d)))``."""
    r2 = y1 - y0
    r3 = hf0 - r2
    r4 = r2 - hf1 - r3
    return [y0, r2 + r3, r4 + d - r3, -r4 - 2.0 * d, d]


_GAMMA: Final = 1.0 / (2.0 + math.sqrt(2.0))
_E32: Final = 6.0 + math.sqrt(2.0)


def rosenbrock_step(accel: SlipAccelerator, slope_x: float, slope_v: float, x0: float, v0: float, a0: float,
                    h: float) -> Step:
    """One Rosenbrock 2(3) step; ``slope_x = da/dx`` and ``slope_v = da/dv`` at ``(x0, v0)``."""
    hg = h * _GAMMA
    det = 1.0 - hg * slope_v - hg * hg * slope_x

    def solve(r0: float, r1: float) -> tuple[float, float]:  # (I - h gamma J)^-1 (r0, r1)
        return ((1.0 - hg * slope_v) * r0 + hg * r1) / det, (hg * slope_x * r0 + r1) / det

    f0x, f0v = v0, a0
    k1x, k1v = solve(f0x, f0v)
    xm, vm = x0 + 0.5 * h * k1x, v0 + 0.5 * h * k1v
    f1x, f1v = vm, accel.at(xm, vm)
    s2x, s2v = solve(f1x - k1x, f1v - k1v)
    k2x, k2v = s2x + k1x, s2v + k1v
    x1, v1 = x0 + h * k2x, v0 + h * k2v
    f2x, f2v = v1, accel.at(x1, v1)
    k3x, k3v = solve(f2x - _E32 * (k2x - f1x) - 2.0 * (k1x - f0x), f2v - _E32 * (k2v - f1v) - 2.0 * (k1v - f0v))
    err_x = h / 6.0 * (k1x - 2.0 * k2x + k3x)
    err_v = h / 6.0 * (k1v - 2.0 * k2v + k3v)
    scale = h / (1.0 - 2.0 * _GAMMA)
    cx = [x0, scale * (k1x - 2.0 * _GAMMA * k2x), scale * (k2x - k1x)]
    cv = [v0, scale * (k1v - 2.0 * _GAMMA * k2v), scale * (k2v - k1v)]
    return Step(h, x1, v1, err_x, err_v, cx, cv, 3)
