"""The systems benchmark's scipy peer: the whole chain integrated by ``scipy.integrate.solve_ivp`` with its event
functions, written as a user would from SPEC sections 1, 2 and 5 (nothing of the package's engine, runtime or
reference; the parameter rows are the numba peer's :func:`~.numba_chain_peer.chain_arrays`).

All ``2N`` states ``[x_1..x_N, v_1..v_N]`` (m, m/s) go to one ``solve_ivp`` call (DOP853, ``rtol``, ``atol`` =
``rtol`` times each block's scales ``F_S(0)/kappa`` and ``F_S(0)/sqrt(kappa M)``) per stretch between events; a
stuck block has ``x' = v_drive``, ``v' = 0``. One terminal event function per block, falling through zero: slipping
in mode ``m``, ``m (v_drive - v)`` (a stick or an overshoot); stuck, ``F_S(t_stick) - |kappa x - F_ext|`` (a
breakaway). At the first event the block's mode changes by SPEC section 1 and ``solve_ivp`` starts again there.
Steps are at most ``STEPS_PER_PERIOD`` times shorter than the chain's shortest free period, as scipy's
documentation advises for events that a long step could pass over (without it the peer's errors on the
Burridge-Knopoff chain were 10 to 50 times larger at the same ``rtol``).
"""

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from .numba_chain_peer import chain_arrays

MAX_EVENTS_PER_INSTANT = 100
STEPS_PER_PERIOD = 20


@dataclass(frozen=True)
class ScipyPeerRun:
    """One run on the grid ``t`` (s): ``x`` (m), ``v`` (m/s), ``mode`` (shape ``(len(t), N)``); ``events``: ``(t (s),
    block (0-based), mode before, mode after)`` in time order; ``solver_calls``: the ``solve_ivp`` calls."""

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    mode: np.ndarray
    events: list
    solver_calls: int


def kinetic_friction(law, p, u):
    """``F_K(u)`` (N) per block: kinetic law codes ``law``, parameter rows ``p`` (N, 5), speeds ``u >= 0`` (m/s)."""
    out = np.empty_like(u)
    for code in np.unique(law):
        i = law == code
        q, s = p[i].T, u[i]
        if code == 1:
            out[i] = q[0]
        elif code == 2:
            out[i] = q[0] + q[1] * s
        elif code == 3:
            out[i] = q[0] + q[1] * np.exp(-(s / q[2]) ** q[3]) + q[4] * s
        elif code == 4:
            d = s - q[2]
            out[i] = 0.5 * s * (q[0] + q[1] + (q[1] - q[0]) * d / np.sqrt(q[3] ** 2 + d ** 2))
        else:
            out[i] = q[0] * (1.0 - q[1]) / (1.0 + 2.0 * q[2] * s / (1.0 - q[1]))
    return out


def static_friction(law, p, t):
    """``F_S(t)`` (N) of one block: static law code ``law``, parameter row ``p``, stuck for ``t >= 0`` s."""
    if law == 1:
        return p[0]
    if law == 2:
        return p[0] + p[1] * np.log1p(t / p[2])
    if law == 3:
        return p[0] + (p[1] - p[0]) * (1.0 - np.exp(-t / p[2]))
    return p[0] + (p[1] - p[0]) * t ** p[3] / (p[2] ** p[3] + t ** p[3])


