"""The peers our stepper is measured against, written as a scipy user would write them.

Both return a :class:`Run` on the output grid ``t_eval`` (s):

- :func:`hybrid_solve_ivp`: the hybrid model (SPEC section 1) integrated phase
  by phase with ``scipy.integrate.solve_ivp`` and terminal events, no closed forms.
  A slip in mode ``m`` integrates ``(x, v)`` with ``F_f = m F_K(m v_rel)`` (the
  law's formula, also for the slightly negative ``m v_rel`` of stages past the
  event) until ``v_rel = 0``; there the block sticks if ``|kappa x - F_ext| <= F_S(0)``,
  else it overshoots into the other mode. A stick integrates ``x' = v_drive``
  until ``|kappa x - F_ext| = F_S(t_stick)``.
- :func:`tuned_solve_ivp`: the same hybrid model as a user tunes it for a scene with constant static
  friction: each stick in closed form (``x`` grows at ``v_drive`` until ``|kappa x - F_ext| = F_S``), each
  slip one DOP853 ``solve_ivp`` call with a terminal event on plain floats, ``atol`` set apart from ``rtol``.
- :func:`regularized_solve_ivp`: one smooth ODE, no events, with the friction law
  of :func:`regularized_friction`.
"""

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from ..suite.compare import Event

MAX_EVENTS_AT_ONE_TIME = 100


@dataclass
class Run:
    """One simulation on its output times ``t`` (s): ``x`` (m), ``v`` (m/s).

    ``events`` are :class:`~stickslip.suite.compare.Event` (None: the method has no events).
    """

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    events: list | None
    n_steps: int | None = None  # Runge-Kutta steps taken, where the method says


def hybrid_solve_ivp(p, x0, v0, v_drive, F_ext, t_eval, method, rtol, atol):
    """Hybrid model with solve_ivp ``method`` and terminal events; constant inputs (m/s, N)."""
    t_end = float(t_eval[-1])
    t, x, v = float(t_eval[0]), float(x0), float(v0)
    holding = p.kappa * x - F_ext
    if v == v_drive:
        mode = 0 if abs(holding) <= p.static.force(0.0) else (1 if holding > 0.0 else -1)
    else:
        mode = 1 if v < v_drive else -1
    xs, vs, events = [np.array([x])], [np.array([v])], []
    while t < t_end:
        after = t_eval[(t_eval > t) & (t_eval <= t_end)]
        if mode == 0:
            sol = _stuck_phase(p, t, x, v_drive, F_ext, t_end, after, method, rtol, atol)
            xs.append(_outputs(sol, 1)[0])
            vs.append(np.full(len(sol.t), v_drive))
        else:
            sol = _slip_phase(p, mode, t, x, v, v_drive, F_ext, t_end, after, method, rtol, atol)
            x_out, v_out = _outputs(sol, 2)
            xs.append(x_out)
            vs.append(v_out)
        if sol.status != 1:  # reached t_end
            break
        t, x, v = float(sol.t_events[0][0]), float(sol.y_events[0][0][0]), v_drive
        holding = p.kappa * x - F_ext
        new_mode = 0 if mode != 0 and abs(holding) <= p.static.force(0.0) else (1 if holding > 0.0 else -1)
        events.append(Event("stick" if new_mode == 0 else "slip" if mode == 0 else "overshoot", t, t))
        if len(events) > MAX_EVENTS_AT_ONE_TIME and events[-MAX_EVENTS_AT_ONE_TIME].t_lo == t:
            raise RuntimeError(f"solve_ivp peer: event chain at t = {t} s")
        mode = new_mode
    return Run(np.asarray(t_eval, float), np.concatenate(xs), np.concatenate(vs), events)


def _outputs(sol, n):
    """``sol.y`` as ``n`` rows, also for a phase with no output time in it (solve_ivp then gives lists ``[]``)."""
    return sol.y if len(sol.t) else np.empty((n, 0))


def _stuck_phase(p, t0, x0, v_drive, F_ext, t_end, t_eval, method, rtol, atol):
    def breakaway(t, y):
        return p.static.force(t - t0) - abs(p.kappa * y[0] - F_ext)

    breakaway.terminal, breakaway.direction = True, -1
    return solve_ivp(lambda t, y: [v_drive], (t0, t_end), [x0], method=method, t_eval=t_eval,
                     events=breakaway, rtol=rtol, atol=atol)


