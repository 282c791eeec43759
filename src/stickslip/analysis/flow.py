"""Batches of smooth slips: many independent slip phases integrated at once, with exact events.

Every tool of the analysis integrates the same thing many times: one slip
phase of the spring-block model in a fixed mode ``s`` (+1 or -1),

    M dv/dt = F_ext - kappa x + s F_K(s (v_drive - v)),   dx/dt = v,

from many starting points and drive velocities (a scan over ``v_drive``, a
grid of Poincare-section points, the slips of a stick-slip map). The slip is
smooth as long as ``s v_rel > 0``; past ``v_rel = 0`` it is continued smoothly
(``F_K`` by its tangent at 0), so grazing margins are continuous functions.

:func:`run` integrates a batch with the 8th-order Dormand-Prince method
(DOP853, the coefficients of :mod:`.dop853_tableau`), vectorized over the
batch with one adaptive step size per member, forward or backward in time.
Along the way it reports, exactly, the events every tool needs:

- ``"vmax"`` / ``"vmin"``: local extrema of ``v`` (zeros of the acceleration);
- ``"xmax"`` / ``"xmin"``: local extrema of ``x`` (zeros of ``v``);
- ``"cross"``: ``s v_rel`` falls to 0 (the end of the slip: stick or overshoot).

Steps are at most 1/16 of the undamped period, so a step holds at most one
extremum of ``v``; the extremum is located first, and between the step's ends
and the extremum ``v`` is monotonic, so every crossing of ``v = 0`` and of
``v = v_drive`` is bracketed exactly, however short the excursion (a graze is
never stepped over). Each event is refined by a safeguarded Newton iteration on
the length of a fresh DOP853 step from the start of the step (the event
function's time derivative is known in closed form), to rounding.
"""

import math
from dataclasses import dataclass, field

import numpy as np

from .dop853_tableau import A, B, E3, E5, N_STAGES
from .kinetic import Kinetic

_SAFETY, _MIN_FACTOR, _MAX_FACTOR = 0.9, 0.2, 10.0
_STEPS_PER_PERIOD = 16


@dataclass
class Record:
    """What happened to one member of a batch: its events and how its run ended.

    ``events`` is a list of ``(kind, t, x, v)`` in path order (``t`` is the
    time along the run: negative when integrating backward). ``reason`` is
    ``"cross"``, ``"policy"``, ``"time"``, ``"escape"``, ``"steps"`` or ``"fail"``
    (the step size collapsed: a non-finite state or right-hand side).
    """

    events: list = field(default_factory=list)
    t: float = 0.0
    x: float = math.nan
    v: float = math.nan
    reason: str = ""
    x_max: float = -math.inf
    x_min: float = math.inf
    v_max: float = -math.inf
    v_min: float = math.inf

    def values(self, kind):
        """``[(t, x, v), ...]`` of the events of one kind."""
        return [(t, x, v) for k, t, x, v in self.events if k == kind]


class System:
    """The slip dynamics of a batch: shared ``M``, ``kappa``, ``F_K``; per-member drive, force, mode, direction."""

    def __init__(self, kinetic, M, kappa, v_drive, F_ext, mode, direction, x_shift):
        self.kin = kinetic
        self.M, self.kappa = float(M), float(kappa)
        self.vd, self.fe, self.s = v_drive, F_ext, mode
        self.dirn, self.xs = direction, x_shift

    def take(self, index):
        return System(self.kin, self.M, self.kappa, self.vd[index], self.fe[index], self.s[index],
                      self.dirn[index], self.xs[index])

    def accel(self, y, v):
        """Physical acceleration ``dv/dt`` at shifted position ``y = x - x_shift``."""
        s = self.s
        return (self.fe - self.kappa * (y + self.xs) + s * self.kin.force(s * (self.vd - v))) / self.M

    def jerk(self, y, v, a):
        """``d^2v/dt^2 = -(kappa v + F_K'(s v_rel) a) / M``."""
        return -(self.kappa * v + self.kin.slope(self.s * (self.vd - v)) * a) / self.M

    def rhs(self, y, v):
        a = self.accel(y, v)
        return self.dirn * v, self.dirn * a


