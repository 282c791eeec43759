"""The phase loop: stuck and slip phases between input breakpoints and events."""

import math

import numpy as np

from .errors import ReferenceParameterError, ReferenceSolverError
from .laws import ReferenceParameters
from .closed_form import run_affine
from .numeric import run_numeric
from .result import ReferenceEvent, ReferenceResult
from .rules import STUCK, hold_or_break, initial_mode, mode_after_input, slip_mode
from .stuck import run_stuck

MAX_EVENTS_PER_INSTANT = 1000


def simulate_reference(params, x0, v0, inputs, t_eval, rtol=1e-12):
    """Simulate the spring-block from ``(x0, v0)`` (m, m/s) at ``t_eval[0]`` (s).

    ``inputs`` are breakpoints ``(t_k, v_drive_k, F_ext_k)`` (s, m/s, N), sorted,
    the first at ``t_eval[0]``, each held until the next (zero-order hold).
    ``params`` is a :class:`~.laws.ReferenceParameters` (the reference's own laws,
    e.g. from :func:`~.laws.parameters_from_values`). Returns a :class:`ReferenceResult` on ``t_eval``.
    """
    if not isinstance(params, ReferenceParameters):
        raise ReferenceParameterError(
            f"params must be the reference's own ReferenceParameters (see parameters_from_values), got {params!r}")
    params.check()
    t_eval = np.asarray(t_eval, float)
    breakpoints = _check(x0, v0, inputs, t_eval)
    run = _Run(params, rtol)
    t_end = t_eval[-1]
    _, vd, F = breakpoints[0]
    run.state = _State(float(t_eval[0]), float(x0), float(v0), initial_mode(params, x0, v0, vd, F, t_eval[0]), 0.0)
    for k, (t_k, vd, F) in enumerate(breakpoints):
        if t_k > t_end:
            break
        if k:
            run.apply_input(vd, F)
        t_next = breakpoints[k + 1][0] if k + 1 < len(breakpoints) else t_end
        run.advance(vd, F, min(t_next, t_end))
    return run.result(t_eval, breakpoints)


class _State:
    """Where the loop stands: time (s), ``x`` (m), ``v`` (m/s), mode, stick time (s)."""

    __slots__ = ("t", "x", "v", "mode", "t_stick")

    def __init__(self, t, x, v, mode, t_stick):
        self.t, self.x, self.v, self.mode, self.t_stick = t, x, v, mode, t_stick


