"""The hybrid model in model-exchange form: states, derivatives, event indicators, discrete update.

For a host that integrates the block with its own ODE solver and locates the
events with its own sign-based root finder (FMI 3 model exchange). Every law,
force and transition comes from :mod:`.model`; this module only holds the
discrete state between the host's calls.

- Continuous states ``x`` (m) and ``v`` (m/s). Stuck: ``x' = v_drive``,
  ``v' = 0`` (the block moves with the surface: ``v`` reads ``v_drive``);
  slipping in mode ``m``: ``x' = v``, ``v' = a`` (:func:`.model.slip_acceleration`).
  The stick time is no state: ``t_stick = t - t_stuck``, exact for any solver.
- Event indicators, each positive while the current mode lasts (``INACTIVE``
  in the modes where it does not apply), zero at the event:

  ``stick`` (m/s)      slipping: ``m v_rel``, zero when the slip reaches ``v_rel = 0``;
  ``breakaway`` (N)    stuck: ``z_slip = F_S(t_stick) - |kappa x - F_ext|``;
  ``graze`` (m/s^2)    slipping: ``m dv_rel/dt = -m a``, zero at each extremum
                       of ``v_rel``: a sign-based locator sees a dip of
                       ``m v_rel`` to or below zero that starts and ends inside
                       one solver step (it changes no sign at the step's ends)
                       because the extremum between them changes this sign.
                       Stuck phases have none: with constant inputs ``z_slip``
                       can dip below zero and back only where ``F_S`` is convex
                       (saturating with F_inf < F0, parts of sigmoid), see docs/fmi3.md.

  An indicator reads exactly zero only where the event update acts on it (it
  changes the mode there). Where the update would leave the mode as it is,
  a zero reads ``LEAVING`` times the indicator's nominal instead, with the sign
  the indicator has just after (positive where that is unknown): a slip that
  leaves ``v_rel = 0`` (right after a breakaway or an overshoot), a stick whose
  ``z_slip`` touches 0 and rises, an extremum of ``v_rel`` (and steady sliding,
  where ``a`` settles on 0 to rounding). So the Reference-FMUs' BouncingBall
  lifts its height to DBL_MIN after a bounce: an indicator on its zero where
  nothing happens would be a root that does not go away (CVode, evaluating it
  again just after, stops: "root found at and very near t"). An arrival's zero
  is located where it is.

- :meth:`ExchangeBlock.update` is the event update: a stuck block breaks away
  when ``z_slip < 0``, or when ``z_slip = 0`` exactly and falling (the
  runtime's breakaway delay is 0: a host's locator that stopped on the zero
  would see no sign change after it); a slip that reached ``v_rel = 0`` sticks or overshoots
  (:func:`.model.mode_at_zero_v_rel`, with ``v`` set to ``v_drive``, the
  event's point; a slip leaving ``v_rel = 0`` has not reached it, so an update
  repeated with nothing changed changes nothing); an input jump acts as in :meth:`.trajectory.Trajectory.set_inputs`
  (:func:`.model.mode_after_input_change`). Inputs are expected to change
  at events (piecewise constant, as FMPy applies a table with steps); any input
  change since the last update counts as a jump at it.
"""

import math
import operator

from . import saved_state
from .errors import ParameterError, StateError
from .model import (
    STUCK,
    breakaway_direction,
    check_input_scales,
    check_inputs,
    check_scales,
    check_start_time,
    check_state,
    check_state_scales,
    friction_force,
    initial_mode,
    mode_after_input_change,
    mode_at_zero_v_rel,
    slip_acceleration,
    slip_departs,
    stuck_or_breakaway,
    z_slip,
)
from .ranges import ANY_FINITE, check
from .stuck import breakaway_delay
from .trajectory import OUTPUT_NAMES

INACTIVE = 1.0  # value of an event indicator in the modes where it does not apply (never crosses zero)
LEAVING = 2.0 ** -52  # of an indicator's nominal: its value at a zero where the mode lasts (module docstring)
INDICATORS = ("stick", "breakaway", "graze")


