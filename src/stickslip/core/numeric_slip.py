"""Adaptive stepping of a slip phase under a general (non-affine) kinetic law.

:class:`SlipStepper` keeps the step size and the method (explicit Dormand-Prince,
or Rosenbrock when the slip is stiff) across steps. ``step()`` returns one
accepted step, cut at the first point where ``v`` reaches ``v_drive`` from the
slip side. That point is searched on the step's dense output between the
extrema of ``v`` (so a short excursion of ``v_rel`` through 0 inside one step
is found), then the step is redone to end exactly there.
"""

from __future__ import annotations  # annotations stay unevaluated: the FMU runs on CPython 3.8+

import math
from typing import Final

from . import poly
from .errors import SolverError
from .integrators import Step, dopri5_step, rosenbrock_step
from .model import Parameters, SlipAccelerator, slip_acceleration_slope
from .rootfind import monotone_fall

_SAFETY: Final = 0.9
_MAX_GROWTH: Final = 5.0
_MIN_SHRINK: Final = 0.2
_EXPLICIT_STABILITY: Final = 3.3  # DOPRI5's stability limit of h * |lambda| on the negative real axis
_SWITCH_AFTER: Final = 8  # consecutive steps that must agree before the method changes
MEMO_SIZE: Final = 4096  # accepted steps remembered for replay (0: integrate every step)


