"""Allowed ranges of parameters, and the checks that report a value outside them."""

import math

from .errors import ParameterError


class Range:
    """An interval of allowed real values, e.g. ``Range(0, None, low_open=True)`` for ``(0, inf)``.

    ``None`` for a bound means unbounded. Every value must be finite.
    """

    __slots__ = ("low", "high", "low_open", "high_open")

    def __init__(self, low=None, high=None, low_open=False, high_open=False):
        self.low = low
        self.high = high
        self.low_open = low_open
        self.high_open = high_open

    def contains(self, value):
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            return False
        if self.low is not None and (value < self.low or (self.low_open and value == self.low)):
            return False
        if self.high is not None and (value > self.high or (self.high_open and value == self.high)):
            return False
        return True

    def __str__(self):
        left = "(-inf" if self.low is None else ("(" if self.low_open else "[") + f"{self.low:g}"
        right = "inf)" if self.high is None else f"{self.high:g}" + (")" if self.high_open else "]")
        return f"{left}, {right}"


POSITIVE = Range(0.0, None, low_open=True)
NON_NEGATIVE = Range(0.0, None)
ANY_FINITE = Range()


def check(name, value, allowed, unit="", error=ParameterError):
    """Raise ``error`` (:class:`ParameterError`) naming ``name`` unless ``value`` lies in ``allowed``; ``unit``
    follows the value in the message ("" or "1": dimensionless, none)."""
    if not allowed.contains(value):
        unit_text = f" {unit}" if unit not in ("", "1") else ""
        raise error(
            f"{name} = {value!r}{unit_text} is out of range: allowed is a finite value in {allowed}"
        )
