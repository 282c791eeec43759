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
from collections.abc import Callable
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

    ``scale`` (m, per member, > 0: ValueError otherwise) sets the absolute tolerance (``rtol * scale`` in
    position, ``rtol * scale * omega0`` in velocity; default ``(F_S(0) +
    |F_ext|)/kappa``); ``x_shift`` (m) is subtracted from ``x`` for the
    integration, so that small oscillations about it are resolved relatively.
    """
    starts = np.broadcast_arrays(*(np.asarray(a, float) for a in (x0, v0, v_drive, F_ext, mode, backward)))
    batch = _Batch(params, [a.ravel().copy() for a in starts], rtol, scale, x_shift, t_max, escape, max_steps)
    recorder = _Recorder([Record() for _ in range(batch.x0.size)], stop_at_cross, policy)
    running = _Running.start(batch)
    while running.idx.size:
        stop = _step(batch, running, recorder)
        if stop.any():
            running.drop(stop, batch.system)
    for i, r in enumerate(recorder.records):
        r.x_max, r.x_min = max(r.x_max, batch.x_range[0][i]), min(r.x_min, batch.x_range[1][i])
        r.v_max, r.v_min = max(r.v_max, batch.v_range[0][i]), min(r.v_min, batch.v_range[1][i])
    return recorder.records


class _Batch:
    """What stays fixed while a batch runs, per member in batch order: its dynamics, tolerances and limits;
    and the largest and smallest ``x`` (m) and ``v`` (m/s) its accepted steps reached."""

    def __init__(self, params, starts, rtol, scale, x_shift, t_max, escape, max_steps):
        x0, v0, vd, fe, md, bw = starts
        n = x0.size
        M, kappa = params.M, params.kappa
        omega0 = math.sqrt(kappa / M)
        self.period0 = 2.0 * math.pi / omega0
        self.t_max = 200.0 * self.period0 if t_max is None else t_max
        self.max_steps = max_steps
        natural = (params.static.force(0.0) + np.abs(fe)) / kappa
        scale = np.broadcast_to(np.asarray(natural if scale is None else scale, float), (n,)).copy()
        if not np.all(scale > 0.0):
            raise ValueError(f"scale: allowed is a length > 0 m (it sets the absolute tolerances), got {scale.min()!r}")
        xs = np.zeros(n) if x_shift is None else np.broadcast_to(np.asarray(x_shift, float), (n,)).copy()
        self.system = System(Kinetic(params.kinetic), M, kappa, vd, fe, md, np.where(bw > 0.0, -1.0, 1.0), xs)
        self.x0, self.v0 = x0, v0
        self.h_max = self.period0 / _STEPS_PER_PERIOD
        self.bound_x = escape * np.maximum(scale, np.abs(xs) + np.abs(x0 - xs) + 1e-300)
        self.bound_v = escape * np.maximum(scale * omega0 + np.abs(vd), np.abs(v0) + 1e-300)
        self.rtol = rtol
        self.atol_y = rtol * scale
        self.atol_v = rtol * scale * omega0
        self.x_range = (x0.copy(), x0.copy())  # (largest, smallest)
        self.v_range = (v0.copy(), v0.copy())

    def extend_ranges(self, members, x, v):
        """Widen the ranges of ``members`` (batch indices) by their states ``x`` (m), ``v`` (m/s)."""
        (XM, Xm), (VM, Vm) = self.x_range, self.v_range
        XM[members] = np.maximum(XM[members], x)
        Xm[members] = np.minimum(Xm[members], x)
        VM[members] = np.maximum(VM[members], v)
        Vm[members] = np.minimum(Vm[members], v)


@dataclass
class _Running:
    """The members still running (``idx``: their batch indices) and their state: ``y = x - x_shift`` (m),
    ``v`` (m/s), the right-hand side ``(fy, fv)`` there, the next step length ``h`` (s), the time ``t`` along
    the run (s), whether no step was accepted yet, accepted steps and rejections in a row; ``sys`` their
    dynamics."""

    idx: np.ndarray
    y: np.ndarray
    v: np.ndarray
    fy: np.ndarray
    fv: np.ndarray
    h: np.ndarray
    t: np.ndarray
    first: np.ndarray
    steps: np.ndarray
    rejected: np.ndarray
    sys: System

    @classmethod
    def start(cls, batch):
        n = batch.x0.size
        y = batch.x0 - batch.system.xs
        v = batch.v0.copy()
        fy, fv = batch.system.rhs(y, v)
        return cls(np.arange(n), y, v, fy, fv, np.full(n, min(batch.h_max, 0.01 * batch.period0)), np.zeros(n),
                   np.ones(n, bool), np.zeros(n, int), np.zeros(n, int), batch.system)

    def drop(self, stop, system):
        """Keep only the members where ``stop`` is False; ``system`` is the whole batch's."""
        keep = ~stop
        for name in ("idx", "y", "v", "fy", "fv", "h", "t", "first", "steps", "rejected"):
            setattr(self, name, getattr(self, name)[keep])
        self.sys = system.take(self.idx)

    def x(self, j):
        """Position (m) of running member ``j``."""
        return self.y[j] + self.sys.xs[j]

    def refine(self, kind, k, lo, hi, glo, ghi):
        """:func:`_refine` for the running members ``k``, from the start of their step."""
        return _refine(kind, self.sys.take(k), self.y[k], self.v[k], self.fy[k], self.fv[k], lo, hi, glo, ghi)