class SlipStepper:
    """Step-size and method state of the numeric slip integration (serializable).

    Every slip phase starts from the same initial step size (:meth:`restart`), so
    a slip's steps depend only on its start state, its inputs and the stepper's
    state then. The accepted steps of each slip are kept in a bounded memo under
    exactly that key: a periodic stick-slip, whose slips start from bit-identical
    states, replays them instead of integrating again, and gets exactly the numbers
    a new integration would. A slip that outgrows the memo keeps the steps it
    recorded (a valid prefix) and integrates on without recording, so a slide that
    never repeats pays one list append per step, then nothing.
    """

    __slots__ = ("rtol", "h", "stiff", "votes", "n_steps", "n_rejected", "_slip", "_memo", "_memo_size",
                 "_recorded", "record", "cursor")
    rtol: float
    h: float | None  # s: the next step's size; None at the start of a slip phase
    stiff: bool
    votes: int
    n_steps: int
    n_rejected: int
    _slip: "_Slip | None"
    _memo: dict  # slip key -> the slip's recorded steps, each (step, ends_in_event, h, stiff, votes, rejected)
    _memo_size: int  # most steps recorded over all slips
    _recorded: int  # steps recorded in the memo
    record: list | None  # the current slip's recorded steps (None: the next step starts a slip)
    cursor: int  # index in record of the next step to replay; len(record) while recording; -1: neither
    # (h to n_rejected, record and cursor: what a Trajectory.state holds of the stepper, read there)

    def __init__(self, rtol: float, h: float | None = None, stiff: bool = False, votes: int = 0, n_steps: int = 0,
                 n_rejected: int = 0, memo_size: int = MEMO_SIZE) -> None:
        self.rtol = rtol
        self.h = h
        self.stiff = stiff
        self.votes = votes
        self.n_steps = n_steps
        self.n_rejected = n_rejected
        self._slip = None  # constants of the current slip, rebuilt when the mode or the inputs change
        self._memo = {}
        self._memo_size = memo_size
        self._recorded = 0
        self.record = None
        self.cursor = -1

    def restore(self, h: float | None, stiff: bool, votes: int, n_steps: int, n_rejected: int, record: list | None,
                cursor: int, own: bool) -> None:
        """Go back to where a step depends on (what a :meth:`.Trajectory.state` holds of this stepper): the step size,
        the method, the counters (these five are what a saved state holds), and where the current slip is in its
        record of steps (shared: a record only grows, by the steps that follow from the same start, so the steps
        replayed from it are the same); ``own``: the record is one of this memo's, else the current slip is recorded
        anew (a record of another stepper may be of other parameters)."""
        self.h, self.stiff, self.votes, self.n_steps, self.n_rejected = h, stiff, votes, n_steps, n_rejected
        self.record, self.cursor = (record, cursor) if own else (None, -1)

    def restart(self):
        """A new slip phase begins (after an event or an input change): forget the step size."""
        self.h = None
        self.record = None

    def step(self, t0: float, x0: float, v0: float, mode: int, v_drive: float, F_ext: float,
             p: Parameters) -> tuple[Step, bool]:
        """One accepted step from ``(t0, x0, v0)``; returns ``(step, ends_in_event)``.

        When the step ends in an event, ``step.x1`` is the position where
        ``v = v_drive`` (``step.v1`` is within the tolerance of ``v_drive``).
        The step does not depend on ``t0`` (the slip is autonomous), which is what
        lets the memo replay it at another time.
        """
        if not self._memo_size:
            return self._integrate(t0, x0, v0, mode, v_drive, F_ext, p)
        record = self.record
        if record is None:  # the slip's first step: its steps are known, or are recorded from here
            key = (x0, v0, mode, v_drive, F_ext, self.h, self.stiff, self.votes)
            known = self._memo.get(key)
            if known is None:
                if self._recorded >= self._memo_size:
                    self._memo.clear()  # bounded memory: a long aperiodic run keeps only recent slips
                    self._recorded = 0
                known = self._memo[key] = []
            record = self.record = known
            self.cursor = 0
        cursor = self.cursor
        if 0 <= cursor < len(record):
            entry: tuple[Step, bool, float | None, bool, int, int] = record[cursor]
            if _advances(t0, entry[0].h):  # else integrated: the record is left
                step, ends_in_event, self.h, self.stiff, self.votes, rejected = entry
                self.cursor = cursor + 1
                self.n_steps += 1
                self.n_rejected += rejected
                return step, ends_in_event
        rejected_before = self.n_rejected
        step, ends_in_event = self._integrate(t0, x0, v0, mode, v_drive, F_ext, p)
        if cursor == len(record) and self._recorded < self._memo_size:
            record.append((step, ends_in_event, self.h, self.stiff, self.votes, self.n_rejected - rejected_before))
            self._recorded += 1
            self.cursor = cursor + 1
        else:
            self.cursor = -1  # the memo is full, or this slip left its record: integrate to its end
        return step, ends_in_event

    def _integrate(self, t0: float, x0: float, v0: float, mode: int, v_drive: float, F_ext: float,
                   p: Parameters) -> tuple[Step, bool]:
        slip = self._slip
        if slip is None or slip.mode != mode or slip.v_drive != v_drive or slip.F_ext != F_ext:
            slip = self._slip = _Slip(mode, v_drive, F_ext, p)
        accel = slip.accel
        a0 = accel.at(x0, v0)
        stiffness = _larger(0.0, -slip_acceleration_slope(mode, v0, v_drive, p))
        h_max = 1.0 / slip.omega0
        if self.h is None:
            self.h = _smaller(h_max, 0.5 / _larger(stiffness, slip.omega0) * self.rtol ** 0.2 * 10.0)
        h = _smaller(self.h, h_max)
        while True:
            step = self._try(accel, mode, v_drive, p, x0, v0, a0, h)
            err = _error_norm(step, x0, v0, self.rtol, slip.scale_x, slip.scale_v)
            if err <= 1.0 and math.isfinite(step.x1) and math.isfinite(step.v1):
                break
            self.n_rejected += 1
            shrink = _SAFETY * err ** (-1.0 / step.order) if math.isfinite(err) and err > 0.0 else _MIN_SHRINK
            h *= _larger(_MIN_SHRINK, _smaller(shrink, 1.0))
            if not _advances(t0, h):
                raise SolverError(
                    f"step size underflow at t = {t0!r} s in slip mode {mode:+d}: "
                    f"the slip dynamics are too stiff or singular for rtol = {self.rtol:g}"
                )
        self.n_steps += 1
        grow = _SAFETY * err ** (-1.0 / step.order) if err > 0.0 else _MAX_GROWTH
        h_next = self.h = h * _larger(_MIN_SHRINK, _smaller(grow, _MAX_GROWTH))
        self._vote_on_stiffness(h, h_next, stiffness)
        theta = _slip_end(step.cv, mode, v_drive)
        if theta is None:
            return step, False
        return self._try(accel, mode, v_drive, p, x0, v0, a0, theta * h), True

    def _try(self, accel: SlipAccelerator, mode: int, v_drive: float, p: Parameters, x0: float, v0: float,
             a0: float, h: float) -> Step:
        if not self.stiff:
            return dopri5_step(accel, x0, v0, a0, h)
        slope_v = slip_acceleration_slope(mode, v0, v_drive, p)
        return rosenbrock_step(accel, -p.kappa / p.M, slope_v, x0, v0, a0, h)

    def _vote_on_stiffness(self, h: float, h_next: float, stiffness: float) -> None:
        """Switch method after several steps agree that stability, not accuracy, limits the step
        (``h`` the step just taken, ``h_next`` the next one's size)."""
        if not self.stiff:
            stiff_now = h * stiffness > 0.8 * _EXPLICIT_STABILITY
        else:
            stiff_now = h_next * stiffness > 0.5 * _EXPLICIT_STABILITY
        self.votes = self.votes + 1 if stiff_now != self.stiff else 0
        if self.votes >= _SWITCH_AFTER:
            self.stiff = not self.stiff
            self.votes = 0


