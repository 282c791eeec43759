"""The stick-slip map of aging static friction (stickslip.analysis.aging_map)."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from stickslip.core import Coulomb, Logarithmic, Parameters, Sigmoid
from stickslip.analysis import aging_map


def log_params():
    return Parameters(1.0, 1.0, Coulomb(F0=0.5), Logarithmic(F0=0.8, A=0.1, tau=1.0))


def test_coulomb_slip_reflects_about_the_kinetic_level():
    p = log_params()
    x = np.linspace(0.85, 1.4, 7)
    vals = aging_map.map_values(p, x, 0.05)
    assert vals["x_stick"] == pytest.approx(2 * 0.5 - x, abs=1e-11)
    # the stick ends where F_S(t)/kappa = x^s + v t
    t = vals["stick_time"]
    assert 0.8 + 0.1 * np.log1p(t) == pytest.approx(vals["x_stick"] + 0.05 * t, abs=1e-11)


@pytest.mark.parametrize("v_drive", [0.01, 0.05, 0.3])
def test_fixed_point_of_logarithmic_aging_with_coulomb_kinetics(v_drive):
    """x* = x^s + v t with x^s = 2 F_K/kappa - x* and kappa x* = F_S(t): F_S(t) - F_K = kappa v t / 2."""
    t = brentq(lambda t: 0.8 + 0.1 * math.log1p(t) - 0.5 - 0.5 * v_drive * t, 1e-12, 1e6, xtol=1e-15)
    x_star = 0.8 + 0.1 * math.log1p(t)
    p = log_params()
    (fp,) = aging_map.fixed_points(p, v_drive)
    assert fp.x == pytest.approx(x_star, abs=1e-10)
    assert fp.stick_time == pytest.approx(t, rel=1e-9)
    # T'(x*) = -dx^s/dx * (kappa + ...) ; here stable: the slope is small and positive
    assert fp.stable and 0.0 < fp.slope < 1.0
    # the Lyapunov exponent of an orbit converging onto it is ln T'(x*)
    assert aging_map.lyapunov_exponent(p, v_drive, n_transient=30, n_iter=20) == pytest.approx(
        math.log(fp.slope), abs=1e-3)


SIGMOID_AGING = Parameters(1.0, 1.0, Coulomb(F0=0.5), Sigmoid(F0=0.8, F_inf=1.5, tau=5.0, n=4.0))


@pytest.mark.parametrize("v_min, v_max, n", [(0.2, 0.3, 21), (0.016, 1.6, 60), (0.016, 1.6, 40)],
                         ids=["fine", "coarse-60", "coarse-40"])
def test_saddle_nodes_of_sigmoid_aging(v_min, v_max, n):
    """On a fine grid and on the coarse grids of ``stickslip map`` (one or two velocities between the two
    saddle-nodes, where the window of the born pair's extremum reached the surviving fixed point): the fixed
    points appear and vanish in pairs within 2e-6 m/s of each saddle-node found."""
    q = SIGMOID_AGING
    sn = aging_map.saddle_nodes(q, v_min, v_max, n=n)
    assert len(sn) == 2
    (v1, x1), (v2, x2) = sn
    assert 0.24 < v1 < 0.25 and 0.255 < v2 < 0.265
    for v, x, side in ((v1, x1, -1), (v2, x2, 1)):
        outside = aging_map.fixed_points(q, v + side * 2e-6, x_range=(x - 0.05, x + 0.05), n=400)
        inside = aging_map.fixed_points(q, v - side * 2e-6, x_range=(x - 0.05, x + 0.05), n=400)
        assert outside == [] and len(inside) == 2
        assert {fp.stable for fp in inside} == {True, False}
    # bistability between the saddle-nodes: two stable stick-slip cycles
    both = aging_map.fixed_points(q, 0.5 * (v1 + v2))
    assert sum(fp.stable for fp in both) == 2 and len(both) == 3


def test_critical_velocity_of_aging_with_viscous_kinetics_matches_the_stepper():
    from stickslip.core import Viscous
    from stickslip.analysis import classify

    p = Parameters(1.0, 1.0, Viscous(F0=0.5, gamma=0.3), Logarithmic(F0=0.8, A=0.1, tau=1.0))
    (vc,) = aging_map.critical_velocity(p, 0.01, 1.0, n=30)
    below = classify.classify_run(p, vc - 1e-4, t_end=400.0, tail=150.0)
    above = classify.classify_run(p, vc + 1e-4, t_end=400.0, tail=150.0)
    assert below.kind == "stick-slip" and above.kind == "continuous-sliding"


def test_overshooting_slips_make_the_map_non_monotonic_and_period_two():
    """Coulomb F_K = 0.1 N far below aged F_S: long sticks end in slips that overshoot and stick on the far side."""
    from stickslip.analysis import classify

    q = Parameters(1.0, 1.0, Coulomb(F0=0.1), Logarithmic(F0=0.3, A=0.5, tau=1.0))
    v = 0.2
    x = np.linspace(0.45, 0.65, 9)
    t = aging_map.map_values(q, x, v)["T"]
    assert np.any(np.diff(t) > 0.0) and np.any(np.diff(t) < 0.0)
    iterates, exponents = aging_map.orbit_diagram(q, [v], n_transient=60, n_keep=8)
    cycle = np.unique(np.round(iterates[0], 8))
    assert cycle.size == 2 and exponents[0] < 0.0
    vals = aging_map.map_values(q, cycle, v)
    assert vals["T"] == pytest.approx(cycle[::-1], abs=1e-7)
    a = classify.classify_run(q, v, t_end=400.0, tail=250.0, x0=float(cycle[0]))  # starts slipping on the cycle
    assert a.kind == "stick-slip" and a.repeat == 2 and a.overshoots
    assert a.period == pytest.approx(float(np.sum(vals["slip_time"] + vals["stick_time"])), rel=1e-6)
