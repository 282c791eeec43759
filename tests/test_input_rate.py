"""An external force that grows linearly over a step (the runtime's ``F_ext_rate``, FMI 2's
``fmi2SetRealInputDerivatives`` of order 1) is followed exactly: against closed forms (Coulomb friction: a stuck
block loaded by a ramp breaks away when the ramp reaches F_S, then slides as a forced harmonic oscillator), a root
of SPEC's aging law, and a tight ``solve_ivp`` of a Stribeck slip. Also: the result does not depend on how time is
sliced, a saved state continues bit for bit, the acceleration and its rate (the FMI 2 output derivatives) match
the motion, and a bad rate is refused by name.
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from stickslip.core import ParameterError, Parameters, Trajectory, kinetic_law, static_law

COULOMB = Parameters(1.0, 1.0, kinetic_law(1, F0=0.5), static_law(1, F0=1.0))
RATE = 0.25  # N/s


def ramp_motion(t):
    """The block at rest at x = 0 on a still surface, F_ext = RATE t, Coulomb F_K = 0.5 N, F_S = 1 N, M = kappa = 1:
    stuck until RATE t = F_S (t = 4 s), then ``x'' + x = RATE t - 0.5`` from rest: ``(x, v)`` for 4 <= t <= the
    next stick."""
    tau = t - 4.0
    x = RATE * t - 0.5 - 0.5 * math.cos(tau) - 0.25 * math.sin(tau)
    v = RATE + 0.5 * math.sin(tau) - 0.25 * math.cos(tau)
    return x, v


def ramp_trajectory(**kwargs):
    return Trajectory(COULOMB, 0.0, 0.0, v_drive=0.0, F_ext=0.0, F_ext_rate=RATE, **kwargs)


def test_a_ramp_breaks_a_stuck_block_away_at_F_S_and_slides_it_as_the_closed_form():
    stick_again = 4.0 + brentq(lambda tau: ramp_motion(4.0 + tau)[1], 3.5, 5.0)
    traj = ramp_trajectory(record_events=True)
    for t in (1.0, 3.999):
        traj.advance_to(t)
        assert (traj.x, traj.v, traj.mode) == (0.0, 0.0, 0)
        assert traj.z_slip == pytest.approx(1.0 - RATE * t, abs=1e-15)
        assert traj.F_ext_now == pytest.approx(RATE * t, abs=1e-15)
    for t in np.linspace(4.1, stick_again - 1e-6, 40):
        traj.advance_to(float(t))
        x, v = ramp_motion(float(t))
        assert abs(traj.x - x) < 1e-13 and abs(traj.v - v) < 1e-13
        assert traj.friction_force == -0.5 and traj.spring_force == -traj.x
    traj.advance_to(stick_again + 0.5)
    assert traj.events[0] == (4.0, 0, -1)
    assert traj.events[1][1:] == (-1, 0) and abs(traj.events[1][0] - stick_again) < 1e-12


def test_an_aging_contact_breaks_away_when_the_ramp_reaches_F_S_of_its_stick_time():
    """SPEC's logarithmic aging, F_S(t_stick) = F0 + A ln(1 + t_stick/tau), against a ramp that starts at 0.4 N."""
    F0, A, tau, start, rate = 1.0, 0.2, 2.0, 0.4, 0.1
    p = Parameters(1.0, 1.0, kinetic_law(1, F0=0.5), static_law(2, F0=F0, A=A, tau=tau))
    expected = brentq(lambda t: F0 + A * math.log1p(t / tau) - (start + rate * t), 0.0, 100.0)
    traj = Trajectory(p, 0.0, 0.0, v_drive=0.0, F_ext=start, F_ext_rate=rate, record_events=True)
    traj.advance_to(expected + 1.0)
    assert traj.events[0][1:] == (0, -1) and abs(traj.events[0][0] - expected) < 1e-9


def _stribeck_force(u):
    """SPEC's kinetic law 3 with the parameters below: F0 + F_stribeck exp(-(u/v_stribeck)^delta) + gamma u."""
    return 0.3 + 0.2 * math.exp(-((u / 0.1) ** 2)) + 0.05 * u


def test_a_stribeck_slip_under_a_ramp_follows_a_tight_integrator():
    p = Parameters(1.0, 1.0, kinetic_law(3, F0=0.3, F_stribeck=0.2, v_stribeck=0.1, delta=2.0, gamma=0.05),
                   static_law(1, F0=0.6))
    v_drive, F0, rate, x0, v0 = 0.2, 0.1, 0.3, 0.0, -0.6  # slipping forward (v < v_drive) throughout [0, 1] s

    def rhs(t, y):
        return [y[1], (F0 + rate * t - y[0] + _stribeck_force(v_drive - y[1])) / 1.0]

    times = np.linspace(0.0, 1.0, 21)
    expected = solve_ivp(rhs, (0.0, 1.0), [x0, v0], method="DOP853", rtol=1e-13, atol=1e-15, t_eval=times).y
    traj = Trajectory(p, x0, v0, v_drive=v_drive, F_ext=F0, F_ext_rate=rate, rtol=1e-12)
    xs, vs = traj.sample(times)
    assert traj.n_events == 0
    assert np.max(np.abs(np.array(xs) - expected[0])) < 1e-10
    assert np.max(np.abs(np.array(vs) - expected[1])) < 1e-10


