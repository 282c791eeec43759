"""Friction laws: values, derivatives against finite differences, validation messages."""

import math

import pytest

from stickslip.core import ParameterError, Parameters, kinetic_law, static_law
from stickslip.core.laws import KINETIC_LAWS, STATIC_LAWS, CallableKinetic, Coulomb, Constant
from stickslip.core.model import check_scales

KINETIC_CASES = {
    "coulomb": {"F0": 0.4},
    "viscous": {"F0": 0.4, "gamma": 0.3},
    "stribeck": {"F0": 0.4, "F_stribeck": 0.3, "v_stribeck": 0.2, "delta": 2.0, "gamma": 0.1},
    "lubricated": {"gamma1": 3.0, "gamma2": 0.1, "v_tilde": 0.2, "dv": 0.05},
    "carlson-langer": {"F0": 1.0, "sigma": 0.05, "alpha": 2.5},
}
STATIC_CASES = {
    "constant": {"F0": 1.0},
    "logarithmic": {"F0": 1.0, "A": 0.2, "tau": 0.5},
    "saturating": {"F0": 1.0, "F_inf": 1.6, "tau": 2.0},
    "sigmoid": {"F0": 1.0, "F_inf": 1.6, "tau": 2.0, "n": 3.0},
}


def _central_difference(f, x, h=1e-6):
    """Second-order central difference: truncation about h^2 f''' / 6, rounding about eps |f| / h (2e-10 here)."""
    return (f(x + h) - f(x - h)) / (2 * h)


@pytest.mark.parametrize("name", KINETIC_CASES)
def test_kinetic_slope_is_the_derivative(name):
    law = kinetic_law(name, **KINETIC_CASES[name])
    for u in (0.01, 0.1, 0.2, 0.35, 1.0, 3.0):
        # measured: relative 8.4e-10, absolute 1.1e-9 at most (the difference's rounding)
        assert law.slope(u) == pytest.approx(_central_difference(law.force, u), rel=1e-8, abs=1e-8)


@pytest.mark.parametrize("name", STATIC_CASES)
def test_static_rate_and_curvature_are_the_derivatives(name):
    law = static_law(name, **STATIC_CASES[name])
    for t in (0.05, 0.5, 1.0, 2.0, 7.0):
        # measured: rate 5.0e-8 relative (truncation where F_S''' is large), curvature 2.9e-10 relative
        assert law.rate(t) == pytest.approx(_central_difference(law.force, t), rel=1e-6, abs=1e-9)
        assert law.curvature(t) == pytest.approx(_central_difference(law.rate, t), rel=3e-9, abs=1e-9)


#: the SPEC formulas are evaluated as written: measured exact, or within 1 ulp (2e-16); about 50 ulps allowed
EXACT = 1e-14


def test_kinetic_values_follow_the_spec_formulas():
    u = 0.37
    assert kinetic_law(1, F0=0.4).force(u) == 0.4
    assert kinetic_law(2, F0=0.4, gamma=0.3).force(u) == pytest.approx(0.4 + 0.3 * u, rel=EXACT)
    stribeck = kinetic_law(3, **KINETIC_CASES["stribeck"])
    assert stribeck.force(u) == pytest.approx(0.4 + 0.3 * math.exp(-((u / 0.2) ** 2)) + 0.1 * u, rel=EXACT)
    lub = kinetic_law(4, **KINETIC_CASES["lubricated"])
    w = u - 0.2
    assert lub.force(u) == pytest.approx(u * (3.1 + (0.1 - 3.0) * w / math.sqrt(0.05**2 + w * w)) / 2, rel=EXACT)
    assert lub.force(0.0) == 0.0
    cl = kinetic_law(5, **KINETIC_CASES["carlson-langer"])
    assert cl.force(u) == pytest.approx(0.95 / (1 + 5.0 * u / 0.95), rel=EXACT)
    assert cl.force(0.0) == cl.at_rest() == pytest.approx(0.95, rel=EXACT)  # the drop sigma F0 at the onset of slip


def test_carlson_langer_weakens_at_every_speed():
    """``F_K' < 0`` everywhere for ``alpha > 0`` (continuous sliding is unstable); the steepest slope, bounding
    ``|F_K'|`` for the damping check, is ``2 alpha F0`` at ``u = 0``; ``alpha = 0`` is coulomb at ``F0 (1 - sigma)``."""
    law = kinetic_law("carlson-langer", **KINETIC_CASES["carlson-langer"])
    speeds = [0.0, 1e-6, 0.01, 0.19, 1.0, 100.0]
    assert all(law.slope(u) < 0 for u in speeds)
    assert law.steepest_slope() == max(abs(law.slope(u)) for u in speeds) == pytest.approx(5.0, rel=EXACT)
    assert law.affine() is None
    assert kinetic_law(5, F0=1.0, sigma=0.2, alpha=0.0).affine() == pytest.approx((0.8, 0.0), rel=EXACT)


