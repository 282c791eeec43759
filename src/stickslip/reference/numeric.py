"""Slip under a general kinetic law: ``solve_ivp`` (DOP853) with graze-proof event location."""

import numpy as np
from scipy.integrate import solve_ivp

from .errors import ReferenceSolverError
from .rules import acceleration, departure, period
from .zero_crossing import first_zero

SUBSTEPS = 20  # dense-output samples per solver step in the graze scan
STEPS_PER_PERIOD = 20  # max_step = period / STEPS_PER_PERIOD


class NumericSlip:
    """Slip in ``mode`` from ``t0`` to ``t1`` (s) on a solver's dense output (None: zero length)."""

    def __init__(self, mode, t0, x0, v0, dense=None):
        self.mode, self.t0, self.t1 = mode, t0, t0
        self.x0, self.v0, self.dense = x0, v0, dense

    def state(self, t):
        """``(x, v)`` at the times ``t`` (array, s)."""
        t = np.asarray(t, float)
        if self.dense is None:
            return np.full_like(t, self.x0), np.full_like(t, self.v0)
        y = self.dense(t)
        return y[0], y[1]

    def t_stick(self, t):
        """Stick time (s): 0 while slipping."""
        return np.zeros_like(np.asarray(t, float))


def tolerances(p, v_drive, rtol):
    """Absolute tolerances ``[x (m), v (m/s)]`` scaled by ``F_S(0)/kappa`` and the slip speeds."""
    x_scale = p.static.force(0.0) / p.kappa
    v_scale = max(abs(v_drive), np.sqrt(p.kappa / p.M) * x_scale)
    return [rtol * x_scale, rtol * v_scale]


def run_numeric(p, mode, t0, x0, v0, v_drive, F_ext, t_max, rtol):
    """Slip from ``t0`` until ``v_rel`` reaches 0 or ``t_max``; returns ``(phase, hit)``.

    The solver's terminal event sees only sign changes of ``v_rel`` at step
    ends; afterwards the dense output is scanned on ``SUBSTEPS`` points per
    step, with the acceleration as derivative, so that a crossing pair inside
    one step (a graze) is found and located with brentq on the dense output.
    """
    rising = True
    if mode * (v_drive - v0) == 0.0:
        rising = departure(p, mode, x0, v_drive, F_ext, t0) > 0
        if not rising:
            return NumericSlip(mode, t0, x0, v0), True
    if t_max <= t0:
        return NumericSlip(mode, t0, x0, v0), False

    def rhs(t, y):
        return [y[1], acceleration(p, mode, y[0], y[1], v_drive, F_ext)]

    def v_rel_event(t, y):
        return mode * (v_drive - y[1])

    v_rel_event.terminal, v_rel_event.direction = True, -1
    sol = solve_ivp(
        rhs, (t0, t_max), [x0, v0], method="DOP853", rtol=rtol, atol=tolerances(p, v_drive, rtol),
        dense_output=True, events=v_rel_event, max_step=period(p) / STEPS_PER_PERIOD,
    )
    if sol.status < 0:
        raise ReferenceSolverError(f"reference slip solver failed after t = {sol.t[-1]!r} s (started at {t0!r} s): {sol.message}")
    phase = NumericSlip(mode, t0, x0, v0, sol.sol)
    t_hit = _scan(p, phase, sol.t, v_drive, F_ext, rising)
    if t_hit is None and sol.t_events[0].size:
        t_hit = sol.t_events[0][0]
    phase.t1 = t_max if t_hit is None else t_hit
    return phase, t_hit is not None


def _scan(p, phase, steps, v_drive, F_ext, rising):
    """First time ``v_rel`` reaches 0 on the dense output over the solver ``steps``, or None."""
    mode = phase.mode

    def e(t):
        return mode * (v_drive - phase.state(t)[1])

    def de(t):
        x, v = phase.state(t)
        return -mode * acceleration(p, mode, float(x), float(v), v_drive, F_ext)

    fractions = np.arange(SUBSTEPS) / SUBSTEPS
    s = np.append((steps[:-1, None] + np.diff(steps)[:, None] * fractions).ravel(), steps[-1])
    x, v = phase.state(s)
    es = mode * (v_drive - v)
    des = np.array([-mode * acceleration(p, mode, xi, vi, v_drive, F_ext) for xi, vi in zip(x, v)])
    return first_zero(e, s, es, de, des, rising=rising)
