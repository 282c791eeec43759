"""The hybrid spring-block model (SPEC section 1) as pure functions of state and parameters.

Sign conventions: ``x`` (m) is the block position from the spring's relaxed
length, ``v = dx/dt`` (m/s); the surface moves at ``v_drive``; the relative
sliding velocity is ``v_rel = v_drive - v``. Forces (N) are positive along +x.
``F_ext`` acts on the block; the spring force on the block is ``-kappa x``;
``F_f`` is the friction force of the surface on the block.

Modes follow Modelica's ``PartialFriction``: FORWARD (+1, the surface drags the
block forward, ``v < v_drive``), STUCK (0) and BACKWARD (-1, the block overtakes
the surface). Transitions are decided from the previous mode.
"""

from __future__ import annotations  # annotations stay unevaluated: the FMU runs on CPython 3.8+

import math
from typing import Final

from .errors import ParameterError
from .laws import KineticLaw, StaticLaw, check_pair
from .ranges import ANY_FINITE, POSITIVE, check

FORWARD = 1
STUCK = 0
BACKWARD = -1
_EPS: Final = 2.220446049250313e-16  # the spacing of floats at 1


class Parameters:
    """Mass ``M`` (kg), stiffness ``kappa`` (N/m) and the two friction laws."""

    __slots__ = ("M", "kappa", "kinetic", "static")
    M: float
    kappa: float
    kinetic: KineticLaw
    static: StaticLaw

    def __init__(self, M: float, kappa: float, kinetic: KineticLaw, static: StaticLaw) -> None:
        self.M = float(M)
        self.kappa = float(kappa)
        self.kinetic = kinetic
        self.static = static

    def __reduce__(self):  # pickling (process pools, dask); compiled classes have no default
        return Parameters, (self.M, self.kappa, self.kinetic, self.static)

    def check(self):
        """Raise ParameterError naming the first parameter outside its range."""
        check("M", self.M, POSITIVE, "kg")
        check("kappa", self.kappa, POSITIVE, "N/m")
        check_pair(self.kinetic, self.static)

    def __repr__(self):
        return f"Parameters(M={self.M!r}, kappa={self.kappa!r}, kinetic={self.kinetic!r}, static={self.static!r})"


def check_inputs(v_drive, F_ext):
    """Raise ParameterError unless both inputs are finite."""
    check("v_drive", v_drive, ANY_FINITE, "m/s")
    check("F_ext", F_ext, ANY_FINITE, "N")


def check_state(x, v, names=("x_start", "v_start")):
    """Raise ParameterError, naming the state by ``names``, unless ``x`` (m) and ``v`` (m/s) are finite."""
    check(names[0], x, ANY_FINITE, "m")
    check(names[1], v, ANY_FINITE, "m/s")


MAX_FORCE_SCALE: Final = 1e150  # N: forces, and the products that build them, stay far from float overflow
OMEGA_SQUARED_RANGE = (1e-100, 1e100)  # 1/s^2: kappa / M, so sqrt(kappa/M) and its inverse are finite


def check_scales(x, v, v_drive, F_ext, p, state_names=("x", "v")):
    """Raise ParameterError if values that are each in range combine into forces or rates that overflow.

    Every force scale of the problem must be at most :data:`MAX_FORCE_SCALE`:
    those of the inputs (:func:`check_input_scales`), the laws' force parameters,
    ``F_S(0)``, ``kappa |x|`` and ``sqrt(kappa M) |v|`` (the spring force built
    over ``1/omega0`` at that speed); and ``kappa / M`` must lie in
    :data:`OMEGA_SQUARED_RANGE`. The message names the variables involved
    (the state by ``state_names``: ``("x_start", "v_start")`` at the start).
    """
    low, high = OMEGA_SQUARED_RANGE
    omega_squared = p.kappa / p.M
    if not low <= omega_squared <= high:
        raise ParameterError(
            f"kappa / M = {omega_squared!r} 1/s^2 (kappa = {p.kappa!r} N/m, M = {p.M!r} kg) is out of range: "
            f"allowed is [{low:g}, {high:g}] 1/s^2; rescale the units of time or mass"
        )
    check_input_scales(v_drive, F_ext, p)
    for prefix, law in (("kinetic", p.kinetic), ("static", p.static)):
        for name, value in law.parameters().items():
            if law.PARAMETERS[name][2] == "N":
                _check_force_scale(f"{prefix}.{name}", value, f"{prefix}.{name} = {value!r} N")
    _check_force_scale("F_S(0)", p.static.force(0.0), f"static law {p.static!r}")
    check_damping(p)
    check_state_scales(x, v, p, state_names)


