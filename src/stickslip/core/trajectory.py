"""The stepper's public face: a trajectory of the hybrid model that advances in time.

Usage (the whole contract the FMU slave and the Python API rely on)::

    traj = Trajectory(params, x0, v0, v_drive=0.1, F_ext=0.0, t0=0.0, rtol=1e-10)
    traj.set_inputs(v_drive, F_ext)   # inputs held constant from now on; no-op if unchanged
    traj.set_inputs(v_drive, F_ext, F_ext_rate)   # F_ext(t) = F_ext + F_ext_rate (t - traj.t) from now on
    traj.advance_to(t)                # t >= traj.t; processes every event up to and at t
    traj.communicate(t, h)            # a co-simulation step from t == traj.t by h >= 0; (x, v) after it
    traj.communicate_to_event(t, h)   # the same, stopping before the first event inside it: True if it did
    traj.apply_events()               # the events due at traj.t applied (after such a stop)
    xs, vs = traj.sample(times)       # advance_to each of the increasing times, collecting x and v
    traj.x, traj.v, traj.mode, ...    # state at traj.t (see the properties below)
    a, jerk = traj.acceleration()     # dv/dt and d2v/dt2 at traj.t (the FMI output derivatives)
    snap = traj.snapshot()            # JSON-serializable dict, exact floats
    traj = Trajectory.from_snapshot(params, snap)   # continues bit for bit (without the event record)
    state = traj.state()              # immutable tuple, nothing copied: cheap to take and to go back to
    traj.restore(state)               # back to it, bit for bit (another trajectory: Trajectory.resumed(state))

Internally the trajectory is a chain of segments (:mod:`.segments`): a stuck
phase or an affine slip (closed form, up to the next event), or one step of a
Runge-Kutta method with dense output. The current segment may reach beyond
``traj.t``; values at ``traj.t`` come from its closed form or dense output, so
the result at a time does not depend on how the caller slices time, only on
when the inputs change.

An external force that grows linearly, ``F_ext(t) = F_ext + F_ext_rate (t - t_f)``
from the time ``t_f`` it was set, is exact too: in the frame ``y = x - c (t - t_f)``,
``c = F_ext_rate / kappa``, the block obeys the model with the constant force
``F_ext`` on a surface moving at ``v_drive - c`` (the spring force ``kappa c (t - t_f)``
of the frame's drift cancels the force's growth; sliding speed, holding force and
indicators are the same in both frames). The segments run in that frame; ``x`` and
``v`` are turned back at the trajectory's surface. With no rate the frame is the
block's own and nothing is turned.
"""

from __future__ import annotations  # annotations stay unevaluated: the FMU runs on CPython 3.8+

import math
from typing import Final, Iterable

from . import saved_state
from .errors import ParameterError, SolverError, StateError
from .model import (
    STUCK,
    check_input_scales,
    check_inputs,
    check_rate_scale,
    check_scales,
    check_start_time,
    check_state,
    check_state_scales,
    force_resolution,
    friction_force,
    initial_mode,
    inputs_within_scales,
    state_within_scales,
    mode_after_input_change,
    mode_after_slip,
    slip_acceleration,
    slip_acceleration_slope,
    slip_departs,
    slip_direction,
    z_slip,
)
from .model import Parameters
from .numeric_slip import MEMO_SIZE, SlipStepper
from .ranges import ANY_FINITE, NON_NEGATIVE, Range, check
from .segments import HarmonicSegment, Segment, StepSegment, StuckSegment, segment_from_list
from .stuck import breakaway_delay

_RTOL_LOW: Final = 1e-14  # solver.rtol's bounds as floats: compiled code compares them natively
_RTOL_HIGH: Final = 1e-2
RTOL_RANGE: Final = Range(_RTOL_LOW, _RTOL_HIGH)
_MAX_EVENT_CHAIN = 100  # mode changes in a row without time advancing
_MAX_BURST: Final = 1000  # mode changes within _BURST_WINDOW time scales sqrt(M/kappa) (stick-slip has a few per period)
_BURST_WINDOW: Final = 1.0  # in units of sqrt(M/kappa)
_EPS: Final = 2.220446049250313e-16  # the spacing of floats at 1
_STEP_ROUNDING: Final = 8 * _EPS  # relative: a host sums the communication points its own way
_STUCK_HORIZON_PERIODS = 1e6  # an aging stick is searched for a breakaway this far ahead, then re-searched
MAX_SEGMENTS: Final = 1_000_000  # segments (events, closed-form phases, Runge-Kutta steps) in one advance_to
_SETTLE_SEGMENTS: Final = 1000  # segments within which a step beyond the time resolution must reach its last phase
SEGMENTS_RANGE = Range(1, None)

# The fields of :meth:`Trajectory.snapshot` and their kinds (:mod:`.saved_state`)
_SNAPSHOT_FIELDS = {"t": saved_state.REAL, "v_drive": saved_state.REAL, "F_ext": saved_state.REAL,
                    "F_ext_rate": saved_state.REAL, "frame_t": saved_state.REAL, "rtol": saved_state.REAL,
                    "counts": saved_state.NESTED, "burst": saved_state.NESTED, "t_last_event": saved_state.REAL,
                    "stepper": saved_state.NESTED, "segment": saved_state.NESTED}
