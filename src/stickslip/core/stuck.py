"""Stuck phases in closed form, and the breakaway time by root finding.

While stuck the block moves with the surface: ``x(t) = x0 + v_drive (t - t0)``,
``v = v_drive``, and the stick time grows as ``t_stick0 + (t - t0)``. The
breakaway comes at the first time where ``z_slip = F_S(t_stick) - |kappa x - F_ext|``
turns negative.
"""

import math

from .rootfind import first_crossing


def breakaway_delay(x0, v_drive, F_ext, t_stick0, p, horizon):
    """Delay (s) from the start of a stick to the breakaway, or None if none within ``horizon``.

    The holding force ``L(tau) = kappa (x0 + v_drive tau) - F_ext`` is linear,
    so ``h(tau) = F_S(t_stick0 + tau) - |L(tau)|`` is convex or concave between
    the kink of ``|L|`` and the convexity breaks of ``F_S``; on each such piece the
    first root is found exactly (no sampling), so a tangential dip is not missed.
    """
    kappa = p.kappa
    static = p.static
    L0 = kappa * x0 - F_ext
    dL = kappa * v_drive
    if static.is_constant():
        return _constant_law_delay(L0, dL, static.force(0.0), horizon)

    cuts = {0.0, horizon}
    if dL != 0.0:
        cuts.add(-L0 / dL)
    cuts.update(b - t_stick0 for b in static.convexity_breaks())
    cuts = sorted(c for c in cuts if 0.0 <= c <= horizon)
    for a, b in zip(cuts, cuts[1:]):
        # |L| = sign * L on the whole piece; its sign is read mid-piece, away from the kink's rounding
        sign = 1.0 if L0 + dL * 0.5 * (a + b) >= 0.0 else -1.0
        root = _first_root_on_piece(static, t_stick0, sign * L0, sign * dL, a, b)
        if root is not None:
            return root
    return None


def _constant_law_delay(L0, dL, F_S, horizon):
    """Breakaway delay for a constant ``F_S``: ``|L0 + dL tau|`` reaches ``F_S``."""
    if abs(L0) > F_S:
        return 0.0
    if dL == 0.0:
        return None
    delay = (math.copysign(F_S, dL) - L0) / dL
    return delay if delay <= horizon else None


def _first_root_on_piece(static, t_stick0, L0, dL, a, b):
    """First tau in [a, b] where ``h = F_S(t_stick0 + tau) - (L0 + dL tau)`` turns negative.

    ``h`` is convex or concave on the piece, as ``F_S`` is.
    """

    def h(tau):
        return static.force(t_stick0 + tau) - (L0 + dL * tau)

    def dh(tau):
        return static.rate(t_stick0 + tau) - dL

    ha = h(a)
    if ha < 0.0:
        return a
    if static.curvature(t_stick0 + 0.5 * (a + b)) <= 0.0:
        hb = h(b)
        return first_crossing(h, a, b, ha, hb) if hb < 0.0 else None
    # Convex: h' increases; the minimum is at a, at b, or where h' = 0.
    da, db = dh(a), dh(b)
    if da >= 0.0:
        return None
    low = b
    if db > 0.0:
        low = first_crossing(dh, a, b, da, db)
    hlow = h(low)
    return first_crossing(h, a, low, ha, hlow) if hlow < 0.0 else None
