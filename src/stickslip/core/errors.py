"""Errors raised by the runtime; each message names what went wrong and where."""


class StickSlipError(Exception):
    """Base class of every error this package raises on purpose."""


class ParameterError(StickSlipError, ValueError):
    """A parameter or input is outside its allowed range.

    The message names the variable (FMU name, e.g. ``kinetic.F0``), its value
    and the allowed range.
    """


class SolverError(StickSlipError, RuntimeError):
    """The integration cannot go on (event chain, step-size underflow, ...).

    The message names the simulation time and the cause.
    """


class StateError(StickSlipError, ValueError):
    """A saved state holds a field that is missing, of the wrong kind or out of range.

    The message names the field (e.g. ``saved state t``), its value and what is allowed.
    """