_COUNT_FIELDS = tuple((name, saved_state.COUNT) for name in ("n_stick_events", "n_slip_events", "n_overshoots",
                                                               "chain"))
_BURST_FIELDS = (("start", saved_state.REAL), ("count", saved_state.COUNT))
_STEPPER_FIELDS = (("h", saved_state.OPTIONAL_STEP), ("stiff", saved_state.FLAG), ("votes", saved_state.COUNT),
                   ("n_steps", saved_state.COUNT), ("n_rejected", saved_state.COUNT))

# The properties that :meth:`Trajectory.outputs` returns, in its order.
OUTPUT_NAMES = (
    "x", "v", "v_rel", "friction_force", "spring_force", "mode", "t_stick", "z_slip", "z_stick", "n_events",
    "n_stick_events", "n_slip_events", "n_overshoots", "t_last_event", "n_steps",
)


class Trajectory:
    """Solution of the hybrid spring-block model with piecewise-constant inputs."""

    # typed, so that compiled code reads the state and calls the segment and the stepper natively
    params: Parameters
    rtol: float
    t: float  # s
    v_drive: float  # m/s
    F_ext: float  # N, at _frame_t
    F_ext_rate: float  # N/s: F_ext(t) = F_ext + F_ext_rate (t - _frame_t)
    n_stick_events: int
    n_slip_events: int
    n_overshoots: int
    t_last_event: float  # s
    events: list | None
    max_segments: int
    _last_time: float  # s: the largest |t| that floats resolve to the block's time scale
    _chain: int
    _burst_start: float  # s: the first mode change counted in _burst
    _burst: int
    _stepper: SlipStepper
    _segment: Segment
    _frame_t: float  # s: when the inputs were last set
    _drift: float  # m/s: F_ext_rate / kappa, the frame's speed; the segments give y = x - _drift (t - _frame_t)
    _v_frame: float  # m/s: v_drive - _drift, the surface's speed in that frame
    _x: float  # m: y at t
    _v: float  # m/s: dy/dt at t

    def __init__(self, params, x0, v0, v_drive=0.0, F_ext=0.0, t0=0.0, rtol=1e-10, record_events=False,
                 reuse_steps=True, max_segments=MAX_SEGMENTS, F_ext_rate=0.0):
        """``F_ext_rate`` (N/s): ``F_ext`` grows at this rate from ``t0`` on (see :meth:`set_inputs`).
        ``record_events``: keep every mode change as ``(t, mode_before, mode_after)`` in ``self.events``
        (memory grows with the run; otherwise ``self.events`` is None and only the counters are kept).
        ``reuse_steps``: replay remembered Runge-Kutta steps from bit-identical states (the same numbers,
        less work, see :class:`~.numeric_slip.SlipStepper`); False integrates every step.
        ``max_segments``: the most segments one :meth:`advance_to` goes through (a count, so that every call
        ends)."""
        params.check()
        check_state(x0, v0)
        check_inputs(v_drive, F_ext)
        drift = _checked_drift(F_ext_rate, params)
        check("solver.rtol", rtol, RTOL_RANGE)
        check("max_segments", max_segments, SEGMENTS_RANGE)
        check_scales(x0, v0, v_drive, F_ext, params, ("x_start", "v_start"))
        check_start_time("start time", t0, params)
        self.params = params
        self.rtol = float(rtol)
        self.t = float(t0)
        self.v_drive = float(v_drive)
        self.F_ext = float(F_ext)
        self.F_ext_rate = float(F_ext_rate)
        self._frame_t, self._drift, self._v_frame = self.t, drift, self.v_drive - drift
        self.n_stick_events = 0
        self.n_slip_events = 0
        self.n_overshoots = 0
        self.t_last_event = self.t  # the start time until the first event
        self.events = [] if record_events else None
        self.max_segments = int(max_segments)
        self._last_time = math.sqrt(params.M / params.kappa) / _EPS
        self._chain = 0
        self._burst_start, self._burst = self.t, 0
        self._stepper = SlipStepper(self.rtol, memo_size=MEMO_SIZE if reuse_steps else 0)
        mode = initial_mode(x0, v0, self.v_drive, self.F_ext, params)
        v_start = self._v_frame if mode == STUCK else float(v0) - drift
        self._segment = self._start_segment(self.t, float(x0), v_start, mode, 0.0)
        self._x, self._v = self._segment.state(self.t)

    # ------------------------------------------------------------------
    # driving
    # ------------------------------------------------------------------

    def set_inputs(self, v_drive, F_ext, F_ext_rate=0.0):
        """Hold ``v_drive`` (m/s) from ``self.t`` on, and ``F_ext`` (N) there, growing at ``F_ext_rate`` (N/s) from
        there; a stuck block moves with the new surface speed. A no-op where nothing changes. ParameterError naming
        the input and its range for one that is not finite or whose force scale overflows (the inputs kept)."""
        if self._holds_inputs(v_drive, F_ext, F_ext_rate):
            return
        check_inputs(v_drive, F_ext)
        check_input_scales(v_drive, F_ext, self.params)
        _checked_drift(F_ext_rate, self.params)
        self._take_inputs(v_drive, F_ext, F_ext_rate)

    def take_checked_inputs(self, v_drive, F_ext, F_ext_rate):
        """:meth:`set_inputs` for inputs that each passed :func:`.model.check_input` with :attr:`params` (a slave's
        inputs that its host's checks already bound): the same result, nothing checked again."""
        if not self._holds_inputs(v_drive, F_ext, F_ext_rate):
            self._take_inputs(v_drive, F_ext, F_ext_rate)

    def _holds_inputs(self, v_drive, F_ext, F_ext_rate) -> bool:
        """Whether the trajectory holds these inputs already from ``self.t`` on (see :meth:`set_inputs`)."""
        return v_drive == self.v_drive and F_ext_rate == self.F_ext_rate and F_ext == (
            self.F_ext if F_ext_rate == 0.0 else self.F_ext_now)

    def _take_inputs(self, v_drive, F_ext, F_ext_rate) -> None:
        """Hold the inputs of :meth:`set_inputs` from ``self.t`` on, their frame moving at :func:`_drift`."""
        drift = _drift(F_ext_rate, self.params)
        x, v = self.x, self.v
        segment = self._segment
        t_stick = segment.t_stick(self.t)
        old_mode = segment.mode
        v_frame = _frame_speed(v_drive, drift)
        new_mode = mode_after_input_change(old_mode, x, v, t_stick, v_drive, F_ext, self.params)
        self.v_drive, self.F_ext, self.F_ext_rate = float(v_drive), float(F_ext), float(F_ext_rate)
        self._frame_t, self._drift, self._v_frame = self.t, drift, v_frame
        if new_mode != old_mode:
            self._log_event(self.t, old_mode, new_mode)
        if new_mode != STUCK or old_mode != STUCK:
            t_stick = 0.0
        v_start = v_frame if new_mode == STUCK or old_mode == STUCK else v - drift
        self._segment = self._start_segment(self.t, x, v_start, new_mode, t_stick)
        self._x, self._v = self._segment.state(self.t)

    def advance_to(self, t: float) -> None:
        """Advance to time ``t >= self.t`` (s), through every event up to and at ``t``.

        Raises SolverError for an end time that is not finite, and after :attr:`max_segments` segments short of
        ``t``, or :data:`_SETTLE_SEGMENTS` where floats space times at ``t`` by more than the block's time scale
        ``sqrt(M/kappa)`` (there only a last phase that lasts, a rest or a stick without drive, can be followed).
        The trajectory then stays at the start of the segment reached, a valid state to go on from."""
        left = self._segments_allowed(t)
        end = float(t)
        while self._segment.t1 <= end:
            self._finish_segment()
            left -= 1
            if left == 0:
                self._stop_short(end)
        self.t = end
        self._x, self._v = self._segment.state(self.t)
        if not (_finite(self._x) and _finite(self._v)):
            raise SolverError(f"the state overflowed at t = {self.t!r} s (x = {self._x!r}, v = {self._v!r})")

    def _segments_allowed(self, t: float) -> int:
        """The most segments an advance to ``t`` (s) may go through (see :meth:`advance_to`); SolverError for an end
        time that is not finite or lies before ``self.t``."""
        left = self.max_segments
        if not abs(t) <= self._last_time:
            if not _finite(t):
                raise SolverError(f"cannot advance from t = {self.t!r} s to t = {t!r} s: the end time must be finite")
            left = min(left, _SETTLE_SEGMENTS)
        if not t >= self.t:
            raise SolverError(f"cannot advance from t = {self.t!r} s back to t = {t!r} s")
        return left

    def advance_to_event(self, t: float, at_end: bool = False) -> bool:
        """Advance towards ``t >= self.t`` (s) as :meth:`advance_to` does, but stop at the first event (stick,
        breakaway or overshoot) strictly between ``self.t`` and ``t``, or with ``at_end`` at ``t`` itself: True,
        ``self.t`` the event's time and the state its left limit (the mode before it, the event not yet applied:
        :meth:`apply_events` applies it, and so does any later advance). False if no such event lies there: then at
        ``t``, every event up to and at it applied. The segments are the same as :meth:`advance_to`'s, so stopping
        changes no result."""
        left = self._segments_allowed(t)
        start, end = self.t, float(t)
        while self._segment.t1 < end or (at_end and self._segment.t1 == end):
            segment = self._segment
            if segment.ends_in_event and segment.t1 > start:
                self.t = segment.t1
                self._x, self._v = segment.end_state()
                return True
            self._finish_segment()
            left -= 1
            if left == 0:
                self._stop_short(end)
        self.advance_to(end)
        return False

    def apply_events(self) -> None:
        """Apply every event due at ``self.t`` (after :meth:`advance_to_event` stopped at one): the mode after it."""
        self.advance_to(self.t)

    def _stop_short(self, end: float) -> None:
        """Stay at the start of the current segment and raise SolverError: the segments allowed to
        :meth:`advance_to` went by short of ``end`` (s)."""
        start = self.t
        self.t = self._segment.t0
        self._x, self._v = self._segment.state(self.t)
        stopped = f"stopped at t = {self.t!r} s after {self.n_events} events in all"
        if abs(end) > self._last_time:
            time_scale = math.sqrt(self.params.M / self.params.kappa)
            raise SolverError(
                f"cannot advance from t = {start!r} s to t = {end!r} s: time resolution lost: floats space times "
                f"there by {_EPS * abs(end):.3g} s, more than the block's time scale sqrt(M/kappa) = "
                f"{time_scale:.3g} s, and the block did not come to a lasting phase within "
                f"{min(self.max_segments, _SETTLE_SEGMENTS)} segments; {stopped}; allowed is |t| <= {self._last_time:.4g} s"
            )
        raise SolverError(
            f"cannot advance from t = {start!r} s to t = {end!r} s: the step would need more than "
            f"{self.max_segments} segments (events and integrator steps); {stopped}; take shorter steps (shorter "
            f"communication steps)"
        )

    def sample(self, times: Iterable[float]) -> tuple[list[float], list[float]]:
        """Advance through the increasing ``times`` (s); the lists of ``x`` (m) and ``v`` (m/s) there."""
        grid: list[float] = [float(t) for t in times]  # plain floats: numpy scalars would slow every step
        xs: list[float] = []
        vs: list[float] = []
        i, n = 0, len(grid)
        while i < n:
            t = grid[i]
            if self.t <= t < self._segment.t1:  # inside the current segment: no event, evaluate its points
                i = self._segment.fill(grid, i, xs, vs)
            else:
                self.advance_to(t)
                xs.append(self._x)
                vs.append(self._v)
                i += 1
        if xs:
            self.t, self._x, self._v = grid[-1], xs[-1], vs[-1]
        if self._drift != 0.0:
            xs, vs = self._unframed(grid, xs, vs)
        if not (all(map(math.isfinite, xs)) and all(map(math.isfinite, vs))):
            bad = next(i for i, (x, v) in enumerate(zip(xs, vs)) if not (math.isfinite(x) and math.isfinite(v)))
            raise SolverError(f"the state overflowed at t = {grid[bad]!r} s (x = {xs[bad]!r}, v = {vs[bad]!r})")
        return xs, vs

    def _unframed(self, grid: list[float], ys: list[float], dys: list[float]) -> tuple[list[float], list[float]]:
        """``x`` (m) and ``v`` (m/s) at the times ``grid`` (s) from the frame's ``y`` and ``dy/dt`` there."""
        drift, start = self._drift, self._frame_t
        return [y + drift * (t - start) for t, y in zip(grid, ys)], [dy + drift for dy in dys]

    def communicate(self, current_time: float, step_size: float) -> tuple[float, float]:
        """A co-simulation step (FMI doStep, inputs held): from ``current_time`` (s), which must be this
        trajectory's time (:func:`check_step`), to ``current_time + step_size`` (s); ``(x, v)`` after it (m, m/s),
        the first two :meth:`outputs`. The FMU's loader calls it directly, once per communication step, and asks
        for the other outputs only when a host reads one."""
        check_step(current_time, step_size, self.t)
        self.advance_to(current_time + step_size)
        if self._drift == 0.0:
            return self._x, self._v
        return self.x, self.v

    def communicate_to_event(self, current_time: float, step_size: float, at_end: bool = False) -> bool:
        """A co-simulation step as :meth:`communicate`, that stops at the first event inside it (FMI 3's early
        return), or with ``at_end`` also at one at its end (FMI 3's event mode): :meth:`advance_to_event` to
        ``current_time + step_size`` (s); True if it stopped at an event."""
        check_step(current_time, step_size, self.t)
        return self.advance_to_event(current_time + step_size, at_end)

    # ------------------------------------------------------------------
    # state and outputs at self.t
    # ------------------------------------------------------------------

    def outputs(self):
        """Every property named in :data:`OUTPUT_NAMES`, in that order, from one evaluation of the state."""
        segment, y, dy, F_ext, p = self._segment, self._x, self._v, self.F_ext, self.params
        mode = segment.mode
        t_stick = segment.t_stick(self.t)
        v_rel = 0.0 if mode == STUCK else self._v_frame - dy
        n_stick, n_slip, n_over = self.n_stick_events, self.n_slip_events, self.n_overshoots
        x = self.x
        return (
            x, self.v, v_rel, friction_force(mode, y, dy, self._v_frame, F_ext, p), -p.kappa * x, mode, t_stick,
            z_slip(y, F_ext, t_stick, p), v_rel, n_stick + n_slip + n_over, n_stick, n_slip, n_over,
            self.t_last_event, self._stepper.n_steps,
        )

    def acceleration(self) -> tuple[float, float]:
        """``(dv/dt, d2v/dt2)`` (m/s^2, m/s^3) at ``self.t``, in the mode there (after an event at ``self.t``): 0 and
        0 while stuck (the surface's speed is held); while slipping, SPEC's ``M dv/dt = F_ext - kappa x + F`` and
        its time derivative ``M d2v/dt2 = dF_ext/dt - kappa v + dF/dv_rel (-dv/dt)``."""
        mode = self._segment.mode
        if mode == STUCK:
            return 0.0, 0.0
        p = self.params
        a = slip_acceleration(mode, self._x, self._v, self._v_frame, self.F_ext, p)
        jerk = -p.kappa / p.M * self._v + slip_acceleration_slope(mode, self._v, self._v_frame, p) * a
        return a, jerk

    @property
    def F_ext_now(self) -> float:
        """The external force (N) at ``self.t``."""
        if self.F_ext_rate == 0.0:
            return self.F_ext
        return self.F_ext + self.F_ext_rate * (self.t - self._frame_t)

    @property
    def x(self) -> float:
        """Block position (m) from the spring's relaxed length."""
        if self._drift == 0.0:
            return self._x
        return self._x + self._drift * (self.t - self._frame_t)

    @property
    def v(self) -> float:
        """Block velocity (m/s)."""
        if self._drift == 0.0:
            return self._v
        return self._v + self._drift

    @property
    def mode(self) -> int:
        """+1 slipping forward (v < v_drive), 0 stuck, -1 slipping backward."""
        return self._segment.mode

    @property
    def t_stick(self) -> float:
        """Time (s) since the current stick began; 0 while slipping."""
        return self._segment.t_stick(self.t)

    @property
    def v_rel(self) -> float:
        """Relative sliding velocity ``v_drive - v`` (m/s); exactly 0 while stuck."""
        return 0.0 if self.mode == STUCK else self._v_frame - self._v

    @property
    def friction_force(self) -> float:
        """Friction force of the surface on the block (N, + along x)."""
        return friction_force(self.mode, self._x, self._v, self._v_frame, self.F_ext, self.params)

    @property
    def spring_force(self) -> float:
        """Spring force on the block (N): ``-kappa x``."""
        return -self.params.kappa * self.x

    @property
    def z_slip(self) -> float:
        """Stick-to-slip indicator (N): ``F_S(t_stick) - |kappa x - F_ext|`` (the same in the frame)."""
        return z_slip(self._x, self.F_ext, self.t_stick, self.params)

    @property
    def z_stick(self) -> float:
        """Slip-to-stick indicator (m/s): ``v_rel``."""
        return self.v_rel

    @property
    def n_events(self) -> int:
        """Mode changes since the start."""
        return self.n_stick_events + self.n_slip_events + self.n_overshoots

    @property
    def n_steps(self) -> int:
        """Runge-Kutta steps taken (closed-form phases take none)."""
        return self._stepper.n_steps

    # ------------------------------------------------------------------
    # save and restore
    # ------------------------------------------------------------------

    def snapshot(self):
        """Everything needed to continue bit for bit, as JSON-serializable values."""
        return state_snapshot(self.state())

    def state(self) -> tuple:
        """Everything needed to continue bit for bit, as an immutable tuple that shares what never changes (the
        parameters, the current segment, the stepper's record of steps): taken and restored (:meth:`restore`)
        without copying or checking anything. :func:`state_snapshot` turns it into :meth:`snapshot`'s values."""
        events = -1 if self.events is None else len(self.events)
        stepper = self._stepper
        return (self, self.params, self.rtol, self.t, self.v_drive, self.F_ext, self.F_ext_rate, self._frame_t,
                self._drift, self._v_frame, self.n_stick_events, self.n_slip_events, self.n_overshoots, self._chain,
                self._burst_start, self._burst, self.t_last_event, self._segment, self._x, self._v, stepper.h,
                stepper.stiff, stepper.votes, stepper.n_steps, stepper.n_rejected, stepper.record, stepper.cursor,
                events)

    def restore(self, state: tuple) -> None:
        """Go back to a :meth:`state` of this trajectory (ValueError for one of another: :meth:`resumed`); the
        event record, if kept, loses the events after it."""
        if state[0] is not self:
            raise ValueError("Trajectory.restore takes a state of this trajectory; Trajectory.resumed(state) makes "
                             "a trajectory from another's")
        self._take(state, True)

    @classmethod
    def resumed(cls, state: tuple) -> Trajectory:
        """A new trajectory (no event record) that goes on from ``state``, a :meth:`state` of any trajectory."""
        traj = cls(state[1], 0.0, 0.0, rtol=state[2])  # at rest: every field is replaced below
        traj._take(state, False)
        return traj

    def _take(self, state: tuple, own: bool) -> None:
        """Every field from ``state`` (``own``: one of this trajectory, whose stepper's record it may share)."""
        (_, self.params, self.rtol, self.t, self.v_drive, self.F_ext, self.F_ext_rate, self._frame_t, self._drift,
         self._v_frame, self.n_stick_events, self.n_slip_events, self.n_overshoots, self._chain, self._burst_start,
         self._burst, self.t_last_event, self._segment, self._x, self._v, h, stiff, votes, n_steps, n_rejected, record,
         cursor, events) = state
        self._stepper.restore(h, stiff, votes, n_steps, n_rejected, record, cursor, own)
        if self.events is not None and events >= 0:
            del self.events[events:]

    @classmethod
    def from_snapshot(cls, params, snap):
        """Rebuild a trajectory saved by :meth:`snapshot` (with the same parameters).

        Every field is checked first (:mod:`.saved_state`, :func:`.segments.segment_from_list`, :func:`checked_state`):
        a missing, ill-typed or non-finite one, inputs or a state whose force scales overflow, or a segment that does
        not hold the saved time raise StateError or ParameterError naming it.
        """
        fields = saved_state.record("", snap, _SNAPSHOT_FIELDS)
        values = [fields[name] for name in ("t", "v_drive", "F_ext", "F_ext_rate", "frame_t", "rtol")]
        values += saved_state.sequence("counts", snap["counts"], _COUNT_FIELDS)
        values += saved_state.sequence("burst", snap["burst"], _BURST_FIELDS) + [fields["t_last_event"]]
        values += saved_state.sequence("stepper", snap["stepper"], _STEPPER_FIELDS)
        return cls.resumed(checked_state(params, segment_from_list(snap["segment"], params), *values))

    # ------------------------------------------------------------------
    # segments and transitions
    # ------------------------------------------------------------------

    def _finish_segment(self) -> None:
        """Move to the end of the current segment, apply its event, start the next one."""
        segment = self._segment
        t1 = segment.t1
        x1, v1 = segment.end_state()
        mode = segment.mode
        t_stick = segment.t_stick(t1)
        if segment.ends_in_event:
            p, v_drive, F_ext = self.params, self._v_frame, self.F_ext
            resolution = force_resolution(t1, x1, v_drive, F_ext, p)
            new_mode = (
                slip_direction(x1, v_drive, F_ext, p, resolution)
                if mode == STUCK
                else mode_after_slip(mode, x1, v_drive, F_ext, p, resolution)
            )
            self._check_chain(t1, segment.t0, new_mode)
            self._log_event(t1, mode, new_mode)
            mode, t_stick = new_mode, 0.0
        self._segment = self._start_segment(t1, x1, v1, mode, t_stick, continues=not segment.ends_in_event)

    def _start_segment(self, t0: float, x0: float, v0: float, mode: int, t_stick: float,
                       continues: bool = False) -> Segment:
        """The segment from ``(t0, x0, v0)`` in ``mode``; ``continues``: the phase goes on from the last one."""
        p = self.params
        if mode == STUCK:
            # a constant F_S gives the breakaway in closed form; an aging one is searched piecewise
            aging = not p.static.is_constant()
            horizon = _STUCK_HORIZON_PERIODS * math.sqrt(p.M / p.kappa) if aging else math.inf
            delay = breakaway_delay(x0, self._v_frame, self.F_ext, t_stick, p, horizon)
            replayable = p.kinetic.affine() is None  # the slip after it is numeric (see StuckSegment)
            if delay is not None:
                return StuckSegment(t0, delay, True, x0, self._v_frame, t_stick, replayable)
            return StuckSegment(t0, horizon, False, x0, self._v_frame, t_stick, replayable)
        v_frame = self._v_frame  # the surface's speed in the frame the segments run in
        if v0 == v_frame and not slip_departs(mode, x0, v_frame, self.F_ext, p,
                                              force_resolution(t0, x0, v_frame, self.F_ext, p)):
            return StepSegment.instant(t0, mode, x0, v0)  # v_rel cannot leave 0 this way: decide again now
        if p.kinetic.affine() is not None:
            return HarmonicSegment.start(t0, mode, x0, v0, v_frame, self.F_ext, p)
        if not continues:
            self._stepper.restart()
        step, ends_in_event = self._stepper.step(t0, x0, v0, mode, v_frame, self.F_ext, p)
        return StepSegment.from_step(t0, mode, step, ends_in_event, v_frame)

    def _log_event(self, t: float, old_mode: int, new_mode: int) -> None:
        self.t_last_event = t
        if self.events is not None:
            self.events.append((t, old_mode, new_mode))
        if new_mode == STUCK:
            self.n_stick_events += 1
        elif old_mode == STUCK:
            self.n_slip_events += 1
        else:
            self.n_overshoots += 1

    def _check_chain(self, t_event: float, t_segment_start: float, new_mode: int) -> None:
        """Guard against endless event chains (never hang): more than :data:`_MAX_EVENT_CHAIN` mode changes
        without time advancing, or more than :data:`_MAX_BURST` within :data:`_BURST_WINDOW` time scales."""
        time_scale = math.sqrt(self.params.M / self.params.kappa)  # s: 1/omega0, the slip's natural time
        if t_event - self._burst_start > _BURST_WINDOW * time_scale:
            self._burst_start, self._burst = t_event, 0
        self._burst += 1
        if self._burst > _MAX_BURST:
            raise SolverError(self._burst_message(t_event, time_scale))
        step = 1e-13 * max(time_scale, abs(t_event))
        if t_event - t_segment_start > step:
            self._chain = 0
            return
        self._chain += 1
        if self._chain > _MAX_EVENT_CHAIN:
            coarse = (f"; floats space times at t by {_EPS * abs(t_event):.3g} s, against the block's time scale "
                      f"sqrt(M/kappa) = {time_scale:.3g} s" if abs(t_event) > time_scale else "")
            raise SolverError(
                f"event chain at t = {t_event!r} s: more than {_MAX_EVENT_CHAIN} mode changes without time "
                f"advancing by {step:.3g} s (now entering mode {new_mode:+d}); the contact cannot decide between "
                f"sticking and slipping; check that F_K(0+) <= F_S(0) and the inputs{coarse}"
            )

    def _burst_message(self, t_event: float, time_scale: float) -> str:
        """Why more than :data:`_MAX_BURST` mode changes came within :data:`_BURST_WINDOW` time scales."""
        p = self.params
        speed = p.static.force(0.0) / math.sqrt(p.kappa * p.M)
        return (
            f"more than {_MAX_BURST} mode changes between t = {self._burst_start!r} s and {t_event!r} s (within "
            f"{_BURST_WINDOW:g} sqrt(M/kappa) = {_BURST_WINDOW * time_scale:.3g} s): the slips creep at velocities "
            f"below what the solver resolves, solver.rtol = {self.rtol:g} times the slip's velocity scale "
            f"F_S(0)/sqrt(kappa M) = {speed:.3g} m/s, so each one sticks again within a few steps; the kinetic law "
            f"is too steep for this tolerance ({p.kinetic.named_values()}): lower solver.rtol"
        )


