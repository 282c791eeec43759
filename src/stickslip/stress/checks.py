"""Checks of an FMU run: invariants, agreement with the reference, energy balance, drift.

Everything here judges samples taken from the FMU at its communication points
(``{column: array}`` as :func:`.session.as_columns` makes them, inputs already
applied for the next step, so a sample is the state right after everything
that happened at its time).

Energy balance (SPEC section 1; what it checks and how)
--------------------------------------------------------
With ``E = kappa x^2/2 + M v^2/2`` the equation of motion gives
``dE/dt = (F_friction + F_ext) v`` in every mode (stuck: ``M dv/dt = 0`` and
``F_friction = kappa x - F_ext``). ``x`` and ``v`` are continuous at events, so
``E`` is too; the only jumps come from input steps of ``v_drive`` while stuck
(the block jumps with the surface: an impulsive friction work equal to the jump
of the kinetic energy, which is not checked, only excluded).

:func:`energy_balance` checks ``E(b) - E(a) = integral_a^b (F_friction + F_ext) v dt``
on every *piece* ``[a, b]`` between consecutive events, input steps and the
ends of the run, through the FMU itself:

1. pass 1 finds every event time exactly: it steps a fresh instance on a
   coarse grid, saving the FMU state before each step; a step with more than one
   mode change is redone in 8 sub-steps (recursively), so each step holds at most
   one event, whose time the FMU reports as ``t_last_event``;
2. pass 2 steps a second fresh instance through the 15 Gauss-Kronrod nodes of
   every cell of every piece (initial cells of at most a quarter of
   ``sqrt(M/kappa)``, graded towards the start of each piece for the fast
   relaxation of overdamped slips). The power is smooth inside a piece; the
   difference between the Kronrod rule and its embedded 7-point Gauss rule
   estimates the error, and a cell whose estimate exceeds its share of the
   quadrature tolerance is redone in halves from the FMU state saved at its
   start (adaptive quadrature in time order).

The residual ``|Delta E - W|`` of a piece is reported relative to the energy
scale of the run (largest ``E`` plus ``F_S(0)^2/kappa``). It must stay below
:func:`energy_tolerance` plus the quadrature estimate: ``1e-11`` for affine laws
(closed forms; observed 1e-17 to 4e-11), ``ENERGY_STEPS_FACTOR * rtol`` for
numeric slips (the solver's local error per step; observed up to 1e-7 for
rtol = 1e-10), plus the resolution of time (one ulp of the end time over the
natural time scale: at t = 2e9 s a double resolves only 2.4e-7 s).

Affine laws could have been integrated in closed form; the quadrature is used
for every law instead, so that the check always runs on what leaves the FMU
(``F_friction``, ``F_ext``, ``v`` at the nodes, ``x`` and ``v`` at the ends)
and is independent of both the runtime and the reference integrator. It
catches wrong event states, wrong friction signs and integration drift.
"""

import math
from dataclasses import dataclass

import numpy as np

from ..core import Parameters, kinetic_law, static_law
from ..reference import parameters_from_values, simulate_reference

EPS = 2.220446049250313e-16
ROUND = 16.0 * EPS  # relative rounding allowance of the invariants

# ---------------------------------------------------------------------------
# parameters from FMU start values
# ---------------------------------------------------------------------------


def params_from_start(values):
    """``Parameters`` from a full set of FMU start values (``kinetic.law``, ``kinetic.F0``, ...)."""
    laws = []
    for kind, build in (("kinetic", kinetic_law), ("static", static_law)):
        code = int(values[f"{kind}.law"])
        names = build(code).PARAMETERS
        laws.append(build(code, **{n: values[f"{kind}.{n}"] for n in names}))
    return Parameters(values["M"], values["kappa"], *laws)


def scales(p, samples):
    """Natural scales of a run: position (m), velocity (m/s), energy (J)."""
    F_ext = np.abs(samples["F_ext"]).max()
    x_scale = max((p.static.force(0.0) + F_ext) / p.kappa, np.abs(samples["x"]).max())
    omega = math.sqrt(p.kappa / p.M)
    v_scale = max(np.abs(samples["v"]).max(), np.abs(samples["v_drive"]).max(), omega * x_scale)
    energy = 0.5 * p.kappa * x_scale**2 + 0.5 * p.M * v_scale**2
    return x_scale, v_scale, energy


