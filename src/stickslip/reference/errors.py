"""Errors of the reference integrator (its own: it shares no code with ``stickslip.core``)."""


class ReferenceFailure(Exception):
    """Base class of every error the reference raises on purpose."""


class ReferenceParameterError(ReferenceFailure, ValueError):
    """A parameter, law or argument is outside its allowed range; the message names it and the range."""


class ReferenceSolverError(ReferenceFailure, RuntimeError):
    """The reference cannot go on (an event chain at one instant, a solver failure); names the time."""