def state_snapshot(state: tuple):
    """:meth:`Trajectory.snapshot`'s JSON-serializable values of a :meth:`Trajectory.state`."""
    (_, _, rtol, t, v_drive, F_ext, F_ext_rate, frame_t, _, _, n_stick, n_slip, n_over, chain, burst_start, burst,
     t_last_event, segment, _, _, h, stiff, votes, n_steps, n_rejected, _, _, _) = state
    return {
        "t": t,
        "v_drive": v_drive,
        "F_ext": F_ext,
        "F_ext_rate": F_ext_rate,
        "frame_t": frame_t,
        "rtol": rtol,
        "counts": [n_stick, n_slip, n_over, chain],
        "burst": [burst_start, burst],
        "t_last_event": t_last_event,
        "stepper": [h, stiff, votes, n_steps, n_rejected],
        "segment": segment.to_list(),
    }


#: The fields of a :meth:`Trajectory.state` that a saved state holds besides its segment, in one row: the values
#: :func:`state_fields` gives and :func:`checked_state` takes, with their kinds (:mod:`.saved_state`); the names are
#: those of :meth:`Trajectory.snapshot`'s (``counts.chain`` is the event chain's guard, ``burst`` the burst guard's)
STATE_FIELDS = (("t", saved_state.REAL), ("v_drive", saved_state.REAL), ("F_ext", saved_state.REAL),
                ("F_ext_rate", saved_state.REAL), ("frame_t", saved_state.REAL), ("rtol", saved_state.REAL),
                *((f"counts.{name}", kind) for name, kind in _COUNT_FIELDS),
                *((f"burst.{name}", kind) for name, kind in _BURST_FIELDS), ("t_last_event", saved_state.REAL),
                *((f"stepper.{name}", kind) for name, kind in _STEPPER_FIELDS))