class ExchangeBlock:
    """The block's discrete state between a host's solver calls, and what the host reads from it.

    The host sets ``t`` (s), the inputs ``v_drive`` (m/s) and ``F_ext`` (N), and the continuous states
    with :meth:`set_states`; it reads :meth:`states`, :meth:`derivatives`, :meth:`indicators` and the
    outputs under the names :class:`~.trajectory.Trajectory` uses.
    """

    def __init__(self, params, x0, v0, v_drive=0.0, F_ext=0.0, t0=0.0):
        params.check()
        check_state(x0, v0)
        check_inputs(v_drive, F_ext)
        check_scales(x0, v0, v_drive, F_ext, params, ("x_start", "v_start"))
        check_start_time("start time", t0, params)
        self.params = params
        self.t = float(t0)
        self.v_drive, self.F_ext = float(v_drive), float(F_ext)
        self.mode = initial_mode(x0, v0, self.v_drive, self.F_ext, params)
        self._x, self._v = float(x0), float(v0)
        self.t_stuck = self.t if self.mode == STUCK else None  # when the current stick began
        self.n_stick_events = self.n_slip_events = self.n_overshoots = 0
        self.t_last_event = self.t
        self._inputs = (self.v_drive, self.F_ext)  # at the last update: a change since is an input jump

    # ---- continuous part -------------------------------------------------------

    def set_time(self, t):
        """The host's time ``t`` (s). ParameterError (the time kept) for a non-finite one, or one before the
        current stick began: the stick time ``t - t_stuck`` would be negative, a state the block never had."""
        t = float(t)
        check("time", t, ANY_FINITE, "s")
        if self.t_stuck is not None and t < self.t_stuck:
            raise ParameterError(
                f"time = {t!r} s is before the current stick began at t = {self.t_stuck!r} s: the block's state "
                f"there is not known (a host goes back past an event by restoring a saved FMU state)"
            )
        self.t = t

    def states(self):
        """``[x, v]`` (m, m/s)."""
        return [self._x, self.v]

    def set_states(self, x, v):
        """The host's states; while stuck ``v`` is the surface's, whatever the host holds. ParameterError (the
        states kept) for a non-finite one, or one whose force scale overflows: no NaN enters the model."""
        x, v = float(x), float(v)
        check_state(x, v, ("x", "v"))
        check_state_scales(x, v, self.params)
        self._x, self._v = x, v

    def set_inputs(self, v_drive, F_ext):
        """The host's inputs ``v_drive`` (m/s) and ``F_ext`` (N), checked as the co-simulation checks them
        (:meth:`.trajectory.Trajectory.set_inputs`): ParameterError naming the input and its range (the inputs
        kept) for a non-finite one or one whose force scale overflows. The event update applies a change."""
        v_drive, F_ext = float(v_drive), float(F_ext)
        check_inputs(v_drive, F_ext)
        check_input_scales(v_drive, F_ext, self.params)
        self.v_drive, self.F_ext = v_drive, F_ext

    def take_checked_input(self, name, value):
        """The input ``name`` ("v_drive" in m/s or "F_ext" in N) set to ``value``, which passed
        :func:`.model.check_input` with :attr:`params` (a slave's input that its host's checks already bound): nothing
        checked again, the other input held as it is."""
        if name == "v_drive":
            self.v_drive = float(value)
        else:
            self.F_ext = float(value)

    def nominals(self):
        """Scales of ``x`` and ``v`` (m, m/s): ``F_S(0)/kappa`` and ``F_S(0)/sqrt(kappa M)``, the stick-slip
        amplitude and the slip's speed scale, so a host's absolute tolerance is relative to them."""
        p = self.params
        force = p.static.force(0.0)
        return [force / p.kappa, force / (math.sqrt(p.kappa) * math.sqrt(p.M))]

    def derivatives(self):
        """``[x', v']`` (m/s, m/s^2) in the current mode."""
        if self.mode == STUCK:
            return [self.v_drive, 0.0]
        return [self._v, slip_acceleration(self.mode, self._x, self._v, self.v_drive, self.F_ext, self.params)]

    def indicators(self):
        """``[stick, breakaway, graze]`` (m/s, N, m/s^2), see the module docstring: exactly zero only where
        :meth:`update` would change the mode."""
        if self.mode == STUCK:
            values = [INACTIVE, self.z_slip, INACTIVE]
        else:
            accel = slip_acceleration(self.mode, self._x, self._v, self.v_drive, self.F_ext, self.params)
            values = [self.mode * (self.v_drive - self._v), INACTIVE, -self.mode * accel]
        if 0.0 not in values or self._transition()[0] != self.mode:
            return values
        return [value if value != 0.0 else LEAVING * self._sign_after(k) * nominal
                for k, (value, nominal) in enumerate(zip(values, self._indicator_nominals()))]

    def _indicator_nominals(self):
        """Scales of the indicators (m/s, N, m/s^2): the speed nominal, ``F_S(0)`` and ``F_S(0)/M``."""
        force = self.params.static.force(0.0)
        return [self.nominals()[1], force, force / self.params.M]

    def _sign_after(self, k):
        """+1 or -1: the sign indicator ``k`` takes just after a zero where the mode lasts. A stick indicator
        there belongs to a slip that leaves ``v_rel = 0``, a breakaway indicator to a ``z_slip`` that does not
        fall (both positive after); the graze indicator ``-m a`` at ``a = 0`` moves as ``m kappa v / M``, and
        at rest too (steady sliding settled to rounding) it takes +1."""
        return -1.0 if k == 2 and self.mode * self._v < 0.0 else 1.0

    def _arrived(self):
        """True if a slip is at or past ``v_rel = 0`` and not leaving it (:func:`.model.slip_departs`)."""
        m_v_rel = self.mode * (self.v_drive - self._v)
        return m_v_rel < 0.0 or (m_v_rel == 0.0 and not slip_departs(self.mode, self._x, self.v_drive, self.F_ext,
                                                                        self.params))

    # ---- event update ------------------------------------------------------------

    def _transition(self):
        """``(mode, v)`` (m/s) that the event update at ``t`` with the current inputs gives, nothing changed."""
        p = self.params
        x, v_drive, F_ext = self._x, self.v_drive, self.F_ext
        old = self.mode
        if old == STUCK:
            new = stuck_or_breakaway(x, F_ext, self.t_stick, p)  # = mode_after_input_change for a stuck block
            if new == STUCK and breakaway_delay(x, v_drive, F_ext, self.t_stick, p, self._time_scale()) == 0.0:
                new = breakaway_direction(x, F_ext, p)  # z_slip = 0 and falling: the contact fails now
            return new, v_drive
        if (v_drive, F_ext) != self._inputs and old * (self._inputs[0] - self._v) > 0.0:  # the jump moved v_rel
            new = mode_after_input_change(old, x, self._v, 0.0, v_drive, F_ext, p)
            return new, (v_drive if new == STUCK else self._v)
        if self._arrived():  # the slip reached v_rel = 0: this is the event's point
            return mode_at_zero_v_rel(x, F_ext, p), v_drive
        return old, self._v

    def update(self):
        """Apply the transition due at ``t`` with the current inputs; True if the host must restart its solver
        from :meth:`states` (``valuesOfContinuousStatesChanged``): its ``v`` changed, or the mode did. At a mode
        change the derivatives jump, and a solver that goes on from its own history (fmusim's CVode does
        unless told) would keep the old mode's solution beyond the event, where it has already integrated."""
        old = self.mode
        new, v = self._transition()
        self._inputs = (self.v_drive, self.F_ext)
        changed = v != self._v or new != old
        self._v = v
        if new != old:
            self._log_event(old, new)
            self.mode = new
            self.t_stuck = self.t if new == STUCK else None
        return changed

    def _time_scale(self):
        """``sqrt(M / kappa)`` (s)."""
        return math.sqrt(self.params.M / self.params.kappa)

    def _log_event(self, old, new):
        self.t_last_event = self.t
        if new == STUCK:
            self.n_stick_events += 1
        elif old == STUCK:
            self.n_slip_events += 1
        else:
            self.n_overshoots += 1

    # ---- outputs (the names of Trajectory's) -------------------------------------

    @property
    def x(self):
        return self._x

    @property
    def v(self):
        return self.v_drive if self.mode == STUCK else self._v

    @property
    def v_rel(self):
        return 0.0 if self.mode == STUCK else self.v_drive - self._v

    @property
    def t_stick(self):
        return 0.0 if self.t_stuck is None else self.t - self.t_stuck

    @property
    def friction_force(self):
        return friction_force(self.mode, self._x, self.v, self.v_drive, self.F_ext, self.params)

    @property
    def spring_force(self):
        return -self.params.kappa * self._x

    @property
    def z_slip(self):
        return z_slip(self._x, self.F_ext, self.t_stick, self.params)

    @property
    def z_stick(self):
        return self.v_rel

    @property
    def n_events(self):
        return self.n_stick_events + self.n_slip_events + self.n_overshoots

    @property
    def n_steps(self):
        """The host's solver takes the steps: 0."""
        return 0

    def outputs(self):
        """Every output named in :data:`.trajectory.OUTPUT_NAMES`, in that order, as
        :meth:`.trajectory.Trajectory.outputs` gives them."""
        return tuple(getattr(self, name) for name in OUTPUT_NAMES)

    # ---- save and restore --------------------------------------------------------

    _SAVED = ("t", "v_drive", "F_ext", "mode", "_x", "_v", "t_stuck", "n_stick_events", "n_slip_events",
              "n_overshoots", "t_last_event", "_inputs")

    def state(self):
        """Every field, parameters included, as a dict that nothing changes (:meth:`restore`, :meth:`resumed`):
        taken and restored without checking anything."""
        return dict(self.__dict__)

    def restore(self, state):
        """Go back to a :meth:`state` (of this block or another)."""
        self.__dict__.update(state)

    @classmethod
    def resumed(cls, state):
        """A new block at a :meth:`state` (of any block)."""
        block = cls.__new__(cls)
        block.restore(state)
        return block

    @staticmethod
    def state_fields(state):
        """The values of :data:`STATE_FIELDS` of a :meth:`state`, in their order."""
        return _pick_saved(state) + state["_inputs"]

    @classmethod
    def checked_state(cls, params, values):
        """A :meth:`state` from the values of :data:`STATE_FIELDS`, each of its kind, saved under ``params``:
        StateError or ParameterError naming a value that no block under ``params`` holds (inputs or a state beyond
        the force scales, a stick start with a slipping mode, times after ``t``)."""
        t, v_drive, F_ext, mode, x, v, t_stuck, _, _, _, t_last_event, input_v_drive, input_F_ext = values
        check_input_scales(v_drive, F_ext, params)
        check_input_scales(input_v_drive, input_F_ext, params)
        check_state_scales(x, v, params, ("saved state x", "saved state v"))
        stuck_since = t if t_stuck is None else t_stuck
        if (t_stuck is None) != (mode != STUCK) or max(stuck_since, t_last_event) > t:
            raise StateError(f"saved state t_stuck = {t_stuck!r} s, t_last_event = {t_last_event!r} s "
                             f"do not fit mode {mode} at t = {t!r} s")
        state = dict(zip(cls._SAVED[:-1], values))
        state["params"], state["_inputs"] = params, (input_v_drive, input_F_ext)
        return state