def _dop853(sys, y, v, fy, fv, h):
    """One DOP853 step of size ``h`` (array) for every member; returns the new state, slopes and K."""
    n = y.shape[0]
    Ky = np.empty((N_STAGES + 1, n))
    Kv = np.empty((N_STAGES + 1, n))
    Ky[0], Kv[0] = fy, fv
    for s in range(1, N_STAGES):
        a = A[s, :s]
        Ky[s], Kv[s] = sys.rhs(y + h * (a @ Ky[:s]), v + h * (a @ Kv[:s]))
    y1 = y + h * (B @ Ky[:N_STAGES])
    v1 = v + h * (B @ Kv[:N_STAGES])
    Ky[N_STAGES], Kv[N_STAGES] = sys.rhs(y1, v1)
    return y1, v1, Ky, Kv


def _error_norm(y, v, y1, v1, Ky, Kv, h, rtol, atol_y, atol_v):
    sy = atol_y + rtol * np.maximum(np.abs(y), np.abs(y1))
    sv = atol_v + rtol * np.maximum(np.abs(v), np.abs(v1))
    e5 = (E5 @ Ky / sy) ** 2 + (E5 @ Kv / sv) ** 2
    e3 = (E3 @ Ky / sy) ** 2 + (E3 @ Kv / sv) ** 2
    denom = e5 + 0.01 * e3
    with np.errstate(invalid="ignore", divide="ignore"):
        err = np.abs(h) * e5 / np.sqrt(denom * 2.0)
    return np.where(denom > 0.0, err, 0.0)


def _substate(sys, y, v, fy, fv, tau):
    """State at step length ``tau`` from ``(y, v)``: a fresh DOP853 step (exact to the method's order)."""
    y1, v1, Ky, Kv = _dop853(sys, y, v, fy, fv, tau)
    return y1, v1, Kv[N_STAGES] * sys.dirn  # physical acceleration at the end


def _event_value(kind, sys, y, v, a):
    """Event function and its derivative along the path parameter."""
    if kind == "a":
        return a, sys.dirn * sys.jerk(y, v, a)
    if kind == "v":
        return v, sys.dirn * a
    # "c": s * (v_drive - v), the slip-side velocity
    return sys.s * (sys.vd - v), -sys.s * sys.dirn * a


def _refine(kind, sys, y, v, fy, fv, lo, hi, glo, ghi, iterations=60):
    """Zero of an event function on ``[lo, hi]`` (step lengths from ``(y, v)``), with a sign change there.

    Safeguarded Newton: a Newton step that leaves the bracket is replaced by
    the bracket's midpoint; the bracket shrinks with every evaluation.
    Returns ``(tau, y, v, a)`` at the zero.
    """
    lo, hi, glo = lo.copy(), hi.copy(), glo.copy()
    span = np.abs(hi - lo)
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = np.where(ghi != glo, lo - glo * (hi - lo) / (ghi - glo), 0.5 * (lo + hi))
    tau = np.where(np.isfinite(tau), tau, 0.5 * (lo + hi))
    done = np.zeros(y.shape[0], bool)
    out_y, out_v, out_a = np.empty_like(y), np.empty_like(y), np.empty_like(y)
    for _ in range(iterations):
        act = ~done
        if not act.any():
            break
        i = np.flatnonzero(act)
        s = sys.take(i)
        yi, vi, ai = _substate(s, y[i], v[i], fy[i], fv[i], tau[i])
        g, dg = _event_value(kind, s, yi, vi, ai)
        out_y[i], out_v[i], out_a[i] = yi, vi, ai
        same = np.sign(g) == np.sign(glo[i])
        lo[i] = np.where(same, tau[i], lo[i])
        glo[i] = np.where(same, g, glo[i])
        hi[i] = np.where(same, hi[i], tau[i])
        with np.errstate(divide="ignore", invalid="ignore"):
            new = tau[i] - g / dg
        a_, b_ = np.minimum(lo[i], hi[i]), np.maximum(lo[i], hi[i])
        bad = ~np.isfinite(new) | (new <= a_) | (new >= b_)
        new = np.where(bad, 0.5 * (lo[i] + hi[i]), new)
        tol = 4e-16 * np.abs(tau[i]) + 1e-15 * span[i] + 1e-300
        converged = (np.abs(new - tau[i]) <= tol) | (g == 0.0) | (np.abs(hi[i] - lo[i]) <= tol)
        tau[i] = np.where(converged, tau[i], new)
        done[i] = converged
    return tau, out_y, out_v, out_a


