"""Pieces of a trajectory between consecutive events or solver steps.

A segment starts at ``t0`` in one ``mode`` with the inputs held constant, and
reaches to ``t1`` (``inf`` when nothing ever ends it). ``ends_in_event`` says
whether a mode transition is due at ``t1`` (breakaway when stuck, ``v_rel = 0``
when slipping); otherwise the next segment just continues from ``t1``.
Each segment evaluates ``(x, v)`` anywhere in ``[t0, t1]`` and serializes to a
list of numbers (``kind`` first) so a trajectory can be saved and restored bit for bit.
"""

from __future__ import annotations  # annotations stay unevaluated: the FMU runs on CPython 3.8+

import math
from typing import Any, ClassVar

from . import poly
from .errors import StateError
from .integrators import Step
from .linear_slip import HarmonicSlip
from .model import STUCK, Parameters
from .saved_state import COUNT, FLAG, MODE, REAL, REALS, TIME_END, sequence


class Segment:
    """What every kind of segment has and does (a typed base: compiled code reads and calls it natively).

    ``t0``, ``t1`` (s): start and end; ``ends_in_event``: a mode transition is due at ``t1``;
    ``mode``: +1, 0 (stuck) or -1 throughout.
    """

    __slots__ = ("t0", "t1", "ends_in_event", "mode")
    t0: float
    t1: float
    ends_in_event: bool
    mode: int

    def __init__(self, t0: float, t1: float, ends_in_event: bool, mode: int) -> None:
        self.t0, self.t1, self.ends_in_event, self.mode = t0, t1, ends_in_event, mode

    def state(self, t: float) -> tuple[float, float]:
        """``(x, v)`` (m, m/s) at ``t`` in ``[t0, t1]``."""
        raise NotImplementedError

    def t_stick(self, t: float) -> float:
        """Time (s) since the stick began, at ``t``; 0 while slipping."""
        return 0.0

    def fill(self, times: list[float], i: int, xs: list[float], vs: list[float]) -> int:
        """Append ``(x, v)`` at ``times[i]``, ``times[i+1]``, ... while they do not decrease and stay before
        ``t1`` (``times[i]`` must be in ``[t0, t1)``); returns the index of the first time not taken."""
        n = len(times)
        lower = times[i]
        while i < n:
            t = times[i]
            if not lower <= t < self.t1:
                break
            x, v = self.state(t)
            xs.append(x)
            vs.append(v)
            lower = t
            i += 1
        return i

    def end_state(self) -> tuple[float, float]:
        """``(x, v)`` at ``t1`` as the next segment starts from it."""
        raise NotImplementedError

    def to_list(self) -> list:
        """The constructor's arguments, ``kind`` first (see :func:`segment_from_list`)."""
        raise NotImplementedError


class StuckSegment(Segment):
    """Stuck for ``duration`` s: ``x = x0 + v_drive (t - t0)``, ``v = v_drive``, ``t_stick = t_stick0 + t - t0``.

    The end time ``t1 = t0 + duration`` is rounded. With ``replayable_end`` the end
    state is ``x0 + v_drive duration``: the same whenever the stick starts, so the
    numeric slip that follows starts from bit-identical states cycle after cycle and
    its steps can be replayed (numeric steps round time the same way, by up to
    ``ulp(t)`` each). Otherwise the end state is the motion at the rounded ``t1``,
    consistent with the event time: a closed-form slip, whose only error is
    rounding, then does not drift over many cycles.
    """

    KIND: ClassVar[str] = "stuck"
    FIELDS: ClassVar[tuple] = (("t0", REAL), ("duration", TIME_END), ("ends_in_event", FLAG), ("x0", REAL),
                               ("v_drive", REAL), ("t_stick0", REAL), ("replayable_end", FLAG))
    __slots__ = ("duration", "x0", "v_drive", "t_stick0", "replayable_end")
    duration: float
    x0: float
    v_drive: float
    t_stick0: float
    replayable_end: bool

    def __init__(self, t0: float, duration: float, ends_in_event: bool, x0: float, v_drive: float, t_stick0: float,
                 replayable_end: bool) -> None:
        super().__init__(t0, t0 + duration, ends_in_event, STUCK)
        self.duration, self.x0, self.v_drive, self.t_stick0 = duration, x0, v_drive, t_stick0
        self.replayable_end = replayable_end

    def state(self, t: float) -> tuple[float, float]:
        if t == self.t1:
            return self.end_state()
        return self.x0 + self.v_drive * (t - self.t0), self.v_drive

    def t_stick(self, t: float) -> float:
        return self.t_stick0 + (t - self.t0)

    def end_state(self) -> tuple[float, float]:
        elapsed = self.duration if self.replayable_end else self.t1 - self.t0
        return self.x0 + self.v_drive * elapsed, self.v_drive

    def to_list(self) -> list:
        return [self.KIND, self.t0, self.duration, self.ends_in_event, self.x0, self.v_drive, self.t_stick0,
                self.replayable_end]


