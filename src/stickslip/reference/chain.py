"""Monolithic reference of a chain of blocks (SPEC section 5): all ``2N`` states in one integration.

Block ``i`` (0-based here, ``b<i+1>`` in files) has its own :class:`~.laws.ReferenceParameters`,
start state and mode; all lie on one surface moving at ``v_drive`` (m/s, constant). Coupling springs
``kc_i`` (N/m) join block ``i`` and ``i+1``, relaxed at ``x_i = x_(i+1)``; block ``i`` feels
``F_ext_i = kc_(i-1) (x_(i-1) - x_i) + kc_i (x_(i+1) - x_i)`` (N, along +x).

Each block follows SPEC section 1 with that ``F_ext_i``, evaluated exactly at its events. Stuck
blocks move with the surface (``x' = v_drive``, ``v' = 0``), slipping ones with
:func:`~.rules.acceleration`. scipy's DOP853 steps all states at ``rtol`` (default 1e-12); after each
step every block's indicator (``mode v_rel`` while slipping, ``z_slip`` while stuck) is scanned on the
step's dense output with its time derivative (:func:`~.zero_crossing.first_zero`), so a graze inside a
step is found; the earliest event of any block ends the step there, the event is applied, and the
integration restarts. While every block is stuck the chain moves with the surface, the coupling forces are
constant and each block's breakaway is the single block's closed form (:func:`~.stuck.run_stuck`).
"""

import math

import numpy as np
from scipy.integrate import DOP853

from .chain_result import ChainBlock, ChainEvent, ChainPiece, ChainResult
from .errors import ReferenceParameterError, ReferenceSolverError
from .laws import ReferenceParameters
from .numeric import STEPS_PER_PERIOD, SUBSTEPS, tolerances
from .rules import STUCK, acceleration, breakaway_mode, hold_or_break, initial_mode, z_slip
from .stuck import run_stuck
from .zero_crossing import first_zero

MAX_EVENTS_PER_INSTANT = 1000
_EPS = 2.220446049250313e-16

def simulate_chain(blocks, coupling, v_drive, t_eval, rtol=1e-12, progress=None):
    """Simulate the chain ``blocks`` (:class:`ChainBlock`) joined by ``coupling`` (``N - 1`` stiffnesses,
    N/m) on a surface at ``v_drive`` (m/s) from ``t_eval[0]`` to ``t_eval[-1]`` (s); ``progress(t)``, if given,
    is called with the time reached (s) after each solver step.

    Returns a :class:`~.chain_result.ChainResult` sampled on ``t_eval`` (state after any event at a
    sample time), with every block's events and the dense solution.
    """
    chain = _Chain(blocks, coupling, v_drive)
    t_eval = np.asarray(t_eval, float)
    if t_eval.ndim != 1 or t_eval.size == 0 or not np.all(np.isfinite(t_eval)) or np.any(np.diff(t_eval) <= 0.0):
        raise ReferenceParameterError("t_eval must be a non-empty 1-D array of finite, strictly increasing times (s)")
    run = _ChainRun(chain, float(t_eval[0]), rtol, progress or (lambda t: None))
    while run.t < t_eval[-1]:
        run.phase(float(t_eval[-1]))
    return ChainResult.sample(chain, run.pieces, run.events, t_eval)


class _Chain:
    """The chain's fixed data and its force and acceleration functions (arrays over blocks)."""

    def __init__(self, blocks, coupling, v_drive):
        self.blocks = [ChainBlock(*b) for b in blocks]
        self.n = len(self.blocks)
        if self.n == 0:
            raise ReferenceParameterError("a chain needs at least one block")
        for i, block in enumerate(self.blocks):
            if not isinstance(block.params, ReferenceParameters):
                raise ReferenceParameterError(f"block {i + 1}: params must be the reference's ReferenceParameters")
            block.params.check()
            for name, value in (("x0", block.x0), ("v0", block.v0)):
                if not math.isfinite(value):
                    raise ReferenceParameterError(f"block {i + 1}: {name} = {value!r} must be finite")
        self.kc = np.asarray(coupling, float).reshape(-1)
        if self.kc.size != self.n - 1 or not np.all(np.isfinite(self.kc)) or np.any(self.kc < 0.0):
            raise ReferenceParameterError(
                f"coupling = {list(self.kc)!r} N/m: allowed is {self.n - 1} finite values >= 0 (one per neighbour pair)")
        if not math.isfinite(v_drive):
            raise ReferenceParameterError(f"v_drive = {v_drive!r} m/s must be finite")
        self.v_drive = float(v_drive)
        self.params = [b.params for b in self.blocks]

    def forces(self, x):
        """``F_ext`` (N) of every block for positions ``x`` (m; shape ``(N,)`` or ``(N, k)``); with
        velocities instead of positions it gives ``dF_ext/dt`` (N/s)."""
        x = np.asarray(x, float)
        f = np.zeros_like(x)
        if self.n > 1:
            kc = self.kc.reshape((-1,) + (1,) * (x.ndim - 1))
            pull = kc * (x[1:] - x[:-1])  # spring i pulls block i towards i+1 and block i+1 back
            f[:-1] += pull
            f[1:] -= pull
        return f

    def accelerations(self, modes, x, v):
        """``dv/dt`` (m/s^2) of every block at one state: 0 while stuck."""
        F = self.forces(x)
        return np.array([0.0 if m == STUCK else acceleration(p, m, x[i], v[i], self.v_drive, F[i])
                         for i, (p, m) in enumerate(zip(self.params, modes))])

    def max_step(self):
        """A twentieth of the shortest free period bound, ``2 pi / omega_max`` (Gershgorin on ``M^-1 K``)."""
        side = np.concatenate([[0.0], self.kc, [0.0]])
        w2 = max((p.kappa + 2.0 * (side[i] + side[i + 1])) / p.M for i, p in enumerate(self.params))
        return 2.0 * math.pi / math.sqrt(w2) / STEPS_PER_PERIOD

    def atol(self, rtol):
        """Absolute tolerances of ``[x_1..x_N, v_1..v_N]``, each block's from the single-block reference."""
        pairs = np.array([tolerances(p, self.v_drive, rtol) for p in self.params])
        return np.concatenate([pairs[:, 0], pairs[:, 1]])


