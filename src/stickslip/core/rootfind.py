"""Bracketed scalar root finding (Brent's method), pure Python."""

from __future__ import annotations  # annotations stay unevaluated: the FMU runs on CPython 3.8+

import math
from typing import Callable


def brent(f: Callable[[float], float], a: float, b: float, fa: float | None = None, fb: float | None = None,
          xtol: float = 0.0, max_iter: int = 200) -> float:
    """A root of ``f`` in ``[a, b]`` where ``f(a)`` and ``f(b)`` differ in sign (or one is 0).

    Converges to ``|error| <= 4 eps |x| + xtol``; returns the end of the final
    bracket on which ``f`` has the sign of ``f(b)`` (the side reached *after*
    the root when ``a < b``), so that callers get a point past the crossing.
    """
    fa = f(a) if fa is None else fa
    fb = f(b) if fb is None else fb
    if fa == 0.0:
        return a
    if fb == 0.0:
        return b
    if (fa > 0.0) == (fb > 0.0):
        raise ValueError("brent: f(a) and f(b) must differ in sign")
    # c is the previous iterate; the root stays between b and c; b is the best guess.
    c, fc = a, fa
    d = e = b - a
    for _ in range(max_iter):
        if (fb > 0.0) == (fc > 0.0):
            c, fc = a, fa
            d = e = b - a
        if abs(fc) < abs(fb):
            a, fa = b, fb
            b, fb = c, fc
            c, fc = a, fa
        tol = 2.0 * 2.220446049250313e-16 * abs(b) + 0.5 * xtol
        m = 0.5 * (c - b)
        if abs(m) <= tol or fb == 0.0:
            return b
        if abs(e) >= tol and abs(fa) > abs(fb):
            s = fb / fa
            if a == c:
                p, q = 2.0 * m * s, 1.0 - s
            else:
                q, r = fa / fc, fb / fc
                p = s * (2.0 * m * q * (q - r) - (b - a) * (r - 1.0))
                q = (q - 1.0) * (r - 1.0) * (s - 1.0)
            if p > 0.0:
                q = -q
            else:
                p = -p
            if 2.0 * p < min(3.0 * m * q - abs(tol * q), abs(e * q)):
                e, d = d, p / q
            else:
                d = e = m
        else:
            d = e = m
        a, fa = b, fb
        b += d if abs(d) > tol else math.copysign(tol, m)
        fb = f(b)
    return b


def first_crossing(f: Callable[[float], float], a: float, b: float, fa: float, fb: float, xtol: float = 0.0) -> float:
    """Locate a sign change of ``f`` in ``[a, b]`` and return a point at or just past it.

    ``fa`` has the 'before' sign and ``fb`` the 'after' sign (or is 0). The
    result ``r`` satisfies ``f(r)`` has the 'after' sign or is 0, within the
    tolerance of :func:`brent`.
    """
    root = brent(f, a, b, fa, fb, xtol)
    fr = f(root)
    if fr != 0.0 and (fr > 0.0) == (fa > 0.0):
        # Brent stopped on the 'before' side: step to the other side of the bracket.
        step = 4.0 * 2.220446049250313e-16 * max(abs(root), 1e-300) + xtol
        direction = 1.0 if b > a else -1.0
        nudged = root + direction * step
        if (nudged - b) * direction > 0.0:
            nudged = b
        return nudged
    return root


def monotone_fall(f: Callable[[float], float], a: float, b: float, fa: float, fb: float,
                  after_start: bool) -> float | None:
    """Where ``f``, monotone on ``[a, b]``, falls from > 0 to <= 0 (:func:`first_crossing`), else None.

    With ``after_start`` (``a`` is an extremum past the start of what ``f`` measures), ``f(a) == 0`` and
    ``f(b) < 0`` give ``a``: ``f`` left 0 at the start and came back at ``a`` by less than rounding.
    """
    if fa > 0.0 and fb <= 0.0:
        return first_crossing(f, a, b, fa, fb)
    if after_start and fa == 0.0 and fb < 0.0:
        return a
    return None