def test_static_values_follow_the_spec_formulas():
    t = 1.3
    assert static_law(2, F0=1, A=0.2, tau=0.5).force(t) == pytest.approx(1 + 0.2 * math.log(1 + t / 0.5), rel=EXACT)
    assert static_law(3, F0=1, F_inf=1.6, tau=2).force(t) == pytest.approx(1 + 0.6 * (1 - math.exp(-t / 2)), rel=EXACT)
    assert static_law(4, F0=1, F_inf=1.6, tau=2, n=3).force(t) == pytest.approx(1 + 0.6 * t**3 / (8 + t**3), rel=EXACT)


def test_sigmoid_convexity_break_is_the_inflection():
    law = static_law("sigmoid", **STATIC_CASES["sigmoid"])
    (t_inflection,) = law.convexity_breaks()
    assert law.curvature(t_inflection * 0.99) > 0 > law.curvature(t_inflection * 1.01)


def test_affine_laws_report_their_coefficients():
    assert kinetic_law("viscous", F0=0.4, gamma=0.3).affine() == (0.4, 0.3)
    assert kinetic_law("stribeck", F0=0.4, F_stribeck=0.0, v_stribeck=0.1, gamma=0.0).affine() == (0.4, 0.0)
    assert kinetic_law("lubricated").affine() is None


def test_law_tables_have_spec_codes():
    assert [KINETIC_LAWS[c].NAME for c in (1, 2, 3, 4, 5)] == ["coulomb", "viscous", "stribeck", "lubricated",
                                                               "carlson-langer"]
    assert [STATIC_LAWS[c].NAME for c in (1, 2, 3, 4)] == ["constant", "logarithmic", "saturating", "sigmoid"]


@pytest.mark.parametrize(
    "build, name",
    [
        (lambda: Parameters(-1, 1, Coulomb(F0=0.5), Constant(F0=1)), "M"),
        (lambda: Parameters(1, 0, Coulomb(F0=0.5), Constant(F0=1)), "kappa"),
        (lambda: Parameters(math.nan, 1, Coulomb(F0=0.5), Constant(F0=1)), "M"),
        (lambda: Parameters(1, math.inf, Coulomb(F0=0.5), Constant(F0=1)), "kappa"),
        (lambda: Parameters(1, 1, Coulomb(F0=-0.1), Constant(F0=1)), "kinetic.F0"),
        (lambda: Parameters(1, 1, kinetic_law(3, v_stribeck=0.0), Constant(F0=1)), "kinetic.v_stribeck"),
        (lambda: Parameters(1, 1, kinetic_law(4, dv=-1.0), Constant(F0=1)), "kinetic.dv"),
        (lambda: Parameters(1, 1, Coulomb(F0=0.5), static_law(2, tau=-1.0)), "static.tau"),
        (lambda: Parameters(1, 1, Coulomb(F0=0.5), static_law(4, n=0.0)), "static.n"),
        (lambda: Parameters(1, 1, Coulomb(F0=1.5), Constant(F0=1)), "F_K(0+)"),
        (lambda: Parameters(1, 1, kinetic_law(5, sigma=1.0), Constant(F0=1)), "kinetic.sigma = 1.0 is out of range: "
                                                                              "allowed is a finite value in [0, 1)"),
        (lambda: Parameters(1, 1, kinetic_law(5, sigma=-0.1), Constant(F0=1)), "kinetic.sigma"),
        (lambda: Parameters(1, 1, kinetic_law(5, alpha=-1.0), Constant(F0=1)), "kinetic.alpha = -1.0 s/m"),
        (lambda: Parameters(1, 1, kinetic_law(5, F0=1.2, sigma=0.1), Constant(F0=1)), "F_K(0+) = 1.08"),
    ],
)
def test_invalid_parameters_name_the_parameter_and_range(build, name):
    with pytest.raises(ParameterError) as info:
        build().check()
    message = str(info.value)
    assert name in message
    assert "allowed" in message


def test_carlson_langer_steeper_than_the_damping_bound_is_refused():
    """``|F_K'(0)| = 2 alpha F0`` beyond 1e7 times ``2 sqrt(kappa M)``: refused at the start, naming the law."""
    p = Parameters(1, 1, kinetic_law(5, alpha=1e8), Constant(F0=1))
    p.check()
    with pytest.raises(ParameterError, match=r"carlson-langer law's steepest slope \|F_K'\| = 2e\+08 N s/m"):
        check_scales(0.0, 0.0, 0.1, 0.0, p)


@pytest.mark.parametrize("table_lookup", [lambda: kinetic_law(7), lambda: static_law("glue")])
def test_unknown_law_codes_list_the_allowed_ones(table_lookup):
    with pytest.raises(ParameterError, match="allowed are 1 .*4"):  # 1 .. 5 (kinetic), 1 .. 4 (static)
        table_lookup()


def test_callable_law_is_accepted_and_checked():
    law = CallableKinetic(lambda u: 0.3 + 0.1 * u, lambda u: 0.1)
    Parameters(1, 1, law, Constant(F0=1)).check()
    with pytest.raises(ParameterError, match="kinetic law callable"):
        CallableKinetic(lambda u: -1.0, lambda u: 0.0).check()