def _larger(a: float, b: float) -> float:
    """``max(a, b)`` of two floats (``a`` unless ``b > a``, as the builtin), without boxing in compiled code."""
    return b if b > a else a


def _smaller(a: float, b: float) -> float:
    """``min(a, b)`` of two floats (``a`` unless ``b < a``, as the builtin), without boxing in compiled code."""
    return b if b < a else a


def _advances(t0: float, h: float) -> bool:
    """True if a step of ``h`` s from ``t0`` moves time by more than rounding (the underflow test)."""
    return h > 1e-15 * _larger(1.0, abs(t0)) and h >= 1e-300


class _Slip:
    """Constants of a slip with fixed mode and inputs: the acceleration ``a(x, v)``, the natural position
    (m) and velocity (m/s) scales of the absolute tolerance, and the natural frequency ``omega0`` (1/s),
    whose inverse is the largest step."""

    __slots__ = ("mode", "v_drive", "F_ext", "accel", "scale_x", "scale_v", "omega0")
    mode: int
    v_drive: float
    F_ext: float
    accel: SlipAccelerator
    scale_x: float
    scale_v: float
    omega0: float

    def __init__(self, mode: int, v_drive: float, F_ext: float, p: Parameters) -> None:
        self.mode, self.v_drive, self.F_ext = mode, v_drive, F_ext
        self.accel = SlipAccelerator(mode, v_drive, F_ext, p)
        self.omega0 = math.sqrt(p.kappa / p.M)
        self.scale_x = (p.static.force(0.0) + abs(F_ext)) / p.kappa
        self.scale_v = max(abs(v_drive), self.omega0 * self.scale_x)


def _error_norm(step: Step, x0: float, v0: float, rtol: float, scale_x: float, scale_v: float) -> float:
    """RMS of the error relative to ``rtol * max(|y|, scale)`` per component."""
    ex = step.err_x / (rtol * _larger(_larger(abs(x0), abs(step.x1)), scale_x))
    ev = step.err_v / (rtol * _larger(_larger(abs(v0), abs(step.v1)), scale_v))
    return math.sqrt(0.5 * (ex * ex + ev * ev))


def _slip_end(cv: list[float], mode: int, v_drive: float) -> float | None:
    """First step fraction where ``v`` (dense output ``cv``) reaches ``v_drive`` from the slip side.

    ``g = mode * (v_drive - v)`` is positive while slipping; between
    consecutive extrema of ``v`` it is monotonic, so its first fall to ``<= 0``
    is bracketed exactly. A start at ``g = 0`` (right after a breakaway) is not an end.
    """

    reach = 0.0  # bounds |v(theta) - v(0)| on [0, 1]
    for k in range(1, len(cv)):
        reach += abs(cv[k])
    if mode * (v_drive - cv[0]) - reach > 0.0:
        return None  # v cannot reach v_drive in this step
    return _search_slip_end(cv, mode, v_drive)


def _search_slip_end(cv: list[float], mode: int, v_drive: float) -> float | None:
    """:func:`_slip_end` where the quick bound does not exclude an end: bracket the first crossing."""

    def g(theta: float) -> float:
        return mode * (v_drive - poly.evaluate(cv, theta))

    breaks = poly.monotone_breaks(cv)
    for a, b in zip(breaks, breaks[1:]):
        end = monotone_fall(g, a, b, g(a), g(b), a > 0.0)
        if end is not None:
            return end
    return None
