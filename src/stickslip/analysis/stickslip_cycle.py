"""The stick-slip cycle of a constant static law: existence (grazing margin), amplitude and period.

With a constant ``F_S`` every stick ends at the same point, the *onset*
``x_on = (F_S(0) + F_ext)/kappa`` with ``v = v_drive`` (the spring pulls back, so
the slip starts in mode +1). A stick-slip cycle exists iff the slip from the
onset ends stuck: it may overshoot on the way (``v_rel`` reaches 0 where the
contact cannot hold, SPEC section 1) and slip on in the other mode, but it must
come back to ``v_rel = 0`` where ``|kappa x - F_ext| <= F_S(0)``.

Existence is decided by a continuous **grazing margin** instead of an event
detector's yes/no. For a slip phase in mode ``s`` from ``(x, v)``, follow the
smooth flow of that mode (continued past ``v_rel = 0``, see :mod:`.flow`) and
take the extrema of the slip-side velocity ``s v_rel`` that approach 0 (the
maxima of ``v`` in mode +1): along one orbit of a planar flow these form a
monotone sequence (they lie on one transversal section, the branch of the
isocline ``dv/dt = 0`` on which the flow turns), so their supremum

    m = sup_k s (v_k - v_drive)

is the first one if they decrease and their limit if they increase (a slip
spiralling out onto a sliding limit cycle; extrapolated by Aitken's method when
the revolutions run out). ``m > 0`` iff the phase reaches ``v_rel = 0``; then
``m`` is the height of the smooth continuation's excursion beyond it, so ``m``
passes continuously through 0 at a graze. The cycle's margin is the minimum of
the margins of its mode +1 phases (every one must reach ``v_rel = 0``; a mode
-1 phase always does, as ``v`` has no minimum while ``v > v_drive > 0``).
A return to ``v_rel = 0`` sticks iff its holding margin ``z = F_S(0) - |kappa x -
F_ext|`` (the SPEC's ``z_slip``) is >= 0; stick-slip can also appear or
disappear where the deciding return has ``z = 0`` (the stick shrinks to nothing
at the onset and the cycle turns into an overshooting sliding cycle). Hence the
**existence margin**

    E = G                           if G < 0 (some mode +1 phase never returns)
    E = min(G, S / sqrt(kappa M))   otherwise,

with ``G`` the smallest grazing margin of the mode +1 phases and ``S`` the
largest ``z`` of the returns up to the first stick (``sqrt(kappa M)`` turns N
into m/s). ``E > 0`` iff the cycle exists, and ``E`` is continuous where
either kind of birth or death happens (both terms pass through 0 there):
births and deaths of stick-slip are its sign changes, located to any tolerance
by :mod:`.roots`, and never depend on whether a detector saw a near-tangent
crossing. Which term vanishes names the kind: ``"graze"`` (the slip touches
``v = v_drive``: the cycle meets the special stick-slip boundary, see
:mod:`.boundary`) or ``"zero-stick"``.
"""

import math
from dataclasses import dataclass, field

import numpy as np

from ..core.model import breakaway_direction
from . import flow
from .roots import refine, sign_changes


@dataclass
class StickSlipCycle:
    """The slip from the stick-slip onset at one drive velocity, and the cycle it makes (if any).

    ``exists``: the slip ends stuck. ``margin`` (m/s): the existence margin ``E``
    (> 0 iff the cycle exists); ``graze_margin`` (m/s): ``G``, > 0 iff every mode
    +1 phase reaches ``v_rel = 0``; ``stick_margin`` (N): ``S``. ``period = slip_time +
    stick_time`` (s); ``x_max, x_min`` (m) and ``v_min, v_max`` (m/s) over the
    cycle; ``x_stick`` (m) where it sticks; ``overshoots``: number of
    overshooting returns to ``v_rel = 0``; ``phases``: ``[(mode, duration s,
    x_end m, margin m/s or None), ...]``. ``fate`` says how the slip ended:
    ``"stick"``, ``"slides"`` (a phase never returns to ``v_rel = 0``),
    ``"no-stick"`` (every return overshoots, up to ``max_phases``),
    ``"undecided"`` (revolutions ran out) or ``"escape"``.
    """

    v_drive: float
    exists: bool
    margin: float
    fate: str
    period: float = math.nan
    slip_time: float = math.nan
    stick_time: float = math.nan
    x_max: float = math.nan
    x_min: float = math.nan
    v_min: float = math.nan
    v_max: float = math.nan
    x_stick: float = math.nan
    overshoots: int = 0
    phases: list = field(default_factory=list)
    graze_margin: float = math.inf
    stick_margin: float = -math.inf
    kind: str = ""
    #: for fate "no-stick": the overshooting sliding cycle the slips settle on (last two phases):
    #: ``(period s, x_max m, x_min m, converged)``
    overshoot_cycle: tuple = ()

    @property
    def stick_fraction(self):
        return self.stick_time / self.period if self.exists else math.nan