class _ChainRun:
    """Phases (event-free integrations) and events of one simulation."""

    def __init__(self, chain, t0, rtol, progress):
        self.chain, self.rtol, self.progress = chain, rtol, progress
        self.t = t0
        self.x = np.array([b.x0 for b in chain.blocks], float)
        self.v = np.array([b.v0 for b in chain.blocks], float)
        F = chain.forces(self.x)
        self.modes = [initial_mode(p, b.x0, b.v0, chain.v_drive, F[i])
                      for i, (p, b) in enumerate(zip(chain.params, chain.blocks))]
        self.t_stuck = np.array([t0 if m == STUCK else math.nan for m in self.modes])
        self.v[[m == STUCK for m in self.modes]] = chain.v_drive
        self.pieces, self.events = [], []
        self._instant, self._count = None, 0

    def phase(self, t_end):
        """Integrate from the current state to the first event of any block (applied) or ``t_end``."""
        scan = _Scan(self.chain, self.modes, self.t_stuck, self.t, self.x, self.v)
        now = scan.at_once()
        if now is not None:
            y = np.concatenate([self.x, self.v])
            self.pieces.append(ChainPiece.linear(self.t, self.t, y, 0.0 * y, self.modes, self.t_stuck))
            self._event(now)
            return
        if all(m == STUCK for m in self.modes):
            self._all_stuck(t_end)
            return
        chain = self.chain
        solver = DOP853(scan.rhs, self.t, np.concatenate([self.x, self.v]), t_end, rtol=self.rtol,
                        atol=chain.atol(self.rtol), max_step=chain.max_step())
        while solver.status == "running":
            message = solver.step()
            if solver.status == "failed":
                raise ReferenceSolverError(f"chain reference solver failed after t = {solver.t!r} s: {message}")
            dense = solver.dense_output()
            t_hit, block = scan.first_event(dense, solver.t_old, solver.t)
            t1 = solver.t if t_hit is None else t_hit
            self.pieces.append(ChainPiece(solver.t_old, t1, dense, self.modes, self.t_stuck))
            y = dense(t1)
            self.t, self.x, self.v = t1, y[:chain.n].copy(), y[chain.n:].copy()
            self.progress(self.t)
            if t_hit is not None:
                self._event(block)
                return

    def _all_stuck(self, t_end):
        """Every block stuck: the chain moves with the surface, each ``F_ext`` is constant, and each block breaks
        away as a single block would (:func:`~.stuck.run_stuck`); the first breakaway ends the phase."""
        chain, t0 = self.chain, self.t
        F = chain.forces(self.x)
        ends = [run_stuck(p, t0, self.x[i], t0 - self.t_stuck[i], chain.v_drive, F[i], t_end)
                for i, p in enumerate(chain.params)]
        first = min(range(chain.n), key=lambda i: ends[i][0].t1)
        t1 = ends[first][0].t1
        rate = np.concatenate([np.full(chain.n, chain.v_drive), np.zeros(chain.n)])
        self.pieces.append(ChainPiece.linear(t0, t1, np.concatenate([self.x, self.v]), rate, self.modes, self.t_stuck))
        self.t, self.x = t1, self.x + chain.v_drive * (t1 - t0)
        self.progress(self.t)
        if ends[first][1]:
            self._event(first)

    def _event(self, i):
        """Apply block ``i``'s event at the current time: a breakaway or ``v_rel`` reaching 0."""
        chain, p = self.chain, self.chain.params[i]
        F = chain.forces(self.x)[i]
        self.v[i] = chain.v_drive  # both events happen at v_rel = 0
        old = self.modes[i]
        if old == STUCK:
            new, kind = breakaway_mode(p, self.x[i], F), "slip"
        else:
            new = hold_or_break(p, self.x[i], F, 0.0)
            kind = "stick" if new == STUCK else "overshoot"
        self.modes = list(self.modes)
        self.modes[i] = new
        self.t_stuck = self.t_stuck.copy()
        self.t_stuck[i] = self.t if new == STUCK else math.nan
        self.events.append(ChainEvent(self.t, i, kind, old, new))
        self._count = self._count + 1 if self.t == self._instant else 1
        self._instant = self.t
        if self._count > MAX_EVENTS_PER_INSTANT:
            raise ReferenceSolverError(
                f"event chain at t = {self.t!r} s: more than {MAX_EVENTS_PER_INSTANT} mode changes at the same "
                f"instant (last: block {i + 1} {kind} {old} -> {new} at x = {self.x[i]!r} m)")


