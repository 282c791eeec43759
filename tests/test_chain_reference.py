"""The chain's monolithic reference (``stickslip.reference.chain``) against closed forms written here: one block
is the single-block reference, uncoupled blocks are independent single blocks, linear chains follow the matrix
exponential, a stuck block breaks when its slipping neighbour pulls it to F_S, and the energy balances."""

import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.linalg import expm
from scipy.optimize import brentq

from stickslip.reference import (ChainBlock, ChainEvent, ReferenceParameterError, parameters_from_values,
                                 simulate_chain, simulate_reference)
from stickslip.reference.laws import Coulomb, Constant, ReferenceParameters, Viscous

#: FMU-named law values of single blocks: every kinetic law and every static law appears
LAWS = {
    "coulomb": {"kinetic.law": 1, "kinetic.F0": 0.5, "static.law": 1, "static.F0": 1.0},
    "stribeck-log": {"kinetic.law": 3, "kinetic.F0": 0.4, "kinetic.F_stribeck": 0.3, "kinetic.v_stribeck": 0.05,
                     "kinetic.delta": 1.0, "kinetic.gamma": 0.1, "static.law": 2, "static.F0": 1.0, "static.A": 0.05,
                     "static.tau": 1.0},
    "viscous-sigmoid": {"kinetic.law": 2, "kinetic.F0": 0.3, "kinetic.gamma": 0.05, "static.law": 4,
                        "static.F0": 0.8, "static.F_inf": 1.2, "static.tau": 3.0, "static.n": 3.0},
    "lubricated-saturating": {"kinetic.law": 4, "kinetic.gamma1": 3.0, "kinetic.gamma2": 0.1, "kinetic.v_tilde": 0.2,
                              "kinetic.dv": 0.05, "static.law": 3, "static.F0": 1.0, "static.F_inf": 1.3,
                              "static.tau": 5.0},
    "carlson-langer": {"kinetic.law": 5, "kinetic.F0": 1.0, "kinetic.sigma": 0.1, "kinetic.alpha": 2.5,
                       "static.law": 1, "static.F0": 1.0},
}
MASSES = {"coulomb": (1.0, 1.0), "stribeck-log": (1.0, 1.0), "viscous-sigmoid": (2.0, 1.5),
          "lubricated-saturating": (40.0, 1.0), "carlson-langer": (1.0, 1.0)}  # (M kg, kappa N/m)


def block(name, x0=0.0, v0=0.1):
    M, kappa = MASSES[name]
    return ChainBlock(parameters_from_values({"M": M, "kappa": kappa, **LAWS[name]}), x0, v0)


def kinds(events):
    return [(e.kind, e.mode_before, e.mode_after) for e in events]


@pytest.mark.parametrize("name", sorted(LAWS))
def test_one_block_is_the_single_block_reference(name):
    b = block(name, x0=0.2)
    t = np.arange(0.0, 200.0 + 1e-9, 0.1)
    single = simulate_reference(b.params, b.x0, b.v0, [(0.0, 0.1, 0.0)], t, rtol=1e-13)
    chain = simulate_chain([b], [], 0.1, t, rtol=1e-13)
    assert len(single.events) >= 4
    assert kinds(chain.events) == kinds(single.events)
    np.testing.assert_allclose([e.t for e in chain.events], [e.t for e in single.events], rtol=0, atol=2e-11)
    np.testing.assert_allclose(chain.x[:, 0], single.x, rtol=0, atol=1e-11)  # 200 s of DOP853 at rtol 1e-13
    np.testing.assert_array_equal(chain.mode[:, 0], single.mode)
    np.testing.assert_allclose(chain.t_stick[:, 0], single.t_stick, rtol=0, atol=1e-9)
    assert np.all(chain.F_ext == 0.0)


