"""Every bifurcation point the analysis tests claim, confirmed by a method that shares no code with
``stickslip.analysis`` (issue 22).

The claimed points are ``ELMER_POINTS`` (elmer-fig3, printed to 7 decimals: the analysis' value rounded, so
within ``ROUNDING`` of it) and ``AGING_SADDLE_NODES`` (``test_analysis_cli.py``). Each test here

1. lets the analysis locate the point (a narrow bracket around the claimed value, refined far below 1e-7),
2. asserts that the claimed value is that result rounded (``abs=ROUNDING``), and
3. evaluates an independent indicator at the analysis' value minus and plus a small ``delta`` (m/s) and asserts
   the two states of the bifurcation on the two sides.

So the independent root lies within ``delta + ROUNDING`` of the claimed value: every point is confirmed to its
claimed precision 1e-7 m/s, the analysis itself to ``delta`` (measured agreement given with each ``delta``).
The independent tools: the reference integrator (``stickslip.reference``: its own laws, stepping and events),
scipy's ``solve_ivp`` on SPEC's formulas written here, and SPEC section 3's closed forms. The Hopf points are
confirmed in ``test_analysis_cli.py`` (brentq on ``F_K'`` of SPEC's formula).
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, minimize_scalar

from stickslip.analysis import aging_map, boundary, sliding_limit_cycles, stickslip_cycle
from stickslip.core import Constant, Coulomb, Lubricated, Parameters, Sigmoid
from stickslip.reference import parameters_from_values, simulate_reference
from test_analysis_cli import AGING_SADDLE_NODES, ELMER_POINTS

ROUNDING = 5e-8  # m/s: the claimed points are the analysis' values printed to 7 decimals

# elmer-fig3 (SPEC section 2): N s/m, N s/m, m/s, m/s; M kg, kappa N/m, F_S(0) N
G1, G2, V_TILDE, DV = 3.0, 0.1, 0.2, 0.05
M, KAPPA, F_S0 = 40.0, 1.0, 1.0
PERIOD = 2.0 * math.pi * math.sqrt(M / KAPPA)  # s, of the undamped spring-block


def claimed(kind):
    """The claimed elmer-fig3 drive velocities (m/s) of one kind of point."""
    return [v for k, v in ELMER_POINTS if k == kind]


def test_every_claimed_kind_is_confirmed_somewhere():
    """A new kind of point in ELMER_POINTS must get its own independent check (here or with the Hopf points)."""
    assert {k for k, _ in ELMER_POINTS} == {"stick-slip-boundary", "fold", "grazing", "boundary-switch", "hopf"}


def elmer():
    """The analysis' model of elmer-fig3 (the code under test)."""
    return Parameters(M, KAPPA, Lubricated(gamma1=G1, gamma2=G2, v_tilde=V_TILDE, dv=DV), Constant(F0=F_S0))


# ----------------------------------------------------------------------
# stick-slip boundaries: does the slip from the onset ever stick? (the reference integrator)
# ----------------------------------------------------------------------

#: m/s; the reference's own roots (bisection to 1e-12 on "sticks within 10 periods") lie 7e-13 (graze) to
#: 1.0e-9 (zero-stick: the reference's x error at rtol 1e-12, 8e-10 m, moves them) from the analysis'
SS_DELTA = 1e-8


@pytest.fixture(scope="module")
def stick_slip_changes():
    """The analysis' stick-slip changes ``{claimed v: (v_drive, "appears"/"disappears", mechanism)}``."""
    claims = claimed("stick-slip-boundary")
    grid = [v + s * 1e-5 for v in claims for s in (-1, 1)]
    changes = stickslip_cycle.existence_changes(elmer(), 0.0, 0.0, v_grid=grid, tol=1e-10)
    assert len(changes) == len(claims), f"the analysis finds {changes}, one within 1e-5 m/s of each of {claims}"
    return dict(zip(claims, changes))