MAX_DAMPING_RATIO = 1e7  # the steepest |F_K'| over 2 sqrt(kappa M)


def check_damping(p):
    """Raise ParameterError naming the kinetic law's parameters if its steepest slope ``|F_K'|``
    (:meth:`~.laws.KineticLaw.steepest_slope`) exceeds :data:`MAX_DAMPING_RATIO` times ``2 sqrt(kappa M)``.

    Beyond it a closed-form slip loses more than ``eps`` times the ratio to cancellation (its centre lies
    ``gamma v / kappa`` away), and a numeric slip creeps at ``(F_S - F_K)/|F_K'|``, below the velocities the
    solver resolves: it would stick and slip again every few steps without end.
    """
    limit = 2.0 * MAX_DAMPING_RATIO * _impedance(p)
    slope = p.kinetic.steepest_slope()
    if not slope <= limit:
        raise ParameterError(
            f"the {p.kinetic.NAME} law's steepest slope |F_K'| = {slope:.4g} N s/m ({p.kinetic.named_values()}; "
            f"kappa = {p.kappa!r} N/m, "
            f"M = {p.M!r} kg) is out of range: allowed is at most {MAX_DAMPING_RATIO:g} * 2 sqrt(kappa M) = "
            f"{limit:.4g} N s/m (a damping ratio of {MAX_DAMPING_RATIO:g})"
        )


def check_state_scales(x, v, p: Parameters, state_names=("x", "v")):
    """Raise ParameterError, naming the state by ``state_names``, if ``kappa |x|`` or ``sqrt(kappa M) |v|``
    exceeds :data:`MAX_FORCE_SCALE`."""
    if state_within_scales(x, v, p):
        return  # the usual case, without making the texts below (saved states are checked with this)
    x_name, v_name = state_names
    _check_force_scale(f"kappa * |{x_name}|", p.kappa * abs(x), f"kappa = {p.kappa!r} N/m, {x_name} = {x!r} m")
    _check_force_scale(f"sqrt(kappa M) * |{v_name}|", _impedance(p) * abs(v),
                       f"kappa = {p.kappa!r} N/m, M = {p.M!r} kg, {v_name} = {v!r} m/s")


def state_within_scales(x: float, v: float, p: Parameters) -> bool:
    """Whether :func:`check_state_scales` passes (false for an infinity or NaN), in native arithmetic."""
    return p.kappa * abs(x) <= MAX_FORCE_SCALE and _impedance(p) * abs(v) <= MAX_FORCE_SCALE


def check_input_scales(v_drive, F_ext, p: Parameters):
    """Raise ParameterError if ``|F_ext|`` or ``sqrt(kappa M) |v_drive|`` exceeds :data:`MAX_FORCE_SCALE`."""
    _check_force_input_scale(F_ext, p)
    _check_drive_scale(v_drive, p)


def _check_force_input_scale(F_ext, p: Parameters):
    """Raise ParameterError if ``|F_ext|`` (N) exceeds :data:`MAX_FORCE_SCALE`."""
    if abs(F_ext) <= MAX_FORCE_SCALE:
        return
    _check_force_scale("|F_ext|", abs(F_ext), f"F_ext = {F_ext!r} N")


def _check_drive_scale(v_drive, p: Parameters):
    """Raise ParameterError if ``sqrt(kappa M) |v_drive|`` (N; v_drive in m/s) exceeds :data:`MAX_FORCE_SCALE`."""
    if _impedance(p) * abs(v_drive) <= MAX_FORCE_SCALE:
        return
    _check_force_scale("sqrt(kappa M) * |v_drive|", _impedance(p) * abs(v_drive),
                       f"kappa = {p.kappa!r} N/m, M = {p.M!r} kg, v_drive = {v_drive!r} m/s")