#: What a :meth:`Trajectory.state` holds, item by item: the fields of :data:`STATE_FIELDS` by their names, the stepper's
#: record of steps and where the current slip is in it (:meth:`.SlipStepper.restore`) after its fields
STATE_LAYOUT = ("trajectory", "params", "rtol", "t", "v_drive", "F_ext", "F_ext_rate", "frame_t", "drift", "v_frame",
                *(name for name, _ in STATE_FIELDS[6:13]), "segment", "x", "v",
                *(name for name, _ in STATE_FIELDS[13:]), "stepper.record", "stepper.cursor", "events")
SEGMENT_PLACE = STATE_LAYOUT.index("segment")
#: where each value of :data:`STATE_FIELDS` lies in a :meth:`Trajectory.state` (a path of one index), in their order
STATE_PLACES = tuple((STATE_LAYOUT.index(name),) for name, _ in STATE_FIELDS)


def state_fields(state: tuple) -> tuple:
    """The values of :data:`STATE_FIELDS` of a :meth:`Trajectory.state`, in their order (those at
    :data:`STATE_PLACES`; its segment is ``state[SEGMENT_PLACE]``)."""
    return state[3:8] + (state[2],) + state[10:17] + state[20:25]


def checked_state(params: Parameters, segment: Segment, t, v_drive, F_ext, F_ext_rate, frame_t, rtol, n_stick,
                  n_slip, n_over, chain, burst_start, burst, t_last_event, h, stiff, votes, n_steps,
                  n_rejected) -> tuple:
    """A :meth:`Trajectory.state` (of no trajectory: :meth:`Trajectory.resumed` goes on from it) from a checked
    segment (:func:`.segments.checked_segment`) and the values of :data:`STATE_FIELDS`, each of its kind, saved under
    ``params``: StateError or ParameterError naming a value that no trajectory under ``params`` holds (a tolerance out
    of range, inputs or a state whose force scales overflow, a segment that does not hold the saved time). The values
    are placed in the state as they are (nothing boxed again, no list of them made); only what follows from them is
    made."""
    if not _saved_values_hold(params, segment, t, v_drive, F_ext, F_ext_rate, frame_t, rtol, t_last_event):
        if not _RTOL_LOW <= rtol <= _RTOL_HIGH:
            check("saved state rtol", rtol, RTOL_RANGE, error=StateError)
        check_input_scales(v_drive, F_ext, params)
        _checked_drift(F_ext_rate, params, StateError)
        raise StateError(f"saved state t = {t!r} s lies outside its segment [{segment.t0!r}, {segment.t1!r}] s "
                         f"or before its last event at {t_last_event!r} s or its inputs' time {frame_t!r} s")
    drift = _drift(F_ext_rate, params)
    v_frame = _frame_speed(v_drive, drift)
    x, v = segment.state(t)
    if not state_within_scales(x, v, params):
        if not (_finite(x) and _finite(v)):
            saved_state.field("x at t", x, saved_state.REAL)
            saved_state.field("v at t", v, saved_state.REAL)
        check_state_scales(x, v, params, ("saved state x", "saved state v"))
    return (None, params, rtol, t, v_drive, F_ext, F_ext_rate, frame_t, drift, v_frame, n_stick, n_slip, n_over,
            chain, burst_start, burst, t_last_event, segment, x, v, h, stiff, votes, n_steps, n_rejected, None, -1, -1)