# ---------------------------------------------------------------------------
# invariants
# ---------------------------------------------------------------------------


class Violations:
    """Invariant violations by name: count and the first few messages."""

    KEEP = 3

    def __init__(self):
        self.counts = {}
        self.examples = {}

    def add(self, name, message):
        self.counts[name] = self.counts.get(name, 0) + 1
        if len(self.examples.setdefault(name, [])) < self.KEEP:
            self.examples[name].append(message)

    def __bool__(self):
        return bool(self.counts)

    def __len__(self):
        return sum(self.counts.values())

    def summary(self):
        return "; ".join(f"{name} x{count}: {self.examples[name][0]}" for name, count in self.counts.items())


def check_invariants(samples, p, t0=0.0, violations=None):
    """Invariants of SPEC sections 1 and 4 at every sample; returns :class:`Violations`.

    - every Real output and input is finite; ``mode`` is -1, 0 or +1;
    - event counters add up and never decrease; ``t_last_event <= t``;
    - ``F_spring == -kappa x`` and ``z_stick == v_rel`` exactly;
    - stuck: ``v == v_drive`` and ``v_rel == 0`` exactly, ``|kappa x - F_ext| <= F_S(t_stick)``
      and ``F_friction = kappa x - F_ext``, ``z_slip = F_S(t_stick) - |kappa x - F_ext|``
      (to rounding), ``0 <= t_stick <= t - t0``;
    - slipping: ``sign(v_rel) == mode`` (``v_rel == 0`` only at the instant of the
      event that started the slip), ``t_stick == 0``, ``F_friction = mode F_K(|v_rel|)``
      and ``z_slip = F_S(0) - |kappa x - F_ext|`` (to rounding).
    """
    v = violations if violations is not None else Violations()
    _check_columns(samples, v)
    FS0 = p.static.force(0.0)
    for i in range(len(samples["time"])):
        s = _Sample.at(samples, i)
        if not all(math.isfinite(c) for c in (s.x, s.v, s.v_rel, s.v_drive, s.F_ext, s.t_stick, s.F_friction,
                                              s.z_slip)):
            continue  # reported by _check_columns
        if s.mode not in (-1, 0, 1):
            v.add("mode", f"mode = {s.mode} {s.where}")
            continue
        if s.F_spring != -p.kappa * s.x:
            v.add("F_spring", f"F_spring = {s.F_spring!r} != -kappa x = {-p.kappa * s.x!r} {s.where}")
        if s.z_stick != s.v_rel:
            v.add("z_stick", f"z_stick = {s.z_stick!r} != v_rel = {s.v_rel!r} {s.where}")
        if s.t_last_event > s.t:
            v.add("t_last_event", f"t_last_event = {s.t_last_event!r} > t {s.where}")
        hold = p.kappa * s.x - s.F_ext
        rounding = ROUND * (abs(p.kappa * s.x) + abs(s.F_ext) + FS0)
        if s.mode == 0:
            _check_stuck(v, s, p, hold, rounding, t0)
        else:
            _check_slipping(v, s, p, hold, rounding, FS0)
    return v


def _check_columns(samples, v):
    """Every Real column is finite; the event counters add up and never decrease."""
    real_columns = ("x", "v", "v_rel", "F_friction", "F_spring", "t_stick", "z_slip", "z_stick", "t_last_event",
                    "v_drive", "F_ext")
    for name in real_columns:
        bad = ~np.isfinite(samples[name])
        for i in np.flatnonzero(bad)[:Violations.KEEP]:
            v.add("finite", f"{name} = {float(samples[name][i])!r} at t = {float(samples['time'][i])!r}")
        if bad.sum() > Violations.KEEP:
            v.counts["finite"] += int(bad.sum()) - Violations.KEEP
    counters = samples["n_stick_events"] + samples["n_slip_events"] + samples["n_overshoots"]
    for i in np.flatnonzero(counters != samples["n_events"])[:1]:
        v.add("counters",
              f"n_events {samples['n_events'][i]} != sum of kinds {counters[i]} at t = {float(samples['time'][i])!r}")
    for name in ("n_events", "n_stick_events", "n_slip_events", "n_overshoots", "n_steps"):
        for i in np.flatnonzero(np.diff(samples[name]) < 0)[:1]:
            v.add("counters", f"{name} decreased at t = {samples['time'][i + 1]!r}")


