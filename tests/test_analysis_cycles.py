"""Sliding limit cycles: shooting against the Hopf normal form, folds, grazing (stickslip.analysis.sliding_limit_cycles)."""

import math

import pytest
from scipy.integrate import solve_ivp

from stickslip.core import CallableKinetic, Constant, Lubricated, Parameters, Stribeck
from stickslip.analysis import boundary, flow, sliding_limit_cycles, steady_sliding


def test_subcritical_hopf_cycle_matches_the_normal_form():
    p = Parameters(2.0, 1.5, Stribeck(F0=0.4, F_stribeck=0.3, v_stribeck=0.1, delta=1.0, gamma=0.5),
                   Constant(F0=1.0))
    (h,) = steady_sliding.hopf_points(p, 0.0, 5.0)
    rmap = sliding_limit_cycles.ReturnMap(p)
    for dv in (2e-3, 1e-3):
        v = h.v_drive + dv  # side +1: the unstable cycles live above the minimum
        predicted = h.amplitude(v, slope=p.kinetic.slope(v)) * h.omega
        c = sliding_limit_cycles.cycle_at(rmap, predicted, v)
        assert c is not None and not c.stable and c.multiplier > 1.0
        assert c.sigma == pytest.approx(predicted, rel=15 * dv / h.v_drive)
        # the period shifts from the Hopf one by O(v - v_H) (measured 0.28 dv); and it is a cycle indeed
        assert c.period == pytest.approx(h.period, rel=0.5 * dv)
        period, x_back = revolution(lambda u: 0.4 + 0.3 * math.exp(-u / 0.1) + 0.5 * u, 2.0, 1.5, v, c.x_max,
                                    h.period)
        assert c.period == pytest.approx(period, rel=1e-9)  # measured 1e-12
        assert x_back == pytest.approx(c.x_max, abs=1e-9)
    # below the minimum CS is unstable and no small cycle exists: the return map pushes outward
    values = rmap.evaluate([0.01 * predicted], [h.v_drive - 1e-3])
    assert values["G"][0] > 0.0



@pytest.mark.filterwarnings("error")
def test_the_return_map_has_no_value_at_an_amplitude_at_or_below_zero():
    """A continuation's predictor may step past the Hopf point to ``sigma <= 0``: no revolution starts there (NaN),
    none is integrated with the zero or negative tolerance that amplitude would set, and the points beside it in
    the batch keep their values."""
    p = Parameters(2.0, 1.5, Stribeck(F0=0.4, F_stribeck=0.3, v_stribeck=0.1, delta=1.0, gamma=0.5),
                   Constant(F0=1.0))
    (h,) = steady_sliding.hopf_points(p, 0.0, 5.0)
    v = h.v_drive + 1e-3
    sigma = h.amplitude(v, slope=p.kinetic.slope(v)) * h.omega
    rmap = sliding_limit_cycles.ReturnMap(p)
    alone = rmap.evaluate([sigma], [v])
    batch = rmap.evaluate([sigma, -0.1 * sigma, 0.0, sigma], [v] * 4)
    for key, values in batch.items():
        assert math.isfinite(alone[key][0]), key
        assert list(values[[0, 3]]) == pytest.approx([alone[key][0]] * 2, rel=1e-9), key  # batches differ by ~1e-11
        assert all(math.isnan(value) for value in values[1:3]), key
    with pytest.raises(ValueError, match="scale: allowed is a length > 0 m"):
        flow.run(p, 1.0, 0.0, 0.1, scale=0.0)

def test_supercritical_hopf_cycle_is_stable():
    d = 0.04
    law = CallableKinetic(lambda u: 1 + (u - 1) ** 3 / 3 - d * (u - 1), lambda u: (u - 1) ** 2 - d)
    p = Parameters(1.0, 1.0, law, Constant(F0=2.0))
    lo, _ = steady_sliding.hopf_points(p, 0.0, 3.0)
    v = lo.v_drive + 2e-3
    predicted = lo.amplitude(v, slope=law.slope(v)) * lo.omega
    c = sliding_limit_cycles.cycle_at(sliding_limit_cycles.ReturnMap(p), predicted, v)
    assert c is not None and c.stable and 0.0 < c.multiplier < 1.0
    assert c.sigma == pytest.approx(predicted, rel=0.02)  # the normal form's error is O(v - v_H): ~1 %
    period, x_back = revolution(lambda u: 1 + (u - 1) ** 3 / 3 - d * (u - 1), 1.0, 1.0, v, c.x_max, lo.period)
    assert c.period == pytest.approx(period, rel=1e-9)
    assert x_back == pytest.approx(c.x_max, abs=1e-9)


def revolution(F_K, M, kappa, v_drive, x_max, period_guess):
    """``(time, x)`` of the next maximum of ``x`` after ``(x_max, v = 0)`` in mode +1: scipy's DOP853 at rtol
    1e-12 on the law ``F_K`` written in the test, independent of the analysis' flow and return map."""

    def velocity(t, y):
        return y[1]

    velocity.direction = -1
    sol = solve_ivp(lambda t, y: [y[1], (-kappa * y[0] + F_K(v_drive - y[1])) / M], (0.0, 3.0 * period_guess),
                    [x_max, 0.0], method="DOP853", rtol=1e-12, atol=1e-14, events=velocity)
    i = next(k for k, t in enumerate(sol.t_events[0]) if t > 0.5 * period_guess)
    return sol.t_events[0][i], sol.y_events[0][i][0]


def elmer():
    return Parameters(40.0, 1.0, Lubricated(gamma1=3.0, gamma2=0.1, v_tilde=0.2, dv=0.05), Constant(F0=1.0))


def test_fold_of_the_large_elmer_cycles():
    """The fold's velocity 1.1572381 m/s (ELMER_POINTS' last) is confirmed independently, by a return map of
    scipy's solve_ivp, in test_bifurcation_independent.py; here: multiplier 1 there, two cycles of opposite
    stability just below, none just above."""
    p = elmer()
    rmap = sliding_limit_cycles.ReturnMap(p)
    (f,) = sliding_limit_cycles.refine_folds(rmap, [(1.05, 1.15)])
    assert f.v_drive == pytest.approx(1.1572381, abs=2e-6)
    assert f.multiplier == pytest.approx(1.0, abs=1e-3)
    # two cycles just below the fold (one stable, one not), none just above
    below = [sliding_limit_cycles.cycle_at(rmap, f.sigma + s, f.v_drive - 2e-4) for s in (-0.03, 0.03)]
    assert all(c is not None for c in below)
    assert {c.stable for c in below} == {True, False}
    assert abs(below[0].sigma - below[1].sigma) > 1e-3
    assert sliding_limit_cycles.cycle_at(rmap, f.sigma, f.v_drive + 2e-4) is None


def test_grazing_cycle_is_where_the_special_boundary_switches():
    """Two independent computations: forward shooting of the cycle, backward orbit from the graze point."""
    p = elmer()
    (g,) = sliding_limit_cycles.refine_grazings(sliding_limit_cycles.ReturnMap(p), [(0.79, 0.78)])
    assert g.v_max == pytest.approx(g.v_drive, abs=1e-10) and g.stable
    (switch,) = boundary.boundary_switches(p, [0.78, 0.79], tol=1e-9)
    assert switch[0] == pytest.approx(g.v_drive, abs=1e-8)
    assert (switch[1], switch[2]) == ("spiral", "stick-line")