class HarmonicSegment(Segment):
    """Slip under an affine kinetic law, in closed form (see :mod:`.linear_slip`)."""

    KIND: ClassVar[str] = "harmonic"
    FIELDS: ClassVar[tuple] = (("t0", REAL), ("t1", TIME_END), ("ends_in_event", FLAG), ("mode", MODE), ("x0", REAL),
                               ("v0", REAL), ("v_drive", REAL), ("F_ext", REAL))
    __slots__ = ("x0", "v0", "v_drive", "F_ext", "motion")
    x0: float
    v0: float
    v_drive: float
    F_ext: float
    motion: HarmonicSlip

    def __init__(self, t0: float, t1: float, ends_in_event: bool, mode: int, x0: float, v0: float, v_drive: float,
                 F_ext: float, p: Parameters) -> None:
        super().__init__(t0, t1, ends_in_event, mode)
        self.x0, self.v0, self.v_drive, self.F_ext = x0, v0, v_drive, F_ext
        self.motion = HarmonicSlip(mode, x0, v0, v_drive, F_ext, p)

    @staticmethod
    def start(t0: float, mode: int, x0: float, v0: float, v_drive: float, F_ext: float,
              p: Parameters) -> HarmonicSegment:
        """The slip from ``(t0, x0, v0)`` up to its end (``v = v_drive``) or forever."""
        segment = HarmonicSegment(t0, math.inf, False, mode, x0, v0, v_drive, F_ext, p)
        delay = segment.motion.stick_delay(mode, v_drive)
        if delay is not None:
            segment.t1, segment.ends_in_event = t0 + delay, True
        return segment

    def state(self, t: float) -> tuple[float, float]:
        return self.motion.state(t - self.t0)

    def end_state(self) -> tuple[float, float]:
        x, v = self.state(self.t1)
        return (x, self.v_drive) if self.ends_in_event else (x, v)

    def to_list(self) -> list:
        return [self.KIND, self.t0, self.t1, self.ends_in_event, self.mode, self.x0, self.v0, self.v_drive, self.F_ext]