def check_rate_scale(F_ext_rate, p: Parameters):
    """Raise ParameterError if ``sqrt(M/kappa) |der(F_ext)|``, the force a growing ``F_ext`` adds over the block's
    time scale, exceeds :data:`MAX_FORCE_SCALE`."""
    force = _rate_force(F_ext_rate, p)
    if force <= MAX_FORCE_SCALE:
        return
    _check_force_scale("sqrt(M/kappa) * |der(F_ext)|", force,
                       f"kappa = {p.kappa!r} N/m, M = {p.M!r} kg, der(F_ext) = {F_ext_rate!r} N/s")


def inputs_within_scales(v_drive: float, F_ext: float, F_ext_rate: float, p: Parameters) -> bool:
    """Whether :func:`check_input_scales` and :func:`check_rate_scale` pass (false for a NaN), in native arithmetic:
    the usual case of checks that run often (saved states)."""
    return (abs(F_ext) <= MAX_FORCE_SCALE and _impedance(p) * abs(v_drive) <= MAX_FORCE_SCALE
            and _rate_force(F_ext_rate, p) <= MAX_FORCE_SCALE)


def _rate_force(F_ext_rate: float, p: Parameters) -> float:
    """``sqrt(M/kappa) |der(F_ext)|`` (N): the force a growing ``F_ext`` (N/s) adds over the block's time scale."""
    return math.sqrt(p.M) / math.sqrt(p.kappa) * abs(F_ext_rate)


# unit and force-scale check of each input by its FMU name (check_input)
_INPUT_CHECKS = {"v_drive": ("m/s", _check_drive_scale), "F_ext": ("N", _check_force_input_scale),
                 "der(F_ext)": ("N/s", check_rate_scale)}


def check_input(name, value, p=None):
    """Raise ParameterError naming the input ``name`` ("v_drive" in m/s, "F_ext" in N, "der(F_ext)" in N/s) and its
    allowed range unless ``value`` is finite and, given the parameters ``p``, within its force scale
    (:func:`check_input_scales`, :func:`check_rate_scale`); without ``p`` (they may still change), finite."""
    unit, check_scale = _INPUT_CHECKS[name]
    check(name, value, ANY_FINITE, unit)
    if p is not None:
        check_scale(value, p)


TIME_RESOLUTION = 1e-8  # the coarsest spacing of floats allowed at a start time, in units of sqrt(M/kappa)


def check_start_time(name, t, p):
    """Raise ParameterError naming ``name`` unless the start time ``t`` (s) is finite and floats resolve it to
    :data:`TIME_RESOLUTION` of the block's time scale ``sqrt(M/kappa)`` (``|t| <= 4.5e7 sqrt(M/kappa)``).

    Events and steps are placed to the spacing of floats at ``t``: far beyond the bound that rounding alone moves
    the block (at 1e12 s with ``M = kappa = 1``, by 1e-5 m per event, 1.5e-3 m after a hundred) and stops the
    stepper (step size underflow, event chains). A run may go on past the bound (a saved state from there is
    taken back); it cannot start there.
    """
    check(name, t, ANY_FINITE, "s")
    time_scale = math.sqrt(p.M / p.kappa)
    bound = TIME_RESOLUTION * time_scale / _EPS
    if abs(t) > bound:
        raise ParameterError(
            f"{name} = {t!r} s is out of range: floats space times there by {_EPS * abs(t):.3g} s, coarser than "
            f"{TIME_RESOLUTION:g} sqrt(M/kappa) = {TIME_RESOLUTION * time_scale:.3g} s; allowed is |{name}| <= "
            f"{bound:.4g} s (move the time origin nearer)"
        )


def _impedance(p: Parameters) -> float:
    """``sqrt(kappa M)`` (N s/m), computed so that the product ``kappa M`` cannot overflow."""
    return math.sqrt(p.kappa) * math.sqrt(p.M)


def _check_force_scale(what, force, values):
    """Raise ParameterError naming ``what`` and the variables ``values`` (a text) unless
    ``force <= MAX_FORCE_SCALE``."""
    if not force <= MAX_FORCE_SCALE:
        raise ParameterError(
            f"the force scale {what} = {force!r} N ({values}) is out of range: allowed is at most "
            f"{MAX_FORCE_SCALE:g} N; rescale the units of force or length"
        )


def holding_force(x, F_ext, p):
    """Friction force (N) that holds a stuck block in place: ``kappa x - F_ext``."""
    return p.kappa * x - F_ext