def reference_stick(v_drive):
    """The first stick of the reference run from a stuck start at ``v_drive`` (m/s), or None if it never sticks
    within 10 periods: ``(time s, stick duration s)``. The block breaks away at the onset ``x = F_S(0)/kappa``
    with ``v = v_drive``, where every stick of the stick-slip cycle ends: the cycle exists iff this slip sticks."""
    p = parameters_from_values({"M": M, "kappa": KAPPA, "kinetic.law": "lubricated", "kinetic.gamma1": G1,
                                "kinetic.gamma2": G2, "kinetic.v_tilde": V_TILDE, "kinetic.dv": DV,
                                "static.law": "constant", "static.F0": F_S0})
    x0 = (F_S0 - 1e-3) / KAPPA
    run = simulate_reference(p, x0, v_drive, [(0.0, v_drive, 0.0)], np.array([0.0, 10.0 * PERIOD]))
    sticks = [k for k, e in enumerate(run.events) if e.kind == "stick"]
    if not sticks:
        return None
    k = sticks[0]
    assert [e.kind for e in run.events[k + 1:k + 2]] == ["slip"]
    return run.events[k].t, run.events[k + 1].t - run.events[k].t


@pytest.mark.parametrize("v_claimed", claimed("stick-slip-boundary"))
def test_stick_slip_boundary_against_the_reference_integrator(v_claimed, stick_slip_changes):
    """Stick-slip appears or disappears: on one side of the point the slip from the onset sticks (in the first
    slip period), on the other it never does. The mechanism shows in the stick: a graze keeps a stick of finite
    length (measured 1.0 to 17 s: the slip touches v = v_drive where the spring holds it), a zero-stick boundary
    shrinks it to nothing (measured 1.0e-8 and 2.3e-8 s: the return is at |kappa x| = F_S(0) to 1e-8 N)."""
    v, change, mechanism = stick_slip_changes[v_claimed]
    assert v == pytest.approx(v_claimed, abs=ROUNDING)
    below, above = reference_stick(v - SS_DELTA), reference_stick(v + SS_DELTA)
    assert (below is not None, above is not None) == ((True, False) if change == "disappears" else (False, True))
    t_stick, duration = below or above
    assert t_stick < 1.2 * PERIOD
    assert (duration < 1e-6) == (mechanism == "zero-stick") and (duration > 0.5) == (mechanism == "graze")


# ----------------------------------------------------------------------
# sliding cycles, grazings and the special boundary: solve_ivp on SPEC's slip flow (mode +1, F_ext = 0)
# ----------------------------------------------------------------------


def kinetic(u):
    """SPEC's law 4, ``F_K(u)`` (N) at the sliding speed ``u`` (m/s); for ``u < 0`` the same formula (smooth
    through 0: the slip flow continued past ``v_rel = 0``, met only by orbits that graze it)."""
    w = u - V_TILDE
    return u * (G1 + G2 + (G2 - G1) * w / math.sqrt(DV * DV + w * w)) / 2


def acceleration(x, v, v_drive):
    """``dv/dt`` (m/s^2) of a mode +1 slip at ``x`` (m), ``v`` (m/s): ``(-kappa x + F_K(v_drive - v))/M``."""
    return (-KAPPA * x + kinetic(v_drive - v)) / M


def slip_orbit(x0, v0, v_drive, t_end):
    """The mode +1 slip flow from ``(x0, v0)`` over ``(0, t_end)`` s (``t_end < 0``: backward), DOP853 at rtol
    1e-12. Events: 0, ``v = 0`` falling (the maxima of ``x``); 1, ``dv/dt = 0`` (the extrema of ``v``: there
    ``d2v/dt2 = -kappa v/M``, so the maxima are those with ``v > 0``)."""

    def x_maximum(t, y):
        return y[1]

    def v_extremum(t, y):
        return acceleration(y[0], y[1], v_drive)

    x_maximum.direction = -1
    return solve_ivp(lambda t, y: [y[1], acceleration(y[0], y[1], v_drive)], (0.0, t_end), [x0, v0],
                     method="DOP853", rtol=1e-12, atol=1e-14, events=[x_maximum, v_extremum])