def onset(params, F_ext=0.0):
    """Position (m) where a stuck block breaks away under a constant ``F_S``: ``(F_S(0) + F_ext)/kappa``."""
    return (params.static.force(0.0) + F_ext) / params.kappa


class _Approach:
    """Policy for :func:`flow.run`: track the approach extrema of one phase and stop when ``m`` is known."""

    def __init__(self, modes, v_drives, max_revs, tol):
        self.modes = modes
        self.vd = v_drives
        self.max_revs = max_revs
        self.tol = tol
        self.crossed = {}
        self.seq = {}
        self.margin = {}

    def __call__(self, i, rec, ev):
        kind, t, x, v = ev
        s = self.modes[i]
        if kind == "cross":
            self.crossed[i] = (t, x)
            return s < 0  # mode -1: the excursion beyond is not needed
        if kind != ("vmax" if s > 0 else "vmin"):
            return False
        m = s * (v - self.vd[i])
        if i in self.crossed:
            self.margin[i] = m
            return True
        seq = self.seq.setdefault(i, [])
        seq.append(m)
        if len(seq) >= 2 and seq[-1] <= seq[-2]:
            self.margin[i] = seq[0]
            return True
        if len(seq) >= 3:
            d1, d2 = seq[-1] - seq[-2], seq[-2] - seq[-3]
            if d1 <= self.tol:
                self.margin[i] = seq[-1]
                return True
        if len(seq) >= self.max_revs:
            self.margin[i] = _aitken(seq)
            return True
        return False


def _aitken(seq):
    """Limit of an increasing sequence with geometric convergence (Aitken), or its last term."""
    if len(seq) < 3:
        return seq[-1]
    d1, d2 = seq[-1] - seq[-2], seq[-2] - seq[-3]
    if d2 > 0.0 and 0.0 < d1 < d2:
        r = d1 / d2
        return seq[-1] + d1 * r / (1.0 - r)
    return seq[-1]


def stick_slip_cycles(params, v_drives, F_ext=0.0, rtol=1e-11, max_phases=20, max_revs=80):
    """The slip from the onset and the stick-slip cycle, for every drive velocity (one batch).

    Requires a constant static law (with aging the cycle is a fixed point of the
    stick-slip map, :mod:`.aging_map`). ``v_drives`` must be > 0.
    """
    if not params.static.is_constant():
        raise ValueError("stick_slip_cycles needs a constant static law; use stickslip.analysis.aging_map")
    vd = np.atleast_1d(np.asarray(v_drives, float))
    x_on = onset(params, F_ext)
    out = slips_to_stick(params, np.full(vd.size, x_on), vd, F_ext, rtol, max_phases, max_revs)
    for c in out:
        if c.exists:
            c.stick_time = (x_on - c.x_stick) / c.v_drive
            c.period = c.slip_time + c.stick_time
    return out


