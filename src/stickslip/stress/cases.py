"""The stress matrix as data: the regimes where friction solvers fail.

A :class:`Case` is an FMU configuration (start values), a communication grid,
input steps at grid points, and what to check. :func:`stress_cases` returns the
whole grid; cases flagged ``quick`` form the CI subset (``tests/test_stress.py``).

Groups (``Case.group``):

- ``scale``: ``M`` and ``kappa`` each 1e-6, 1 and 1e6 (``M/kappa`` over 12 orders
  of magnitude), times and velocities in the natural units ``T0 = sqrt(M/kappa)``,
  ``V0 = F_S/sqrt(kappa M)``; plus a stiff slip far shorter than the step.
- ``ratio``: ``F_S/F_K`` from 1 + 1e-9 (stick phases of 1e-8 s) to 1e3, with
  aging laws that make the slip overshoot hundreds of times before it sticks.
- ``drive``: ``v_drive`` 0, 1e-9, 1e-3, 1, 1e3, and drives that reverse direction.
- ``overdamped``: ``|F_K'|`` up to 1e6 ``sqrt(kappa M)``, strengthening (viscous,
  Stribeck) and weakening (steep Stribeck, boundary lubrication: relaxation oscillations).
- ``grazing``: drive velocities within a relative 1e-9 of the death of stick-slip,
  where the slip just touches ``v_rel = 0`` (critical velocity computed here with scipy on
  the reference's SPEC law formulas, independently of the FMU's runtime).
- ``chatter``: ``F_K(0+) = F_S(0)``, tiny stiffness, holding force at the limit.
- ``comm-step``: communication steps from 1e-9 to 1e4 s and random step
  sequences, each checked against a refined grid (results must not depend on it).
- ``input-jumps``: both inputs jump at every step.
- ``long``: 1e6 time units and 1e6 events (memory, event counts, drift; see runner).
"""

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from ..reference import parameters_from_values
from ..reference.closed_form import AffineSlip

COULOMB = {"kinetic.law": 1, "static.law": 1}

#: reported bugs that are still open; cases that show them carry the name.
#: Fixed since (regression tests in tests/test_stress.py): a constant-law breakaway later than 1e6 natural
#: periods was never found; Sigmoid.rate(0) had the wrong sign for weakening n < 1; a slip that could not
#: leave v_rel = 0 stayed in mode -1 with v_rel == 0 (all f13ede0); a stick beginning against the drive
#: under a static law convex after the kink of |kappa x - F_ext| broke away late or never (edbf5be);
#: Sigmoid.curvature divided by t * t, which underflowed to 0 for t < 1e-154 s; advance_to(inf) never returned.


@dataclass(frozen=True)
class Case:
    """One stress configuration.

    ``start``: FMU start values (unlisted ones keep the FMU's defaults).
    ``grid``: communication times, first = start time. ``inputs``: input steps
    ``(t, v_drive, F_ext)`` at grid times after the first (held until the next).
    ``tol``: allowed normalized error vs the reference (|dx|/x_scale, |dv|/v_scale).
    ``refine``: a second grid sharing times with ``grid`` (a refinement or a subset); results at the
    common times must agree to ``grid_tol``.
    ``expect``: extra expectations: ``min_events``, ``max_events``, ``min_overshoots``,
    ``final_mode``, ``error`` (text the FMU's error must contain: the run must fail cleanly).
    ``long``: settings of a long run (``kind`` "time" or "events", see runner).
    ``known_bug``: the case fails because of a reported bug (named here); the table counts it apart.
    """

    name: str
    group: str
    start: dict
    grid: tuple = ()
    inputs: tuple = ()
    tol: float = 1e-9
    reference: bool = True
    energy: bool = True
    refine: tuple = ()
    grid_tol: float = 1e-9
    expect: dict = field(default_factory=dict)
    long: dict = field(default_factory=dict)
    quick: bool = False
    note: str = ""
    known_bug: str = ""

    @property
    def t_end(self):
        return self.grid[-1]

    @property
    def affine(self):
        return int(self.start.get("kinetic.law", 1)) in (1, 2) or (
            int(self.start.get("kinetic.law", 1)) == 3 and self.start.get("kinetic.F_stribeck", 0.3) == 0.0)


