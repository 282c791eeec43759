"""First zero of a sampled function, robust against grazes between samples."""

import numpy as np
from scipy.optimize import brentq

_EPS = np.finfo(float).eps


def root(f, a, b):
    """A zero of ``f`` in ``[a, b]`` to machine precision, given a sign change there.

    If pointwise values contradict the samples in the last bit (no sign change
    left), ``b`` is returned: the zero is there to rounding.
    """
    fa, fb = f(a), f(b)
    if fb == 0.0 or fa * fb > 0.0:
        return b
    if fa == 0.0:
        return a
    return brentq(f, a, b, xtol=2.0 * _EPS * (abs(a) + abs(b)) + 1e-300, rtol=4.0 * _EPS, maxiter=500)


def first_zero(f, s, fs, df=None, dfs=None, rising=True):
    """First time in ``[s[0], s[-1]]`` at which ``f`` comes down to 0, or None.

    ``s`` are increasing sample times and ``fs = f(s) >= 0`` at ``s[0]``. With
    the derivative (``df`` callable, ``dfs = df(s)``) a dip between two positive
    samples (``df`` going from - to +) is located and counts if its minimum is
    <= 0: a graze is not stepped over. Without it, ``f`` must be monotonic
    between samples.

    If ``fs[0] == 0``, ``f`` is leaving 0 and a zero counts only after ``f`` has
    been positive; ``rising=True`` says it is known to rise (non-positive values
    before that are rounding; a maximum at or below 0 before any positive value,
    a rise smaller than rounding, is the zero), ``rising=False`` that a negative
    value means it never rose, so the zero is ``s[0]``.
    """
    start = 0
    if fs[0] <= 0.0:
        start, hit = _leave_zero(f, s, fs, df, dfs, rising)
        if start is None:
            return hit
    ends = fs[start + 1:] <= 0.0
    dips = np.zeros_like(ends) if dfs is None else (dfs[start:-1] < 0.0) & (dfs[start + 1:] > 0.0)
    for j in np.flatnonzero(ends | dips):
        a, b = s[start + j], s[start + j + 1]
        if ends[j]:
            return root(f, a, b)
        t_min = root(df, a, b)
        if f(t_min) <= 0.0:
            return root(f, a, t_min)
    return None


def _leave_zero(f, s, fs, df, dfs, rising):
    """Scan ``f`` leaving 0: ``(index of its first positive sample, None)`` or ``(None, zero or None)``."""
    positive = np.flatnonzero(fs[1:] > 0.0)
    last = positive[0] if positive.size else len(s) - 1  # intervals [s[i], s[i+1]] with fs[i+1] <= 0
    peaks = np.zeros(last, bool) if dfs is None else (dfs[:last] > 0.0) & (dfs[1:last + 1] <= 0.0)
    negative = np.zeros(last, bool) if rising else fs[1:last + 1] < 0.0
    for i in np.flatnonzero(peaks | negative):
        if peaks[i]:
            t_max = root(df, s[i], s[i + 1])
            if f(t_max) > 0.0:
                return None, root(f, t_max, s[i + 1])
            if rising:
                return None, t_max
        if negative[i]:
            return None, s[0]
    return (last + 1, None) if positive.size else (None, None)