def revolution(x, v_drive):
    """The Poincare return map on the section ``v = 0`` at the maxima of ``x``: from ``(x, 0)`` (m) to the next
    maximum of ``x``; returns ``(that x (m), the largest v on the way (m/s))``."""
    sol = slip_orbit(x, 0.0, v_drive, 1.5 * PERIOD)
    t_back, x_back = next((t, y[0]) for t, y in zip(sol.t_events[0], sol.y_events[0]) if t > 0.5 * PERIOD)
    return x_back, max(y[1] for t, y in zip(sol.t_events[1], sol.y_events[1]) if t < t_back)


#: at each claimed grazing point: an x (m) bracket of the stable sliding cycle that grazes (it alone changes the
#: sign of P(x) - x there; the unstable cycle of the same branch lies below 0.9 m), and the side of the point
#: where it crosses v = v_drive (its branch grows towards that side)
GRAZING_CYCLE = {0.1620558: ((1.10, 1.18), "above"), 0.7850776: ((5.05, 5.18), "below")}
#: m/s; the roots of both margins below (bisection to 1e-12) lie 1.4e-12 to 7.9e-11 from the analysis'
GRAZE_DELTA = 2e-9


def cycle_top_margin(v_drive, bracket):
    """``v_max - v_drive`` (m/s) of the sliding cycle in ``bracket`` (brentq on ``P(x) - x``): > 0 iff it
    crosses ``v = v_drive``, i.e. is no sliding cycle."""
    x = brentq(lambda x: revolution(x, v_drive)[0] - x, *bracket, xtol=1e-14)
    return revolution(x, v_drive)[1] - v_drive


def backward_margin(v_drive):
    """The special stick-slip boundary (SPEC section 3) followed backward from the graze point ``(F_K(0+)/kappa,
    v_drive)``: its first maximum of ``v`` minus ``v_drive`` (m/s). >= 0 iff it meets the stick line again; < 0:
    the maxima fall for ever (a planar flow), it spirals."""
    sol = slip_orbit(kinetic(0.0) / KAPPA, v_drive, v_drive, -1.5 * PERIOD)
    return next(y[1] for t, y in zip(sol.t_events[1], sol.y_events[1]) if t < -0.1 * PERIOD and y[1] > 0.0) - v_drive


@pytest.fixture(scope="module")
def return_map():
    return sliding_limit_cycles.ReturnMap(elmer())


def check_cycle_point(refine, rmap, v_claimed, bracket, side, holds, delta):
    """Steps 1 to 3 (see the module) for a point of the sliding cycles: ``refine`` is the analysis'
    ``refine_folds`` or ``refine_grazings``, started in the middle of the x ``bracket`` (m); the independent
    ``holds(v_drive, bracket)`` must be true only on ``side`` (``"above"`` or ``"below"``) of the point."""
    sigma = math.sqrt(KAPPA / M) * (0.5 * (bracket[0] + bracket[1]) - kinetic(v_claimed) / KAPPA)
    (point,) = refine(rmap, [(sigma, v_claimed)])
    assert point is not None, f"the analysis finds no such point near {v_claimed} m/s"
    assert point.v_drive == pytest.approx(v_claimed, abs=ROUNDING)
    below, above = (holds(point.v_drive + s * delta, bracket) for s in (-1, 1))
    assert (below, above) == ((False, True) if side == "above" else (True, False))