def uniform(t_end, h, t0=0.0):
    """``t0, t0 + h, ...`` up to ``t_end`` (the last point is ``t_end``); times as k*h, no accumulation."""
    n = max(1, int(math.ceil((t_end - t0) / h - 1e-9)))
    grid = [t0 + k * h for k in range(n)] + [t_end]
    return tuple(sorted(set(grid)))


def random_grid(seed, t_end, h_min, h_max, t0=0.0):
    """Log-uniform random steps in ``[h_min, h_max]`` up to ``t_end``."""
    rng = np.random.default_rng(seed)
    grid = [t0]
    while grid[-1] < t_end:
        h = float(np.exp(rng.uniform(math.log(h_min), math.log(h_max))))
        grid.append(min(grid[-1] + h, t_end))
    return tuple(grid)


def refined(grid, seed, max_parts=3):
    """``grid`` with every step split into 1..max_parts random pieces."""
    rng = np.random.default_rng(seed)
    out = [grid[0]]
    for a, b in zip(grid, grid[1:]):
        parts = int(rng.integers(1, max_parts + 1))
        inner = np.sort(rng.uniform(a, b, parts - 1))
        out += [float(t) for t in inner if a < t < b] + [b]
    return tuple(out)


def _every(grid, n):
    """Every ``n``-th point of ``grid`` and its end: a coarser grid with the same float times."""
    return tuple(grid[::n]) + ((grid[-1],) if (len(grid) - 1) % n else ())


def params_of(start):
    """The reference's own laws (SPEC formulas, not the runtime's) for a case's ``start`` with M = kappa = 1
    unless given; every law parameter must be in ``start``."""
    return parameters_from_values({"M": 1.0, "kappa": 1.0, **start})


# ---------------------------------------------------------------------------
# critical drive velocities (grazing), computed independently
# ---------------------------------------------------------------------------


def _graze_margin_affine(p, v_drive):
    """``max v - v_drive`` over the first return of the slip that starts at breakaway (closed form)."""
    x_s = p.static.force(0.0) / p.kappa
    slip = AffineSlip(p, 1, 0.0, x_s, v_drive, v_drive, 0.0)
    period = 2.0 * math.pi * math.sqrt(p.M / p.kappa)
    taus = slip.extrema(3.0 * period)
    if len(taus) < 2:
        return -v_drive
    return float(slip.state(taus[1])[1]) - v_drive


def graze_velocity_affine(p, lo, hi):
    """Drive velocity in ``[lo, hi]`` at which the first slip just grazes ``v = v_drive`` (affine law)."""
    return brentq(lambda vd: _graze_margin_affine(p, vd), lo, hi, xtol=1e-300, rtol=4 * np.finfo(float).eps,
                  maxiter=500)


def _graze_margin_numeric(p, v_drive):
    """As :func:`_graze_margin_affine` for any law, with scipy's DOP853 at rtol 1e-13 (a third integrator)."""
    x_s = p.static.force(0.0) / p.kappa

    def rhs(t, y):
        u = v_drive - y[1]
        force = p.kinetic.force(u) if u >= 0.0 else p.kinetic.force(0.0) + p.kinetic.slope(0.0) * u
        return [y[1], (-p.kappa * y[0] + force) / p.M]

    def accel(t, y):
        return rhs(t, y)[1]

    accel.direction = -1.0  # maximum of v: acceleration goes from + to -
    period = 2.0 * math.pi * math.sqrt(p.M / p.kappa)
    sol = solve_ivp(rhs, (0.0, 3.0 * period), [x_s, v_drive], method="DOP853", rtol=1e-13, atol=1e-15,
                    events=accel, dense_output=True)
    maxima = [t for t in sol.t_events[0] if t > 1e-9 * period]
    if not maxima:
        return -v_drive
    return float(sol.sol(maxima[0])[1]) - v_drive


def graze_velocity_numeric(p, lo, hi):
    """Critical drive velocity for a general law (see :func:`_graze_margin_numeric`)."""
    return brentq(lambda vd: _graze_margin_numeric(p, vd), lo, hi, xtol=1e-300, rtol=1e-14, maxiter=200)


# ---------------------------------------------------------------------------
# the groups
# ---------------------------------------------------------------------------


