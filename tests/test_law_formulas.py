"""Every friction law, in the runtime (``core``) and in the reference, pinned against SPEC section 2; and the
kinetic laws of the analysis (:mod:`stickslip.analysis.kinetic`, the same formulas on numpy arrays).

The SPEC formulas are written out here once more; each law is evaluated at many
points across each branch (below, at and above its characteristic speed or
time, 0 and far out), with several parameter sets per law. Derivatives
(``slope``, ``rate``, the runtime's ``curvature``) are checked against
fourth-order central differences of the force, and at ``u = 0`` / ``t = 0``
against their limits derived by hand. A 1 % error in any parameter of any law
fails here (it changes the values by far more than the 1e-12 allowed).
"""

import math

import numpy as np
import pytest

from stickslip.analysis.kinetic import Kinetic
from stickslip.core import kinetic_law, static_law
from stickslip.reference import laws as reference_laws


def spec_kinetic(name, p, u):
    """``F_K(u)`` (N) as SPEC section 2 writes it."""
    if name == "coulomb":
        return p["F0"]
    if name == "viscous":
        return p["F0"] + p["gamma"] * u
    if name == "stribeck":
        return p["F0"] + p["F_stribeck"] * math.exp(-((u / p["v_stribeck"]) ** p["delta"])) + p["gamma"] * u
    if name == "carlson-langer":
        return p["F0"] * (1 - p["sigma"]) / (1 + 2 * p["alpha"] * u / (1 - p["sigma"]))
    g1, g2, vt, dv = p["gamma1"], p["gamma2"], p["v_tilde"], p["dv"]
    return u * (g1 + g2 + (g2 - g1) * (u - vt) / math.sqrt(dv**2 + (u - vt) ** 2)) / 2


def spec_kinetic_slope(name, p, u):
    """``F_K'(u)`` (N s/m): SPEC section 2's formula differentiated by hand."""
    if name == "coulomb":
        return 0.0
    if name == "viscous":
        return p["gamma"]
    if name == "stribeck":
        s, d = u / p["v_stribeck"], p["delta"]
        return p["gamma"] - p["F_stribeck"] * d * s ** (d - 1) * math.exp(-(s**d)) / p["v_stribeck"]
    if name == "carlson-langer":  # F0 (1 - sigma) times d/du 1/(1 + b u) = -b/(1 + b u)^2, b = 2 alpha/(1 - sigma)
        b = 2 * p["alpha"] / (1 - p["sigma"])
        return -p["F0"] * (1 - p["sigma"]) * b / (1 + b * u) ** 2
    g1, g2, vt, dv = p["gamma1"], p["gamma2"], p["v_tilde"], p["dv"]
    root = math.sqrt(dv**2 + (u - vt) ** 2)
    return (g1 + g2) / 2 + (g2 - g1) / 2 * ((u - vt) / root + u * dv**2 / root**3)


def spec_static(name, p, t):
    """``F_S(t)`` (N) as SPEC section 2 writes it."""
    if name == "constant":
        return p["F0"]
    if name == "logarithmic":
        return p["F0"] + p["A"] * math.log(1 + t / p["tau"])
    if name == "saturating":
        return p["F0"] + (p["F_inf"] - p["F0"]) * (1 - math.exp(-t / p["tau"]))
    n = p["n"]
    return p["F0"] + (p["F_inf"] - p["F0"]) * t**n / (p["tau"] ** n + t**n)


def spec_slope_at_zero(name, p):
    """``F_K'(0+)`` (N s/m), by hand from the formulas."""
    if name == "coulomb":
        return 0.0
    if name == "viscous":
        return p["gamma"]
    if name == "stribeck":
        return p["gamma"] - (p["F_stribeck"] / p["v_stribeck"] if p["delta"] == 1.0 else 0.0)
    if name == "carlson-langer":
        return -2 * p["alpha"] * p["F0"]
    g1, g2, vt, dv = p["gamma1"], p["gamma2"], p["v_tilde"], p["dv"]
    return (g1 + g2) / 2 + (g2 - g1) / 2 * (-vt / math.sqrt(dv**2 + vt**2))


