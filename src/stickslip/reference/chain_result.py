"""What :func:`~.chain.simulate_chain` takes and returns: the chain's blocks; its trajectory on a grid, its events and
its dense solution."""

import math
from collections import namedtuple
from dataclasses import dataclass, field

import numpy as np

from .rules import STUCK

#: one block of a chain: its parameters, start position ``x0`` (m) and velocity ``v0`` (m/s)
ChainBlock = namedtuple("ChainBlock", "params x0 v0")


@dataclass(frozen=True)
class ChainEvent:
    """A mode change of block ``block`` (0-based) at time ``t`` (s): ``kind`` "stick", "slip" or "overshoot"
    (SPEC section 1), modes +1, 0, -1 before and after."""

    t: float
    block: int
    kind: str
    mode_before: int
    mode_after: int


class ChainPiece:
    """The chain between ``t0`` and ``t1`` (s) without events: ``dense(t)`` gives the states
    ``[x_1..x_N, v_1..v_N]`` at the times ``t`` (a solver step's dense output, or :meth:`linear`); each block's mode
    and the time its stick began (``t_stuck``, NaN while slipping)."""

    def __init__(self, t0, t1, dense, modes, t_stuck):
        self.t0, self.t1, self.dense = t0, t1, dense
        self.modes, self.t_stuck = tuple(modes), t_stuck

    @classmethod
    def linear(cls, t0, t1, y0, rate, modes, t_stuck):
        """States ``y0 + rate (t - t0)``: every block stuck (the chain moves with the surface), or a zero-length
        piece (``rate`` 0) holding the state before an event at ``t0``."""
        y0, rate = np.asarray(y0, float), np.asarray(rate, float)
        return cls(t0, t1, lambda t: y0[:, None] + rate[:, None] * (np.atleast_1d(t) - t0)[None, :], modes, t_stuck)

    def states(self, t):
        """``[x_1..x_N, v_1..v_N]`` at the times ``t`` (array, s): shape ``(2N, len(t))``."""
        return self.dense(np.asarray(t, float))


@dataclass
class ChainResult:
    """The chain on the grid ``t`` (s), state after any event at each grid time. Arrays of shape ``(len(t), N)``:
    ``x`` (m), ``v`` (m/s), ``mode`` (int), ``t_stick`` (s, 0 while slipping) and ``F_ext`` (N, the coupling force).
    ``events`` lists every block's mode changes in time order; :meth:`state` reads the dense solution."""

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    mode: np.ndarray
    t_stick: np.ndarray
    F_ext: np.ndarray
    events: list = field(default_factory=list)
    pieces: list = field(default_factory=list, repr=False)

    @classmethod
    def sample(cls, chain, pieces, events, t):
        """The result of ``pieces`` (in time order) of ``chain`` on the grid ``t``: each time from the last piece
        starting at or before it."""
        n, m = chain.n, t.size
        x, v, t_stick = np.empty((m, n)), np.empty((m, n)), np.zeros((m, n))
        mode = np.empty((m, n), int)
        starts = np.array([piece.t0 for piece in pieces])
        owner = np.searchsorted(starts, t, side="right") - 1
        for k in np.unique(owner):
            at = owner == k
            piece = pieces[k]
            y = piece.states(t[at])
            x[at], v[at] = y[:n].T, y[n:].T
            mode[at] = piece.modes
            stuck = np.array([mo == STUCK for mo in piece.modes])
            t_stick[np.ix_(at, stuck)] = t[at][:, None] - piece.t_stuck[stuck][None, :]
        return cls(t.copy(), x, v, mode, t_stick, chain.forces(x.T).T, list(events), list(pieces))

    def state(self, t):
        """``(x, v, modes)`` of every block at the time ``t`` (s) from the dense solution (after events at ``t``)."""
        starts = [piece.t0 for piece in self.pieces]
        piece = self.pieces[max(0, int(np.searchsorted(starts, t, side="right")) - 1)]
        y = piece.states([t])[:, 0]
        n = y.size // 2
        return y[:n], y[n:], piece.modes

    def event_times(self, block):
        """Times (s) of the events of ``block`` (0-based)."""
        return np.array([e.t for e in self.events if e.block == block])

    def amplitude(self):
        """The chain's amplitude (m): the largest range ``max x_i - min x_i`` of any block over the grid."""
        return float(np.max(np.ptp(self.x, axis=0))) if self.t.size else math.nan