# The kinds of the fields of an ExchangeBlock.state that a saved state holds (:mod:`.saved_state`)
_SAVED_KINDS = {"t": saved_state.REAL, "v_drive": saved_state.REAL, "F_ext": saved_state.REAL,
                "mode": saved_state.MODE, "_x": saved_state.REAL, "_v": saved_state.REAL,
                "t_stuck": saved_state.OPTIONAL_REAL, "n_stick_events": saved_state.COUNT,
                "n_slip_events": saved_state.COUNT, "n_overshoots": saved_state.COUNT,
                "t_last_event": saved_state.REAL}
_INPUT_FIELDS = (("v_drive", saved_state.REAL), ("F_ext", saved_state.REAL))  # the inputs at the last update
_pick_saved = operator.itemgetter(*ExchangeBlock._SAVED[:-1])  # from a state, the saved fields but the inputs
#: The fields of an :meth:`ExchangeBlock.state` that a saved state holds, in one row (its inputs at the last update
#: last): the values :meth:`ExchangeBlock.state_fields` gives and :meth:`ExchangeBlock.checked_state` takes, with
#: their kinds
STATE_FIELDS = tuple((name, _SAVED_KINDS[name]) for name in ExchangeBlock._SAVED[:-1]) + tuple(
    (f"_inputs.{name}", kind) for name, kind in _INPUT_FIELDS)