def test_the_motion_does_not_depend_on_how_time_is_sliced():
    whole = ramp_trajectory()
    whole.advance_to(7.5)
    sliced = ramp_trajectory()
    t = 0.0
    for _ in range(75):
        x, v = sliced.communicate(t, 0.1)
        t += 0.1
    assert abs(x - whole.x) < 1e-14 and abs(v - whole.v) < 1e-14
    assert (x, v) == (sliced.x, sliced.v)


def test_a_snapshot_with_a_rate_continues_bit_for_bit():
    traj = ramp_trajectory()
    traj.advance_to(5.0)
    restored = Trajectory.from_snapshot(COULOMB, traj.snapshot())
    for t in (5.5, 7.0, 9.0):
        traj.advance_to(t)
        restored.advance_to(t)
        assert traj.outputs() == restored.outputs()


def test_the_same_ramp_set_again_changes_nothing_and_a_held_force_ends_it():
    traj = ramp_trajectory()
    traj.advance_to(5.0)
    before = traj.snapshot()
    traj.set_inputs(0.0, traj.F_ext_now, RATE)
    assert traj.snapshot() == before
    held = traj.F_ext_now
    traj.set_inputs(0.0, held)  # from now on a constant force: x'' + x = held - 0.5 about the state at 5 s
    x5, v5 = ramp_motion(5.0)
    traj.advance_to(5.5)
    centre = held - 0.5
    x = centre + (x5 - centre) * math.cos(0.5) + v5 * math.sin(0.5)
    assert abs(traj.x - x) < 1e-13 and traj.F_ext_now == held


def test_the_acceleration_and_its_rate_are_those_of_the_motion():
    traj = ramp_trajectory()
    traj.advance_to(2.0)
    assert traj.acceleration() == (0.0, 0.0)  # stuck on a still surface
    for t in (4.5, 6.0, 7.5):
        traj.advance_to(t)
        x, v = ramp_motion(t)
        a = RATE * t - x - 0.5  # M a = F_ext - kappa x + F, F = -0.5 N sliding backward
        jerk = RATE - v  # M da/dt = dF_ext/dt - kappa v (Coulomb: F constant)
        assert traj.acceleration() == pytest.approx((a, jerk), abs=1e-13)


@pytest.mark.parametrize("rate, named", [(math.nan, "der(F_ext)"), (math.inf, "der(F_ext)"),
                                         (1e160, "der(F_ext)")])
def test_a_bad_rate_is_refused_by_name(rate, named):
    with pytest.raises(ParameterError, match=named.replace("(", r"\(").replace(")", r"\)")):
        Trajectory(COULOMB, 0.0, 0.0, F_ext_rate=rate)
    traj = Trajectory(COULOMB, 0.0, 0.0)
    with pytest.raises(ParameterError, match=r"der\(F_ext\)"):
        traj.set_inputs(0.0, 0.0, rate)
    assert traj.F_ext_rate == 0.0  # refused: the trajectory is unchanged


def test_inputs_taken_as_checked_move_the_block_as_set_inputs_does():
    """take_checked_inputs (inputs a slave knows pass the checks) against set_inputs: the ramp's closed form, and the
    same state bit for bit after each change of the inputs, through the stick, the breakaway and the slide."""
    checked, unchecked = Trajectory(COULOMB, 0.0, 0.0, v_drive=0.0), Trajectory(COULOMB, 0.0, 0.0, v_drive=0.0)
    unchecked.take_checked_inputs(0.0, 0.0, RATE)
    unchecked.advance_to(6.0)
    assert abs(unchecked.x - ramp_motion(6.0)[0]) < 1e-13 and abs(unchecked.v - ramp_motion(6.0)[1]) < 1e-13
    unchecked = Trajectory(COULOMB, 0.0, 0.0, v_drive=0.0)
    for k, t in enumerate(np.arange(0.0, 9.0, 0.5)):
        inputs = (0.1 * (k % 3), 1.5 * math.sin(t), 0.5 * math.cos(t))
        for trajectory, take in ((checked, checked.set_inputs), (unchecked, unchecked.take_checked_inputs)):
            trajectory.advance_to(float(t))
            take(*inputs)
        assert unchecked.snapshot() == checked.snapshot()
    assert checked.n_events >= 3 and checked.n_slip_events >= 1