@pytest.mark.parametrize("v_claimed", claimed("grazing"))
def test_grazing_point_against_a_return_map_of_solve_ivp(v_claimed, return_map):
    """The stable sliding cycle's largest velocity reaches v_drive: on one side of the point it stays under
    v_drive, on the other it crosses (and is no sliding cycle)."""
    check_cycle_point(sliding_limit_cycles.refine_grazings, return_map, v_claimed, *GRAZING_CYCLE[v_claimed],
                      lambda v, bracket: cycle_top_margin(v, bracket) > 0.0, GRAZE_DELTA)


@pytest.mark.parametrize("v_claimed", claimed("boundary-switch"))
def test_boundary_switch_against_the_backward_orbit_of_solve_ivp(v_claimed):
    """The special boundary switches between ending on the stick line and spiralling: the sign of its first
    backward maximum above v_drive changes, in the direction the analysis names."""
    switches = boundary.boundary_switches(elmer(), [v_claimed - 1e-5, v_claimed + 1e-5], tol=1e-10)
    assert len(switches) == 1, f"the analysis finds {switches} within 1e-5 m/s"
    ((v, below, above),) = switches
    assert v == pytest.approx(v_claimed, abs=ROUNDING)
    fate = {True: "stick-line", False: "spiral"}
    assert (fate[backward_margin(v - GRAZE_DELTA) >= 0.0], fate[backward_margin(v + GRAZE_DELTA) >= 0.0]) == (
        below, above)
    assert below != above


#: at each claimed fold: an x (m) bracket holding both its cycles (and the maximum of P(x) - x between them), and
#: the side of the point where they exist
FOLD_CYCLES = {0.1492599: ((0.80, 0.92), "above"), 1.1572381: ((6.70, 6.86), "below")}
#: m/s; the independent roots (bisection to 1e-11) lie 8e-14 (0.149) and 2.8e-10 (1.157) from the analysis'
FOLD_DELTA = 1e-8


def fold_margin(v_drive, bracket):
    """The largest ``P(x) - x`` (m) in ``bracket``, where ``P(x) - x < 0`` at both ends: > 0 iff two sliding
    cycles lie inside (an unstable one, where ``P' > 1``, below a stable one)."""
    lo, hi = bracket
    assert revolution(lo, v_drive)[0] < lo and revolution(hi, v_drive)[0] < hi
    best = minimize_scalar(lambda x: x - revolution(x, v_drive)[0], bounds=bracket, method="bounded",
                           options={"xatol": 1e-9})
    assert lo + 1e-3 < best.x < hi - 1e-3
    return -best.fun


@pytest.mark.parametrize("v_claimed", claimed("fold"))
def test_fold_of_sliding_cycles_against_a_return_map_of_solve_ivp(v_claimed, return_map):
    """Two sliding cycles merge and vanish: present on one side of the point, absent on the other."""
    check_cycle_point(sliding_limit_cycles.refine_folds, return_map, v_claimed, *FOLD_CYCLES[v_claimed],
                      lambda v, bracket: fold_margin(v, bracket) > 0.0, FOLD_DELTA)


# ----------------------------------------------------------------------
# aging saddle-nodes: SPEC section 3's map in closed form (Coulomb slips, sigmoid static friction)
# ----------------------------------------------------------------------

F_K, F_S_0, F_S_INF, TAU, N_SIG = 0.5, 0.8, 1.5, 5.0, 4.0  # N, N, N, s, 1; M = 1 kg, kappa = 1 N/m


def static_force(t):
    """SPEC's sigmoid ``F_S(t)`` (N) after sticking ``t`` s."""
    return F_S_0 + (F_S_INF - F_S_0) * t**N_SIG / (TAU**N_SIG + t**N_SIG)


def static_rate(t):
    """``dF_S/dt`` (N/s) of :func:`static_force`."""
    return (F_S_INF - F_S_0) * N_SIG * TAU**N_SIG * t ** (N_SIG - 1) / (TAU**N_SIG + t**N_SIG) ** 2