class _Scan:
    """One phase's modes: its right-hand side and the blocks' indicators with their time derivatives.

    Indicator of block ``i``: slipping in mode ``m``, ``e = m v_rel`` (m/s), ``de/dt = -m a``; stuck,
    ``g = z_slip = F_S(t - t_stuck) - |kappa x - F_ext|`` (N),
    ``dg/dt = F_S'(t_stick) - sign(kappa x - F_ext) (kappa v_drive - dF_ext/dt)``.
    Each reaches 0 at the block's event; a block whose indicator starts at 0 (it has just had an event)
    is leaving 0 if its derivative says so (:meth:`at_once` decides).
    """

    def __init__(self, chain, modes, t_stuck, t0, x0, v0):
        self.chain, self.modes, self.t_stuck = chain, tuple(modes), t_stuck
        self.stuck = np.array([m == STUCK for m in modes])
        self.rising = [True] * chain.n
        self.start = (t0, x0, v0)

    def rhs(self, t, y):
        n, chain = self.chain.n, self.chain
        x, v = y[:n], y[n:]
        return np.concatenate([np.where(self.stuck, chain.v_drive, v), chain.accelerations(self.modes, x, v)])

    def values(self, i, t, x, v, F, dF):
        """Block ``i``'s indicator and its derivative at time ``t`` from its ``x`` (m), ``v`` (m/s), ``F_ext`` (N)
        and ``dF_ext/dt`` (N/s)."""
        chain, p, m = self.chain, self.chain.params[i], self.modes[i]
        if m == STUCK:
            t_stick = t - self.t_stuck[i]
            h = p.kappa * x - F
            return z_slip(p, x, F, t_stick), p.static.rate(t_stick) - np.sign(h) * (p.kappa * chain.v_drive - dF)
        a = acceleration(p, m, x, v, chain.v_drive, F)
        return m * (chain.v_drive - v), -m * a

    def values_at(self, i, dense, t):
        """:meth:`values` of block ``i`` at time ``t`` on a step's ``dense`` output."""
        n = self.chain.n
        y = dense(t)
        F, dF = self.chain.forces(y[:n])[i], self.chain.forces(y[n:])[i]
        return self.values(i, t, y[i], y[n + i], F, dF)

    def at_once(self):
        """The first block whose indicator is at or below 0 and does not rise: its event is now (else None).

        For a slip starting at ``v_rel = 0`` with ``a`` zero to rounding, the second derivative
        ``d2e/dt2 = m (kappa v_drive - dF_ext/dt) / M`` decides, as for one block.
        """
        t, x, v = self.start
        forces, rates = self.chain.forces(x), self.chain.forces(v)
        for i in range(self.chain.n):
            F, dF = forces[i], rates[i]
            value, slope = self.values(i, t, x[i], v[i], F, dF)
            if value > 0.0:
                continue
            p, m = self.chain.params[i], self.modes[i]
            if m != STUCK:
                scale = max(abs(p.kappa * x[i]), abs(F), p.kinetic.force(0.0), p.static.force(0.0))
                if abs(p.M * slope) <= 16.0 * _EPS * scale:
                    slope = m * (p.kappa * self.chain.v_drive - dF) / p.M
            self.rising[i] = slope > 0.0
            if not self.rising[i]:
                return i
        return None

    def first_event(self, dense, t_a, t_b):
        """``(time, block)`` of the earliest event in the step ``[t_a, t_b]`` (dense output), or ``(None, None)``."""
        n = self.chain.n
        s = t_a + (t_b - t_a) * np.arange(SUBSTEPS + 1) / SUBSTEPS
        ys = dense(s)
        x, v = ys[:n], ys[n:]
        forces, rates = self.chain.forces(x), self.chain.forces(v)
        best = (None, None)
        for i in range(n):
            def f(t, i=i):
                return self.values_at(i, dense, t)[0]

            def df(t, i=i):
                return self.values_at(i, dense, t)[1]

            pairs = np.array([self.values(i, t, x[i, k], v[i, k], forces[i, k], rates[i, k]) for k, t in enumerate(s)])
            hit = first_zero(f, s, pairs[:, 0], df, pairs[:, 1], rising=self.rising[i])
            if hit is not None and (best[0] is None or hit < best[0]):
                best = (hit, i)
        return best
