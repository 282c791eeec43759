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
from typing import ClassVar

from . import poly
from .linear_slip import HarmonicSlip
from .model import STUCK


class StuckSegment:
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
    __slots__ = ("t0", "duration", "t1", "ends_in_event", "x0", "v_drive", "t_stick0", "replayable_end")
    mode: ClassVar[int] = STUCK

    def __init__(self, t0, duration, ends_in_event, x0, v_drive, t_stick0, replayable_end):
        self.t0, self.duration, self.t1, self.ends_in_event = t0, duration, t0 + duration, ends_in_event
        self.x0, self.v_drive, self.t_stick0 = x0, v_drive, t_stick0
        self.replayable_end = replayable_end

    def state(self, t):
        if t == self.t1:
            return self.end_state()
        return self.x0 + self.v_drive * (t - self.t0), self.v_drive

    def t_stick(self, t):
        return self.t_stick0 + (t - self.t0)

    def end_state(self):
        elapsed = self.duration if self.replayable_end else self.t1 - self.t0
        return self.x0 + self.v_drive * elapsed, self.v_drive

    def to_list(self):
        return [self.KIND, self.t0, self.duration, self.ends_in_event, self.x0, self.v_drive, self.t_stick0,
                self.replayable_end]


class HarmonicSegment:
    """Slip under an affine kinetic law, in closed form (see :mod:`.linear_slip`)."""

    KIND: ClassVar[str] = "harmonic"
    __slots__ = ("t0", "t1", "ends_in_event", "mode", "x0", "v0", "v_drive", "F_ext", "motion")

    def __init__(self, t0, t1, ends_in_event, mode, x0, v0, v_drive, F_ext, p):
        self.t0, self.t1, self.ends_in_event = t0, t1, ends_in_event
        self.mode, self.x0, self.v0, self.v_drive, self.F_ext = mode, x0, v0, v_drive, F_ext
        self.motion = HarmonicSlip(mode, x0, v0, v_drive, F_ext, p)

    @classmethod
    def start(cls, t0, mode, x0, v0, v_drive, F_ext, p):
        """The slip from ``(t0, x0, v0)`` up to its end (``v = v_drive``) or forever."""
        segment = cls(t0, math.inf, False, mode, x0, v0, v_drive, F_ext, p)
        delay = segment.motion.stick_delay(mode, v_drive)
        if delay is not None:
            segment.t1, segment.ends_in_event = t0 + delay, True
        return segment

    def state(self, t):
        return self.motion.state(t - self.t0)

    def t_stick(self, t):
        return 0.0

    def end_state(self):
        x, v = self.state(self.t1)
        return (x, self.v_drive) if self.ends_in_event else (x, v)

    def to_list(self):
        return [self.KIND, self.t0, self.t1, self.ends_in_event, self.mode, self.x0, self.v0, self.v_drive, self.F_ext]


class StepSegment:
    """One Runge-Kutta step of a slip under a general law; ``(x, v)`` from its dense output."""

    KIND: ClassVar[str] = "step"
    __slots__ = ("t0", "t1", "ends_in_event", "mode", "h", "cx", "cv", "x1", "v1")
    t0: float
    t1: float
    ends_in_event: bool
    mode: int
    h: float
    cx: list[float]
    cv: list[float]
    x1: float
    v1: float

    def __init__(self, t0: float, t1: float, ends_in_event: bool, mode: int, h: float, cx: list[float],
                 cv: list[float], x1: float, v1: float) -> None:
        self.t0, self.t1, self.ends_in_event = t0, t1, ends_in_event
        self.mode, self.h, self.cx, self.cv = mode, h, list(cx), list(cv)
        self.x1, self.v1 = x1, v1

    @classmethod
    def instant(cls, t0, mode, x0, v0):
        """A slip of zero length that ends in an event at once (it cannot leave ``v_rel = 0``)."""
        return cls(t0, t0, True, mode, 0.0, [x0], [v0], x0, v0)

    @classmethod
    def from_step(cls, t0, mode, step, ends_in_event, v_drive):
        v1 = v_drive if ends_in_event else step.v1
        return cls(t0, t0 + step.h, ends_in_event, mode, step.h, step.cx, step.cv, step.x1, v1)

    def state(self, t: float) -> tuple[float, float]:
        if t == self.t1:
            return self.x1, self.v1
        theta = (t - self.t0) / self.h
        return poly.evaluate_pair(self.cx, self.cv, theta)

    def t_stick(self, t):
        return 0.0

    def end_state(self):
        return self.x1, self.v1

    def to_list(self):
        return [self.KIND, self.t0, self.t1, self.ends_in_event, self.mode, self.h, self.cx, self.cv, self.x1, self.v1]


def segment_from_list(values, p):
    """Rebuild a segment from :meth:`to_list` output."""
    kind, *fields = values
    if kind == StuckSegment.KIND:
        return StuckSegment(*fields)
    if kind == HarmonicSegment.KIND:
        return HarmonicSegment(*fields, p)
    if kind == StepSegment.KIND:
        return StepSegment(*fields)
    raise ValueError(f"unknown segment kind {kind!r} in a saved trajectory state")