def spec_rate_at_zero(name, p):
    """``F_S'(0+)`` (N/s), by hand from the formulas."""
    if name == "constant":
        return 0.0
    if name == "logarithmic":
        return p["A"] / p["tau"]
    jump = p["F_inf"] - p["F0"]
    if name == "saturating":
        return jump / p["tau"]
    if p["n"] > 1.0 or jump == 0.0:
        return 0.0
    return jump / p["tau"] if p["n"] == 1.0 else math.copysign(math.inf, jump)


KINETIC = [
    ("coulomb", {"F0": 0.4}, 1.0),
    ("coulomb", {"F0": 0.0}, 1.0),
    ("viscous", {"F0": 0.4, "gamma": 0.3}, 1.0),
    ("viscous", {"F0": 0.0, "gamma": 7.0}, 1.0),
    ("stribeck", {"F0": 0.4, "F_stribeck": 0.3, "v_stribeck": 0.2, "delta": 1.0, "gamma": 0.1}, 0.2),
    ("stribeck", {"F0": 0.4, "F_stribeck": 0.3, "v_stribeck": 0.2, "delta": 2.0, "gamma": 0.1}, 0.2),
    ("stribeck", {"F0": 0.1, "F_stribeck": 0.6, "v_stribeck": 0.03, "delta": 3.7, "gamma": 0.0}, 0.03),
    ("stribeck", {"F0": 0.5, "F_stribeck": 0.3, "v_stribeck": 1.5, "delta": 10.0, "gamma": 2.0}, 1.5),
    ("lubricated", {"gamma1": 3.0, "gamma2": 0.1, "v_tilde": 0.2, "dv": 0.05}, 0.2),  # elmer-fig3
    ("lubricated", {"gamma1": 0.5, "gamma2": 4.0, "v_tilde": 1.0, "dv": 0.3}, 1.0),
    ("lubricated", {"gamma1": 2.0, "gamma2": 0.2, "v_tilde": 0.0, "dv": 0.01}, 0.01),
    # scale: the speed (1 - sigma)/(2 alpha) at which F_K halves
    ("carlson-langer", {"F0": 1.0, "sigma": 0.01, "alpha": 2.5}, 0.198),  # Carlson and Langer's values
    ("carlson-langer", {"F0": 0.7, "sigma": 0.0, "alpha": 40.0}, 0.0125),
    ("carlson-langer", {"F0": 3.0, "sigma": 0.9, "alpha": 0.01}, 5.0),
    ("carlson-langer", {"F0": 0.5, "sigma": 0.2, "alpha": 0.0}, 1.0),  # no weakening: coulomb at F0 (1 - sigma)
]
STATIC = [
    ("constant", {"F0": 1.0}, 1.0),
    ("logarithmic", {"F0": 1.0, "A": 0.2, "tau": 0.5}, 0.5),
    ("logarithmic", {"F0": 0.7, "A": 0.0, "tau": 3.0}, 3.0),
    ("saturating", {"F0": 1.0, "F_inf": 1.6, "tau": 2.0}, 2.0),
    ("saturating", {"F0": 1.0, "F_inf": 0.4, "tau": 0.1}, 0.1),  # weakening
    ("sigmoid", {"F0": 1.0, "F_inf": 1.6, "tau": 2.0, "n": 3.0}, 2.0),
    ("sigmoid", {"F0": 1.0, "F_inf": 1.6, "tau": 2.0, "n": 1.0}, 2.0),
    ("sigmoid", {"F0": 1.0, "F_inf": 0.6, "tau": 1.0, "n": 0.5}, 1.0),  # weakening, infinite slope at 0
    ("sigmoid", {"F0": 0.5, "F_inf": 3.0, "tau": 0.01, "n": 20.0}, 0.01),
]
#: points per branch, in units of the law's characteristic speed or time
SCALED_POINTS = (0.0, 1e-9, 1e-3, 0.1, 0.5, 0.9, 0.99, 1.0, 1.01, 1.1, 1.5, 2.0, 3.0, 7.0, 30.0, 1e3)


