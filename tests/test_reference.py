"""The independent reference integrator against closed forms written here, not taken from the package.

Every law appears twice where it matters: as the coded affine law (closed-form
path of the reference) and as a ``CustomKinetic`` with the same force, which
the reference must integrate numerically (solve_ivp path). The reference's laws
are its own (``stickslip.reference.laws``), never the runtime's.
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from stickslip.reference import (CustomKinetic, CustomStatic, ReferenceEvent, ReferenceParameterError,
                                 ReferenceResult, ReferenceSolverError, simulate_reference)
from stickslip.reference.laws import Constant, Coulomb, ReferenceParameters as Parameters, Sigmoid, Stribeck, Viscous


def coulomb(F0, numeric):
    """``F_K = F0``: the coded law (closed form) or the same force as a callable (numeric path)."""
    return CustomKinetic(lambda u: F0, lambda u: 0.0) if numeric else Coulomb(F0=F0)


PATHS = pytest.mark.parametrize("numeric", [False, True], ids=["closed-form", "numeric"])


def kinds(events):
    return [e.kind for e in events]


# ---------------------------------------------------------------- Coulomb stick-slip


@PATHS
def test_coulomb_stick_slip_cycle(numeric):
    M, kappa, F_S, F_K, v_drive = 2.0, 3.0, 1.0, 0.4, 0.1
    p = Parameters(M, kappa, coulomb(F_K, numeric), Constant(F0=F_S))
    w = math.sqrt(kappa / M)
    # slip: harmonic about F_K/kappa from y0 = (F_S - F_K)/kappa, v = v_drive:
    # v(t) = v_drive cos(wt) - w y0 sin(wt) = R cos(wt + phi) returns to v_drive at wt = 2 pi - 2 phi
    y0 = (F_S - F_K) / kappa
    t_slip = (2.0 * math.pi - 2.0 * math.atan2(w * y0, v_drive)) / w
    t_stick = 2.0 * (F_S - F_K) / (kappa * v_drive)
    t_first = F_S / (kappa * v_drive)  # from x = 0 stuck until kappa x = F_S

    t = np.linspace(0.0, t_first + 4 * (t_slip + t_stick) + t_slip + 1.0, 2001)
    res = simulate_reference(p, 0.0, v_drive, [(0.0, v_drive, 0.0)], t)

    assert isinstance(res, ReferenceResult)
    assert kinds(res.events) == ["slip", "stick"] * 5
    for n in range(5):
        slip, stick = res.events[2 * n], res.events[2 * n + 1]
        start = t_first + n * (t_slip + t_stick)
        assert slip == ReferenceEvent(slip.t, "slip", 0, 1)
        assert slip.t == pytest.approx(start, rel=1e-9)
        assert stick.t == pytest.approx(start + t_slip, rel=1e-9)
    # every slip starts at kappa x = F_S and sticks at kappa x = 2 F_K - F_S
    for slip, stick in zip(res.events[::2], res.events[1::2]):
        x_slip = np.interp(slip.t, res.t, res.x)
        assert kappa * x_slip == pytest.approx(F_S, abs=2e-3)  # grid interpolation only
    stuck = res.mode == 0
    assert np.all(res.v[stuck] == v_drive)
    later = stuck & (res.t > t_first + t_slip) & (res.t < t_first + t_slip + t_stick)
    x_stuck = (2 * F_K - F_S) / kappa + v_drive * (res.t[later] - (t_first + t_slip))
    np.testing.assert_allclose(res.x[later], x_stuck, atol=1e-9)
    np.testing.assert_allclose(res.t_stick[later], res.t[later] - (t_first + t_slip), atol=1e-9)
    assert np.all(res.t_stick[res.mode != 0] == 0.0)


# ---------------------------------------------------------------- viscous slip


def test_viscous_slip_is_damped_harmonic():
    M, kappa, F0, gamma, F_S, v_drive = 1.0, 1.0, 0.5, 0.2, 1.0, 0.1
    p = Parameters(M, kappa, Viscous(F0=F0, gamma=gamma), Constant(F0=F_S))
    t_break = F_S / (kappa * v_drive)
    # M x'' + gamma x' + kappa x = gamma v_drive + F0 from x = F_S/kappa, v = v_drive
    b, x_eq = gamma / (2 * M), (gamma * v_drive + F0) / kappa
    wd = math.sqrt(kappa / M - b * b)
    y0, v0 = F_S / kappa - x_eq, v_drive

    def x_of(tau):
        return x_eq + np.exp(-b * tau) * (y0 * np.cos(wd * tau) + (v0 + b * y0) / wd * np.sin(wd * tau))

    def v_of(tau):
        return np.exp(-b * tau) * (v0 * np.cos(wd * tau) - (kappa / M * y0 + b * v0) / wd * np.sin(wd * tau))

    grid = np.linspace(1e-6, 2 * math.pi / wd, 100001)
    i = np.flatnonzero(v_of(grid) - v_drive >= 0)[0]
    tau_stick = brentq(lambda s: v_of(s) - v_drive, grid[i - 1], grid[i], xtol=1e-15)

    t = np.linspace(0.0, t_break + tau_stick + 1.0, 4001)
    res = simulate_reference(p, 0.0, v_drive, [(0.0, v_drive, 0.0)], t)

    assert kinds(res.events[:2]) == ["slip", "stick"]
    assert res.events[0].t == pytest.approx(t_break, rel=1e-12)
    assert res.events[1].t == pytest.approx(t_break + tau_stick, rel=1e-9)
    slipping = (t > t_break) & (t < t_break + tau_stick)
    assert np.all(res.mode[slipping] == 1)
    np.testing.assert_allclose(res.x[slipping], x_of(t[slipping] - t_break), rtol=0, atol=1e-11)
    np.testing.assert_allclose(res.v[slipping], v_of(t[slipping] - t_break), rtol=0, atol=1e-11)


# ---------------------------------------------------------------- overshoot


@PATHS
def test_overshoot_is_never_a_stick(numeric):
    """F_S/F_K = 20, F_ext steps from 0 to 3.03 at t = 1 with the surface at rest (v_drive = 0).

    Each half swing lasts pi sqrt(M/kappa) and the turning point's distance
    from F_ext/kappa drops by 2 F_K: 2.93, 2.83, ..., 1.03 (> F_S: overshoot),
    then 0.93 (<= F_S: stick).
    """
    M, kappa, F_S, F_K, F_ext = 1.0, 1.0, 1.0, 0.05, 3.03
    p = Parameters(M, kappa, coulomb(F_K, numeric), Constant(F0=F_S))
    half = math.pi * math.sqrt(M / kappa)
    t = np.linspace(0.0, 1.0 + 22 * half, 3001)
    res = simulate_reference(p, 0.0, 0.0, [(0.0, 0.0, 0.0), (1.0, 0.0, F_ext)], t)

    assert kinds(res.events) == ["input"] + ["overshoot"] * 20 + ["stick"]
    assert res.events[0] == ReferenceEvent(1.0, "input", 0, -1)
    for n, event in enumerate(res.events[1:], start=1):
        mode_before = -1 if n % 2 else 1
        assert event.t == pytest.approx(1.0 + n * half, rel=1e-9)
        assert event.mode_before == mode_before
        assert event.mode_after == (0 if n == 21 else -mode_before)
    x_end = (F_ext + (F_ext - 2 * 21 * F_K)) / kappa  # odd turning points lie above F_ext/kappa
    assert res.x[-1] == pytest.approx(x_end, abs=1e-9)
    assert res.mode[-1] == 0


# ---------------------------------------------------------------- graze


@PATHS
@pytest.mark.parametrize("excess", [1e-6, 1e-8, -1e-6])
def test_graze_is_not_stepped_over(numeric, excess):
    """A Coulomb slip whose top speed passes v_drive by ``excess`` for under 10 ms of a 6.3 s period.

    From the turning point x0 = F_K/kappa + A, v = 0 (A w = v_drive + excess)
    v(t) = -A w sin(wt): it reaches v_drive at w t1 = pi + asin(v_drive/(A w))
    and leaves it again at w t2 = 2 pi - asin(v_drive/(A w)). The block must
    stick at t1; with a negative excess it never reaches v_drive. The 1e-8
    excursion (1 ms) falls between the numeric path's dense-output samples, so
    only the dip check on the acceleration finds it.
    """
    M, kappa, F_S, F_K, v_drive = 1.0, 1.0, 1.0, 0.5, 0.1
    w = math.sqrt(kappa / M)
    A = (v_drive + excess) / w
    p = Parameters(M, kappa, coulomb(F_K, numeric), Constant(F0=F_S))
    t = np.linspace(0.0, 2 * math.pi / w, 1001)
    res = simulate_reference(p, F_K / kappa + A, 0.0, [(0.0, v_drive, 0.0)], t)

    if excess < 0:
        assert res.events == []
        assert np.all(res.mode == 1)
        return
    t1 = (math.pi + math.asin(v_drive / (A * w))) / w
    t2 = (2 * math.pi - math.asin(v_drive / (A * w))) / w
    assert 0 < t2 - t1 < 1e-2  # the excursion is far shorter than a solver step
    assert res.events == [ReferenceEvent(res.events[0].t, "stick", 1, 0)]
    # a velocity error dv shifts a crossing by dv / |a|, and |a| at t1 is small near a graze
    a1 = A * w * w * math.sqrt(1.0 - (v_drive / (A * w)) ** 2)
    assert res.events[0].t == pytest.approx(t1, rel=1e-9, abs=1e-10 * v_drive / a1)
    assert res.events[0].t < t1 + 0.01 * (t2 - t1)
    assert np.all(res.mode[t > res.events[0].t] == 0)


@pytest.mark.parametrize("dip", [1e-7, -1e-7])
def test_stuck_block_breaks_in_a_short_dip_of_the_holding_margin(dip):
    """Sigmoid aging, F_ext = 0: stuck at x_s with kappa (x_s + v_drive t) tangent to F_S(t) at t = 0.53 s,
    shifted up by ``dip``. With dip > 0 the margin F_S - kappa x is negative only for ~0.6 ms
    (400 scan points over 100 s are 0.25 s apart): the block must break there. With dip < 0
    it must hold past the tangency and break later, where the line overtakes F_S for good.
    """
    F0, F_inf, tau, n, t_touch = 1.0, 2.0, 1.0, 4.0, 0.53

    def F_S(t):
        return F0 + (F_inf - F0) * t**n / (tau**n + t**n)

    v_drive = (F_inf - F0) * n * tau**n * t_touch ** (n - 1) / (tau**n + t_touch**n) ** 2  # F_S'(t_touch)
    x_s = F_S(t_touch) - v_drive * t_touch + dip

    def margin(t):
        return F_S(t) - (x_s + v_drive * t)

    if dip > 0:  # margin decreases on [0, t_touch] (convex F_S, tangent slope): one root there
        t_break = brentq(margin, 0.0, t_touch, xtol=1e-15)
    else:  # first root after the tangency, where the saturating F_S falls below the line
        t_break = brentq(margin, 1.0, 10.0, xtol=1e-15)
    p = Parameters(1.0, 1.0, Coulomb(F0=0.5), Sigmoid(F0=F0, F_inf=F_inf, tau=tau, n=n))
    res = simulate_reference(p, x_s, v_drive, [(0.0, v_drive, 0.0)], np.linspace(0.0, 100.0, 11))
    assert res.events[0] == ReferenceEvent(res.events[0].t, "slip", 0, 1)
    assert res.events[0].t == pytest.approx(t_break, rel=1e-9)


# ---------------------------------------------------------------- input jumps


def test_drive_jump_while_stuck_moves_the_block_with_the_surface():
    p = Parameters(1.0, 1.0, Coulomb(F0=0.5), Constant(F0=10.0))
    inputs = [(0.0, 0.1, 0.0), (1.0, -0.3, 0.0), (2.0, 0.2, 0.5)]
    t = np.linspace(0.0, 3.0, 31)
    res = simulate_reference(p, 0.0, 0.1, inputs, t)

    x = np.where(t <= 1, 0.1 * t, np.where(t <= 2, 0.1 - 0.3 * (t - 1), -0.2 + 0.2 * (t - 2)))
    v_drive = np.where(t < 1, 0.1, np.where(t < 2, -0.3, 0.2))
    assert res.events == []
    assert np.all(res.mode == 0)
    np.testing.assert_allclose(res.x, x, atol=1e-14)
    np.testing.assert_array_equal(res.v, v_drive)
    np.testing.assert_array_equal(res.v_drive, v_drive)
    np.testing.assert_allclose(res.t_stick, t, atol=1e-14)


def test_force_jump_breaks_a_stuck_block_at_the_breakpoint():
    p = Parameters(1.0, 1.0, Coulomb(F0=0.5), Constant(F0=1.0))
    t = np.linspace(0.0, 2.0, 21)
    res = simulate_reference(p, 0.0, 0.0, [(0.0, 0.0, 0.0), (1.0, 0.0, -1.5)], t)
    assert res.events[0] == ReferenceEvent(1.0, "input", 0, 1)  # F_ext - kappa x < 0: mode +1
    assert res.mode[10] == 1 and res.x[10] == 0.0 and res.v[10] == 0.0
    assert res.v[11] < 0.0


# ---------------------------------------------------------------- numeric path vs Radau


def test_stribeck_slip_matches_independent_radau():
    M, kappa, v_drive, F_S = 1.0, 1.0, 0.1, 1.0
    law = Stribeck(F0=0.5, F_stribeck=0.3, v_stribeck=0.1, delta=2.0, gamma=0.05)
    p = Parameters(M, kappa, law, Constant(F0=F_S))
    x0, v0 = 1.0, 0.0  # slipping forward (v < v_drive) from the start

    def rhs(t, y):
        u = v_drive - y[1]
        return [y[1], (-kappa * y[0] + 0.5 + 0.3 * math.exp(-((u / 0.1) ** 2)) + 0.05 * u) / M]

    def reaches_drive(t, y):
        return y[1] - v_drive

    reaches_drive.terminal, reaches_drive.direction = True, 1
    radau = solve_ivp(rhs, (0.0, 20.0), [x0, v0], method="Radau", rtol=1e-12, atol=1e-14,
                      dense_output=True, events=reaches_drive)
    t_stick = radau.t_events[0][0]

    t = np.linspace(0.0, t_stick + 0.5, 501)
    res = simulate_reference(p, x0, v0, [(0.0, v_drive, 0.0)], t)

    assert res.events[0].kind == "stick" and res.events[0].mode_before == 1
    assert res.events[0].t == pytest.approx(t_stick, rel=1e-8)
    slipping = t < t_stick
    y = radau.sol(t[slipping])
    np.testing.assert_allclose(res.x[slipping], y[0], rtol=0, atol=1e-8)
    np.testing.assert_allclose(res.v[slipping], y[1], rtol=0, atol=1e-8)


# ---------------------------------------------------------------- guards


def test_event_chain_raises_solver_error():
    """F_K(0+) = F_S(0) with a weakening contact and a resting surface: stick and slip forever at t = 0."""
    weakening = CustomStatic(force=lambda t: 1.0 - 0.1 * t / (1.0 + t), rate=lambda t: -0.1 / (1.0 + t) ** 2)
    p = Parameters(1.0, 1.0, Coulomb(F0=1.0), weakening)
    with pytest.raises(ReferenceSolverError, match="t = 0.0 s"):
        simulate_reference(p, 1.0, 0.0, [(0.0, 0.0, 0.0)], np.linspace(0.0, 1.0, 3))


# ---------------------------------------------------------------- independence from the runtime


def test_reference_imports_nothing_from_the_runtime():
    """No module of ``stickslip.reference`` imports ``stickslip.core`` (or anything but itself from the package),
    and no object in their namespaces comes from it: the comparison with the FMU shares no law or rule."""
    import ast
    import importlib
    import pathlib

    import stickslip.reference

    folder = pathlib.Path(stickslip.reference.__file__).parent
    modules = sorted(folder.glob("*.py"))
    assert len(modules) >= 8
    for path in modules:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                target = "." * node.level + (node.module or "")
                assert node.level <= 1 and "core" not in target, f"{path.name} imports {target}"
                assert node.level == 1 or not target.startswith("stickslip"), f"{path.name} imports {target}"
            elif isinstance(node, ast.Import):
                assert not any(a.name.startswith("stickslip") for a in node.names), f"{path.name} imports stickslip"
        module = importlib.import_module(f"stickslip.reference.{path.stem}" if path.stem != "__init__"
                                         else "stickslip.reference")
        for name, value in vars(module).items():
            origin = getattr(value, "__module__", None) or getattr(value, "__name__", "")
            assert not str(origin).startswith("stickslip.core"), f"{path.name}: {name} comes from {origin}"


def test_reference_refuses_the_runtime_parameters():
    """Passing ``core.Parameters`` would share the runtime's laws: it is an error naming the builder."""
    from stickslip.core import Parameters as CoreParameters, kinetic_law, static_law

    p = CoreParameters(1.0, 1.0, kinetic_law(1, F0=0.5), static_law(1, F0=1.0))
    with pytest.raises(ReferenceParameterError, match="parameters_from_values"):
        simulate_reference(p, 0.0, 0.1, [(0.0, 0.1, 0.0)], np.linspace(0.0, 1.0, 3))


