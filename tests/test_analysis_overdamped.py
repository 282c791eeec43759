"""Strongly overdamped limit (stickslip.analysis.overdamped)."""

import math

import numpy as np
import pytest

from stickslip.core import Constant, Parameters, Stribeck
from stickslip.analysis import overdamped


def params():
    # the overdamped-stribeck scenario: M = 0.01, |F_K'| up to 2 >> sqrt(kappa M) = 0.1
    return Parameters(0.01, 1.0, Stribeck(F0=0.5, F_stribeck=0.3, v_stribeck=0.1, delta=1.0, gamma=1.0),
                      Constant(F0=1.0))


def test_slow_manifold_branches_and_fold():
    m = overdamped.slow_manifold(params(), 1.0)
    u_min = 0.1 * math.log(0.3 / (1.0 * 0.1))  # minimum of F_K
    ((u_f, x_f),) = m.folds
    assert u_f == pytest.approx(u_min, abs=1e-12)
    assert x_f == pytest.approx(0.5 + 0.3 * math.exp(-u_min / 0.1) + u_min)
    assert np.all(m.stable == (m.u > u_min))
    assert m.ratio.max() > 10.0


def test_relaxation_oscillation_follows_the_attracting_branch():
    p = params()
    t, x, v_rel, mode = overdamped.relaxation_run(p, 0.05, t_end=25.0, x0=0.95)
    slipping = mode != 0
    gap = overdamped.distance_to_manifold(p, x[slipping], v_rel[slipping])
    on_branch = v_rel[slipping] > 0.2  # on the fast-sliding (attracting) branch, away from the jumps
    assert on_branch.sum() > 100
    assert np.median(np.abs(gap[on_branch])) < 0.02  # N, against F_K ~ 1 N
    assert np.any(mode == 0)  # relaxation oscillations stick