@dataclass
class _Sample:
    """One sample of a run, in the FMU's names and SI units (``mode`` an int, the rest floats)."""

    t: float
    mode: int
    x: float
    v: float
    v_rel: float
    v_drive: float
    F_ext: float
    t_stick: float
    F_friction: float
    z_slip: float
    F_spring: float
    z_stick: float
    t_last_event: float

    @classmethod
    def at(cls, samples, i):
        return cls(float(samples["time"][i]), int(samples["mode"][i]),
                   *(float(samples[name][i]) for name in ("x", "v", "v_rel", "v_drive", "F_ext", "t_stick",
                                                          "F_friction", "z_slip", "F_spring", "z_stick",
                                                          "t_last_event")))

    @property
    def where(self):
        return f"at t = {self.t!r}"


def _check_stuck(v, s, p, hold, rounding, t0):
    """A stuck sample: moves with the drive, is held (``hold = kappa x - F_ext``, N), ``t_stick`` in range."""
    FS = p.static.force(s.t_stick)
    if s.v != s.v_drive or s.v_rel != 0.0:
        v.add("stuck v == v_drive", f"v = {s.v!r}, v_drive = {s.v_drive!r}, v_rel = {s.v_rel!r} {s.where}")
    if abs(hold) > FS + rounding + ROUND * FS:
        v.add("stuck holds", f"|kappa x - F_ext| = {abs(hold)!r} > F_S(t_stick = {s.t_stick!r}) = {FS!r} {s.where}")
    if abs(s.F_friction - hold) > rounding:
        v.add("stuck friction", f"F_friction = {s.F_friction!r} != kappa x - F_ext = {hold!r} {s.where}")
    if abs(s.z_slip - (FS - abs(hold))) > rounding + ROUND * FS:
        v.add("z_slip", f"z_slip = {s.z_slip!r} != F_S - |kappa x - F_ext| = {FS - abs(hold)!r} {s.where}")
    if not -ROUND * max(1.0, abs(s.t - t0)) <= s.t_stick <= (s.t - t0) * (1 + ROUND) + ROUND:
        v.add("t_stick", f"t_stick = {s.t_stick!r} outside [0, t - t0] {s.where}")


def _check_slipping(v, s, p, hold, rounding, FS0):
    """A slipping sample: ``v_rel`` has the mode's sign, no stick time, kinetic friction, ``z_slip`` at ``F_S(0)``."""
    started_now = s.t_last_event == s.t
    if s.mode * s.v_rel < 0.0 or (s.v_rel == 0.0 and not started_now):
        v.add("slip sign", f"mode {s.mode:+d} but v_rel = {s.v_rel!r} {s.where}")
    if s.t_stick != 0.0:
        v.add("t_stick", f"t_stick = {s.t_stick!r} while slipping {s.where}")
    u = max(s.mode * s.v_rel, 0.0)
    FK = s.mode * p.kinetic.force(u)
    if abs(s.F_friction - FK) > ROUND * (abs(FK) + FS0):
        v.add("slip friction", f"F_friction = {s.F_friction!r} != mode F_K(|v_rel|) = {FK!r} {s.where}")
    if abs(s.z_slip - (FS0 - abs(hold))) > rounding:
        v.add("z_slip", f"z_slip = {s.z_slip!r} != F_S(0) - |kappa x - F_ext| = {FS0 - abs(hold)!r} {s.where}")


# ---------------------------------------------------------------------------
# reference
# ---------------------------------------------------------------------------


def reference_for(values, x0, v0, breakpoints, times, rtol=1e-12):
    """The independent reference on the sample ``times`` with the inputs the FMU saw.

    Its laws are the reference's own, built from the FMU start ``values`` (not from core objects).
    """
    return simulate_reference(parameters_from_values(values), x0, v0, breakpoints, np.asarray(times, float),
                              rtol=rtol)


def mode_changes(ref):
    """Number of mode changes of a reference result (input-caused ones included, as the FMU counts them)."""
    return sum(1 for e in ref.events if e.mode_before != e.mode_after)