@pytest.mark.parametrize("values, name", [
    ({"M": -1.0}, "M = -1.0"),
    ({"kappa": 0.0}, "kappa = 0.0"),
    ({"kinetic.F0": -0.1}, "kinetic.F0"),
    ({"kinetic.F0": 1.5}, "F_K\\(0\\+\\) = 1.5 N exceeds F_S\\(0\\)"),
    ({"static.F0": math.nan}, "static.F0 = nan"),
    ({"kinetic.law": 7}, "kinetic.law = 7"),
    ({"kinetic.law": "stribeck", "kinetic.F_stribeck": 0.1, "kinetic.v_stribeck": 0.0, "kinetic.gamma": 0.0,
      "kinetic.delta": 1.0}, "kinetic.v_stribeck = 0.0"),
    ({"static.law": "sigmoid", "static.F_inf": 2.0, "static.tau": 1.0, "static.n": 0.1}, "static.n = 0.1"),
])
def test_reference_checks_its_own_parameters(values, name):
    from stickslip.reference import parameters_from_values

    base = {"M": 1.0, "kappa": 1.0, "kinetic.law": "coulomb", "kinetic.F0": 0.5, "static.law": 1, "static.F0": 1.0}
    with pytest.raises(ReferenceParameterError, match=name):
        simulate_reference(parameters_from_values({**base, **values}), 0.0, 0.1, [(0.0, 0.1, 0.0)],
                           np.linspace(0.0, 1.0, 3))


def test_reference_laws_require_every_parameter():
    from stickslip.reference import parameters_from_values

    with pytest.raises(ReferenceParameterError, match=r"missing \['gamma'\]"):
        parameters_from_values({"M": 1.0, "kappa": 1.0, "kinetic.law": 2, "kinetic.F0": 0.5, "static.law": 1,
                                "static.F0": 1.0})