def runtime_kinetic(name, p):
    return kinetic_law(name, **p)


def reference_kinetic(name, p):
    return reference_laws.law("kinetic", name, **p)


def runtime_static(name, p):
    return static_law(name, **p)


def reference_static(name, p):
    return reference_laws.law("static", name, **p)


KINETIC_IMPLS = pytest.mark.parametrize("build", [runtime_kinetic, reference_kinetic], ids=["core", "reference"])
STATIC_IMPLS = pytest.mark.parametrize("build", [runtime_static, reference_static], ids=["core", "reference"])
KINETIC_CASES = pytest.mark.parametrize("name, p, scale", KINETIC, ids=[f"{n}-{i}" for i, (n, _, _) in enumerate(KINETIC)])
STATIC_CASES = pytest.mark.parametrize("name, p, scale", STATIC, ids=[f"{n}-{i}" for i, (n, _, _) in enumerate(STATIC)])


def derivative(f, x, h):
    """Fourth-order central difference of ``f`` at ``x`` with step ``h``."""
    return (f(x - 2 * h) - 8 * f(x - h) + 8 * f(x + h) - f(x + 2 * h)) / (12 * h)


def rounding(value, h):
    """What rounding of ``f ~ value`` costs :func:`derivative` with step ``h``: about 10 eps |f| / h."""
    return 10 * 2.2e-16 * max(abs(value), 1.0) / h


def points(scale):
    return [s * scale for s in SCALED_POINTS]


@KINETIC_IMPLS
@KINETIC_CASES
def test_kinetic_force_is_the_spec_formula(build, name, p, scale):
    law = build(name, p)
    for u in points(scale):
        expected = spec_kinetic(name, p, u)
        assert law.force(u) == pytest.approx(expected, rel=1e-13, abs=1e-15), f"F_K({u})"


@KINETIC_IMPLS
@KINETIC_CASES
def test_kinetic_slope_is_the_derivative_of_the_spec_formula(build, name, p, scale):
    law = build(name, p)
    # measured: 1 ulp at most (1.6e-16 relative, 2.2e-16 absolute)
    assert law.slope(0.0) == pytest.approx(spec_slope_at_zero(name, p), rel=1e-14, abs=1e-15)
    for u in points(scale)[2:]:
        h = 1e-3 * min(u, scale)
        expected = derivative(lambda w: spec_kinetic(name, p, w), u, h)
        assert law.slope(u) == pytest.approx(expected, rel=1e-7, abs=rounding(spec_kinetic(name, p, u), h)), f"F_K'({u})"


@STATIC_IMPLS
@STATIC_CASES
def test_static_force_is_the_spec_formula(build, name, p, scale):
    law = build(name, p)
    for t in points(scale):
        # measured: 4.1e-16 relative at most
        assert law.force(t) == pytest.approx(spec_static(name, p, t), rel=2e-14), f"F_S({t})"


@STATIC_IMPLS
@STATIC_CASES
def test_static_rate_is_the_derivative_of_the_spec_formula(build, name, p, scale):
    law = build(name, p)
    assert law.rate(0.0) == spec_rate_at_zero(name, p) or law.rate(0.0) == pytest.approx(
        spec_rate_at_zero(name, p), rel=1e-13)
    for t in points(scale)[2:]:  # finite differences need t >> 1e-16 scale / 1e-3
        h = 1e-3 * t
        expected = derivative(lambda s: spec_static(name, p, s), t, h)
        assert law.rate(t) == pytest.approx(expected, rel=1e-7, abs=rounding(spec_static(name, p, t), h)), f"F_S'({t})"