def slips_to_stick(params, x_start, v_drives, F_ext=0.0, rtol=1e-11, max_phases=20, max_revs=80):
    """The slips from ``(x_start, v_drive)`` (breakaway points) until they stick, batched.

    Returns one :class:`StickSlipCycle` per member with the slip part filled in
    (``exists`` says it ends stuck; ``x_stick``, ``slip_time``, margins, phases,
    ranges); ``stick_time`` and ``period`` are left to the caller, who knows the
    static law's aging.
    """
    vd = np.atleast_1d(np.asarray(v_drives, float))
    n = vd.size
    kappa = params.kappa
    out = [StickSlipCycle(float(v), False, math.nan, "") for v in vd]
    slips = _Slips(params, F_ext, np.broadcast_to(np.asarray(x_start, float), (n,)).copy(), vd)
    active = np.arange(n)
    scale = slips.fs0 / kappa + abs(F_ext) / kappa
    for _ in range(max_phases):
        if active.size == 0:
            break
        policy = _Approach(slips.mode[active], vd[active], max_revs, 1e-12 * np.maximum(vd[active], 1e-300))
        recs = flow.run(params, slips.x[active], vd[active], vd[active], F_ext, slips.mode[active], rtol=rtol,
                        stop_at_cross=False, policy=policy, scale=scale)
        still = []
        for j, (i, rec) in enumerate(zip(active, recs)):
            if j not in policy.crossed:
                slips.never_returned(out[i], i, rec, policy.margin.get(j))
            elif slips.returned(out[i], i, rec, policy.crossed[j], policy.margin.get(j)):
                still.append(i)
        active = np.array(still, int)
    for i in active:
        out[i].fate = "no-stick"
        out[i].overshoot_cycle = _last_turn(out[i].phases, slips.turns[i])
    unit = math.sqrt(kappa * params.M)
    for c in out:
        _set_existence_margin(c, unit)
    return out


class _Slips:
    """The slips of :func:`slips_to_stick`, per member: where the current phase starts (``x`` m, ``mode``), the
    slip time so far (s), the ranges of ``x`` (m) and ``v`` (m/s), and for each overshoot ``(x m, largest x m,
    smallest x m)`` of the phase it ended."""

    def __init__(self, params, F_ext, x_start, v_drives):
        self.params, self.F_ext = params, F_ext
        self.fs0 = params.static.force(0.0)
        self.x = x_start
        self.mode = np.array([breakaway_direction(float(xi), F_ext, params) for xi in self.x], float)
        self.t_slip = np.zeros(x_start.size)
        self.xmax, self.xmin = self.x.copy(), self.x.copy()
        self.vmax, self.vmin = v_drives.copy(), v_drives.copy()
        self.turns = [[] for _ in range(x_start.size)]

    def returned(self, c, i, rec, crossed, m):
        """Member ``i``'s phase (record ``rec``, approach margin ``m`` m/s) returned to ``v_rel = 0`` at
        ``crossed = (t s, x m)``: fill in ``c``; True if it overshoots there (a next phase follows)."""
        tc, xc = crossed
        s = self.mode[i]
        for kind, t, xe, ve in rec.events:
            if t > tc:
                break
            if kind in ("xmax", "xmin"):
                self.xmax[i], self.xmin[i] = max(self.xmax[i], xe), min(self.xmin[i], xe)
            elif kind in ("vmax", "vmin"):
                self.vmax[i], self.vmin[i] = max(self.vmax[i], ve), min(self.vmin[i], ve)
        self.xmax[i], self.xmin[i] = max(self.xmax[i], xc), min(self.xmin[i], xc)
        c.phases.append((int(s), tc, xc, m))
        if s > 0:
            c.graze_margin = min(c.graze_margin, m if m is not None else math.inf)
        self.t_slip[i] += tc
        z = self.fs0 - abs(self.params.kappa * xc - self.F_ext)
        c.stick_margin = max(c.stick_margin, z)
        if z >= 0.0:
            c.exists, c.fate = True, "stick"
            c.x_stick = xc
            c.slip_time = self.t_slip[i]
            c.x_max, c.x_min, c.v_min, c.v_max = self.xmax[i], self.xmin[i], self.vmin[i], self.vmax[i]
            return False
        c.overshoots += 1
        self.turns[i].append((xc, xmax_before(rec, tc), xmin_before(rec, tc)))
        self.x[i] = xc
        self.mode[i] = breakaway_direction(xc, self.F_ext, self.params)
        return True

    def never_returned(self, c, i, rec, m):
        """Member ``i``'s phase ended without returning to ``v_rel = 0``: it escaped, slides or is undecided."""
        if rec.reason == "escape":
            c.fate, c.margin = "escape", -math.inf
            return
        c.phases.append((int(self.mode[i]), rec.t, rec.x, m))
        c.graze_margin = min(c.graze_margin, m if m is not None else -math.inf)
        c.fate = "slides" if rec.reason == "policy" else "undecided"