def test_uncoupled_blocks_are_independent_single_blocks():
    """kc = 0: each block as if alone, including a graze (a slip whose top speed passes v_drive by 1e-8 m/s for
    1 ms) and a stuck block whose holding margin dips below 0 for 0.6 ms (sigmoid aging), both between samples."""
    grazing = ChainBlock(ReferenceParameters(1.0, 1.0, Coulomb(F0=0.5), Constant(F0=1.0)), 0.5 + 0.1 + 1e-8, 0.0)
    blocks = [block("stribeck-log"), grazing, block("viscous-sigmoid", 0.3, 0.1), _dipping_block()]
    t = np.arange(0.0, 60.0 + 1e-9, 0.05)
    chain = simulate_chain(blocks, [0.0, 0.0, 0.0], 0.1, t, rtol=1e-13)
    for i, b in enumerate(blocks):
        single = simulate_reference(b.params, b.x0, b.v0, [(0.0, 0.1, 0.0)], t, rtol=1e-13)
        mine = [e for e in chain.events if e.block == i]
        assert kinds(mine) == kinds(single.events), f"block {i + 1}"
        np.testing.assert_allclose([e.t for e in mine], [e.t for e in single.events], rtol=0, atol=1e-9)
        np.testing.assert_allclose(chain.x[:, i], single.x, rtol=0, atol=1e-10)
    assert kinds([e for e in chain.events if e.block == 1])[0] == ("stick", 1, 0)  # the graze was not stepped over
    assert chain.event_times(3)[0] < 0.6  # the dip of the holding margin was not stepped over


def _dipping_block():
    """Sigmoid aging, stuck with kappa x + ... tangent to F_S at 0.53 s, shifted up by 1e-7 (as in test_reference)."""
    F0, F_inf, tau, n, t_touch = 1.0, 2.0, 1.0, 4.0, 0.53
    v_drive = 0.1
    slope = (F_inf - F0) * n * tau**n * t_touch ** (n - 1) / (tau**n + t_touch**n) ** 2
    kappa = slope / v_drive  # kappa v_drive = F_S'(t_touch)
    F_S_touch = F0 + (F_inf - F0) * t_touch**n / (tau**n + t_touch**n)
    x_s = (F_S_touch - slope * t_touch + 1e-7) / kappa
    values = {"M": 1.0, "kappa": kappa, "kinetic.law": 1, "kinetic.F0": 0.5, "static.law": 4, "static.F0": F0,
              "static.F_inf": F_inf, "static.tau": tau, "static.n": n}
    return ChainBlock(parameters_from_values(values), x_s, v_drive)


def _linear(M, K, damping, forcing):
    """``(A, b)`` of ``y' = A y + b`` for ``y = [x, v]``: ``M v' = -K x - damping v + forcing``."""
    n = len(M)
    Minv = np.diag(1.0 / np.asarray(M))
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ np.diag(damping)]])
    return A, np.concatenate([np.zeros(n), Minv @ forcing])


def _flow(A, b, y0, t):
    """``y(t)`` of ``y' = A y + b`` from ``y0`` at 0: ``y_eq + expm(A t) (y0 - y_eq)``, shape ``(len(t), 2n)``;
    ``expm(A t) = V exp(L t) V^-1`` from the eigenvectors (checked against scipy's expm at the last time)."""
    y_eq = -np.linalg.solve(A, b)
    t = np.atleast_1d(np.asarray(t, float))
    L, V = np.linalg.eig(A)
    c = np.linalg.solve(V, y0 - y_eq)
    y = y_eq + np.real((V[None, :, :] * np.exp(np.outer(t, L))[:, None, :]) @ c)
    np.testing.assert_allclose(y[-1], y_eq + expm(A * t[-1]) @ (y0 - y_eq), rtol=0, atol=1e-12)
    return y