class SlipAccelerator:
    """``a(x, v)`` (:meth:`at`): ``dv/dt`` (m/s^2) while slipping in ``mode`` with constant inputs.

    The kinetic law is continued below ``u = 0`` by its tangent there: Runge-Kutta stages next to
    a slip's end may probe ``u < 0`` slightly; the continuation is smooth, defined for every law,
    and never becomes part of the solution. The constants are bound once, so an integrator's many
    evaluations per step cost little more than the law's own.
    """

    __slots__ = ("law", "force0", "slope0", "mode", "v_drive", "F_ext", "kappa", "M")
    law: KineticLaw
    force0: float  # N: F_K(0)
    slope0: float  # N s/m: F_K'(0)
    mode: int
    v_drive: float
    F_ext: float
    kappa: float
    M: float

    def __init__(self, mode: int, v_drive: float, F_ext: float, p: Parameters) -> None:
        self.law, self.force0, self.slope0 = p.kinetic, p.kinetic.force(0.0), p.kinetic.slope(0.0)
        self.mode, self.v_drive, self.F_ext, self.kappa, self.M = mode, v_drive, F_ext, p.kappa, p.M

    def at(self, x: float, v: float) -> float:
        """``dv/dt`` (m/s^2) at position ``x`` (m) and velocity ``v`` (m/s)."""
        u = self.mode * (self.v_drive - v)
        force = self.law.force(u) if u >= 0.0 else self.force0 + self.slope0 * u
        return (self.F_ext - self.kappa * x + self.mode * force) / self.M


def slip_friction(mode: int, v_rel: float, p: Parameters) -> float:
    """Friction force (N) while slipping in ``mode`` (+1 or -1): ``mode * F_K(mode * v_rel)``, with ``F_K``
    continued below 0 as in :class:`SlipAccelerator`."""
    u = mode * v_rel
    law = p.kinetic
    return mode * (law.force(u) if u >= 0.0 else law.force(0.0) + law.slope(0.0) * u)


def slip_acceleration(mode: int, x: float, v: float, v_drive: float, F_ext: float, p: Parameters) -> float:
    """``dv/dt`` (m/s^2) while slipping in ``mode``."""
    return SlipAccelerator(mode, v_drive, F_ext, p).at(x, v)


def slip_acceleration_slope(mode: int, v: float, v_drive: float, p: Parameters) -> float:
    """``d(dv/dt)/dv`` (1/s) while slipping: ``-F_K'(mode * v_rel)/M`` (tangent-continued below 0)."""
    u = mode * (v_drive - v)
    return -p.kinetic.slope(0.0 if u < 0.0 else u) / p.M  # max(u, 0.0), without boxing in compiled code


def slip_departs(mode, x, v_drive, F_ext, p, resolution=0.0):
    """True if a slip in ``mode`` starting at ``v_rel = 0`` moves into its own side (``mode * v_rel > 0``).

    ``v_rel' = -a`` decides, the sign of the force ``M a = F_ext - kappa x + mode F_K(0+)``; where that force
    is within ``resolution`` (N, :func:`force_resolution`; 0: exactly 0) and ``v_drive != 0``,
    ``v_rel'' = kappa v_drive / M`` does: a block at a tangential return or a breakaway where ``F_K(0+)``
    balances the spring to rounding leaves ``v_rel = 0`` on the side the drive takes it (as Modelica's
    ``PartialFriction`` keeps a started slip while the force exceeds the kinetic friction).
    """
    force = F_ext - p.kappa * x + mode * p.kinetic.force(0.0)
    if (force > resolution or force < -resolution) or (force != 0.0 and v_drive == 0.0):
        return mode * force < 0.0
    return mode * v_drive > 0.0


def slip_direction(x, v_drive, F_ext, p, resolution=0.0):
    """Slip mode of a block at ``v_rel = 0`` that the contact does not hold.

    That of the net force without friction (:func:`breakaway_direction`), unless a slip that way cannot leave
    ``v_rel = 0`` and one the other way can (:func:`slip_departs` with ``resolution``): the force balance is
    then within rounding, and the block moves the way the drive takes it.
    """
    mode = breakaway_direction(x, F_ext, p)
    if slip_departs(mode, x, v_drive, F_ext, p, resolution) or not slip_departs(-mode, x, v_drive, F_ext, p,
                                                                                  resolution):
        return mode
    return -mode


