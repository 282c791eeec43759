"""The mapping of docs/chains.md between a plate-driven Burridge-Knopoff chain and our chain (walls, moving surface).

The plate-driven chain is integrated here directly, in Carlson and Langer's scaled variables (time ``tau = omega_p
t``, ``omega_p = sqrt(kp/m)``; lengths in ``D0 = F0/kp``; ``U_j`` the position of block ``j`` relative to the plate,
whose leaf spring pulls with ``-U_j``): ``U_j'' = l^2 (U_(j+1) - 2 U_j + U_(j-1)) - U_j - s_j phi(|nu + U_j'|)`` with
``phi(y) = (1 - sigma)/(1 + 2 alpha y/(1 - sigma))`` against the fixed ground, ``s_j`` the sign of the block's
velocity over the ground ``nu + U_j'``; a block stuck to the ground (``U_j' = -nu``) holds while its spring forces
stay within ``|G_j| <= 1``. scipy's DOP853 with its own event location, restarted at each event; nothing of the
package. Our reference chain, built from SI values by the mapping (``kappa = kp``, ``kc = l^2 kp``, ``v_drive = nu
D0 omega_p``, ``alpha_ours = alpha / (D0 omega_p)``, ``x = -D0 U``, ``t = tau / omega_p``), must give the same
trajectory.
"""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from stickslip.reference import ChainBlock, parameters_from_values, simulate_chain

# Carlson and Langer's dimensionless parameters (a short chain, stiff coupling, strong weakening)
L2, ALPHA, SIGMA, NU = 9.0, 1.5, 0.05, 0.02
# start: every block stuck to the ground, at these positions relative to the plate (units of D0)
U_START = np.array([-0.70, -0.705, -0.695, -0.71, -0.70])
TAU_END = 60.0
# the same chain in SI: none of these is 1, so that every conversion factor shows
M, KP, F0 = 2.0, 0.5, 3.0
D0, OMEGA_P = F0 / KP, np.sqrt(KP / M)  # m, 1/s


def _phi(y):
    """Carlson and Langer's friction over ``F0`` at the ground speed ``y >= 0`` (units of ``D0 omega_p``)."""
    return (1.0 - SIGMA) / (1.0 + 2.0 * ALPHA * y / (1.0 - SIGMA))


def _spring_forces(u):
    """``G_j = l^2 (U_(j+1) - 2 U_j + U_(j-1)) - U_j`` (units of F0), free ends."""
    padded = np.concatenate([u[:1], u, u[-1:]])
    return L2 * (padded[2:] - 2.0 * u + padded[:-2]) - u


class _PlateChain:
    """The plate-driven chain as a hybrid system: modes ``s_j`` (+1, -1 sliding over the ground, 0 stuck)."""

    def __init__(self):
        self.n = U_START.size
        self.modes = np.zeros(self.n, int)

    def rhs(self, tau, y):
        u, w = y[:self.n], y[self.n:]
        g = _spring_forces(u)
        dw = np.where(self.modes == 0, 0.0, g - self.modes * _phi(np.abs(NU + w)))
        return np.concatenate([np.where(self.modes == 0, -NU, w), dw])

    def events(self):
        """One event function per block: a sliding block's ground speed reaching 0, a stuck block's |G| reaching 1."""
        functions = []
        for j in range(self.n):
            if self.modes[j] == 0:
                def breaks(tau, y, j=j):
                    return 1.0 - abs(_spring_forces(y[:self.n])[j])
            else:
                def breaks(tau, y, j=j, s=self.modes[j]):
                    return s * (NU + y[self.n + j])
            breaks.terminal, breaks.direction = True, -1
            functions.append(breaks)
        return functions

    def apply(self, j, y):
        """The transition of block ``j`` at its event (SPEC section 1 in the plate's words); its kind."""
        g = _spring_forces(y[:self.n])[j]
        kind = "slip" if self.modes[j] == 0 else "overshoot" if abs(g) > 1.0 else "stick"
        if kind == "stick":  # the ground holds it
            self.modes[j] = 0
            y[self.n + j] = -NU
        else:  # breakaway, or an overshoot: it slides the way the springs pull
            self.modes[j] = 1 if g > 0.0 else -1
        return kind

    def run(self, taus):
        """``[U, U']`` on the times ``taus`` (state after any event there) and the events ``(tau, block, kind)``."""
        y = np.concatenate([U_START, np.full(self.n, -NU)])
        tau, out, events = 0.0, [], []
        while tau < taus[-1]:
            inside = taus[(taus >= tau) & (taus <= taus[-1])]
            sol = solve_ivp(self.rhs, (tau, taus[-1]), y, method="DOP853", rtol=1e-13, atol=1e-15,
                            events=self.events(), dense_output=True)
            end = sol.t[-1]
            keep = inside[inside < end] if sol.status == 1 else inside
            out.append(sol.sol(keep).T if keep.size else np.empty((0, 2 * self.n)))
            tau, y = end, sol.y[:, -1].copy()
            if sol.status == 1:
                j = next(k for k, hits in enumerate(sol.t_events) if hits.size)
                events.append((end, j, self.apply(j, y)))
        return np.concatenate(out), events