def _slip_phase(p, mode, t0, x0, v0, v_drive, F_ext, t_end, t_eval, method, rtol, atol):
    kappa, M, F_K = p.kappa, p.M, p.kinetic.force

    def rhs(t, y):
        return y[1], (F_ext - kappa * y[0] + mode * F_K(mode * (v_drive - y[1]))) / M

    def v_rel_zero(t, y):
        return mode * (v_drive - y[1])

    v_rel_zero.terminal, v_rel_zero.direction = True, -1
    return solve_ivp(rhs, (t0, t_end), [x0, v0], method=method, t_eval=t_eval, events=v_rel_zero,
                     rtol=rtol, atol=atol)


def tuned_solve_ivp(p, x0, v0, v_drive, F_ext, t_eval, rtol, atol):
    """:class:`Run` of the hybrid model, sticks in closed form and slips by DOP853 with a terminal event at
    ``v_rel = 0``; constant inputs (m/s, N). ValueError if the static friction ages (no closed-form stick)."""
    if not p.static.is_constant():
        raise ValueError(f"tuned_solve_ivp: static.law must be constant (its sticks are closed forms), got "
                         f"{p.static.NAME}")
    F_S, t_eval = p.static.force(0.0), np.asarray(t_eval, float)
    t, x, t_end = float(t_eval[0]), float(x0), float(t_eval[-1])
    xs, vs, filled, events = np.empty(len(t_eval)), np.full(len(t_eval), float(v_drive)), 1, []
    xs[0], vs[0] = x, v0
    holding = p.kappa * x - F_ext
    stuck = v0 == v_drive and abs(holding) <= F_S
    mode = (1 if holding > 0.0 else -1) if v0 == v_drive else (1 if v0 < v_drive else -1)
    v = float(v0)
    while t < t_end:
        if stuck:
            edge = (F_ext + math.copysign(F_S, v_drive)) / p.kappa  # where the contact lets go
            t_slip = t + (edge - x) / v_drive if v_drive != 0.0 else math.inf
            upto = int(np.searchsorted(t_eval, min(t_slip, t_end), side="right"))
            xs[filled:upto] = x + v_drive * (t_eval[filled:upto] - t)
            filled = upto
            if t_slip >= t_end:
                break
            t, x, v, stuck, mode = t_slip, edge, v_drive, False, 1 if v_drive > 0.0 else -1
            events.append(Event("slip", t, t))
            continue
        sol = _slip_phase(p, mode, t, x, v, v_drive, F_ext, t_end, t_eval[filled:], "DOP853", rtol, atol)
        if len(sol.t):  # the output times up to the event (solve_ivp includes one at the event)
            xs[filled:filled + len(sol.t)], vs[filled:filled + len(sol.t)] = sol.y
        filled += len(sol.t)
        if sol.status != 1:  # reached t_end
            break
        t, x, v = float(sol.t_events[0][0]), float(sol.y_events[0][0][0]), v_drive
        stuck = abs(p.kappa * x - F_ext) <= F_S
        mode = mode if stuck else -mode
        events.append(Event("stick" if stuck else "overshoot", t, t))
    return Run(t_eval, xs, vs, events)


def regularized_friction(p, v_rel, v_eps):
    """Smooth friction force (N) at ``v_rel`` (m/s) with breakaway velocity ``v_eps`` (m/s).

    Simscape's translational friction with our laws: a Stribeck bump that peaks at
    ``F_S(0) - F_K(0+)`` at ``v_rel = v_eps`` plus ``tanh(v_rel/(v_eps/10)) F_K(|v_rel|)``,
    so the force peaks near ``F_S(0)`` and the model tends to the hybrid one as
    ``v_eps -> 0`` (``tanh(v_rel/v_eps) F_K(|v_rel|)`` alone holds at most ``F_K(0+)``).
    Aging (``F_S`` growing with stick time) is not representable.
    """
    v_st = math.sqrt(2.0) * v_eps
    s = v_rel / v_st
    bump = math.sqrt(2.0 * math.e) * (p.static.force(0.0) - p.kinetic.force(0.0)) * math.exp(-s * s) * s
    return bump + math.tanh(10.0 * v_rel / v_eps) * p.kinetic.force(abs(v_rel))


def regularized_solve_ivp(p, x0, v0, v_drive, F_ext, t_eval, v_eps, method, rtol, atol):
    """Regularized model (no stuck state, no events) with solve_ivp ``method``; constant inputs."""

    def rhs(t, y):
        return [y[1], (F_ext - p.kappa * y[0] + regularized_friction(p, v_drive - y[1], v_eps)) / p.M]

    sol = solve_ivp(rhs, (t_eval[0], t_eval[-1]), [x0, v0], method=method, t_eval=t_eval, rtol=rtol, atol=atol)
    if sol.status != 0:
        raise RuntimeError(f"regularized peer ({method}, v_eps = {v_eps}): {sol.message}")
    return Run(sol.t, sol.y[0], sol.y[1], None)
