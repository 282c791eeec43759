"""The hybrid model's rules (SPEC section 1), written here independently of ``core.model``.

``x`` (m) from the spring's relaxed length, ``v`` (m/s), ``v_rel = v_drive - v``;
forces (N) positive along +x. Modes: +1 slipping with ``v < v_drive``, 0 stuck,
-1 slipping with ``v > v_drive``. ``p`` is a :class:`~.laws.ReferenceParameters`.
"""

import math

STUCK = 0
_EPS = 2.220446049250313e-16


def z_slip(p, x, F_ext, t_stick):
    """Holding margin (N): ``F_S(t_stick) - |kappa x - F_ext|``; the contact holds while >= 0."""
    return p.static.force(t_stick) - abs(p.kappa * x - F_ext)


def breakaway_mode(p, x, F_ext):
    """Slip direction when the contact gives way: +1 if ``F_ext - kappa x < 0`` else -1."""
    return 1 if F_ext - p.kappa * x < 0.0 else -1


def slip_mode(p, x, v_drive, F_ext, t):
    """Slip direction of a block at ``v_rel = 0`` at time ``t`` (s) that the contact does not hold:
    :func:`breakaway_mode`, unless that slip cannot leave ``v_rel = 0`` and the opposite one can
    (:func:`departure`): then the forces balance to rounding and the drive takes the block the other way."""
    mode = breakaway_mode(p, x, F_ext)
    if departure(p, mode, x, v_drive, F_ext, t) < 0 and departure(p, -mode, x, v_drive, F_ext, t) > 0:
        return -mode
    return mode


def hold_or_break(p, x, F_ext, t_stick, v_drive=0.0, t=0.0):
    """Mode of a block at ``v_rel = 0`` held for ``t_stick`` s: STUCK if the contact holds, else
    :func:`slip_mode` (``v_drive`` and the time ``t`` matter only where the forces balance to rounding)."""
    return STUCK if z_slip(p, x, F_ext, t_stick) >= 0.0 else slip_mode(p, x, v_drive, F_ext, t)


def initial_mode(p, x, v, v_drive, F_ext, t=0.0):
    """Mode at the start time ``t`` (s): stuck if ``v == v_drive`` and ``F_S(0)`` holds, else the sign of
    ``v_rel`` (``t`` matters only where the forces balance to rounding, see :func:`departure`)."""
    v_rel = v_drive - v
    if v_rel == 0.0:
        return hold_or_break(p, x, F_ext, 0.0, v_drive, t)
    return 1 if v_rel > 0.0 else -1


def mode_after_input(p, mode, x, v, t_stick, v_drive, F_ext, t):
    """Mode right after the inputs jump to ``(v_drive, F_ext)`` at time ``t`` (s).

    A stuck block moves on with the new surface speed and stays stuck while
    ``F_S(t_stick)`` holds; a slipping block keeps ``v`` and takes the sign of
    the new ``v_rel`` (at ``v_rel == 0`` the slip -> ``v_rel = 0`` rule applies).
    """
    if mode == STUCK:
        return hold_or_break(p, x, F_ext, t_stick, v_drive, t)
    return initial_mode(p, x, v, v_drive, F_ext, t)


def kinetic_force(p, u):
    """``F_K(u)`` (N) for ``u >= 0``; for ``u < 0`` its tangent at 0.

    Only a Runge-Kutta stage past a ``v_rel = 0`` crossing sees ``u < 0``; the
    C1 continuation keeps the step smooth and is never part of the solution.
    """
    if u >= 0.0:
        return p.kinetic.force(u)
    return p.kinetic.force(0.0) + p.kinetic.slope(0.0) * u


def acceleration(p, mode, x, v, v_drive, F_ext):
    """``dv/dt`` (m/s^2) while slipping in ``mode``: ``(F_ext - kappa x + mode F_K(mode v_rel)) / M``."""
    return (F_ext - p.kappa * x + mode * kinetic_force(p, mode * (v_drive - v))) / p.M


def departure(p, mode, x, v_drive, F_ext, t):
    """How ``e = mode * v_rel`` leaves 0 at the start of a slip with ``v = v_drive`` at time ``t`` (s).

    +1: ``e`` grows (a breakaway or overshoot start, not an event); -1: it does
    not, so ``v_rel = 0`` is reached at once. Decided by ``de/dt = -mode a``
    unless that is zero to rounding, then by ``d2e/dt2 = mode kappa v_drive / M``. Rounding is relative to
    the forces summed, to the spring force over the oscillation that brought the block to ``v_rel = 0``
    (``sqrt(kappa M) |v_drive|``) and to the spring force over the drive's travel since time 0
    (``kappa |v_drive t|``): they set how well ``x`` is known there.
    """
    a = acceleration(p, mode, x, v_drive, v_drive, F_ext)
    scale = max(abs(p.kappa * x), abs(F_ext), p.kinetic.force(0.0), p.static.force(0.0),
                math.sqrt(p.kappa * p.M) * abs(v_drive), p.kappa * abs(v_drive * t))
    if abs(p.M * a) > 16.0 * _EPS * scale:
        return 1 if -mode * a > 0.0 else -1
    return 1 if mode * v_drive > 0.0 else -1


def period(p):
    """Period (s) of the undamped spring-block oscillation, ``2 pi sqrt(M/kappa)``."""
    return 2.0 * math.pi * math.sqrt(p.M / p.kappa)
