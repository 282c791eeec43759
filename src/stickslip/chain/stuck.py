"""Breakaway of a stuck block whose neighbours all stick (compiled kernels).

Such a block and its neighbours move with the surface, so its coupling force ``F_ext`` stays constant and
``kappa x - F_ext = h0 + kappa v_drive tau`` grows linearly with the delay ``tau`` (s). Under a constant static law it
breaks away when that reaches ``sign(v_drive) F_S``: a closed form. Under an aging law the first zero of
``z_slip(tau) = F_S(t_stick + tau) - |h0 + kappa v_drive tau|`` is searched on samples that include the law's
convexity break and the kink ``h = 0``, between which ``z_slip`` is convex or concave, so that a dip between
samples is seen in its rate.
"""

import math

from .arrays import SAMPLES
from .events import first_zero, indicator
from .jit import njit
from .laws import static_bend, static_force
from .stepper import coupling_force


@njit
def constant_static(code, p):
    """Whether the static law ``code`` with the row ``p`` is a constant ``F0``."""
    return code == 1 or (code == 2 and p[1] == 0.0) or (code >= 3 and p[1] == p[0])


@njit
def quiet_break(ch, bl, wk, j, t, t_stop):
    """When (s, at or after ``t``) the stuck block ``j``, whose neighbours all stick, breaks away; inf if not before
    ``t_stop`` under an aging law, or never under a constant one."""
    value, rate = indicator(ch, bl, j, t, bl.x, bl.v)
    if value < 0.0:
        return t  # held beyond F_S by rounding only: the contact gives way at once
    if constant_static(ch.sta_law[j], ch.sta[j]):
        if ch.v_drive == 0.0:
            return math.inf
        h0 = ch.kappa[j] * (bl.x_stuck[j] + ch.v_drive * (t - bl.t_stuck[j])) - coupling_force(ch, bl, bl.x, j, t)
        F_S = static_force(ch.sta_law[j], ch.sta[j], 0.0)
        return t + max(0.0, (math.copysign(F_S, ch.v_drive) - h0) / (ch.kappa[j] * ch.v_drive))
    if value == 0.0 and rate < 0.0:
        return t
    if t_stop <= t:
        return math.inf
    n = _aging_samples(ch, bl, wk, j, t, t_stop)
    return first_zero(ch, bl, wk, j, t, t_stop - t, False, n, rate > 0.0)


@njit
def _aging_samples(ch, bl, wk, j, t, t_stop):
    """Fill the samples of ``z_slip`` of block ``j`` over ``[t, t_stop]``: a uniform grid with the law's convexity
    break and the kink inserted; returns the index of the last sample."""
    s = wk.sample_t
    for k in range(SAMPLES + 1):
        s[k] = t + (t_stop - t) * k / SAMPLES
    s[SAMPLES] = t_stop
    n = SAMPLES
    special = (bl.t_stuck[j] + static_bend(ch.sta_law[j], ch.sta[j]), math.inf)
    if ch.v_drive != 0.0:
        x = bl.x_stuck[j] + ch.v_drive * (t - bl.t_stuck[j])
        special = (special[0], t + (coupling_force(ch, bl, bl.x, j, t) / ch.kappa[j] - x) / ch.v_drive)
    for when in special:
        if t < when < t_stop:
            n += 1
            k = n
            while s[k - 1] > when:
                s[k] = s[k - 1]
                k -= 1
            s[k] = when
    for k in range(n + 1):
        wk.sample_f[k], wk.sample_d[k] = indicator(ch, bl, j, s[k], bl.x, bl.v)
    return n