def compare_reference(samples, ref, p):
    """``(error, detail)``: the largest of ``|dx|/x_scale`` and ``|dv|/v_scale`` over the samples, and a text."""
    x_scale, v_scale, _ = scales(p, samples)
    dx = np.abs(samples["x"] - ref.x) / x_scale
    dv = np.abs(samples["v"] - ref.v) / v_scale
    i, j = int(np.argmax(dx)), int(np.argmax(dv))
    if dx[i] >= dv[j]:
        return float(dx[i]), f"|dx|/x_scale = {dx[i]:.2e} at t = {samples['time'][i]:.6g}"
    return float(dv[j]), f"|dv|/v_scale = {dv[j]:.2e} at t = {samples['time'][j]:.6g}"


# ---------------------------------------------------------------------------
# energy balance
# ---------------------------------------------------------------------------

_XGK = (0.991455371120812639206854697526329, 0.949107912342758524526189684047851,
        0.864864423359769072789712788640926, 0.741531185599394439863864773280788,
        0.586087235467691130294144845693013, 0.405845151377397166906606412076961,
        0.207784955007898467600689403773245, 0.0)
_WGK = (0.022935322010529224963732008058970, 0.063092092629978553290700663189204,
        0.104790010322250183839876322541518, 0.140653259715525918745189590510238,
        0.169004726639267902826583426598550, 0.190350578064785409913256402421014,
        0.204432940075298892414161999234649, 0.209482141084727828012999174891714)
_WG = (0.129484966168869693270611432679082, 0.279705391489276667901467771423780,
       0.381830050505118944950369775488975, 0.417959183673469387755102040816327)
KRONROD_NODES = np.array([-a for a in _XGK[:-1]] + [0.0] + list(_XGK[:-1][::-1]))
KRONROD_WEIGHTS = np.array(list(_WGK[:-1]) + [_WGK[-1]] + list(_WGK[:-1][::-1]))
GAUSS_WEIGHTS = np.zeros(15)  # 7-point Gauss rule on the odd Kronrod nodes
GAUSS_WEIGHTS[[1, 3, 5, 7, 9, 11, 13]] = [_WG[0], _WG[1], _WG[2], _WG[3], _WG[2], _WG[1], _WG[0]]

MAX_CELLS = 200  # initial Gauss-Kronrod cells per piece (adaptivity may split them)
MAX_DEPTH = 40  # sub-division levels (pass 1 and the quadrature)
ENERGY_STEPS_FACTOR = 1e3


def energy_tolerance(rtol, affine, t_end=0.0, period=1.0):
    """Allowed relative residual of one piece (see the module text).

    ``1e-11`` for closed forms, ``ENERGY_STEPS_FACTOR * rtol`` for numeric slips, plus the
    resolution of time itself: the FMU's times are doubles, and a time error of one ulp of
    ``t_end`` shifts the energy of an oscillation of natural time scale ``period`` by about ulp/period.
    """
    base = 1e-11 if affine else max(ENERGY_STEPS_FACTOR * rtol, 1e-11)
    return base + math.ulp(max(abs(t_end), 1.0)) / period


class EnergyResult:
    """Worst relative residual over the pieces and where, the numbers of pieces and events, the summed
    quadrature error estimate (relative), the energy scale (J), the Gauss-Kronrod cells used, and whether
    the cell budget ran out before every cell met its tolerance."""

    def __init__(self, worst, where, n_pieces, n_events, quadrature, energy_scale, cells=0, exhausted=False):
        self.worst, self.where = worst, where
        self.n_pieces, self.n_events = n_pieces, n_events
        self.quadrature, self.energy_scale = quadrature, energy_scale
        self.cells, self.exhausted = cells, exhausted


def _schedule(breakpoints):
    """``{t_k: (v_drive, F_ext)}`` of the input steps after the first."""
    return {float(t): (vd, F) for t, vd, F in breakpoints[1:]}


