"""Stuck phases: ``x = x0 + v_drive (t - t0)``, ``v = v_drive``, until the contact gives way."""

import math

import numpy as np

from .rules import STUCK, z_slip
from .zero_crossing import first_zero

GRID = 400  # scan points per stuck phase (besides convexity breaks and the kink)


class StuckPhase:
    """A stuck block from ``t0`` to ``t1`` (s), stuck since ``t0 - t_stick0``."""

    mode = STUCK

    def __init__(self, t0, t1, x0, v_drive, t_stick0):
        self.t0, self.t1 = t0, t1
        self.x0, self.v_drive, self.t_stick0 = x0, v_drive, t_stick0

    def state(self, t):
        """``(x, v)`` at the times ``t`` (array, s)."""
        t = np.asarray(t, float)
        return self.x0 + self.v_drive * (t - self.t0), np.full_like(t, self.v_drive)

    def t_stick(self, t):
        """Stick time (s) at the times ``t``."""
        return self.t_stick0 + (np.asarray(t, float) - self.t0)


def run_stuck(p, t0, x0, t_stick0, v_drive, F_ext, t_max):
    """Stay stuck from ``t0`` up to ``t_max`` or the first time ``|kappa x - F_ext| > F_S(t_stick)``.

    Returns ``(phase, broke)``; if ``broke`` the phase ends at the break time (at once where the start
    does not hold: ``z_slip < 0`` at ``t0``).
    """
    horizon = t_max - t0
    if z_slip(p, x0, F_ext, t_stick0) < 0.0:
        tau = 0.0  # a tangential return held beyond F_S by rounding only: the contact gives way at once
    elif p.static.is_constant():
        tau = _linear_break(p, x0, v_drive, F_ext)
    else:
        tau = _aging_break(p, x0, t_stick0, v_drive, F_ext, horizon)
    broke = tau is not None and tau <= horizon
    t1 = t0 + tau if broke else t_max
    return StuckPhase(t0, t1, x0, v_drive, t_stick0), broke


def _linear_break(p, x0, v_drive, F_ext):
    """Break delay (s) under a constant ``F_S``: ``kappa x - F_ext`` reaches ``sign(v_drive) F_S``."""
    if v_drive == 0.0:
        return None
    h0 = p.kappa * x0 - F_ext
    return max(0.0, (math.copysign(p.static.force(0.0), v_drive) - h0) / (p.kappa * v_drive))


def _aging_break(p, x0, t_stick0, v_drive, F_ext, horizon):
    """First delay ``tau`` (s) in ``[0, horizon]`` with ``g(tau) = F_S(t_stick0 + tau) - |kappa x - F_ext| < 0``.

    ``g`` is sampled on a grid that contains the static law's convexity breaks
    and the kink ``kappa x = F_ext``, so it is convex or concave between breaks;
    a dip between samples is caught from ``dg/dtau``.
    """

    def g(tau):
        return z_slip(p, x0 + v_drive * tau, F_ext, t_stick0 + tau)

    def dg(tau):
        h = p.kappa * (x0 + v_drive * tau) - F_ext
        return p.static.rate(t_stick0 + tau) - np.sign(h) * p.kappa * v_drive

    g0, dg0 = g(0.0), dg(0.0)
    if g0 == 0.0 and dg0 < 0.0:
        return 0.0
    if horizon <= 0.0:
        return None
    s = _grid(p, x0, t_stick0, v_drive, F_ext, horizon)
    gs = np.array([g(tau) for tau in s])
    dgs = np.array([dg(tau) for tau in s])
    return first_zero(g, s, gs, dg, dgs, rising=dg0 > 0.0)


def _grid(p, x0, t_stick0, v_drive, F_ext, horizon):
    """Scan delays (s): a uniform grid, the law's convexity breaks and the kink."""
    special = [b - t_stick0 for b in p.static.convexity_breaks()]
    if v_drive != 0.0:
        special.append((F_ext / p.kappa - x0) / v_drive)
    inside = [tau for tau in special if 0.0 < tau < horizon]
    return np.unique(np.concatenate([np.linspace(0.0, horizon, GRID + 1), inside]))