def _set_existence_margin(c, unit):
    """``c.margin`` (m/s) and ``c.kind``: the existence margin ``E`` from the grazing and holding margins
    (``unit = sqrt(kappa M)`` turns N into m/s)."""
    if c.fate == "escape":
        c.margin = -math.inf
    elif c.graze_margin < 0.0:
        c.margin, c.kind = c.graze_margin, "graze"
    else:
        s_v = c.stick_margin / unit
        c.margin, c.kind = (c.graze_margin, "graze") if c.graze_margin <= s_v else (s_v, "zero-stick")


def xmax_before(rec, t_end):
    return max((x for k, t, x, v in rec.events if k == "xmax" and t <= t_end), default=-math.inf)


def xmin_before(rec, t_end):
    return min((x for k, t, x, v in rec.events if k == "xmin" and t <= t_end), default=math.inf)


def _last_turn(phases, extremes):
    """Period and x range of the last two phases (one turn of an overshooting cycle), and whether it repeats."""
    if len(phases) < 4:
        return ()
    period = phases[-1][1] + phases[-2][1]
    xs = [x for e in extremes[-2:] for x in e]
    xs = [x for x in xs if math.isfinite(x)]
    converged = abs(phases[-1][2] - phases[-3][2]) <= 1e-6 * (max(xs) - min(xs))
    return (period, max(xs), min(xs), converged)


def grazing_margin(params, v_drives, F_ext=0.0, rtol=1e-11):
    """The existence margin ``E`` (m/s) at each drive velocity: > 0 where the stick-slip cycle exists."""
    cycles = stick_slip_cycles(params, v_drives, F_ext, rtol)
    return np.array([c.margin if math.isfinite(c.margin) else math.copysign(1e3, c.margin) for c in cycles])


def existence_changes(params, v_min, v_max, n=200, F_ext=0.0, tol=1e-7, v_grid=None, rtol=1e-11):
    """Drive velocities where the stick-slip cycle appears or disappears in ``[v_min, v_max]``.

    Returns ``[(v_drive, "appears" or "disappears", kind), ...]`` (as ``v_drive``
    increases; ``kind`` is ``"graze"`` or ``"zero-stick"``, see the module), each
    a sign change of the existence margin refined to ``tol``.
    """
    grid = np.linspace(v_min, v_max, n) if v_grid is None else np.asarray(v_grid, float)
    return changes_from_samples(params, grid, grazing_margin(params, grid, F_ext, rtol), F_ext, tol, rtol)


def changes_from_samples(params, grid, margin, F_ext=0.0, tol=1e-7, rtol=1e-11):
    """Refine the sign changes of sampled existence margins (see :func:`existence_changes`)."""
    found = refine(lambda v: grazing_margin(params, v, F_ext, rtol), sign_changes(grid, margin), tol=tol)
    out = []
    for root, a, b, fa, fb in found:
        ends = stick_slip_cycles(params, [a, b], F_ext, rtol)
        kind = min(ends, key=lambda c: abs(c.margin)).kind
        out.append((root, "appears" if fb >= 0.0 else "disappears", kind))
    return out


# ----------------------------------------------------------------------
# overshooting sliding cycles (the slips pass v_rel = 0 both ways and never stick)
# ----------------------------------------------------------------------


@dataclass
class OvershootCycle:
    """A periodic slip that overshoots at both ends (mode +1, then -1) and never sticks.

    ``x_start`` (m): where its mode +1 phase starts (on ``v = v_drive``, beyond
    the onset); ``period`` (s); ``x_max, x_min`` (m); ``v_min, v_max`` (m/s);
    ``multiplier``: derivative of the return map (stable iff ``|.| < 1``).
    """

    v_drive: float
    x_start: float
    period: float
    x_max: float
    x_min: float
    v_min: float
    v_max: float
    multiplier: float

    @property
    def stable(self):
        return abs(self.multiplier) < 1.0