class StepSegment(Segment):
    """One Runge-Kutta step of a slip under a general law; ``(x, v)`` from its dense output.

    The coefficient lists are shared, not copied (with the step and its memo entry): nothing changes them.
    """

    KIND: ClassVar[str] = "step"
    FIELDS: ClassVar[tuple] = (("t0", REAL), ("t1", REAL), ("ends_in_event", FLAG), ("mode", MODE), ("h", REAL),
                               ("cx", REALS), ("cv", REALS), ("x1", REAL), ("v1", REAL))
    __slots__ = ("h", "cx", "cv", "x1", "v1")
    h: float
    cx: list[float]
    cv: list[float]
    x1: float
    v1: float

    def __init__(self, t0: float, t1: float, ends_in_event: bool, mode: int, h: float, cx: list[float],
                 cv: list[float], x1: float, v1: float) -> None:
        super().__init__(t0, t1, ends_in_event, mode)
        self.h, self.cx, self.cv = h, cx, cv
        self.x1, self.v1 = x1, v1

    @staticmethod
    def instant(t0: float, mode: int, x0: float, v0: float) -> StepSegment:
        """A slip of zero length that ends in an event at once (it cannot leave ``v_rel = 0``)."""
        return StepSegment(t0, t0, True, mode, 0.0, [x0], [v0], x0, v0)

    @staticmethod
    def from_step(t0: float, mode: int, step: Step, ends_in_event: bool, v_drive: float) -> StepSegment:
        v1 = v_drive if ends_in_event else step.v1
        return StepSegment(t0, t0 + step.h, ends_in_event, mode, step.h, step.cx, step.cv, step.x1, v1)

    def state(self, t: float) -> tuple[float, float]:
        if t == self.t1:
            return self.x1, self.v1
        theta = (t - self.t0) / self.h
        return poly.evaluate_pair(self.cx, self.cv, theta)

    def fill(self, times: list[float], i: int, xs: list[float], vs: list[float]) -> int:
        if len(self.cx) != 5:
            return super().fill(times, i, xs, vs)
        # the Dormand-Prince dense output, at every output point of the step: poly.evaluate_pair inlined
        a0, a1, a2, a3, a4 = self.cx
        b0, b1, b2, b3, b4 = self.cv
        t0, t1, h = self.t0, self.t1, self.h
        n = len(times)
        lower = times[i]
        while i < n:
            t = times[i]
            if not lower <= t < t1:
                break
            theta = (t - t0) / h
            xs.append(a0 + theta * (a1 + theta * (a2 + theta * (a3 + theta * a4))))
            vs.append(b0 + theta * (b1 + theta * (b2 + theta * (b3 + theta * b4))))
            lower = t
            i += 1
        return i

    def end_state(self) -> tuple[float, float]:
        return self.x1, self.v1

    def to_list(self) -> list:
        return [self.KIND, self.t0, self.t1, self.ends_in_event, self.mode, self.h, list(self.cx), list(self.cv),
                self.x1, self.v1]


#: every kind of segment, in the order of their codes in a state's bytes (:mod:`.state_bytes`)
SEGMENT_CLASSES: tuple[Any, ...] = (StuckSegment, HarmonicSegment, StepSegment)


def segment_from_list(values, p):
    """Rebuild a segment from :meth:`~Segment.to_list` output (with the parameters ``p`` it was saved with).

    StateError names a field that is missing, of the wrong kind or inconsistent (see :func:`checked_segment`).
    """
    kinds = {segment_class.KIND: segment_class for segment_class in SEGMENT_CLASSES}
    kind = values[0] if isinstance(values, list) and values else None
    if not isinstance(kind, str) or kind not in kinds:
        raise StateError(f"saved state segment {values!r:.80} is not a list that starts with one of {sorted(kinds)}")
    segment_class = kinds[kind]
    return checked_segment(segment_class, sequence(f"segment ({kind})", values[1:], segment_class.FIELDS), p)


def checked_segment(segment_class, values, p):
    """The segment of ``segment_class`` whose constructor's arguments (without ``p``) are ``values``, each of its kind
    in ``segment_class.FIELDS``: StateError naming what no segment saved by this runtime under ``p`` holds (times
    out of order, a negative duration or stick time, a slip in mode 0, a closed-form slip under a law that has
    none)."""
    _check_segment(segment_class, values, p)
    if segment_class is HarmonicSegment:
        return HarmonicSegment(*values, p)
    return segment_class(*values)


def _check_segment(segment_class, values: list, p):
    """StateError for ``values`` (in the order of ``segment_class.FIELDS``) that no segment of ``segment_class`` saved
    by this runtime under ``p`` holds. A stuck segment's duration and t_stick0 are its fields 1 and 5; a slip's t0,
    t1 and mode its fields 0, 1 and 3, a step's h, cx and cv its fields 4 to 6."""
    if segment_class is StuckSegment:
        problem = "duration < 0" if values[1] < 0.0 else "t_stick0 < 0" if values[5] < 0.0 else None
    elif values[1] < values[0]:
        problem = "t1 < t0"
    elif values[3] == STUCK:
        problem = "a slip in mode 0"
    elif segment_class is HarmonicSegment:
        problem = "a closed-form slip under a kinetic law that has none" if p.kinetic.affine() is None else None
    else:
        problem = ("h < 0" if values[4] < 0.0 else "cx and cv of different lengths"
                   if len(values[5]) != len(values[6]) else None)
    if problem:
        raise StateError(f"saved state segment ({segment_class.KIND}) is inconsistent: {problem}")