class _Chain:
    """The chain's equations with the blocks' current modes ``mode`` and stick start times ``t_stuck`` (s)."""

    def __init__(self, system):
        c = chain_arrays(system.blocks, system.coupling, system.v_drive)
        self.c, self.n = c, c.M.size
        self.kc_left, self.kc_right = np.r_[0.0, c.coupling], np.r_[c.coupling, 0.0]
        self.mode = np.zeros(self.n, int)
        self.t_stuck = np.zeros(self.n)
        omega_max = np.sqrt(np.max((c.kappa + 2.0 * (self.kc_left + self.kc_right)) / c.M))  # Gershgorin, 1/s
        self.max_step = 2.0 * np.pi / omega_max / STEPS_PER_PERIOD

    def coupling(self, x):
        """``F_ext`` (N) per block at the positions ``x`` (m)."""
        left, right = np.r_[x[0], x[:-1]], np.r_[x[1:], x[-1]]
        return self.kc_left * (left - x) + self.kc_right * (right - x)

    def rhs(self, t, y):
        c, n = self.c, self.n
        x, v = y[:n], y[n:]
        u = np.abs(c.v_drive - v)
        a = (self.coupling(x) - c.kappa * x + self.mode * kinetic_friction(c.kinetic_law, c.kinetic, u)) / c.M
        stuck = self.mode == 0
        return np.concatenate([np.where(stuck, c.v_drive, v), np.where(stuck, 0.0, a)])

    def force(self, i, y):
        """Block ``i``'s ``F_ext`` (N) at the state ``y``."""
        x = y[:self.n]
        return (self.kc_left[i] * (x[i - 1] - x[i]) if i > 0 else 0.0) + \
            (self.kc_right[i] * (x[i + 1] - x[i]) if i < self.n - 1 else 0.0)

    def margin(self, i, t, y):
        """Block ``i``'s holding margin ``F_S(t_stick) - |kappa x - F_ext|`` (N) at ``(t, y)``, stuck since
        ``t_stuck``."""
        c = self.c
        held = static_friction(c.static_law[i], c.static[i], t - self.t_stuck[i])
        return held - abs(c.kappa[i] * y[i] - self.force(i, y))

    def event(self, i):
        """Block ``i``'s terminal event function, falling through zero."""
        def g(t, y):
            if self.mode[i] == 0:
                return self.margin(i, t, y)
            return self.mode[i] * (self.c.v_drive - y[self.n + i])
        g.terminal, g.direction = True, -1
        return g

    def start_modes(self, y):
        """Stuck where a block starts at ``v_drive`` and its contact holds it, else slipping by ``v_rel``'s sign."""
        for i in range(self.n):
            vrel = self.c.v_drive - y[self.n + i]
            if vrel != 0.0:
                self.mode[i] = 1 if vrel > 0.0 else -1
            else:
                self.mode[i] = 0 if self.margin(i, 0.0, y) >= 0.0 else self._slip_direction(i, y)

    def _slip_direction(self, i, y):
        """+1 where the net force without friction, ``F_ext - kappa x``, is negative, else -1."""
        return 1 if self.force(i, y) - self.c.kappa[i] * y[i] < 0.0 else -1

    def transition(self, i, t, y):
        """Block ``i``'s event at ``(t, y)``: its new mode (SPEC section 1); a stick sets ``v = v_drive``."""
        c = self.c
        if self.mode[i] == 0:
            return self._slip_direction(i, y)
        if abs(c.kappa[i] * y[i] - self.force(i, y)) <= static_friction(c.static_law[i], c.static[i], 0.0):
            self.t_stuck[i] = t
            y[self.n + i] = c.v_drive
            return 0
        return -self.mode[i]


def run_scipy_peer(system, rtol):
    """``system`` (a :class:`~stickslip.systems.system_file.System`) on its output grid at ``rtol``: a
    :class:`ScipyPeerRun`."""
    chain = _Chain(system)
    c, n, grid = chain.c, chain.n, system.times()
    y = np.concatenate([c.x0, c.v0]).astype(float)
    atol = rtol * np.concatenate([c.static[:, 0] / c.kappa, c.static[:, 0] / np.sqrt(c.kappa * c.M)])
    chain.start_modes(y)
    events = [chain.event(i) for i in range(n)]
    out = np.empty((grid.size, 2 * n))
    modes = np.empty((grid.size, n), int)
    out[0], modes[0] = y, chain.mode
    t, k, found, calls, repeats = 0.0, 1, [], 0, 0
    while t < grid[-1]:
        sol = solve_ivp(chain.rhs, (t, grid[-1]), y, method="DOP853", rtol=rtol, atol=atol, events=events,
                        t_eval=grid[k:], max_step=chain.max_step)
        calls += 1
        if sol.status < 0:
            raise RuntimeError(f"scipy peer: solve_ivp failed at t = {t!r} s: {sol.message}")
        m = np.size(sol.t)
        if m:
            out[k:k + m], modes[k:k + m] = sol.y.T, chain.mode
        k += m
        if sol.status == 0:
            break
        i = next(j for j, te in enumerate(sol.t_events) if te.size)
        t_e, y = float(sol.t_events[i][0]), sol.y_events[i][0].copy()
        repeats = repeats + 1 if t_e == t else 0
        if repeats > MAX_EVENTS_PER_INSTANT:
            raise RuntimeError(f"scipy peer: more than {MAX_EVENTS_PER_INSTANT} events at t = {t_e!r} s")
        before = int(chain.mode[i])
        chain.mode[i] = chain.transition(i, t_e, y)
        found.append((t_e, i, before, int(chain.mode[i])))
        t = t_e
    return ScipyPeerRun(grid, out[:, :n], out[:, n:], modes, found, calls)