_ROUNDING_ULPS: Final = 16.0  # rounding of a sum of forces, in units of eps times its terms


def force_resolution(t, x, v_drive, F_ext, p):
    """How closely (N) the stepper knows the force balance of a block at ``v_rel = 0`` at ``t`` (s) and ``x`` (m).

    The rounding of the forces summed (``kappa x``, ``F_ext``, ``F_K(0+)``, and the spring force over the
    oscillation ``sqrt(kappa M) |v_drive|`` that brought the block there), plus the change of the holding
    force ``kappa |v_drive|`` over one rounding of ``t``: a stick shorter than that ends where its start was.
    """
    terms = abs(p.kappa * x) + abs(F_ext) + p.kinetic.force(0.0) + _impedance(p) * abs(v_drive)
    return _EPS * (_ROUNDING_ULPS * terms + p.kappa * abs(v_drive) * abs(t))


def friction_force(mode, x, v, v_drive, F_ext, p):
    """Friction force on the block (N) in any mode."""
    if mode == STUCK:
        return holding_force(x, F_ext, p)
    return slip_friction(mode, v_drive - v, p)


def z_slip(x, F_ext, t_stick, p):
    """Stick-to-slip indicator (N): ``F_S(t_stick) - |kappa x - F_ext|``."""
    return p.static.force(t_stick) - abs(holding_force(x, F_ext, p))


def breakaway_direction(x, F_ext, p):
    """Slip mode when the contact cannot hold: +1 if ``F_ext - kappa x < 0`` else -1."""
    return FORWARD if F_ext - p.kappa * x < 0.0 else BACKWARD


def mode_at_zero_v_rel(x, F_ext, p, v_drive=0.0, resolution=0.0):
    """Mode when ``v_rel`` reaches 0 from slip: STUCK if ``F_S(0)`` holds, else overshoot
    (:func:`slip_direction`; with ``resolution`` 0 that of the net force, whatever ``v_drive``)."""
    if abs(holding_force(x, F_ext, p)) <= p.static.force(0.0):
        return STUCK
    return slip_direction(x, v_drive, F_ext, p, resolution)


def mode_after_slip(mode, x, v_drive, F_ext, p, resolution):
    """Mode when a slip in ``mode`` reaches ``v_rel = 0`` at ``x`` (:func:`mode_at_zero_v_rel`), decided from
    the previous mode as Modelica's ``PartialFriction`` does: a slip that would go on in its own mode touched
    ``v_rel = 0`` tangentially, where the holding force is ``F_K(0+) <= F_S(0)`` (above it only by rounding),
    so the block sticks, to break away at once if the holding force is at ``F_S``."""
    new_mode = mode_at_zero_v_rel(x, F_ext, p, v_drive, resolution)
    return STUCK if new_mode == mode else new_mode


def stuck_or_breakaway(x, F_ext, t_stick, p):
    """Mode of a block at ``v_rel = 0`` that has stuck for ``t_stick`` s: STUCK while ``z_slip >= 0``."""
    if z_slip(x, F_ext, t_stick, p) >= 0.0:
        return STUCK
    return breakaway_direction(x, F_ext, p)


def initial_mode(x, v, v_drive, F_ext, p):
    """Mode at the start: stuck if ``v == v_drive`` and the contact holds, else slipping."""
    v_rel = v_drive - v
    if v_rel == 0.0:
        return stuck_or_breakaway(x, F_ext, 0.0, p)
    return FORWARD if v_rel > 0.0 else BACKWARD


def mode_after_input_change(mode, x, v, t_stick, v_drive, F_ext, p):
    """Mode after the inputs jumped to ``(v_drive, F_ext)`` at fixed ``x``.

    A stuck block moves with the surface (``v`` becomes ``v_drive``) and stays
    stuck while the contact holds; a slipping block keeps its velocity, and its
    mode follows the sign of the new ``v_rel``.
    """
    if mode == STUCK:
        return stuck_or_breakaway(x, F_ext, t_stick, p)
    v_rel = v_drive - v
    if v_rel == 0.0:
        return mode_at_zero_v_rel(x, F_ext, p)
    return FORWARD if v_rel > 0.0 else BACKWARD