def stick_slip_map(x, v_drive):
    """``T(x)`` (m, SPEC section 3): the Coulomb slip from ``(x, v_drive)`` is harmonic about ``F_K/kappa`` and
    returns to ``v = v_drive`` at ``x_s = 2 F_K/kappa - x``, where it sticks (``|kappa x_s| <= F_S(0)`` for ``x``
    in [0.2, 1.8] m); the stick lasts the smallest ``t > 0`` with ``F_S(t) = kappa (x_s + v_drive t)``."""
    x_s = 2.0 * F_K - x
    t = np.linspace(0.0, (F_S_INF - x_s) / v_drive + 1.0, 4001)
    gap = static_force(t) - (x_s + v_drive * t)
    i = int(np.argmax(gap <= 0.0))
    t_stick = brentq(lambda s: static_force(s) - (x_s + v_drive * s), t[i - 1], t[i], xtol=1e-15)
    return static_force(t_stick)


def fixed_points_near(x, v_drive, width=0.05):
    """Number of fixed points of ``T`` near ``x`` (m) at a saddle-node: 2 or 0, from the sign of the extremum of
    ``g = T - x`` (convex ``g``: two iff its minimum is < 0)."""
    h = 1e-3
    g = [stick_slip_map(y, v_drive) - y for y in (x - h, x, x + h)]
    sign = math.copysign(1.0, g[0] - 2.0 * g[1] + g[2])
    best = minimize_scalar(lambda y: sign * (stick_slip_map(y, v_drive) - y), bounds=(x - width, x + width),
                           method="bounded", options={"xatol": 1e-10})
    return 2 if best.fun < 0.0 else 0


#: m/s; the closed form and the analysis (tol 1e-12) agree to 1.5e-13
AGING_TOL = 1e-11


@pytest.fixture(scope="module")
def aging_saddle_nodes():
    q = Parameters(1.0, 1.0, Coulomb(F0=F_K), Sigmoid(F0=F_S_0, F_inf=F_S_INF, tau=TAU, n=N_SIG))
    return aging_map.saddle_nodes(q, 0.2, 0.3, n=21, tol=1e-12)


def test_aging_saddle_nodes_are_the_tangents_of_the_static_law(aging_saddle_nodes):
    """A fixed point ``x* = F_S(t)/kappa`` of the map needs ``x* = x_s + v t`` with ``x_s = 2 F_K/kappa - x*``:
    ``F_S(t) - F_K = kappa v t/2``, the line from ``(0, F_K)`` of slope ``kappa v/2`` meets ``F_S``. Two fixed
    points merge where it touches: ``F_S(t) - F_K = t F_S'(t)``, ``v = 2 F_S'(t)/kappa`` (brentq; two tangents to
    the sigmoid). The map written here has the fixed point there (the stick time is the first root) and two or
    no fixed points on the two sides, as the analysis' test says (bistability between the two)."""
    def tangent(t):
        return static_force(t) - F_K - t * static_rate(t)

    ts = np.linspace(0.1, 20.0, 400)
    touch = [brentq(tangent, a, b, xtol=1e-15) for a, b in zip(ts, ts[1:]) if tangent(a) * tangent(b) < 0.0]
    closed = [2.0 * static_rate(t) for t in touch]
    assert closed == pytest.approx(AGING_SADDLE_NODES, abs=ROUNDING)
    assert [v for v, _ in aging_saddle_nodes] == pytest.approx(closed, abs=AGING_TOL)
    delta = 1e-10  # m/s: the extremum of T - x moves by ~1e-10 m there, 1e5 times its error (brentq to 1e-15 s)
    for (v, x_an), t, inside in zip(aging_saddle_nodes, touch, (1, -1)):
        x = static_force(t)
        assert x_an == pytest.approx(x, abs=1e-6)  # measured 1e-8: the analysis' extremum is flat in x
        assert stick_slip_map(x, 2.0 * static_rate(t)) == pytest.approx(x, abs=1e-12)
        assert fixed_points_near(x, v + inside * delta) == 2 and fixed_points_near(x, v - inside * delta) == 0