def test_two_viscous_blocks_sliding_all_along_follow_the_matrix_exponential():
    """v_drive = 5 m/s: both blocks slide forward (mode +1) the whole time, a linear system with constant forcing."""
    M, kappa, F0, gamma, kc, v_drive = (1.0, 2.0), (1.0, 1.5), (0.5, 0.4), (0.3, 0.1), 0.7, 5.0
    blocks = [ChainBlock(ReferenceParameters(M[i], kappa[i], Viscous(F0=F0[i], gamma=gamma[i]), Constant(F0=1.0)),
                         x0, v0) for i, (x0, v0) in enumerate([(0.5, 0.0), (-0.3, 1.0)])]
    t = np.linspace(0.0, 40.0, 401)
    chain = simulate_chain(blocks, [kc], v_drive, t)
    K = np.diag(kappa) + kc * np.array([[1.0, -1.0], [-1.0, 1.0]])
    A, b = _linear(M, K, gamma, np.array(F0) + np.array(gamma) * v_drive)
    y = _flow(A, b, np.array([0.5, -0.3, 0.0, 1.0]), t)
    assert chain.events == [] and np.all(chain.mode == 1)
    np.testing.assert_allclose(chain.x, y[:, :2], rtol=0, atol=1e-11)
    np.testing.assert_allclose(chain.v, y[:, 2:], rtol=0, atol=5e-11)
    np.testing.assert_allclose(chain.F_ext[:, 0], kc * (y[:, 1] - y[:, 0]), rtol=0, atol=1e-11)


def test_stuck_block_breaks_when_its_slipping_neighbour_pulls_it_to_F_S():
    """Block 1 stuck (F_S = 1.5 N) moves with the surface at 1 m/s; block 2 slides forward (Coulomb 0.5 N) pulled
    by the coupling. Closed form until block 1 breaks where 1.5 x1 - 0.5 x2 = F_S, then both slide (Coulomb, a
    linear system) until the first v_rel = 0."""
    v_drive, kc = 1.0, 0.5
    p1 = ReferenceParameters(1.0, 1.0, Coulomb(F0=0.5), Constant(F0=1.5))
    p2 = ReferenceParameters(1.0, 1.0, Coulomb(F0=0.5), Constant(F0=1.0))
    t = np.linspace(0.0, 8.0, 801)
    chain = simulate_chain([ChainBlock(p1, 0.0, v_drive), ChainBlock(p2, 0.0, 0.0)], [kc], v_drive, t)

    w = math.sqrt(1.5)  # block 2 while block 1 is stuck: x2'' = -1.5 x2 + 0.5 t + 0.5
    def x2(s):
        return (0.5 * s + 0.5) / 1.5 - (0.5 / 1.5) * math.cos(w * s) - (0.5 / 1.5) / w * math.sin(w * s)

    def v2(s):
        return 0.5 / 1.5 + (0.5 / 1.5) * w * math.sin(w * s) - (0.5 / 1.5) * math.cos(w * s)

    t_break = brentq(lambda s: 1.5 - (1.5 * v_drive * s - 0.5 * x2(s)), 0.0, 5.0, xtol=1e-15)
    K = np.array([[1.5, -0.5], [-0.5, 1.5]])
    A, b = _linear((1.0, 1.0), K, (0.0, 0.0), np.array([0.5, 0.5]))
    y_b = np.array([v_drive * t_break, x2(t_break), v_drive, v2(t_break)])
    def v_rel(s, i):
        return v_drive - _flow(A, b, y_b, s - t_break)[0, 2 + i]

    grid = np.linspace(t_break + 1e-6, t[-1], 4000)
    reached = v_drive - _flow(A, b, y_b, grid - t_break)[:, 2:] <= 0.0
    k, i_stick = np.argwhere(reached)[0]  # the first block to come back to v_rel = 0
    t_stick = brentq(lambda s: v_rel(s, i_stick), grid[k - 1], grid[k], xtol=1e-15)

    assert chain.events[0] == ChainEvent(chain.events[0].t, 0, "slip", 0, 1)
    assert chain.events[0].t == pytest.approx(t_break, abs=1e-10)
    assert (chain.events[1].block, chain.events[1].kind) == (i_stick, "stick")
    assert chain.events[1].t == pytest.approx(t_stick, abs=1e-9)
    before = t < t_break
    np.testing.assert_allclose(chain.x[before, 1], [x2(s) for s in t[before]], rtol=0, atol=1e-11)
    between = (t > t_break) & (t < t_stick)
    np.testing.assert_allclose(chain.x[between], _flow(A, b, y_b, t[between] - t_break)[:, :2], rtol=0, atol=1e-10)