def _scale_cases():
    cases = []
    for M in (1e-6, 1.0, 1e6):
        for kappa in (1e-6, 1.0, 1e6):
            T0, V0 = math.sqrt(M / kappa), 1.0 / math.sqrt(kappa * M)
            start = {**COULOMB, "M": M, "kappa": kappa, "kinetic.F0": 0.5, "static.F0": 1.0, "v_drive": 0.2 * V0,
                     "v_start": 0.2 * V0}
            quick = (M, kappa) in ((1e-6, 1e6), (1e6, 1e-6))
            cases.append(Case(f"scale-coulomb-M{M:g}-k{kappa:g}", "scale", start, uniform(40 * T0, T0 / 3),
                              expect={"min_events": 4}, quick=quick))
            if M != kappa:
                stribeck = {**start, "kinetic.law": 3, "kinetic.F0": 0.4, "kinetic.F_stribeck": 0.3,
                            "kinetic.v_stribeck": 0.5 * V0, "kinetic.gamma": 0.05 * math.sqrt(kappa * M),
                            "kinetic.delta": 1.0}
                cases.append(Case(f"scale-stribeck-M{M:g}-k{kappa:g}", "scale", stribeck, uniform(40 * T0, T0 / 3),
                                  tol=1e-7, expect={"min_events": 4}))
    # stiff slip inside one long step: period 6e-6 s, stick 1 s, step 0.7 s
    stiff = {**COULOMB, "M": 1e-6, "kappa": 1e6, "kinetic.F0": 0.5, "static.F0": 1.0, "v_drive": 1e-6,
             "v_start": 1e-6}
    cases.append(Case("scale-stiff-slip-in-long-step", "scale", stiff, uniform(10.0, 0.7), expect={"min_events": 16},
                      quick=True, note="slips of 3e-6 s inside steps of 0.7 s"))
    big_forces = {**COULOMB, "kinetic.F0": 0.5e6, "static.F0": 1e6, "v_drive": 2e5, "v_start": 2e5}
    cases.append(Case("scale-forces-1e6", "scale", big_forces, uniform(40.0, 1 / 3), expect={"min_events": 4}))
    small_forces = {**COULOMB, "kinetic.F0": 0.5e-6, "static.F0": 1e-6, "v_drive": 2e-7, "v_start": 2e-7}
    cases.append(Case("scale-forces-1e-6", "scale", small_forces, uniform(40.0, 1 / 3), expect={"min_events": 4}))
    return cases


def _ratio_cases():
    cases = []
    for label, ratio in (("1+1e-9", 1 + 1e-9), ("1+1e-6", 1 + 1e-6), ("1.5", 1.5), ("10", 10.0), ("1e3", 1e3)):
        start = {**COULOMB, "kinetic.F0": 1.0 / ratio, "static.F0": 1.0, "v_drive": 0.1, "v_start": 0.1}
        cases.append(Case(f"ratio-coulomb-{label}", "ratio", start, uniform(60.0, 0.25), expect={"min_events": 6},
                          quick=label in ("1+1e-9", "1e3")))
    stribeck = {"kinetic.law": 3, "static.law": 1, "kinetic.F0": 0.5, "kinetic.F_stribeck": 0.5 - 1e-9,
                "kinetic.v_stribeck": 0.05, "kinetic.gamma": 0.0, "kinetic.delta": 1.0, "static.F0": 1.0,
                "v_drive": 0.1, "v_start": 0.1}
    cases.append(Case("ratio-stribeck-1+1e-9", "ratio", stribeck, uniform(60.0, 0.25), tol=1e-7,
                      expect={"min_events": 4}))
    # aging: F_S grows to 3 N while F_K = 1e-3 N; each slip overshoots ~500 times before it sticks
    overshoot = {"kinetic.law": 1, "static.law": 3, "kinetic.F0": 1e-3, "static.F0": 1.0, "static.F_inf": 3.0,
                 "static.tau": 1.0, "v_drive": 0.1, "v_start": 0.1}
    cases.append(Case("ratio-aging-overshoots-1e3", "ratio", overshoot, uniform(4000.0, 2.5),
                      expect={"min_overshoots": 500}, quick=True, note="hundreds of overshoots per slip"))
    sigmoid = {"kinetic.law": 3, "static.law": 4, "kinetic.F0": 0.05, "kinetic.F_stribeck": 0.05,
               "kinetic.v_stribeck": 0.05, "kinetic.gamma": 0.0, "kinetic.delta": 2.0, "static.F0": 1.0,
               "static.F_inf": 4.0, "static.tau": 20.0, "static.n": 3.0, "v_drive": 0.1, "v_start": 0.1}
    cases.append(Case("ratio-sigmoid-aging-stribeck", "ratio", sigmoid, uniform(300.0, 0.5), tol=1e-7,
                      expect={"min_overshoots": 2}))
    return cases


