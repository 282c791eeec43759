"""Continuous sliding and Hopf points against closed forms (stickslip.analysis.steady_sliding)."""

import math

import pytest

from stickslip.core import CallableKinetic, Constant, Lubricated, Parameters, Stribeck
from stickslip.analysis import kinetic, steady_sliding


def stribeck_params():
    # F_K = F0 + Fs exp(-u/vs) + gamma u: a single minimum at u* = vs ln(Fs / (gamma vs))
    return Parameters(2.0, 1.5, Stribeck(F0=0.4, F_stribeck=0.3, v_stribeck=0.1, delta=1.0, gamma=0.5),
                      Constant(F0=1.0))


def test_hopf_point_at_the_stribeck_minimum_with_closed_form_derivatives():
    p = stribeck_params()
    u = 0.1 * math.log(0.3 / (0.5 * 0.1))
    (h,) = steady_sliding.hopf_points(p, 0.0, 5.0)
    assert h.v_drive == pytest.approx(u, abs=1e-12)
    assert h.extremum == "min"
    decay = 0.3 * math.exp(-u / 0.1)
    assert h.F2 == pytest.approx(decay / 0.1**2, rel=1e-7)
    assert h.F3 == pytest.approx(-decay / 0.1**3, rel=1e-6)
    # F''' < 0: subcritical; F'' > 0 so the unstable cycles live above the minimum, where CS is stable
    assert h.criticality == "subcritical" and h.side == 1 and not h.cycles_stable
    omega = math.sqrt(1.5 / 2.0)
    assert h.lyapunov == pytest.approx(-omega**2 * h.F3 / (16 * 2.0), rel=1e-12)
    assert h.period == pytest.approx(2 * math.pi / omega)


def test_supercritical_hopf_of_a_cubic_law():
    # F_K = 1 + (u-1)^3/3 - d (u-1): extrema at 1 -+ sqrt(d), F''' = 2 > 0 at both
    d = 0.04
    law = CallableKinetic(lambda u: 1 + (u - 1) ** 3 / 3 - d * (u - 1), lambda u: (u - 1) ** 2 - d)
    p = Parameters(1.0, 1.0, law, Constant(F0=2.0))
    lo, hi = steady_sliding.hopf_points(p, 0.0, 3.0)
    assert lo.v_drive == pytest.approx(0.8, abs=1e-12) and hi.v_drive == pytest.approx(1.2, abs=1e-12)
    assert (lo.extremum, hi.extremum) == ("max", "min")
    for h in (lo, hi):
        assert h.F3 == pytest.approx(2.0, rel=1e-6)
        assert h.criticality == "supercritical" and h.cycles_stable
    # the stable cycles exist between the extrema, where CS is unstable
    assert lo.side == 1 and hi.side == -1
    # small-cycle amplitude V^2 = -8 F'/F''' with F' = (v-1)^2 - d exactly
    v = 0.85
    exact = math.sqrt(-8 * ((v - 1) ** 2 - d) / 2.0)
    assert lo.amplitude(v, slope=law.slope(v)) * lo.omega == pytest.approx(exact, rel=1e-12)
    # without the slope it linearizes F' about the Hopf point: F'(v) ~ F''(0.8) (v - 0.8) = -0.4 (v - 0.8)
    linearized = math.sqrt(-8 * (-0.4 * (v - 0.8)) / 2.0)
    assert lo.amplitude(v) * lo.omega == pytest.approx(linearized, rel=1e-6)  # F2, F3 are found numerically
    assert math.isnan(lo.amplitude(0.75))


def test_continuous_sliding_stability_follows_the_slope():
    p = Parameters(40.0, 1.0, Lubricated(gamma1=3.0, gamma2=0.1, v_tilde=0.2, dv=0.05), Constant(F0=1.0))
    (top, bottom) = steady_sliding.hopf_points(p, 0.0, 1.2)
    assert top.extremum == "max" and bottom.extremum == "min"
    for v in (0.05, 0.1, 0.3, 0.5, 1.0):
        cs = steady_sliding.continuous_sliding(p, v)
        assert cs.x == pytest.approx(p.kinetic.force(v))
        assert cs.stable == (not top.v_drive < v < bottom.v_drive)
        assert all((e.real < 0) == cs.stable for e in cs.eigenvalues)


def test_numeric_higher_derivatives_of_the_lubricated_law():
    law = Lubricated(gamma1=3.0, gamma2=0.1, v_tilde=0.2, dv=0.05)
    # analytic F'' of u (g(u)) with g = mean + half w/s: F' = g + u g', F'' = 2 g' + u g''
    u, vt, dv, half = 0.3, 0.2, 0.05, 0.5 * (0.1 - 3.0)
    w = u - vt
    s = math.hypot(dv, w)
    g1 = half * dv * dv / s**3
    g2 = -3 * half * dv * dv * w / s**5
    g3 = -3 * half * dv * dv * (s * s - 5 * w * w) / s**7
    f1, f2, f3 = kinetic.derivatives(law, u)
    assert f1 == pytest.approx(law.slope(u))
    assert f2 == pytest.approx(2 * g1 + u * g2, rel=1e-8)
    assert f3 == pytest.approx(3 * g2 + u * g3, rel=1e-6)
