"""The DOP853 tableau of the analysis's batch integrator: its order conditions, and the same doubles as SciPy's."""

import importlib
from math import factorial

import numpy as np
import pytest

from stickslip.analysis.dop853_tableau import A, B, C, E3, E5, N_STAGES

#: the nodes with ``c_13 = 1`` of the stage ``k_13 = f(t + h, y1)`` the error weights also use
C13 = np.append(C, 1.0)


def test_the_tableau_is_explicit_and_its_rows_sum_to_the_nodes():
    assert A.shape == (N_STAGES, N_STAGES) and B.shape == C.shape == (N_STAGES,)
    assert E3.shape == E5.shape == (N_STAGES + 1,)
    assert np.array_equal(A, np.tril(A, -1))
    assert np.abs(A.sum(axis=1) - C).max() <= 1e-15


@pytest.mark.parametrize("k", range(1, 9))
def test_the_weights_integrate_polynomials_of_degree_below_8_exactly(k):
    """``sum_i b_i c_i^(k-1) = 1/k`` for k = 1..8 (the bushy trees of order 8)."""
    assert B @ C ** (k - 1) == pytest.approx(1.0 / k, abs=1e-15)


@pytest.mark.parametrize("m", range(7))
def test_the_tall_trees_up_to_order_8(m):
    """``b A^m c = 1/(m+2)!``: the order condition of the tall tree of order m + 2."""
    assert B @ np.linalg.matrix_power(A, m) @ C == pytest.approx(1.0 / factorial(m + 2), rel=1e-12, abs=1e-17)


def test_a_few_order_conditions_of_mixed_trees():
    assert B @ (C * (A @ C)) == pytest.approx(1.0 / 8.0, abs=1e-15)
    assert B @ A @ C**2 == pytest.approx(1.0 / 12.0, abs=1e-15)
    assert B @ (C**2 * (A @ C)) == pytest.approx(1.0 / 10.0, abs=1e-15)


def test_the_error_weights_are_differences_of_solutions_of_orders_5_and_3():
    """``E5 @ k`` vanishes on polynomials of degree < 5 (and not on degree 5), ``E3 @ k`` on degree < 3."""
    for k in range(1, 6):
        assert abs(E5 @ C13 ** (k - 1)) <= 1e-15
    assert abs(E5 @ C13**5) > 1e-4
    for k in range(1, 4):
        assert abs(E3 @ C13 ** (k - 1)) <= 1e-15
    assert abs(E3 @ C13**3) > 1e-3


def test_the_tableau_holds_the_same_doubles_as_scipys():
    """Bit for bit SciPy's coefficients, which the analysis used before (so every result is unchanged).

    SciPy keeps them in a private module: imported here only, to compare; skipped where it moved."""
    try:
        scipy_tableau = importlib.import_module("scipy.integrate._ivp.dop853_coefficients")
    except ImportError:
        pytest.skip("SciPy's private DOP853 coefficients moved")
    assert np.array_equal(A, scipy_tableau.A[:N_STAGES, :N_STAGES])
    assert np.array_equal(B, scipy_tableau.B)
    assert np.array_equal(C, scipy_tableau.C[:N_STAGES])
    assert np.array_equal(E3, scipy_tableau.E3)
    assert np.array_equal(E5, scipy_tableau.E5)