def run(params, x0, v0, v_drive, F_ext=0.0, mode=1, *, backward=False, rtol=1e-11, scale=None,
        x_shift=None, stop_at_cross=True, t_max=None, max_steps=200000, escape=1e6, policy=None):
    """Integrate a batch of slip phases; returns one :class:`Record` per member.

    ``x0, v0, v_drive, F_ext, mode`` broadcast to one shape (``mode`` +1 or -1;
    ``backward`` may be a bool or an array). Each member runs until its slip
    ends (``"cross"``, if ``stop_at_cross``), ``policy(i, record, event)``
    returns True after one of its events (``"policy"``), ``|t|`` reaches
    ``t_max`` (default 200 undamped periods; ``"time"``), the state leaves
    ``escape`` times its natural scale (``"escape"``) or ``max_steps`` steps
    were taken (``"steps"``).

    ``scale`` (m, per member) sets the absolute tolerance (``rtol * scale`` in
    position, ``rtol * scale * omega0`` in velocity; default ``(F_S(0) +
    |F_ext|)/kappa``); ``x_shift`` (m) is subtracted from ``x`` for the
    integration, so that small oscillations about it are resolved relatively.
    """
    x0, v0, vd, fe, md, bw = np.broadcast_arrays(*(np.asarray(a, float) for a in
                                                  (x0, v0, v_drive, F_ext, mode, backward)))
    n = x0.size
    x0, v0, vd, fe, md, bw = (a.ravel().copy() for a in (x0, v0, vd, fe, md, bw))
    M, kappa = params.M, params.kappa
    omega0 = math.sqrt(kappa / M)
    period0 = 2.0 * math.pi / omega0
    if t_max is None:
        t_max = 200.0 * period0
    natural = (params.static.force(0.0) + np.abs(fe)) / kappa
    scale = np.broadcast_to(np.asarray(natural if scale is None else scale, float), (n,)).copy()
    xs = np.zeros(n) if x_shift is None else np.broadcast_to(np.asarray(x_shift, float), (n,)).copy()
    dirn = np.where(bw > 0.0, -1.0, 1.0)
    full = System(Kinetic(params.kinetic), M, kappa, vd, fe, md, dirn, xs)
    records = [Record() for _ in range(n)]
    h_max = period0 / _STEPS_PER_PERIOD
    bound_x = escape * np.maximum(scale, np.abs(xs) + np.abs(x0 - xs) + 1e-300)
    bound_v = escape * np.maximum(scale * omega0 + np.abs(vd), np.abs(v0) + 1e-300)

    idx = np.arange(n)  # members still running
    y = x0 - xs
    v = v0.copy()
    t = np.zeros(n)
    sys = full
    fy, fv = sys.rhs(y, v)
    h = np.full(n, min(h_max, 0.01 * period0))
    atol_y = rtol * scale
    atol_v = rtol * scale * omega0
    first = np.ones(n, bool)
    steps = np.zeros(n, int)
    rejected = np.zeros(n, int)
    XM, Xm, VM, Vm = x0.copy(), x0.copy(), v0.copy(), v0.copy()

    while idx.size:
        y1, v1, Ky, Kv = _dop853(sys, y, v, fy, fv, h)
        err = _error_norm(y, v, y1, v1, Ky, Kv, h, rtol, atol_y[idx], atol_v[idx])
        ok = (err <= 1.0) & np.isfinite(y1) & np.isfinite(v1)
        with np.errstate(divide="ignore"):
            factor = np.where(err > 0.0, _SAFETY * err ** (-1.0 / 8.0), _MAX_FACTOR)
        factor = np.clip(np.where(np.isfinite(factor), factor, _MIN_FACTOR), _MIN_FACTOR, _MAX_FACTOR)
        h_next = np.minimum(h * np.where(ok, factor, np.minimum(factor, 1.0)), h_max)
        stop = np.zeros(idx.size, bool)
        if ok.any():
            k = np.flatnonzero(ok)
            fy1, fv1 = Ky[N_STAGES], Kv[N_STAGES]
            ended = _events(sys, k, idx, y, v, fy, fv, y1, v1, fv1, h, t, first, records, stop_at_cross, policy)
            stop[k] = ended
            go = k[~ended]
            t[go] += dirn[idx[go]] * h[go]
            y[go], v[go], fy[go], fv[go] = y1[go], v1[go], fy1[go], fv1[go]
            first[go] = False
            steps[go] += 1
            xg = y[go] + xs[idx[go]]
            ig = idx[go]
            XM[ig] = np.maximum(XM[ig], xg)
            Xm[ig] = np.minimum(Xm[ig], xg)
            VM[ig] = np.maximum(VM[ig], v[go])
            Vm[ig] = np.minimum(Vm[ig], v[go])
            over_t = np.abs(t[go]) >= t_max
            escaped = (np.abs(y[go] + xs[idx[go]]) > bound_x[idx[go]]) | (np.abs(v[go]) > bound_v[idx[go]])
            over_s = steps[go] >= max_steps
            for j, reason in ((go[escaped], "escape"), (go[over_t & ~escaped], "time"),
                              (go[over_s & ~over_t & ~escaped], "steps")):
                for jj in j:
                    r = records[idx[jj]]
                    r.reason = reason
                    r.t, r.x, r.v = t[jj], y[jj] + xs[idx[jj]], v[jj]
                stop[j] = True
        h = np.maximum(h_next, 1e-14 * period0)
        rejected = np.where(ok, 0, rejected + 1)
        stuck = (rejected > 60) & ~stop
        for j in np.flatnonzero(stuck):
            r = records[idx[j]]
            r.reason, r.t, r.x, r.v = "fail", t[j], y[j] + xs[idx[j]], v[j]
        stop |= stuck
        if stop.any():
            keep = ~stop
            idx, y, v, fy, fv, h, t = idx[keep], y[keep], v[keep], fy[keep], fv[keep], h[keep], t[keep]
            first, steps, rejected = first[keep], steps[keep], rejected[keep]
            sys = full.take(idx)
    for i, r in enumerate(records):
        r.x_max, r.x_min = max(r.x_max, XM[i]), min(r.x_min, Xm[i])
        r.v_max, r.v_min = max(r.v_max, VM[i]), min(r.v_min, Vm[i])
    return records


