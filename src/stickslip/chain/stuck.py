"""Breakaway of a stuck block whose neighbours all stick (compiled kernels).

Such a block and its neighbours move with the surface, so its coupling force ``F_ext`` stays constant and
``kappa x - F_ext = h0 + kappa v_drive tau`` grows linearly with the delay ``tau`` (s). Under a constant static law it
breaks away when that reaches ``sign(v_drive) F_S``: a closed form. Under an aging law the first zero of
``z_slip(tau) = F_S(t_stick + tau) - |h0 + kappa v_drive tau|`` is searched on samples that include the law's
convexity break and the kink ``h = 0``, between which ``z_slip`` is convex or concave, so that a dip between
samples is seen in its rate.
"""

import math

from .arrays import KAPPA, SAMPLES, STA, T_STUCK, X_STUCK
from .events import first_zero, indicator
from .jit import njit
from .laws import static_bend, static_force
from .stepper import coupling_force


@njit
def constant_static(code, par, i):
    """Whether block ``i``'s static law ``code`` is a constant ``F0``."""
    return code == 1 or (code == 2 and par[i, STA + 1] == 0.0) or (code >= 3 and par[i, STA + 1] == par[i, STA])


@njit
def quiet_break(ch, bl, wk, vd, j, t, t_stop):
    """When (s, at or after ``t``) the stuck block ``j``, whose neighbours all stick, breaks away; inf if not before
    ``t_stop`` under an aging law, or never under a constant one."""
    par, law = ch
    mode, x, v, blk = bl
    value, rate = indicator(par, law, mode, blk, vd, x, v, j, t)
    if value < 0.0:
        return t  # held beyond F_S by rounding only: the contact gives way at once
    if constant_static(law[j, 1], par, j):
        if vd == 0.0:
            return math.inf
        h0 = par[j, KAPPA] * (blk[j, X_STUCK] + vd * (t - blk[j, T_STUCK]))
        h0 -= coupling_force(par, mode, blk, vd, x, j, t)
        F_S = static_force(law[j, 1], par, j, STA, 0.0)
        return t + max(0.0, (math.copysign(F_S, vd) - h0) / (par[j, KAPPA] * vd))
    if value == 0.0 and rate < 0.0:
        return t
    if t_stop <= t:
        return math.inf
    n = _aging_samples(ch, bl, wk, vd, j, t, t_stop)
    return first_zero(par, law, mode, x, v, blk, wk.fx, wk.fv, wk.sx, wk.sv, vd, j, t, t_stop - t, False, wk.smp, n,
                      rate > 0.0)


@njit
def _aging_samples(ch, bl, wk, vd, j, t, t_stop):
    """Fill the samples of ``z_slip`` of block ``j`` over ``[t, t_stop]``: a uniform grid with the law's convexity
    break and the kink inserted; returns the index of the last sample."""
    par, law = ch
    mode, x, v, blk = bl
    s = wk.smp[0]
    for k in range(SAMPLES + 1):
        s[k] = t + (t_stop - t) * k / SAMPLES
    s[SAMPLES] = t_stop
    n = SAMPLES
    kink = math.inf
    if vd != 0.0:
        here = blk[j, X_STUCK] + vd * (t - blk[j, T_STUCK])
        kink = t + (coupling_force(par, mode, blk, vd, x, j, t) / par[j, KAPPA] - here) / vd
    for when in (blk[j, T_STUCK] + static_bend(law[j, 1], par, j, STA), kink):
        if t < when < t_stop:
            n += 1
            k = n
            while s[k - 1] > when:
                s[k] = s[k - 1]
                k -= 1
            s[k] = when
    for k in range(n + 1):
        wk.smp[1, k], wk.smp[2, k] = indicator(par, law, mode, blk, vd, x, v, j, s[k])
    return n