def _overshoot_return(params, x, vd, F_ext, rtol):
    """Return map of the overshooting slip: mode +1 from ``(x, v_drive)``, overshoot, mode -1 back to ``v_drive``.

    Arrays ``(x_next, period, x_max, x_min, v_min, v_max)``; NaN where a return sticks or never comes.
    """
    n = x.size
    fs0, kappa = params.static.force(0.0), params.kappa
    res = {k: np.full(n, np.nan) for k in ("x", "T", "xmax", "xmin", "vmin", "vmax")}
    period0 = 2.0 * math.pi * math.sqrt(params.M / kappa)
    fin = np.flatnonzero(np.isfinite(x))
    if fin.size == 0:
        return res
    r1 = [None] * n
    for i, r in zip(fin, flow.run(params, x[fin], vd[fin], vd[fin], F_ext, 1, rtol=rtol, t_max=3.0 * period0)):
        r1[i] = r
    mid = np.array([r.x if r is not None and r.reason == "cross" and abs(kappa * r.x - F_ext) > fs0
                    and F_ext - kappa * r.x > 0.0 else np.nan for r in r1])
    ok = np.flatnonzero(np.isfinite(mid))
    if ok.size == 0:
        return res
    r2 = flow.run(params, mid[ok], vd[ok], vd[ok], F_ext, -1, rtol=rtol, t_max=3.0 * period0)
    for j, i in enumerate(ok):
        a, b = r1[i], r2[j]
        if b.reason != "cross" or abs(kappa * b.x - F_ext) <= fs0:
            continue
        res["x"][i] = b.x
        res["T"][i] = a.t + b.t
        res["xmax"][i] = max(a.x_max, b.x_max)
        res["xmin"][i] = min(a.x_min, b.x_min)
        res["vmin"][i] = min(a.v_min, b.v_min)
        res["vmax"][i] = max(a.v_max, b.v_max)
    return res


def overshoot_cycles(params, v_drives, x_guess, F_ext=0.0, rtol=1e-11, iterations=12):
    """Overshooting sliding cycles by Newton on their return map (batched): one result (or None) per drive."""
    vd = np.atleast_1d(np.asarray(v_drives, float))
    x = np.array(x_guess, float)
    live = np.isfinite(x)
    deriv = np.full(vd.size, np.nan)
    for _ in range(iterations):
        idx = np.flatnonzero(live)
        if idx.size == 0:
            break
        dx = 1e-6 * np.maximum(np.abs(x[idx]), 1.0)
        xs = np.concatenate([x[idx], x[idx] + dx, x[idx] - dx])
        vv = np.concatenate([vd[idx]] * 3)
        r = _overshoot_return(params, xs, vv, F_ext, rtol)["x"]
        m = idx.size
        g = r[:m] - x[idx]
        dg = (r[m:2 * m] - r[2 * m:]) / (2 * dx) - 1.0
        step = -g / dg
        bad = ~np.isfinite(step)
        live[idx[bad]] = False
        good = idx[~bad]
        x[good] += step[~bad]
        deriv[good] = dg[~bad] + 1.0
        conv = np.abs(step[~bad]) <= 1e-12 * np.maximum(np.abs(x[good]), 1.0)
        live[good[conv]] = False
    fin = _overshoot_return(params, x, vd, F_ext, rtol)
    out = []
    for i in range(vd.size):
        if not np.isfinite(fin["x"][i]) or abs(fin["x"][i] - x[i]) > 1e-8 * max(abs(x[i]), 1.0):
            out.append(None)
            continue
        out.append(OvershootCycle(float(vd[i]), float(x[i]), float(fin["T"][i]), float(fin["xmax"][i]),
                                  float(fin["xmin"][i]), float(fin["vmin"][i]), float(fin["vmax"][i]),
                                  float(deriv[i])))
    return out