def _events(sys, k, idx, y, v, fy, fv, y1, v1, fv1, h, t, first, records, stop_at_cross, policy):
    """Find, refine and record the events inside the accepted steps ``k``; True where a member stops."""
    ended = np.zeros(k.size, bool)
    dirn = sys.dirn[k]
    a0 = fv[k] * dirn
    a1 = fv1[k] * dirn
    v0k, v1k = v[k], v1[k]
    s = sys.s[k]
    vd = sys.vd[k]
    c0, c1 = s * (vd - v0k), s * (vd - v1k)
    fst = first[k]
    if fst.any():  # a start on an event surface is not an event
        a0 = np.where(fst & (np.abs(a0) <= 1e-9 * np.abs(a1)), 0.0, a0)
        v0k = np.where(fst & (np.abs(v0k) <= 1e-9 * np.abs(v1k)), 0.0, v0k)
        c0 = np.where(fst & (np.abs(c0) <= 1e-9 * np.abs(c1)), 0.0, c0)
    hk = h[k]
    ext = a0 * a1 < 0.0
    # the extremum of v inside the step, if any
    tau_e = np.full(k.size, np.nan)
    ye = np.full(k.size, np.nan)
    ve = np.full(k.size, np.nan)
    if ext.any():
        j = np.flatnonzero(ext)
        kk = k[j]
        sub = sys.take(kk)
        tau_e[j], ye[j], ve[j], _ = _refine("a", sub, y[kk], v[kk], fy[kk], fv[kk], np.zeros(j.size), hk[j],
                                            a0[j], a1[j])
    ce = s * (vd - ve)
    found = {}
    # level crossings (v = 0 and s v_rel = 0) on the monotone pieces [0, tau_e], [tau_e, h] or [0, h]
    for kind, g0, ge, g1 in (("v", v0k, ve, v1k), ("c", c0, ce, c1)):
        first_piece = ext & (g0 * ge < 0.0)
        second_piece = ext & ~first_piece & (ge * g1 < 0.0)
        whole = ~ext & (g0 * g1 < 0.0)
        if kind == "c":  # the slip side is c > 0: only a fall to 0 ends it
            first_piece &= g0 > 0.0
            second_piece &= ge > 0.0
            whole &= g0 > 0.0
            # a fall onto exactly 0 at the end of the step
            whole |= ~ext & (g0 > 0.0) & (g1 == 0.0)
        has = first_piece | second_piece | whole
        if not has.any():
            continue
        j = np.flatnonzero(has)
        lo = np.where(second_piece, tau_e, 0.0)[j]
        hi = np.where(first_piece, tau_e, hk)[j]
        glo = np.where(second_piece, ge, g0)[j]
        ghi = np.where(first_piece, ge, g1)[j]
        kk = k[j]
        sub = sys.take(kk)
        tau, yy, vv, _ = _refine(kind, sub, y[kk], v[kk], fy[kk], fv[kk], lo, hi, glo, ghi)
        found[kind] = (j, tau, yy, vv, glo)
    # assemble in path order per member
    per = {}
    if ext.any():
        for j in np.flatnonzero(ext):
            kind = "vmax" if dirn[j] * a0[j] > 0.0 else "vmin"
            per.setdefault(j, []).append((tau_e[j], kind, ye[j], ve[j]))
    if "v" in found:
        j, tau, yy, vv, glo = found["v"]
        for jj, tt, yv, gl in zip(j, tau, yy, glo):
            per.setdefault(jj, []).append((tt, "xmax" if dirn[jj] * gl > 0.0 else "xmin", yv, 0.0))
    if "c" in found:
        j, tau, yy, vv, _ = found["c"]
        for jj, tt, yv in zip(j, tau, yy):
            per.setdefault(jj, []).append((tt, "cross", yv, vd[jj]))
    for j, evs in per.items():
        member = idx[k[j]]
        rec = records[member]
        xs = sys.xs[k[j]]
        tstart = t[k[j]]
        d = dirn[j]
        for tau, kind, yy, vv in sorted(evs, key=lambda e: e[0]):
            x = yy + xs
            ev = (kind, tstart + d * tau, x, vv)
            rec.events.append(ev)
            rec.x_max, rec.x_min = max(rec.x_max, x), min(rec.x_min, x)
            rec.v_max, rec.v_min = max(rec.v_max, vv), min(rec.v_min, vv)
            if kind == "cross" and stop_at_cross:
                rec.reason, rec.t, rec.x, rec.v = "cross", ev[1], x, vv
                ended[j] = True
                break
            if policy is not None and policy(member, rec, ev):
                rec.reason, rec.t, rec.x, rec.v = "policy", ev[1], x, vv
                ended[j] = True
                break
    return ended