@dataclass
class _Recorder:
    """Where a batch's events go: one :class:`Record` per member; a slip ends at its crossing of ``v_rel = 0``
    if ``stop_at_cross``, or where ``policy(member, record, event)`` says so."""

    records: list
    stop_at_cross: bool
    policy: Callable | None

    def end(self, member, reason, t, x, v):
        r = self.records[member]
        r.reason, r.t, r.x, r.v = reason, t, x, v

    def record(self, member, events, t_start, direction, x_shift):
        """Add ``events`` ``[(tau, kind, y, v), ...]`` of one step from ``t_start`` in path order; True where
        the member's run ends at one of them (the later ones are dropped)."""
        rec = self.records[member]
        for tau, kind, yy, vv in sorted(events, key=lambda e: e[0]):
            x = yy + x_shift
            ev = (kind, t_start + direction * tau, x, vv)
            rec.events.append(ev)
            rec.x_max, rec.x_min = max(rec.x_max, x), min(rec.x_min, x)
            rec.v_max, rec.v_min = max(rec.v_max, vv), min(rec.v_min, vv)
            if kind == "cross" and self.stop_at_cross:
                self.end(member, "cross", ev[1], x, vv)
                return True
            if self.policy is not None and self.policy(member, rec, ev):
                self.end(member, "policy", ev[1], x, vv)
                return True
        return False


def _step(batch, running, recorder):
    """One DOP853 step of every running member, accepted or rejected by its error; True where a member stops."""
    y1, v1, Ky, Kv = _dop853(running.sys, running.y, running.v, running.fy, running.fv, running.h)
    err = _error_norm(running.y, running.v, y1, v1, Ky, Kv, running.h, batch.rtol, batch.atol_y[running.idx],
                      batch.atol_v[running.idx])
    ok = (err <= 1.0) & np.isfinite(y1) & np.isfinite(v1)
    with np.errstate(divide="ignore"):
        factor = np.where(err > 0.0, _SAFETY * err ** (-1.0 / 8.0), _MAX_FACTOR)
    factor = np.clip(np.where(np.isfinite(factor), factor, _MIN_FACTOR), _MIN_FACTOR, _MAX_FACTOR)
    h_next = np.minimum(running.h * np.where(ok, factor, np.minimum(factor, 1.0)), batch.h_max)
    stop = np.zeros(running.idx.size, bool)
    if ok.any():
        _accept(batch, running, recorder, np.flatnonzero(ok), (y1, v1, Ky[N_STAGES], Kv[N_STAGES]), stop)
    running.h = np.maximum(h_next, 1e-14 * batch.period0)
    running.rejected = np.where(ok, 0, running.rejected + 1)
    stuck = (running.rejected > 60) & ~stop
    for j in np.flatnonzero(stuck):
        recorder.end(running.idx[j], "fail", running.t[j], running.x(j), running.v[j])
    return stop | stuck


def _accept(batch, running, recorder, k, ends, stop):
    """Take the accepted steps ``k`` (``ends``: the new ``y, v, fy, fv``) up to their events; sets ``stop``
    where a member's run ends (at an event, or past its time, bounds or step count)."""
    y1, v1, fy1, fv1 = ends
    ended = _events(running, k, v1, fv1, recorder)
    stop[k] = ended
    go = k[~ended]
    ig = running.idx[go]
    running.t[go] += running.sys.dirn[go] * running.h[go]
    running.y[go], running.v[go], running.fy[go], running.fv[go] = y1[go], v1[go], fy1[go], fv1[go]
    running.first[go] = False
    running.steps[go] += 1
    xg = running.x(go)
    batch.extend_ranges(ig, xg, running.v[go])
    over_t = np.abs(running.t[go]) >= batch.t_max
    escaped = (np.abs(xg) > batch.bound_x[ig]) | (np.abs(running.v[go]) > batch.bound_v[ig])
    over_s = running.steps[go] >= batch.max_steps
    for j, reason in ((go[escaped], "escape"), (go[over_t & ~escaped], "time"),
                      (go[over_s & ~over_t & ~escaped], "steps")):
        for jj in j:
            recorder.end(running.idx[jj], reason, running.t[jj], running.x(jj), running.v[jj])
        stop[j] = True