def _our_chain():
    """Our chain by the mapping of docs/chains.md, in SI: the reference's blocks, coupling and drive."""
    values = {"M": M, "kappa": KP, "kinetic.law": "carlson-langer", "kinetic.F0": F0, "kinetic.sigma": SIGMA,
              "kinetic.alpha": ALPHA / (D0 * OMEGA_P), "static.law": "constant", "static.F0": F0}
    v_drive = NU * D0 * OMEGA_P
    blocks = [ChainBlock(parameters_from_values(values), -D0 * u, v_drive) for u in U_START]
    return blocks, [L2 * KP] * (len(blocks) - 1), v_drive


def test_plate_driven_chain_is_our_chain_through_the_mapping():
    assert np.all(np.abs(_spring_forces(U_START)) < 1.0)  # every block starts stuck
    taus = np.linspace(0.0, TAU_END, 1201)
    plate, plate_events = _PlateChain().run(taus)
    blocks, coupling, v_drive = _our_chain()
    ours = simulate_chain(blocks, coupling, v_drive, taus / OMEGA_P, rtol=1e-13)
    # every block slips, some more than once, in events of one block and of the whole chain
    assert len(plate_events) >= 30 and {j for _, j, _ in plate_events} == set(range(U_START.size))
    assert [(e.block, e.kind) for e in ours.events] == [(j, kind) for _, j, kind in plate_events]
    # measured: 1.2e-8 s at most over 120 s (a stick, where the speed reaches 0 slowly)
    assert np.allclose([e.t for e in ours.events], [tau / OMEGA_P for tau, _, _ in plate_events], rtol=0, atol=5e-8)
    x_mapped = -D0 * plate[:, :U_START.size]  # x_ours = v_drive t - X_plate = -D0 U
    v_mapped = -D0 * OMEGA_P * plate[:, U_START.size:]
    # measured: 2.5e-10 of the amplitude in x, 1.3e-9 in v (the reference's own error at rtol 1e-13)
    assert np.max(np.abs(ours.x - x_mapped)) <= 2e-9 * np.ptp(ours.x)
    assert np.max(np.abs(ours.v - v_mapped)) <= 1e-8 * np.ptp(ours.v)


def test_velocity_argument_is_the_ground_speed_of_the_plate_chain():
    """Our sliding speed ``v_drive - v`` is the block's speed over the ground in the plate's chain, ``D0 omega_p
    (nu + U')``: our friction law at it is Carlson and Langer's ``F0 phi``."""
    blocks, _, v_drive = _our_chain()
    law = blocks[0].params.kinetic
    for w in (-0.019, 0.0, 0.3, 2.0):
        u_ours = v_drive - (-D0 * OMEGA_P * w)  # v = dx/dt = -D0 omega_p dU/dtau
        assert u_ours == pytest.approx(D0 * OMEGA_P * (NU + w), rel=1e-14)
        assert law.force(u_ours) == pytest.approx(F0 * _phi(NU + w), rel=1e-14)