class _Run:
    """Phases and events of one simulation."""

    def __init__(self, p, rtol):
        self.p, self.rtol = p, rtol
        self.state = None
        self.phases, self.events = [], []
        self._instant, self._count = None, 0

    def advance(self, v_drive, F_ext, t_max):
        """Run phases under constant inputs up to ``t_max``, processing every event on the way and at it."""
        while True:
            phase, hit = self._phase(v_drive, F_ext, t_max)
            self.phases.append(phase)
            s = self.state
            x, v = phase.state(phase.t1)
            s.t, s.x, s.v = float(phase.t1), float(x), float(v)
            s.t_stick = float(phase.t_stick(phase.t1))
            if not hit:
                return
            self._event(v_drive, F_ext)

    def _phase(self, v_drive, F_ext, t_max):
        s, p = self.state, self.p
        if s.mode == STUCK:
            return run_stuck(p, s.t, s.x, s.t_stick, v_drive, F_ext, t_max)
        if p.kinetic.affine() is not None:
            return run_affine(p, s.mode, s.t, s.x, s.v, v_drive, F_ext, t_max)
        return run_numeric(p, s.mode, s.t, s.x, s.v, v_drive, F_ext, t_max, self.rtol)

    def _event(self, v_drive, F_ext):
        """Apply the event that ended the last phase: a breakaway or ``v_rel`` reaching 0."""
        s, p = self.state, self.p
        s.v = v_drive  # both events happen at v_rel = 0
        if s.mode == STUCK:
            self._record("slip", slip_mode(p, s.x, v_drive, F_ext, s.t), 0.0)
            return
        mode = hold_or_break(p, s.x, F_ext, 0.0, v_drive, s.t)
        if mode == s.mode:  # no crossing: a tangential return, held by F_K(0+) <= F_S(0) (beyond it by rounding)
            mode = STUCK
        self._record("stick" if mode == STUCK else "overshoot", mode, 0.0)

    def apply_input(self, v_drive, F_ext):
        """Inputs jump at the current time: a stuck block takes the new ``v_drive``, a slipping one keeps ``v``."""
        s = self.state
        if s.mode == STUCK:
            s.v = v_drive
        mode = mode_after_input(self.p, s.mode, s.x, s.v, s.t_stick, v_drive, F_ext, s.t)
        if mode != s.mode:
            self._record("input", mode, 0.0)

    def _record(self, kind, mode, t_stick):
        s = self.state
        self.events.append(ReferenceEvent(float(s.t), kind, s.mode, mode))
        s.mode, s.t_stick = mode, t_stick
        self._count = self._count + 1 if s.t == self._instant else 1
        self._instant = s.t
        if self._count > MAX_EVENTS_PER_INSTANT:
            raise ReferenceSolverError(
                f"event chain at t = {s.t!r} s: more than {MAX_EVENTS_PER_INSTANT} mode changes at the same "
                f"instant (last: {kind} {self.events[-1].mode_before} -> {mode} at x = {s.x!r} m)"
            )

    def result(self, t_eval, breakpoints):
        """Sample the phases on ``t_eval``: the last phase starting at or before each time."""
        n = len(t_eval)
        x, v, mode, t_stick = np.empty(n), np.empty(n), np.empty(n, int), np.empty(n)
        starts = np.array([phase.t0 for phase in self.phases])
        owner = np.searchsorted(starts, t_eval, side="right") - 1
        for i in np.unique(owner):
            at = owner == i
            phase = self.phases[i]
            x[at], v[at] = phase.state(t_eval[at])
            mode[at], t_stick[at] = phase.mode, phase.t_stick(t_eval[at])
        times = np.array([b[0] for b in breakpoints])
        held = np.searchsorted(times, t_eval, side="right") - 1
        v_drive = np.array([breakpoints[k][1] for k in held])
        F_ext = np.array([breakpoints[k][2] for k in held])
        return ReferenceResult(t_eval.copy(), x, v, mode, t_stick, v_drive, F_ext, list(self.events))


def _check(x0, v0, inputs, t_eval):
    """Validate the arguments; return the breakpoints that change the inputs, as float triples."""
    if t_eval.ndim != 1 or t_eval.size == 0 or not np.all(np.isfinite(t_eval)) or np.any(np.diff(t_eval) <= 0.0):
        raise ReferenceParameterError("t_eval must be a non-empty 1-D array of finite, strictly increasing times (s)")
    for name, value in (("x0", x0), ("v0", v0)):
        if not math.isfinite(value):
            raise ReferenceParameterError(f"{name} = {value!r} must be finite")
    breakpoints = [tuple(float(c) for c in row) for row in inputs]
    if not breakpoints or breakpoints[0][0] != t_eval[0]:
        raise ReferenceParameterError(f"inputs must start with a breakpoint at t_eval[0] = {t_eval[0]!r} s")
    for t_k, vd, F in breakpoints:
        if not (math.isfinite(t_k) and math.isfinite(vd) and math.isfinite(F)):
            raise ReferenceParameterError(f"input breakpoint ({t_k!r}, {vd!r}, {F!r}) must be finite")
    if any(b[0] < a[0] for a, b in zip(breakpoints, breakpoints[1:])):
        raise ReferenceParameterError("input breakpoints must be sorted by time")
    # a breakpoint that repeats the held values is no jump: drop it, so results do not depend on the master's grid
    return breakpoints[:1] + [b for a, b in zip(breakpoints, breakpoints[1:]) if b[1:] != a[1:]]