def _saved_values_hold(p: Parameters, segment: Segment, t: float, v_drive: float, F_ext: float, F_ext_rate: float,
                       frame_t: float, rtol: float, t_last_event: float) -> bool:
    """Whether :func:`checked_state`'s checks of the saved values pass (the tolerance, the inputs' force scales, the
    segment holding ``t`` after the last event and the inputs' time), in native arithmetic: false for a NaN."""
    return (_RTOL_LOW <= rtol <= _RTOL_HIGH and inputs_within_scales(v_drive, F_ext, F_ext_rate, p)
            and segment.t0 <= t <= segment.t1 and t_last_event <= t and frame_t <= t)


def check_step(current_time: float, step_size: float, t: float) -> None:
    """Raise ParameterError unless ``currentCommunicationPoint`` and ``communicationStepSize`` (s) are finite, the
    step size is >= 0, and the step starts at the FMU's time ``t`` (s), the start time or the end of the last step,
    to rounding: a gap or an overlap between communication points is refused, not integrated through."""
    gap, allowed = abs(current_time - t), _STEP_ROUNDING * max(abs(current_time), abs(t))
    if step_size >= 0.0 and _finite(current_time + step_size) and gap <= allowed:
        return  # the usual step, in a few comparisons (this runs at every doStep)
    check("currentCommunicationPoint", current_time, ANY_FINITE, "s")
    check("communicationStepSize", step_size, NON_NEGATIVE, "s")
    if gap > allowed:
        kind = "a gap" if current_time > t else "an overlap"
        raise ParameterError(
            f"currentCommunicationPoint = {current_time!r} s is not the FMU's time t = {t!r} s (the start time or "
            f"the end of the last step): {kind} of {abs(current_time - t):.6g} s between communication points; "
            f"a step starts where the last ended (restore a saved FMU state to go back)"
        )


def _checked_drift(F_ext_rate, p, error=ParameterError):
    """``F_ext_rate / kappa`` (m/s), the frame's speed for a growing ``F_ext`` (see the module's docstring), after
    checking the rate ``der(F_ext)`` (N/s): finite, and within the force scale over the block's time scale."""
    if not (isinstance(F_ext_rate, float) and _finite(F_ext_rate)):
        check("der(F_ext)", F_ext_rate, ANY_FINITE, "N/s", error=error)
    check_rate_scale(F_ext_rate, p)
    return _drift(F_ext_rate, p)


def _drift(F_ext_rate: float, p: Parameters) -> float:
    """``F_ext_rate / kappa`` (m/s): the frame's speed for ``F_ext`` growing at ``F_ext_rate`` (N/s)."""
    return F_ext_rate / p.kappa


def _frame_speed(v_drive: float, drift: float) -> float:
    """``v_drive - drift`` (m/s): the surface's speed in the frame that drifts at ``drift`` (m/s)."""
    return v_drive - drift


def _finite(value: float) -> bool:
    """``math.isfinite(value)`` as native float arithmetic in the compiled runtime (mypyc calls ``math.isfinite``
    as a Python function, boxing its argument): false for an infinity or NaN only."""
    return value - value == 0.0