@dataclass
class _StepEnds:
    """The accepted steps ``k`` seen from their two ends: direction, mode, drive (m/s), step length (s), and at
    each end the acceleration ``a`` (m/s^2), ``v`` (m/s) and the slip-side velocity ``c = s v_rel`` (m/s);
    ``extremum``: ``v`` has an extremum inside the step (``a`` changes sign)."""

    dirn: np.ndarray
    s: np.ndarray
    vd: np.ndarray
    h: np.ndarray
    a0: np.ndarray
    a1: np.ndarray
    v0: np.ndarray
    v1: np.ndarray
    c0: np.ndarray
    c1: np.ndarray
    extremum: np.ndarray

    @classmethod
    def of(cls, running, k, v1, fv1):
        """The ends of steps ``k``; a start on an event surface (first step only) is not an event."""
        dirn, s, vd = running.sys.dirn[k], running.sys.s[k], running.sys.vd[k]
        a0, a1 = running.fv[k] * dirn, fv1[k] * dirn
        v0k, v1k = running.v[k], v1[k]
        c0, c1 = s * (vd - v0k), s * (vd - v1k)
        fst = running.first[k]
        if fst.any():
            a0 = np.where(fst & (np.abs(a0) <= 1e-9 * np.abs(a1)), 0.0, a0)
            v0k = np.where(fst & (np.abs(v0k) <= 1e-9 * np.abs(v1k)), 0.0, v0k)
            c0 = np.where(fst & (np.abs(c0) <= 1e-9 * np.abs(c1)), 0.0, c0)
        return cls(dirn, s, vd, running.h[k], a0, a1, v0k, v1k, c0, c1, a0 * a1 < 0.0)


def _events(running, k, v1, fv1, recorder):
    """Find, refine and record the events inside the accepted steps ``k``; True where a member stops."""
    ends = _StepEnds.of(running, k, v1, fv1)
    tau_e, ye, ve = _v_extremum(running, k, ends)
    found = _level_crossings(running, k, ends, tau_e, ve)
    per = {}  # member j of k -> [(tau, kind, y, v), ...]
    for j in np.flatnonzero(ends.extremum):
        kind = "vmax" if ends.dirn[j] * ends.a0[j] > 0.0 else "vmin"
        per.setdefault(j, []).append((tau_e[j], kind, ye[j], ve[j]))
    if "v" in found:
        j, tau, yy, glo = found["v"]
        for jj, tt, yv, gl in zip(j, tau, yy, glo):
            per.setdefault(jj, []).append((tt, "xmax" if ends.dirn[jj] * gl > 0.0 else "xmin", yv, 0.0))
    if "c" in found:
        j, tau, yy, _ = found["c"]
        for jj, tt, yv in zip(j, tau, yy):
            per.setdefault(jj, []).append((tt, "cross", yv, ends.vd[jj]))
    ended = np.zeros(k.size, bool)
    for j, evs in per.items():
        ended[j] = recorder.record(running.idx[k[j]], evs, running.t[k[j]], ends.dirn[j], running.sys.xs[k[j]])
    return ended


def _v_extremum(running, k, ends):
    """``(tau, y, v)`` at the extremum of ``v`` inside each step ``k`` (NaN where there is none)."""
    tau_e = np.full(k.size, np.nan)
    ye = np.full(k.size, np.nan)
    ve = np.full(k.size, np.nan)
    if ends.extremum.any():
        j = np.flatnonzero(ends.extremum)
        tau_e[j], ye[j], ve[j], _ = running.refine("a", k[j], np.zeros(j.size), ends.h[j], ends.a0[j], ends.a1[j])
    return tau_e, ye, ve


def _level_crossings(running, k, ends, tau_e, ve):
    """The crossings of ``v = 0`` (``"v"``) and the falls of ``s v_rel`` to 0 (``"c"``) inside the steps ``k``,
    on the monotone pieces ``[0, tau_e]``, ``[tau_e, h]`` or ``[0, h]`` (``tau_e``, ``ve``: the extremum of
    ``v``): ``{kind: (j, tau, y, g at the start of the bracket)}``."""
    ext = ends.extremum
    found = {}
    for kind, g0, ge, g1 in (("v", ends.v0, ve, ends.v1), ("c", ends.c0, ends.s * (ends.vd - ve), ends.c1)):
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
        hi = np.where(first_piece, tau_e, ends.h)[j]
        glo = np.where(second_piece, ge, g0)[j]
        ghi = np.where(first_piece, ge, g1)[j]
        tau, yy, _, _ = running.refine(kind, k[j], lo, hi, glo, ghi)
        found[kind] = (j, tau, yy, glo)
    return found
