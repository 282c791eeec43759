"""Slip under an affine kinetic law ``F_K(u) = F0 + gamma u``, in closed form.

In mode ``m`` the friction force is ``m F_K(m v_rel) = m F0 + gamma (v_drive - v)``,
so ``M x'' + gamma x' + kappa x = F_ext + gamma v_drive + m F0``: a damped
oscillator about ``x_eq = (F_ext + gamma v_drive + m F0) / kappa``. With
``y = x - x_eq``, ``b = gamma / 2M``, ``w0^2 = kappa / M``, ``tau = t - t0``::

    y(tau) = y0 E(tau) + (v0 + b y0) S(tau)
    v(tau) = v0 E(tau) - (w0^2 y0 + b v0) S(tau)

with, under damping (``wd^2 = w0^2 - b^2 > 0``), ``E = e^{-b tau} cos(wd tau)``,
``S = e^{-b tau} sin(wd tau)/wd``; critically ``E = e^{-b tau}``, ``S = tau e^{-b tau}``;
over damping (``s^2 = b^2 - w0^2 > 0``) ``E = e^{-b tau} cosh(s tau)``,
``S = e^{-b tau} sinh(s tau)/s``, written without overflow. The acceleration
``a = v'`` obeys the same equation, so ``a = a0 E - (w0^2 v0 + b a0) S`` with
``a0 = -2 b v0 - w0^2 y0``.
"""

import math

import numpy as np

from .rules import departure
from .zero_crossing import first_zero


class AffineSlip:
    """Slip in ``mode`` (+1/-1) from ``(x0, v0)`` at ``t0`` (s) under constant inputs."""

    def __init__(self, p, mode, t0, x0, v0, v_drive, F_ext):
        F0, gamma = p.kinetic.affine()
        self.mode, self.t0, self.t1 = mode, t0, t0
        self.x_eq = (F_ext + gamma * v_drive + mode * F0) / p.kappa
        self.b = gamma / (2.0 * p.M)
        self.w2 = p.kappa / p.M
        self.y0, self.v0 = x0 - self.x_eq, v0
        self.a0 = -2.0 * self.b * v0 - self.w2 * self.y0
        self.q = self.b * self.b - self.w2  # < 0 under-, 0 critically, > 0 over-damped

    def _basis(self, tau):
        """``(E, S)`` at the delays ``tau`` (s)."""
        b = self.b
        if self.q < 0.0:
            wd = math.sqrt(-self.q)
            decay = np.exp(-b * tau)
            return decay * np.cos(wd * tau), decay * np.sin(wd * tau) / wd
        if self.q == 0.0:
            decay = np.exp(-b * tau)
            return decay, tau * decay
        s = math.sqrt(self.q)
        slow = np.exp(-(self.w2 / (b + s)) * tau)  # e^{-(b - s) tau}
        fast = np.exp(-(b + s) * tau)
        return 0.5 * (slow + fast), slow * -np.expm1(-2.0 * s * tau) / (2.0 * s)

    def state(self, t):
        """``(x, v)`` at the times ``t`` (array, s)."""
        E, S = self._basis(np.asarray(t, float) - self.t0)
        y = self.y0 * E + (self.v0 + self.b * self.y0) * S
        v = self.v0 * E - (self.w2 * self.y0 + self.b * self.v0) * S
        return self.x_eq + y, v

    def acceleration(self, t):
        """``dv/dt`` (m/s^2) at the times ``t`` (array, s): ``a0 E - (w0^2 v0 + b a0) S``."""
        E, S = self._basis(np.asarray(t, float) - self.t0)
        return self.a0 * E - (self.w2 * self.v0 + self.b * self.a0) * S

    def t_stick(self, t):
        """Stick time (s): 0 while slipping."""
        return np.zeros_like(np.asarray(t, float))

    def extrema(self, horizon):
        """Delays (s) in ``(0, horizon)`` where ``a = 0``: ``v`` is monotonic between them."""
        K = self.w2 * self.v0 + self.b * self.a0  # a = a0 E - K S
        if self.q < 0.0:
            wd = math.sqrt(-self.q)
            first = math.atan2(self.a0 * wd, K) % math.pi or math.pi
            return np.arange(first, wd * horizon, math.pi) / wd
        if K == 0.0 or self.a0 / K <= 0.0:
            return np.empty(0)
        ratio = self.a0 / K  # S/C = tanh(s tau)/s (tau if critical) reaches it once, if at all
        s = math.sqrt(self.q)
        if s * ratio >= 1.0:
            return np.empty(0)
        tau = math.atanh(s * ratio) / s if s > 0.0 else ratio
        return np.array([tau]) if tau < horizon else np.empty(0)


def run_affine(p, mode, t0, x0, v0, v_drive, F_ext, t_max):
    """Slip from ``t0`` until ``v_rel`` reaches 0 or ``t_max``; returns ``(phase, hit)``.

    ``v`` is monotonic between the computed extrema, so each piece holds at
    most one crossing, located with brentq on the closed form; the acceleration
    at mid-piece samples shows which extremum is a maximum of ``v_rel``.
    """
    phase = AffineSlip(p, mode, t0, x0, v0, v_drive, F_ext)
    rising = True
    if mode * (v_drive - v0) == 0.0:
        rising = departure(p, mode, x0, v_drive, F_ext, t0) > 0
        if not rising:
            return phase, True
    horizon = t_max - t0
    if horizon <= 0.0:
        return phase, False

    def e(tau):
        return mode * (v_drive - phase.state(t0 + tau)[1])  # mode * v_rel, scalar or array

    def de(tau):
        return -mode * phase.acceleration(t0 + tau)

    ends = np.concatenate([[0.0], phase.extrema(horizon), [horizon]])
    s = np.sort(np.concatenate([ends, 0.5 * (ends[:-1] + ends[1:])]))  # mid-piece samples give de its signs
    tau = first_zero(e, s, e(s), de, de(s), rising=rising)
    phase.t1 = t_max if tau is None else t0 + tau
    return phase, tau is not None