def _drive_cases():
    cases = []
    base = {**COULOMB, "kinetic.F0": 0.5, "static.F0": 1.0}
    cases.append(Case("drive-0-slip-to-rest", "drive", {**base, "v_drive": 0.0, "v_start": 2.0, "x_start": 0.3},
                      uniform(30.0, 0.2), expect={"final_mode": 0}, quick=True))
    cases.append(Case("drive-1e-9", "drive", {**base, "v_drive": 1e-9, "v_start": 1e-9}, uniform(1.05e9, 5e6),
                      expect={"min_events": 2}, note="stick of 1e9 s, slip of 3 s inside one 5e6 s step",
                      energy=False))
    aging = {**base, "static.law": 2, "static.A": 0.05, "static.tau": 1.0, "v_drive": 1e-9, "v_start": 1e-9}
    cases.append(Case("drive-1e-9-aging", "drive", aging, uniform(2.1e9, 1e7), expect={"min_events": 2},
                      energy=False, note="no energy check (time resolution 2.4e-7 s at t = 2e9 s); "
                      "aging: the stuck phase is re-searched every 1e6 s; breakaway at 2.05e9 s"))
    cases.append(Case("drive-1e-3", "drive", {**base, "v_drive": 1e-3, "v_start": 1e-3}, uniform(3000.0, 7.0),
                      expect={"min_events": 4}))
    cases.append(Case("drive-1", "drive", {**base, "v_drive": 1.0, "v_start": 1.0}, uniform(60.0, 0.1),
                      expect={"min_events": 10}))
    cases.append(Case("drive-1e3", "drive", {**base, "v_drive": 1e3, "v_start": 1e3}, uniform(60.0, 0.1),
                      expect={"min_events": 10}, quick=True))
    stribeck = {"kinetic.law": 3, "static.law": 1, "kinetic.F0": 0.4, "kinetic.F_stribeck": 0.3,
                "kinetic.v_stribeck": 0.05, "kinetic.gamma": 0.05, "kinetic.delta": 1.0, "static.F0": 1.0}
    for vd in (0.0, 1e-3, 1.0):
        cases.append(Case(f"drive-stribeck-{vd:g}", "drive", {**stribeck, "v_drive": vd, "v_start": vd + 0.5},
                          uniform(60.0, 0.2), tol=1e-7))
    # reversing drives: square wave and a sampled sine (v_drive exactly 0 at some steps)
    grid = uniform(90.0, 0.25)
    square = tuple((t, 0.3 if (t // 15.0) % 2 == 0 else -0.3, 0.0) for t in grid[1:-1] if t % 15.0 == 0.0)
    cases.append(Case("drive-reversing-square", "drive", {**base, "v_drive": 0.3, "v_start": 0.3}, grid, square,
                      expect={"min_events": 8}, quick=True))
    cases.append(Case("drive-reversing-square-stribeck", "drive", {**stribeck, "v_drive": 0.3, "v_start": 0.3}, grid,
                      square, tol=1e-7, expect={"min_events": 8}))
    sine = tuple((t, round(0.4 * math.sin(2 * math.pi * t / 30.0), 12), 0.0) for t in grid[1:-1])
    aging = {"kinetic.law": 2, "static.law": 2, "kinetic.F0": 0.4, "kinetic.gamma": 0.1, "static.F0": 1.0,
             "static.A": 0.2, "static.tau": 1.0}
    cases.append(Case("drive-reversing-sine-aging", "drive", {**aging, "v_drive": 0.0}, grid, sine,
                      expect={"min_events": 4}))
    return cases


def _overdamped_cases():
    cases = []
    for factor in (1e2, 1e4, 1e6):  # F_K' = factor sqrt(kappa M)
        start = {"kinetic.law": 2, "static.law": 1, "kinetic.F0": 0.5, "kinetic.gamma": factor, "static.F0": 1.0,
                 "v_drive": 0.1, "v_start": 0.1}
        slow = factor  # gamma / kappa
        cases.append(Case(f"overdamped-viscous-{factor:g}", "overdamped", start, uniform(3.0 * slow, slow / 40.0),
                          quick=factor == 1e6, note="fast relaxation M/gamma, then drift over gamma/kappa"))
    stiff = {"kinetic.law": 3, "static.law": 1, "kinetic.F0": 0.4, "kinetic.F_stribeck": 0.3,
             "kinetic.v_stribeck": 0.05, "kinetic.gamma": 1e3, "kinetic.delta": 1.0, "static.F0": 1.0,
             "v_drive": 0.1, "v_start": 0.1}
    cases.append(Case("overdamped-stribeck-gamma1e3", "overdamped", stiff, uniform(3000.0, 25.0), tol=1e-6,
                      reference=False, note="stiff numeric slip (Rosenbrock); reference too slow, energy + invariants"))
    weakening = {"kinetic.law": 3, "static.law": 1, "kinetic.F0": 0.5, "kinetic.F_stribeck": 0.3,
                 "kinetic.v_stribeck": 1e-6, "kinetic.gamma": 0.0, "kinetic.delta": 1.0, "static.F0": 1.0,
                 "v_drive": 0.1, "v_start": 0.1}
    cases.append(Case("overdamped-stribeck-weakening-3e5", "overdamped", weakening, uniform(60.0, 0.25), tol=1e-6,
                      expect={"min_events": 4}, quick=True, note="F_K'(0) = -3e5 sqrt(kappa M)"))
    for M in (4e-3, 4e-7):  # elmer-fig3 laws with a tiny mass: |F_K'| / sqrt(kappa M) ~ 50 and 5e3
        fig3 = {"kinetic.law": 4, "static.law": 1, "kinetic.gamma1": 3.0, "kinetic.gamma2": 0.1,
                "kinetic.v_tilde": 0.2, "kinetic.dv": 0.05, "static.F0": 1.0, "M": M, "kappa": 1.0,
                "v_drive": 0.25, "v_start": 0.25}
        cases.append(Case(f"overdamped-lubricated-M{M:g}", "overdamped", fig3, uniform(20.0, 0.05), tol=1e-6,
                          reference=M > 1e-5, note="relaxation oscillations on the weakening branch"))
    return cases


def _grazing_cases():
    cases = []
    viscous = {"kinetic.law": 2, "static.law": 1, "kinetic.F0": 0.5, "kinetic.gamma": 0.1, "static.F0": 1.0}
    vc = graze_velocity_affine(params_of(viscous), 0.05, 2.0)
    for label, factor, expect in (("below", 1 - 1e-9, {"min_events": 4}), ("above", 1 + 1e-9, {"max_events": 1})):
        vd = vc * factor
        start = {**viscous, "v_drive": vd, "v_start": vd}
        cases.append(Case(f"grazing-viscous-{label}-1e-9", "grazing", start, uniform(80.0, 0.25), tol=1e-7,
                          expect=expect, quick=True, note=f"v_c = {vc!r} m/s"))
    stribeck = {"kinetic.law": 3, "static.law": 1, "kinetic.F0": 0.4, "kinetic.F_stribeck": 0.3,
                "kinetic.v_stribeck": 0.1, "kinetic.gamma": 0.3, "kinetic.delta": 2.0, "static.F0": 1.0}
    vc = graze_velocity_numeric(params_of(stribeck), 0.05, 1.0)
    for label, factor, expect in (("below", 1 - 1e-7, {"min_events": 4}), ("above", 1 + 1e-7, {"max_events": 1})):
        vd = vc * factor
        start = {**stribeck, "v_drive": vd, "v_start": vd, "solver.rtol": 1e-12}
        cases.append(Case(f"grazing-stribeck-{label}-1e-7", "grazing", start, uniform(60.0, 0.25), tol=1e-6,
                          expect=expect, quick=label == "below",  # a graze inside a numeric slip
                          note=f"v_c = {vc!r} m/s (scipy DOP853, rtol 1e-13)"))
    return cases


def _chatter_cases():
    cases = []
    equal = {**COULOMB, "kinetic.F0": 1.0, "static.F0": 1.0, "v_drive": 0.1, "v_start": 0.1}
    cases.append(Case("chatter-coulomb-FK-equals-FS", "chatter", equal, uniform(60.0, 0.25),
                      expect={"min_events": 8}, quick=True, note="zero-length sticks"))
    viscous = {"kinetic.law": 2, "static.law": 1, "kinetic.F0": 1.0, "kinetic.gamma": 0.2, "static.F0": 1.0,
               "v_drive": 0.1, "v_start": 0.1}
    cases.append(Case("chatter-viscous-FK0-equals-FS", "chatter", viscous, uniform(60.0, 0.25)))
    stribeck = {"kinetic.law": 3, "static.law": 2, "kinetic.F0": 0.6, "kinetic.F_stribeck": 0.4,
                "kinetic.v_stribeck": 0.05, "kinetic.gamma": 0.0, "kinetic.delta": 1.0, "static.F0": 1.0,
                "static.A": 0.05, "static.tau": 0.1, "v_drive": 0.1, "v_start": 0.1}
    cases.append(Case("chatter-stribeck-FK0-equals-FS-aging", "chatter", stribeck, uniform(60.0, 0.25), tol=1e-7))
    soft = {**COULOMB, "kappa": 1e-12, "kinetic.F0": 0.5, "static.F0": 1.0, "v_drive": 0.1, "v_start": 2.0}
    cases.append(Case("chatter-kappa-1e-12", "chatter", soft, uniform(100.0, 0.5), expect={"final_mode": 0}))
    edge = {**COULOMB, "kappa": 1e-9, "kinetic.F0": 0.5, "static.F0": 1.0, "F_ext": 1.0 - 1e-12,
            "v_drive": -1e-3, "v_start": -1e-3}
    cases.append(Case("chatter-holding-at-the-limit", "chatter", edge, uniform(20.0, 0.1), quick=True,
                      expect={"min_events": 1}, note="F_ext within 1e-12 N of F_S, kappa 1e-9"))
    weakening = {**COULOMB, "static.law": 4, "kinetic.F0": 0.5, "static.F0": 1.0, "static.F_inf": 0.6,
                 "static.tau": 1.0, "static.n": 0.5, "v_drive": 0.1, "v_start": 0.1}
    cases.append(Case("chatter-sigmoid-weakening-n0.5", "chatter", weakening, uniform(60.0, 0.25),
                      expect={"min_events": 4}, note="F_S falls from 1 N with infinite slope at t_stick = 0"))
    balance = {**COULOMB, "static.law": 3, "kinetic.F0": 1.0, "static.F0": 1.0, "static.F_inf": 0.5,
               "static.tau": 1.0, "F_ext": 1.0, "v_drive": 0.0, "v_start": 0.0}
    cases.append(Case("chatter-degenerate-balance", "chatter", balance, uniform(10.0, 0.25), reference=False,
                      energy=False, expect={"error": "event chain at t = 0.0 s"},
                      note="F_ext = F_S(0) = F_K(0+), F_S weakening: stick and slip cannot be decided; a clean error"))
    kink = {**COULOMB, "static.law": 4, "kinetic.F0": 0.0, "static.F0": 1.0, "static.F_inf": 0.5,
            "static.tau": 1.0, "static.n": 1.0, "x_start": 1e-229, "v_drive": -1.0, "v_start": -1.0}
    cases.append(Case("chatter-sigmoid-kink-at-start", "chatter", kink, uniform(3.0, 0.25), expect={"min_events": 1},
                      note="found by hypothesis: the holding force changes sign 1e-229 s after the start"))
    side = {"kinetic.law": 1, "static.law": 4, "kinetic.F0": 0.125, "static.F0": 1.0, "static.F_inf": 0.5,
            "static.tau": 1.0, "static.n": 1.0, "x_start": -0.3842606550925819, "v_drive": 0.36787944117144233,
            "v_start": 0.36787944117144233}
    cases.append(Case("chatter-weakening-aging-kink-rounding", "chatter", side, uniform(10.0, 0.25),
                      expect={"min_events": 1}, note="found by hypothesis (exploration mode); fixed"))
    rising = {"kinetic.law": 1, "static.law": 4, "kinetic.F0": 0.5, "static.F0": 1.0, "static.F_inf": 2.0,
              "static.tau": math.exp(2.0), "static.n": 2.0, "x_start": -0.015112811684831473, "v_drive": 1.59375,
              "v_start": 1.59375}
    cases.append(Case("chatter-strengthening-sigmoid-kink-rounding", "chatter", rising, uniform(10.0, 0.25),
                      expect={"min_events": 2},
                      note="found by hypothesis (exploration mode): broke away 3.6 s late; fixed"))
    jitter = {**COULOMB, "kinetic.F0": 1.0, "static.F0": 1.0, "v_drive": 0.0, "F_ext": 0.0}
    steps = tuple((t, 0.0, (1.0 if k % 2 else -1.0) * (1.0 - 1e-15)) for k, t in enumerate(uniform(5.0, 0.05)[1:-1]))
    cases.append(Case("chatter-force-at-limit-alternating", "chatter", jitter, uniform(5.0, 0.05), steps,
                      expect={"max_events": 0}, note="|F_ext| alternates 1 - 1e-15 N around a held block"))
    return cases


def _comm_step_cases():
    cases = []
    fast = {**COULOMB, "M": 1e-12, "kappa": 1.0, "kinetic.F0": 0.5, "static.F0": 1.0, "x_start": 0.999,
            "v_drive": 1e3, "v_start": 1e3}
    grid = uniform(2e-5, 1e-9)
    cases.append(Case("comm-step-1e-9", "comm-step", fast, grid, refine=_every(grid, 1000), energy=False,
                      expect={"min_events": 2}, note="20000 steps; compared with a 1e-6 grid at common points"))
    base = {**COULOMB, "kinetic.F0": 0.5, "static.F0": 1.0, "v_drive": 0.1, "v_start": 0.1}
    stribeck = {"kinetic.law": 3, "static.law": 1, "kinetic.F0": 0.4, "kinetic.F_stribeck": 0.3,
                "kinetic.v_stribeck": 0.05, "kinetic.gamma": 0.0, "kinetic.delta": 1.0, "static.F0": 1.0,
                "v_drive": 0.1, "v_start": 0.1}
    micro = {**base, "x_start": 1.0 - 3e-5}
    cases.append(Case("comm-step-1e-6", "comm-step", micro, uniform(1e-3, 1e-6), refine=refined(uniform(1e-3, 1e-6), 1),
                      energy=False, expect={"min_events": 1}, note="breakaway at 3e-4 s"))
    grid = uniform(30.0, 1e-3)
    cases.append(Case("comm-step-1e-3", "comm-step", stribeck, grid, tol=1e-7, energy=False,
                      refine=_every(grid, 500), note="compared with every 500th point as a grid"))
    cases.append(Case("comm-step-1", "comm-step", stribeck, uniform(200.0, 1.0), tol=1e-7,
                      refine=refined(uniform(200.0, 1.0), 2), quick=True))
    cases.append(Case("comm-step-1e2", "comm-step", base, uniform(3e3, 1e2), refine=refined(uniform(3e3, 1e2), 3)))
    cases.append(Case("comm-step-1e4", "comm-step", base, uniform(1e5, 1e4), refine=refined(uniform(1e5, 1e4), 4),
                      energy=False, expect={"min_events": 1000}, note="~750 stick-slip cycles per step"))
    for seed, start, tol in ((11, base, 1e-9), (12, stribeck, 1e-7), (13, {**stribeck, "static.law": 2,
                                                                          "static.A": 0.1, "static.tau": 1.0}, 1e-7)):
        grid = random_grid(seed, 100.0, 1e-9, 10.0)
        cases.append(Case(f"comm-step-random-{seed}", "comm-step", start, grid, tol=tol,
                          refine=refined(grid, seed), quick=seed == 12, note=f"{len(grid) - 1} log-uniform steps"))
    return cases


def _input_jump_cases():
    cases = []
    laws = {
        "coulomb": {**COULOMB, "kinetic.F0": 0.5, "static.F0": 1.0},
        "stribeck": {"kinetic.law": 3, "static.law": 1, "kinetic.F0": 0.4, "kinetic.F_stribeck": 0.3,
                     "kinetic.v_stribeck": 0.05, "kinetic.gamma": 0.05, "kinetic.delta": 1.0, "static.F0": 1.0},
        "aging": {"kinetic.law": 2, "static.law": 3, "kinetic.F0": 0.4, "kinetic.gamma": 0.2, "static.F0": 1.0,
                  "static.F_inf": 1.8, "static.tau": 2.0},
    }
    for seed, (label, law) in enumerate(laws.items()):
        rng = np.random.default_rng(100 + seed)
        for h in (0.3, 0.05):
            grid = uniform(60.0 if h > 0.1 else 15.0, h)
            v = rng.choice([-1.0, -0.1, 0.0, 0.0, 0.1, 0.5, 1.0], size=len(grid)) * rng.uniform(0.5, 1.0, len(grid))
            F = rng.uniform(-0.9, 0.9, size=len(grid))
            steps = tuple((t, float(v[k]), float(F[k])) for k, t in enumerate(grid[1:-1], start=1))
            start = {**law, "v_drive": float(v[0]), "F_ext": float(F[0]), "v_start": float(v[0])}
            cases.append(Case(f"input-jumps-{label}-h{h:g}", "input-jumps", start, grid, steps,
                              tol=1e-9 if label != "stribeck" else 1e-7, quick=(label, h) == ("stribeck", 0.3)))
    return cases


def _long_cases():
    coulomb = {**COULOMB, "kinetic.F0": 0.5, "static.F0": 1.0, "v_drive": 0.1, "v_start": 0.1}
    fast = {**COULOMB, "kinetic.F0": 0.5, "static.F0": 1.0, "v_drive": 10.0, "v_start": 10.0}
    stribeck = {"kinetic.law": 3, "static.law": 1, "kinetic.F0": 0.4, "kinetic.F_stribeck": 0.3,
                "kinetic.v_stribeck": 0.05, "kinetic.gamma": 0.0, "kinetic.delta": 1.0, "static.F0": 1.0,
                "v_drive": 0.1, "v_start": 0.1}
    return [
        Case("long-coulomb-1e6-time", "long", coulomb, (0.0, 1e6), reference=False, energy=False,
             long={"kind": "time", "amount": 1e6, "step": 1e3, "closed_form": True},
             note="FMU, 1000 steps of 1e3 s (~148000 events); closed-form cycle"),
        Case("long-coulomb-1e6-events", "long", fast, (0.0, 0.0), reference=False, energy=False,
             long={"kind": "events", "amount": 1_000_000, "step": 500.0, "closed_form": True},
             note="FMU, steps of 500 s until 1e6 events (~3.1e6 s); closed-form cycle"),
        Case("long-stribeck-1e5-time", "long", stribeck, (0.0, 1e5), reference=False, energy=False,
             long={"kind": "time", "amount": 1e5, "step": 1e3, "closed_form": False},
             note="FMU, numeric slips (~6.4e5 RK steps); cycle from the reference integrator"),
        Case("long-coulomb-quick", "long", coulomb, (0.0, 1e5), reference=False, energy=False, quick=True,
             long={"kind": "time", "amount": 1e5, "step": 1e3, "closed_form": True}, note="CI: 1e5 s"),
    ]


GROUPS = ("scale", "ratio", "drive", "overdamped", "grazing", "chatter", "comm-step", "input-jumps", "long")


def stress_cases(quick=False, groups=None):
    """The stress matrix; ``quick`` keeps the CI subset; ``groups`` filters by group name."""
    cases = (_scale_cases() + _ratio_cases() + _drive_cases() + _overdamped_cases() + _grazing_cases()
             + _chatter_cases() + _comm_step_cases() + _input_jump_cases() + _long_cases())
    if quick:
        cases = [c for c in cases if c.quick]
    else:
        cases = [c for c in cases if c.name != "long-coulomb-quick"]
    if groups:
        cases = [c for c in cases if c.group in groups]
    return cases