def _friction(p, mode, x, F_ext, v_rel):
    """The surface's force on a block (N): ``kappa x - F_ext`` stuck, ``mode F_K(mode v_rel)`` slipping (laws
    written out here for Coulomb, Stribeck and viscous)."""
    if mode == 0:
        return p.kappa * x - F_ext
    law, u = p.kinetic, mode * v_rel
    force = law.F0 + getattr(law, "gamma", 0.0) * u
    if hasattr(law, "F_stribeck"):
        force += law.F_stribeck * math.exp(-((u / law.v_stribeck) ** law.delta))
    return mode * force


def test_energy_balance():
    """Spring and kinetic energy change = work of the drive on the friction forces - dissipation, with
    ``E = sum M v^2/2 + kappa x^2/2 + kc (x_(i+1) - x_i)^2/2``, drive power ``sum F_f v_drive`` and dissipation
    ``sum F_f v_rel >= 0``, integrated between events from the dense solution."""
    blocks = [block("coulomb", 0.0), block("stribeck-log", 0.4), block("coulomb", -0.3, 0.0)]
    kc, v_drive, t_end = np.array([0.5, 0.8]), 0.1, 80.0
    chain = simulate_chain(blocks, kc, v_drive, np.linspace(0.0, t_end, 801))
    params = [b.params for b in blocks]

    def energy(s):
        x, v, _ = chain.state(s)
        return sum(0.5 * p.M * vi**2 + 0.5 * p.kappa * xi**2 for p, xi, vi in zip(params, x, v)) + \
            float(np.sum(0.5 * kc * np.diff(x) ** 2))

    def powers(s):
        x, v, modes = chain.state(s)
        F = np.zeros(3)
        F[:-1] += kc * (x[1:] - x[:-1])
        F[1:] -= kc * (x[1:] - x[:-1])
        f = [_friction(p, m, xi, Fi, v_drive - vi) for p, m, xi, Fi, vi in zip(params, modes, x, F, v)]
        return sum(f) * v_drive, sum(fi * (v_drive - vi) for fi, vi in zip(f, v))

    cuts = np.unique([0.0, *(e.t for e in chain.events), t_end])
    drive = sum(quad(lambda s: powers(s)[0], a, b, epsabs=1e-13, limit=200)[0] for a, b in zip(cuts, cuts[1:]))
    loss = sum(quad(lambda s: powers(s)[1], a, b, epsabs=1e-13, limit=200)[0] for a, b in zip(cuts, cuts[1:]))
    assert len(chain.events) >= 10 and loss > 0.1
    assert energy(t_end) - energy(0.0) == pytest.approx(drive - loss, abs=1e-9)


def test_bad_chains_are_refused_with_the_cause():
    b = block("coulomb")
    t = np.linspace(0.0, 1.0, 3)
    with pytest.raises(ReferenceParameterError, match="coupling .* 1 finite values >= 0"):
        simulate_chain([b, b], [0.5, 0.5], 0.1, t)
    with pytest.raises(ReferenceParameterError, match="coupling"):
        simulate_chain([b, b], [-1.0], 0.1, t)
    with pytest.raises(ReferenceParameterError, match="block 2: x0 = nan"):
        simulate_chain([b, ChainBlock(b.params, math.nan, 0.0)], [0.5], 0.1, t)
    with pytest.raises(ReferenceParameterError, match="at least one block"):
        simulate_chain([], [], 0.1, t)