@STATIC_IMPLS
@STATIC_CASES
def test_static_aging_flags_and_convexity_breaks(build, name, p, scale):
    """``is_constant`` exactly when F_S does not change; ``F_S''`` changes sign at the breaks and nowhere else."""
    law = build(name, p)
    ts = points(scale)[2:]
    values = [spec_static(name, p, t) for t in ts]
    assert law.is_constant() == (max(values) == min(values) == p["F0"])

    def second(t):
        h = 1e-3 * t
        return spec_static(name, p, t - h) - 2 * spec_static(name, p, t) + spec_static(name, p, t + h)

    breaks = law.convexity_breaks()
    for t_break in breaks:
        assert second(0.9 * t_break) * second(1.1 * t_break) < 0
    grid = [scale * 10 ** (k / 8) for k in range(-16, 17)]
    signs = [math.copysign(1, second(t)) for t in grid if abs(second(t)) > 1e-12 * abs(spec_static(name, p, t))]
    changes = sum(1 for a, b in zip(signs, signs[1:]) if a != b)
    assert changes == len(breaks)


@STATIC_CASES
def test_runtime_static_curvature_is_the_second_derivative(name, p, scale):
    law = runtime_static(name, p)
    for t in points(scale)[3:]:
        h = 1e-3 * t
        expected = derivative(law.rate, t, h)
        size = max(abs(expected), abs(p.get("F_inf", p["F0"]) - p["F0"]) / scale**2 * 1e-6, 1e-300)
        assert law.curvature(t) == pytest.approx(expected, rel=1e-6, abs=1e-6 * size), f"F_S''({t})"


@KINETIC_IMPLS
@KINETIC_CASES
def test_affine_is_reported_exactly_when_the_law_is_affine(build, name, p, scale):
    law = build(name, p)
    coefficients = law.affine()
    straight = name in ("coulomb", "viscous") or (name == "stribeck" and p["F_stribeck"] == 0.0) or (
        name == "carlson-langer" and p["alpha"] == 0.0)
    if straight:
        F0, gamma = coefficients
        for u in points(scale):
            assert F0 + gamma * u == pytest.approx(spec_kinetic(name, p, u), rel=1e-14, abs=1e-15)
    elif name in ("stribeck", "carlson-langer") or coefficients is not None:
        assert coefficients is None or p.get("gamma1") == p.get("gamma2")


def analysis_speeds(scale):
    """Speeds (m/s) for the analysis's laws: the points of every branch and a fine grid up to 5 ``scale``."""
    return np.unique(np.concatenate([points(scale), np.linspace(0.0, 5.0 * scale, 401)]))


@KINETIC_CASES
def test_analysis_kinetic_force_and_slope_are_the_spec_formulas(name, p, scale):
    """The analysis evaluates whole arrays of speeds at once, in its own numpy copy of the formulas."""
    law = Kinetic(kinetic_law(name, **p))
    u = analysis_speeds(scale)
    assert law.force(u) == pytest.approx([spec_kinetic(name, p, w) for w in u], rel=1e-13, abs=1e-15)
    assert law.slope(u) == pytest.approx([spec_kinetic_slope(name, p, w) for w in u], rel=1e-13, abs=1e-15)


@KINETIC_CASES
def test_analysis_kinetic_is_continued_by_its_tangent_at_zero_below_zero(name, p, scale):
    """Below ``u = 0`` (the smooth continuation of a slip past ``v_rel = 0``): ``F_K(0) + F_K'(0) u``."""
    law = Kinetic(kinetic_law(name, **p))
    below = -analysis_speeds(scale)[1:]
    u = np.concatenate([below, analysis_speeds(scale)])
    F0, slope0 = spec_kinetic(name, p, 0.0), spec_kinetic_slope(name, p, 0.0)
    expected_force = [F0 + slope0 * w if w < 0.0 else spec_kinetic(name, p, w) for w in u]
    expected_slope = [slope0 if w < 0.0 else spec_kinetic_slope(name, p, w) for w in u]
    assert law.force(u) == pytest.approx(expected_force, rel=1e-13, abs=1e-15)
    assert law.slope(u) == pytest.approx(expected_slope, rel=1e-13, abs=1e-15)