def locate_events(make_instance, breakpoints, t_end, h):
    """Pass 1: every event time of the run (sorted, with repeats for simultaneous events) and the final sample."""
    inst = make_instance()
    events = []
    steps = _schedule(breakpoints)
    try:
        grid = sorted(set(np.arange(inst.time, t_end, h).tolist()) | set(steps) | {t_end})
        grid = [t for t in grid if inst.time <= t <= t_end]
        n_before = inst.read()["n_events"]
        for a, b in zip(grid, grid[1:]):
            if a in steps:
                inst.set_inputs(*steps[a])
                row = inst.read()
                if row["n_events"] > n_before:
                    events += [row["t_last_event"]] * (row["n_events"] - n_before)
                    n_before = row["n_events"]
            n_before = _step_one_event(inst, a, b, n_before, events, 0)
        return events, inst.read()
    finally:
        inst.free()


def _step_one_event(inst, a, b, n_before, events, depth):
    """Step from ``a`` (the instance's time) to ``b``; a step with several events is redone in 8 sub-steps."""
    state = inst.get_state()
    a = inst.time
    try:
        inst.step_to(b)
        row = inst.read()
        n = row["n_events"]
        if n - n_before <= 1 or depth >= MAX_DEPTH or (b - a) <= 4 * EPS * max(abs(a), abs(b)):
            events += [row["t_last_event"]] * (n - n_before)
            return n
        inst.set_state(state, a)
        subs = np.linspace(a, b, 9)
        subs[-1] = b
        for s1 in subs[1:]:
            n_before = _step_one_event(inst, inst.time, float(s1), n_before, events, depth + 1)
        return n_before
    finally:
        inst.free_state(state)


def _cells(a, b, t_fast, t_slow):
    """Initial cell boundaries on ``[a, b]``: graded from ``t_fast`` at ``a`` up to ``t_slow``, at most MAX_CELLS."""
    length = b - a
    size = min(t_fast, length)
    edges = [0.0]
    while edges[-1] < length and len(edges) <= MAX_CELLS:
        edges.append(edges[-1] + size)
        size = min(2.0 * size, t_slow)
    if edges[-1] < length:  # too many: spread MAX_CELLS over the piece, still graded (adaptivity refines)
        edges = [0.0] + list(np.geomspace(min(t_fast, length / MAX_CELLS), length, MAX_CELLS))
    edges = [e for e in edges if e < length * (1.0 - 1e-9)] + [length]  # no sliver before the end
    return a + np.unique(np.clip(np.array(edges), 0.0, length))


class _Quadrature:
    """Adaptive Gauss-Kronrod in time order: a cell whose G7/K15 difference exceeds both its share of the
    absolute tolerance and ``rel`` times its integral of ``|power|`` is redone in halves from the saved FMU state."""

    def __init__(self, inst, budget, rel):
        self.inst = inst
        self.rel = rel  # accepted error relative to the cell's integral of |power|
        self.budget = budget  # cells left for the whole run
        self.exhausted = False

    def cell(self, c0, c1, tol, depth=0):
        """``(work, error estimate)`` on ``[c0, c1]``; the instance is at or before ``c0``."""
        inst = self.inst
        if c1 - max(c0, inst.time) <= 64 * EPS * max(abs(c0), abs(c1)):  # too short for 15 distinct nodes
            r = inst.read()
            return (r["F_friction"] + r["F_ext"]) * r["v"] * (c1 - c0), 0.0
        split = depth < MAX_DEPTH and self.budget > 0 and (c1 - c0) > 64 * EPS * max(abs(c0), abs(c1))
        state = inst.get_state() if split else None
        t_before = inst.time
        try:
            half, mid = 0.5 * (c1 - c0), 0.5 * (c0 + c1)
            power = np.empty(15)
            for k, node in enumerate(mid + half * KRONROD_NODES):
                node = float(node)
                if node > inst.time:  # (nodes closer than rounding are evaluated where the instance is)
                    inst.step_to(node)
                r = inst.read()
                power[k] = (r["F_friction"] + r["F_ext"]) * r["v"]
            self.budget -= 1
            kronrod = half * float(KRONROD_WEIGHTS @ power)
            error = abs(kronrod - half * float(GAUSS_WEIGHTS @ power))
            tol = max(tol, self.rel * half * float(KRONROD_WEIGHTS @ np.abs(power)))
            if error <= tol or not split:
                if error > tol:
                    self.exhausted = True
                return kronrod, error
            inst.set_state(state, t_before)
            w1, e1 = self.cell(c0, mid, 0.5 * tol, depth + 1)
            w2, e2 = self.cell(mid, c1, 0.5 * tol, depth + 1)
            return w1 + w2, e1 + e2
        finally:
            if state is not None:
                inst.free_state(state)


