"""Stick-slip cycle, grazing margin and critical velocity against closed forms and the exact stepper."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from stickslip.core import Constant, Coulomb, Lubricated, Parameters, Viscous
from stickslip.analysis import classify, critical, stickslip_cycle


def elmer():
    return Parameters(40.0, 1.0, Lubricated(gamma1=3.0, gamma2=0.1, v_tilde=0.2, dv=0.05), Constant(F0=1.0))


@pytest.mark.parametrize("v_drive", [0.02, 0.1, 0.7])
def test_coulomb_cycle_matches_the_closed_form(v_drive):
    M, kappa, F0, FS = 2.0, 0.5, 0.3, 0.8
    p = Parameters(M, kappa, Coulomb(F0=F0), Constant(F0=FS))
    (c,) = stickslip_cycle.stick_slip_cycles(p, [v_drive])
    omega = math.sqrt(kappa / M)
    A = (FS - F0) / kappa  # start of the slip relative to the centre F0/kappa
    slip = (2 * math.pi - 2 * math.atan(A * omega / v_drive)) / omega
    stick = 2 * (FS - F0) / (kappa * v_drive)
    R = math.hypot(A, v_drive / omega)
    assert c.exists and c.fate == "stick" and c.overshoots == 0
    assert c.x_stick == pytest.approx((2 * F0 - FS) / kappa, abs=1e-10)
    assert c.slip_time == pytest.approx(slip, rel=1e-10)
    assert c.stick_time == pytest.approx(stick, rel=1e-10)
    assert c.period == pytest.approx(slip + stick, rel=1e-10)
    assert c.x_max == pytest.approx(F0 / kappa + R, rel=1e-10)
    assert c.x_min == pytest.approx(F0 / kappa - R, rel=1e-10)
    assert c.v_min == pytest.approx(-R * omega, rel=1e-9)
    assert c.stick_fraction == pytest.approx(stick / (slip + stick))


def test_classified_coulomb_run_measures_the_cycle():
    p = Parameters(1.0, 1.0, Coulomb(F0=0.5), Constant(F0=1.0))
    a = classify.classify_run(p, 0.1, t_end=200.0, tail=100.0)
    A, v = 0.5, 0.1
    slip = 2 * math.pi - 2 * math.atan(A / v)
    stick = 2 * 0.5 / v
    assert a.kind == "stick-slip" and a.repeat == 1 and not a.overshoots
    assert a.period == pytest.approx(slip + stick, rel=1e-8)
    assert a.stick_fraction == pytest.approx(stick / (slip + stick), rel=1e-6)
    assert a.x_max == pytest.approx(0.5 + math.hypot(A, v), abs=1e-4)  # sampled


def viscous_first_return(M, kappa, F0, gamma, FS, v):
    """Height of the first velocity maximum of the slip from x = F_S/kappa, v = v_drive, minus v_drive.

    Under F_K = F0 + gamma u the slip is M y'' + gamma y' + kappa y = 0 about x_c = (F0 + gamma v)/kappa,
    so v(t) = R e^{-alpha t} cos(omega t - phi) with R cos(phi) = v, R sin(phi) = (a0 + alpha v)/omega,
    a0 = (F0 - FS)/M. Its maxima lie at omega t - phi = psi + 3 pi/2 + 2 pi k, psi = atan2(omega, alpha),
    with value R e^{-alpha t} omega/omega0, a decreasing sequence: stick-slip iff the first is >= v.
    """
    alpha = gamma / (2 * M)
    omega0 = math.sqrt(kappa / M)
    omega = math.sqrt(omega0**2 - alpha**2)
    a0 = (F0 - FS) / M
    R = math.hypot(v, (a0 + alpha * v) / omega)
    phi = math.atan2((a0 + alpha * v) / omega, v)
    psi = math.atan2(omega, alpha)
    theta = psi + 1.5 * math.pi
    while theta > -phi + 2 * math.pi:
        theta -= 2 * math.pi
    while theta <= -phi:
        theta += 2 * math.pi
    t = (theta + phi) / omega
    return R * math.exp(-alpha * t) * omega / omega0 - v


def test_viscous_critical_velocity_from_the_damped_closed_form():
    M, kappa, F0, gamma, FS = 1.0, 1.0, 0.5, 0.3, 1.0
    vc = brentq(lambda v: viscous_first_return(M, kappa, F0, gamma, FS, v), 1e-3, 1.0, xtol=1e-14)
    p = Parameters(M, kappa, Viscous(F0=F0, gamma=gamma), Constant(F0=FS))
    result = critical.critical_velocities(p, 0.01, 1.0, n=40)
    assert result.critical == pytest.approx((vc,), abs=1e-6)
    assert result.windows[0][0] == 0.01 and result.windows[0][1] == pytest.approx(vc, abs=1e-6)
    # the margin is the closed-form first-return height below v_c
    v = 0.5 * vc
    assert stickslip_cycle.grazing_margin(p, [v])[0] == pytest.approx(
        viscous_first_return(M, kappa, F0, gamma, FS, v), abs=1e-9)


def test_elmer_stick_slip_windows_agree_with_the_exact_stepper():
    p = elmer()
    changes = stickslip_cycle.existence_changes(p, 0.03, 0.12, n=10)
    assert [(w, k) for _, w, k in changes] == [("disappears", "graze"), ("appears", "graze")]
    for v, what, _ in changes:
        for dv, expect in ((-2e-4, what == "disappears"), (2e-4, what == "appears")):
            a = classify.classify_run(p, v + dv, t_end=800.0, tail=300.0)
            assert (a.kind == "stick-slip") == expect, (v + dv, a)
    below = stickslip_cycle.stick_slip_cycles(p, [changes[0][0] - 1e-6, changes[0][0] + 1e-6])
    assert below[0].exists and not below[1].exists
    assert abs(below[0].margin) < 1e-5 and abs(below[1].margin) < 1e-5


def test_overshooting_stick_slip_cycle():
    """Stick position and period against the independent reference integrator (its own laws, DOP853),
    run from a stuck start onto the cycle (the block breaks away at x = F_S/kappa, on the cycle at once)."""
    from stickslip.reference import parameters_from_values, simulate_reference

    p = elmer()
    (c,) = stickslip_cycle.stick_slip_cycles(p, [0.3])
    assert c.exists and c.overshoots == 1
    values = {"M": 40.0, "kappa": 1.0, "kinetic.law": "lubricated", "kinetic.gamma1": 3.0, "kinetic.gamma2": 0.1,
              "kinetic.v_tilde": 0.2, "kinetic.dv": 0.05, "static.law": "constant", "static.F0": 1.0}
    ref_p = parameters_from_values(values)
    run = simulate_reference(ref_p, 0.0, 0.3, [(0.0, 0.3, 0.0)], np.linspace(0.0, 200.0, 201))
    sticks = [e.t for e in run.events if e.kind == "stick"]
    at = simulate_reference(ref_p, 0.0, 0.3, [(0.0, 0.3, 0.0)], np.array([0.0, sticks[-1]]))
    assert c.x_stick == pytest.approx(at.x[-1], abs=1e-8)  # measured 1e-10
    assert c.period == pytest.approx(sticks[-1] - sticks[-2], rel=1e-8)
    a = classify.classify_run(p, 0.3, t_end=500.0, tail=200.0)
    assert a.kind == "stick-slip" and a.overshoots
    assert a.period == pytest.approx(c.period, rel=1e-7)
    assert a.x_min == pytest.approx(c.x_min, abs=1e-3) and a.x_max == pytest.approx(c.x_max, abs=1e-3)
