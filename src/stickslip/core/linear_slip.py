"""Slip under an affine kinetic law ``F_K(u) = F0 + gamma u`` in closed form.

In slip mode ``s`` the block obeys ``M x'' + gamma x' + kappa x = F_ext + gamma v_drive + s F0``:
a (damped) harmonic oscillator about ``x_c``. With ``y = x - x_c``,
``alpha = gamma / 2M`` and ``w2 = kappa/M - alpha^2``, every derivative ``u`` of
``y`` obeys the same equation and evolves as

    u(tau) = e^{-alpha tau} (u0 C(tau) + (u0' + alpha u0) S(tau)),

with ``C = cos(sqrt(w2) tau)``, ``S = sin(sqrt(w2) tau)/sqrt(w2)`` (cosh/sinh when
``w2 < 0``, ``1`` and ``tau`` when ``w2 = 0``). The end of the slip, ``v = v_drive``,
is found between consecutive extrema of ``v`` (zeros of the acceleration,
known in closed form), where ``v`` is monotonic: exact, and blind to no graze.
"""

from __future__ import annotations  # annotations stay unevaluated: the FMU runs on CPython 3.8+

import math

from .rootfind import brent, monotone_fall

_MAX_PIECES = 64


class HarmonicSlip:
    """The closed-form motion of one affine slip phase starting at ``(x0, v0)``."""

    __slots__ = ("alpha", "w2", "omega0_sq", "x_c", "y0", "v0", "a0", "j0")
    # typed, so that the compiled runtime evaluates the motion in native floats (it runs at every step)
    alpha: float  # 1/s
    w2: float  # 1/s^2
    omega0_sq: float  # 1/s^2
    x_c: float  # m
    y0: float  # m
    v0: float  # m/s
    a0: float  # m/s^2
    j0: float  # m/s^3

    def __init__(self, mode, x0, v0, v_drive, F_ext, p):
        F0, gamma = p.kinetic.affine()
        self.alpha = 0.5 * gamma / p.M
        self.omega0_sq = p.kappa / p.M
        self.w2 = self.omega0_sq - self.alpha * self.alpha
        self.x_c = (F_ext + gamma * v_drive + mode * F0) / p.kappa
        self.y0 = x0 - self.x_c
        self.v0 = v0
        self.a0 = -(2.0 * self.alpha * v0 + self.omega0_sq * self.y0)
        self.j0 = -(2.0 * self.alpha * self.a0 + self.omega0_sq * v0)

    def _damped_basis(self, tau: float) -> tuple[float, float]:
        """``(e^{-alpha tau} C(tau), e^{-alpha tau} S(tau))``, overflow-safe."""
        alpha, w2 = self.alpha, self.w2
        if w2 > 0.0:
            omega = math.sqrt(w2)
            decay = math.exp(-alpha * tau)
            return decay * math.cos(omega * tau), decay * math.sin(omega * tau) / omega
        if w2 == 0.0:
            decay = math.exp(-alpha * tau)
            return decay, decay * tau
        beta = math.sqrt(-w2)
        if beta * tau < 1.0:
            decay = math.exp(-alpha * tau)
            return decay * math.cosh(beta * tau), decay * math.sinh(beta * tau) / beta
        slow = math.exp(-self.omega0_sq / (alpha + beta) * tau)  # e^{(beta - alpha) tau} without cancellation
        fast = math.exp(-(alpha + beta) * tau)
        return 0.5 * (slow + fast), 0.5 * (slow - fast) / beta

    def _response(self, u0: float, du0: float, tau: float) -> float:
        c, s = self._damped_basis(tau)
        return u0 * c + (du0 + self.alpha * u0) * s

    def position(self, tau: float) -> float:
        return self.x_c + self._response(self.y0, self.v0, tau)

    def velocity(self, tau: float) -> float:
        return self._response(self.v0, self.a0, tau)

    def acceleration(self, tau: float) -> float:
        return self._response(self.a0, self.j0, tau)

    def state(self, tau: float) -> tuple[float, float]:
        c, s = self._damped_basis(tau)
        alpha = self.alpha
        x = self.x_c + self.y0 * c + (self.v0 + alpha * self.y0) * s
        v = self.v0 * c + (self.a0 + alpha * self.v0) * s
        return x, v

    # ------------------------------------------------------------------
    # end of the slip
    # ------------------------------------------------------------------

    def stick_delay(self, mode, v_drive):
        """Delay (s) until ``v`` reaches ``v_drive`` from the slip side, or None if never.

        The slip side is ``mode * (v_drive - v) > 0``; the start, where ``v_rel``
        may be 0 (just after a breakaway), does not count.
        """

        def g(tau):
            return mode * (v_drive - self.velocity(tau))

        if self.w2 > 0.0:
            return self._delay_oscillatory(g, v_drive)
        return self._delay_aperiodic(g, mode, v_drive)

    def _delay_oscillatory(self, g, v_drive):
        """Underdamped: extrema of ``v`` are evenly spaced by ``pi / omega``."""
        omega = math.sqrt(self.w2)
        a_cos, a_sin = self.a0, (self.j0 + self.alpha * self.a0) / omega
        # a(tau) ~ cos(omega tau - psi) vanishes at omega tau = psi + pi/2 + k pi
        first = (math.atan2(a_sin, a_cos) + 0.5 * math.pi) % math.pi
        if first == 0.0:
            first = math.pi
        half_period = math.pi / omega
        amplitude = math.hypot(self.v0, (self.a0 + self.alpha * self.v0) / omega)
        start = 0.0
        end = first / omega
        for _ in range(_MAX_PIECES):
            if math.exp(-self.alpha * start) * amplitude < abs(v_drive):
                return None  # |v| stays below |v_drive| from here on: no crossing ever
            root = _crossing_on_monotone_piece(g, start, end)
            if root is not None:
                return root
            start, end = end, end + half_period
        return None

    def _delay_aperiodic(self, g, mode, v_drive):
        """Over- or critically damped: ``v`` has at most one extremum, then tends to 0."""
        knee = self._acceleration_zero()
        pieces = [(0.0, knee)] if knee is not None else []
        start = knee if knee is not None else 0.0
        if mode * v_drive < 0.0:  # g(inf) = mode v_drive < 0: the tail crosses
            end = max(start, 1.0 / math.sqrt(self.omega0_sq))
            for _ in range(2000):
                end *= 2.0
                if g(end) <= 0.0:
                    break
            pieces.append((start, end))
        for a, b in pieces:
            root = _crossing_on_monotone_piece(g, a, b)
            if root is not None:
                return root
        return None

    def _acceleration_zero(self):
        """The positive zero of the acceleration (the extremum of ``v``), or None."""
        a0 = self.a0
        rate = self.alpha + math.sqrt(max(-self.w2, 0.0))
        end = 1e-3 / rate
        for _ in range(2000):
            a_end = self.acceleration(end)
            if a0 == 0.0 or a_end == 0.0 or (a_end > 0.0) != (a0 > 0.0):
                break
            if abs(a_end) < 1e-300 or end > 1e300:
                return None
            end *= 2.0
        else:
            return None
        if a0 == 0.0:
            return None
        return brent(self.acceleration, 0.0, end, a0, a_end)


def _crossing_on_monotone_piece(g, a, b):
    """Where monotone ``g`` goes from > 0 (slip side) at ``a`` to <= 0 at ``b``, else None; past the slip's
    start (``a > 0``) also ``a`` itself where ``g`` is 0 there and falls (:func:`.rootfind.monotone_fall`)."""
    return monotone_fall(g, a, b, g(a), g(b), a > 0.0)
