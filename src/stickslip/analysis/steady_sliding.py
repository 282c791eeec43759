"""Continuous sliding, its linear stability, and the Hopf points at the extrema of ``F_K``.

Continuous sliding (CS): the block rests at ``x_c = (F_K(v_drive) + F_ext)/kappa``
while the surface slides under it (``v_drive > 0``). With ``y = x - x_c`` the
slip dynamics (mode +1) read

    M y'' + kappa y = F_K(v_drive - y') - F_K(v_drive)
                    = -F' y' + F''/2 y'^2 - F'''/6 y'^3 + O(y'^4),

derivatives of ``F_K`` taken at ``v_drive``. Linearized: ``M y'' + F' y' +
kappa y = 0``, eigenvalues ``(-F' +- sqrt(F'^2 - 4 kappa M)) / 2M``: CS is
stable iff ``F'(v_drive) > 0`` (SPEC section 3). At an extremum ``v_H`` of
``F_K`` a complex pair crosses the imaginary axis at ``+- i omega``, ``omega =
sqrt(kappa/M)``, with speed ``d Re(lambda)/d v_drive = -F''(v_H)/2M != 0``: a Hopf
bifurcation.

Criticality (derivation). Divide by ``M``: ``y'' + omega^2 y = a y' + b y'^2 +
c y'^3`` with ``a = -F'/M``, ``b = F''/2M``, ``c = -F'''/6M``. Scale ``p =
y'/omega`` and write the system as ``X = p``, ``Y = y``:

    X' = -omega Y + f(X),  Y' = omega X,   f(X) = b omega X^2 + c omega^2 X^3   (at a = 0).

The first Lyapunov coefficient of ``X' = -omega Y + f, Y' = omega X + g``
(Guckenheimer & Holmes, *Nonlinear Oscillations, Dynamical Systems, and
Bifurcations of Vector Fields*, 1983, eq. 3.4.11) is

    l1 = (f_XXX + f_XYY + g_XXY + g_YYY)/16
         + (f_XY (f_XX + f_YY) - g_XY (g_XX + g_YY) - f_XX g_XX + f_YY g_YY) / (16 omega).

Here ``g = 0`` and ``f`` depends on ``X`` only, so every term of the second
bracket vanishes: the quadratic coefficient ``b`` (that is ``F''``) does not
enter, not even through the squares of quadratic terms, and

    l1 = 6 c omega^2 / 16 = -omega^2 F'''(v_H) / (16 M).

The same follows from first-order averaging of ``y = r cos(phi)``: ``r' = a r/2
+ (3/8) c omega^2 r^3`` (the ``b y'^2`` term averages to zero against ``sin``).
So the Hopf point is **supercritical** (stable cycles, on the side where CS is
unstable) iff ``F'''(v_H) > 0`` and **subcritical** (unstable cycles, on the
side where CS is stable) iff ``F'''(v_H) < 0``. Near ``v_H`` the cycle's
velocity amplitude ``V = r omega`` is ``V^2 = -8 F'(v_drive)/F'''(v_drive)``
(about ``-8 F''(v_H)(v_drive - v_H)/F'''(v_H)``), with position amplitude
``V/omega`` about ``x_c``; it exists on the side where ``F'/F''' < 0``.
"""

import math
from dataclasses import dataclass

from . import kinetic as kin


@dataclass(frozen=True)
class SlidingState:
    """Continuous sliding at ``v_drive`` (m/s): position ``x`` (m), ``F_K'(v_drive)`` (N s/m), stability.

    ``eigenvalues`` (1/s) of the linearized slip; ``stable`` iff ``slope > 0``.
    """

    v_drive: float
    x: float
    slope: float
    stable: bool
    eigenvalues: tuple


@dataclass(frozen=True)
class HopfPoint:
    """A Hopf bifurcation of continuous sliding at an extremum of ``F_K``.

    ``extremum`` is ``"max"`` or ``"min"`` of ``F_K``; ``x`` (m) the sliding
    position; ``omega`` (1/s) and ``period`` (s) of the emerging cycle;
    ``F2, F3``: ``F_K''`` (N s^2/m^2) and ``F_K'''`` (N s^3/m^3) at ``v_drive``;
    ``lyapunov``: the first Lyapunov coefficient ``-omega^2 F'''/(16 M)``
    (1/(m^2 s)); ``criticality``: ``"supercritical"``, ``"subcritical"`` or
    ``"degenerate"``; ``side``: +1 if the cycles exist for larger drive
    velocities, -1 for smaller; ``cycles_stable``: the emerging cycles' stability.
    """

    v_drive: float
    extremum: str
    x: float
    omega: float
    period: float
    F2: float
    F3: float
    lyapunov: float
    criticality: str
    side: int
    cycles_stable: bool

    def amplitude(self, v_drive, slope=None):
        """Predicted position amplitude (m) of the small cycle at ``v_drive`` (NaN on the wrong side).

        ``slope``: ``F_K'(v_drive)`` if known (better than its linearization ``F''(v_H)(v_drive - v_H)``).
        """
        if slope is None:
            slope = self.F2 * (v_drive - self.v_drive)
        v2 = -8.0 * slope / self.F3 if self.F3 != 0.0 else math.nan
        return math.sqrt(v2) / self.omega if v2 >= 0.0 else math.nan


def continuous_sliding(params, v_drive, F_ext=0.0):
    """The continuous-sliding state at ``v_drive > 0`` and its linear stability."""
    if not v_drive > 0.0:
        raise ValueError("continuous sliding needs v_drive > 0")
    law = params.kinetic
    slope = float(law.slope(v_drive))
    disc = complex(slope * slope - 4.0 * params.kappa * params.M) ** 0.5
    eig = ((-slope + disc) / (2.0 * params.M), (-slope - disc) / (2.0 * params.M))
    return SlidingState(float(v_drive), (law.force(v_drive) + F_ext) / params.kappa, slope, slope > 0.0, eig)


def hopf_points(params, v_min, v_max, F_ext=0.0):
    """The Hopf points with ``v_min < v_drive <= v_max`` (extrema of ``F_K``), in increasing order."""
    law = params.kinetic
    if law.affine() is not None:
        return []
    omega = math.sqrt(params.kappa / params.M)
    out = []
    for u, kind in kin.extrema(law, v_max, max(v_min, 0.0)):
        if not v_min < u <= v_max:
            continue
        _, f2, f3 = kin.derivatives(law, u)
        l1 = -omega * omega * f3 / (16.0 * params.M)
        scale = max(abs(f2) * u, 1e-300)
        if abs(f3) * u * u <= 1e-8 * scale:
            crit, side = "degenerate", 0
        else:
            crit = "supercritical" if f3 > 0.0 else "subcritical"
            side = 1 if -f2 * f3 > 0.0 else -1
        out.append(HopfPoint(u, kind, (law.force(u) + F_ext) / params.kappa, omega, 2.0 * math.pi / omega,
                             f2, f3, l1, crit, side, crit == "supercritical"))
    return out