def energy_balance(make_instance, p, breakpoints, t_end, h_pass1, quad_rel=1e-14, cell_budget=20000):
    """Energy balance on every piece of the run; returns :class:`EnergyResult` (see the module text)."""
    events, _ = locate_events(make_instance, breakpoints, t_end, h_pass1)
    steps = _schedule(breakpoints)
    inst = make_instance()
    t0 = inst.time
    cuts = sorted({t0, t_end, *(t for t in steps if t0 < t < t_end), *(t for t in events if t0 < t < t_end)})
    t_slow = 0.25 * math.sqrt(p.M / p.kappa)
    slope = max(abs(p.kinetic.slope(u)) for u in (0.0, 1e-6, 1e-3, 0.1, 1.0))
    t_fast = min(t_slow, 0.25 * p.M / slope) if slope > 0 else t_slow
    worst, where, quad_total, e_max = 0.0, "", 0.0, 0.0
    residuals = []
    try:
        row = inst.read()
        first = 0.5 * p.kappa * row["x"] ** 2 + 0.5 * p.M * max(abs(row["v"]), abs(row["v_drive"])) ** 2
        e_guess = first + p.static.force(0.0) ** 2 / p.kappa
        quadrature = _Quadrature(inst, cell_budget, quad_rel)
        for a, b in zip(cuts, cuts[1:]):
            if a in steps:
                inst.set_inputs(*steps[a])
                row = inst.read()
            e_a = 0.5 * p.kappa * row["x"] ** 2 + 0.5 * p.M * row["v"] ** 2
            work, quad = 0.0, 0.0
            edges = _cells(a, b, t_fast, t_slow)
            target = quad_rel * max(e_guess, e_a)
            for c0, c1 in zip(edges, edges[1:]):
                w, q = quadrature.cell(float(c0), float(c1), target * (c1 - c0) / (b - a))
                work += w
                quad += q
            if b > inst.time:
                inst.step_to(b)
            row = inst.read()
            e_b = 0.5 * p.kappa * row["x"] ** 2 + 0.5 * p.M * row["v"] ** 2
            e_max = max(e_max, e_a, e_b, abs(work))
            residuals.append((abs(e_b - e_a - work), quad, a, b, e_b - e_a, work))
            quad_total += quad
        scale = e_max + p.static.force(0.0) ** 2 / p.kappa
        worst = -1.0
        for r, quad, a, b, de, w in residuals:
            rel = r / scale
            if not rel <= worst:  # NaN counts as worst
                worst = rel
                where = f"piece [{a:.6g}, {b:.6g}] s: dE = {de:.6g} J, work = {w:.6g} J (quadrature +-{quad:.1e})"
        return EnergyResult(max(worst, 0.0) if worst == worst else worst, where, len(residuals), len(events),
                            quad_total / scale, scale, cell_budget - quadrature.budget, quadrature.exhausted)
    finally:
        inst.free()


# ---------------------------------------------------------------------------
# closed-form Coulomb cycle (SPEC section 3), for drift checks
# ---------------------------------------------------------------------------


def coulomb_cycle(M, kappa, F_K, F_S, v_drive):
    """Stick-slip cycle under constant laws (``F_ext = 0``, ``v_drive > 0``): ``(period, x_max, x_min, t_slip)``.

    Stick: ``2 (F_S - F_K) / (kappa v_drive)``. Slip from ``kappa x = F_S`` with
    ``v = v_drive`` about ``F_K / kappa``: ``y = A cos(w t) + (v/w) sin(w t)``,
    ``A = (F_S - F_K)/kappa``; it ends when ``v`` is back at ``v_drive``, at
    ``w t = 2 pi - 2 atan2(A w, v)``.
    """
    w = math.sqrt(kappa / M)
    A = (F_S - F_K) / kappa
    phase = 2.0 * math.atan2(A * w, v_drive)
    t_slip = (2.0 * math.pi - phase) / w
    t_stick = 2.0 * (F_S - F_K) / (kappa * v_drive)
    R = math.hypot(A, v_drive / w)
    return t_stick + t_slip, F_K / kappa + R, F_K / kappa - R, t_slip
