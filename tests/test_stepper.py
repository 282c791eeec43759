"""The exact stepper (stickslip.core.Trajectory) against closed forms and tight scipy runs."""

import json
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from stickslip.core import (
    FORWARD,
    STUCK,
    BACKWARD,
    Constant,
    Coulomb,
    Logarithmic,
    Lubricated,
    Parameters,
    Sigmoid,
    SolverError,
    Stribeck,
    Trajectory,
    Viscous,
    state_snapshot,
)
from stickslip.core import poly
from stickslip.core.integrators import dopri5_step
from stickslip.core.model import SlipAccelerator
from stickslip.core.numeric_slip import MEMO_SIZE, _slip_end
from stickslip.core.trajectory import (SEGMENT_PLACE, STATE_FIELDS, STATE_LAYOUT, STATE_PLACES, checked_state,
                                      state_fields)


def event_log(traj, t_end, dt):
    """(time, mode after) of every event, sampling the trajectory every dt."""
    events, seen = [], traj.n_events
    for k in range(1, int(round(t_end / dt)) + 1):
        traj.advance_to(k * dt)
        if traj.n_events != seen:
            assert traj.n_events == seen + 1, "sampling too coarse to see every event"
            events.append((traj.t_last_event, traj.mode))
            seen = traj.n_events
    return events


def test_coulomb_stick_and_slip_durations_are_the_closed_form():
    F_S, F_K, kappa, M, vd = 1.0, 0.3, 2.0, 0.5, 0.2
    traj = Trajectory(Parameters(M, kappa, Coulomb(F0=F_K), Constant(F0=F_S)), F_S / kappa - 1e-3, vd, v_drive=vd)
    events = event_log(traj, 60.0, 0.01)
    omega = math.sqrt(kappa / M)
    # slip from (y, v) = ((F_S - F_K)/kappa, vd) about F_K/kappa until v = vd again, at y = -(F_S - F_K)/kappa
    y0 = (F_S - F_K) / kappa
    phase0, phase1 = math.atan2(-vd / omega, y0), math.atan2(-vd / omega, -y0)
    slip_time = ((phase1 - phase0) % (2 * math.pi)) / omega
    stick_time = 2 * (F_S - F_K) / (kappa * vd)
    durations = np.diff([t for t, _ in events])
    modes = [m for _, m in events]
    assert modes[:4] == [FORWARD, STUCK, FORWARD, STUCK]
    for (t_a, mode), duration in zip(events, durations):
        expected = slip_time if mode == FORWARD else stick_time
        assert duration == pytest.approx(expected, rel=1e-12)
    assert len(events) >= 8


def test_coulomb_stick_position_is_2FK_minus_FS():
    F_S, F_K = 1.0, 0.3
    traj = Trajectory(Parameters(1.0, 1.0, Coulomb(F0=F_K), Constant(F0=F_S)), F_S, 0.1, v_drive=0.1)
    traj.advance_to(0.0)
    assert traj.mode == FORWARD  # holding force exactly F_S: the contact gives (strict >) only after
    traj.advance_to(10.0)  # slip ~3.9 s, then a stick of 2 (F_S - F_K)/(kappa v_drive) = 14 s
    stick_start = traj.t_last_event
    assert traj.mode == STUCK
    assert traj.x - 0.1 * (10.0 - stick_start) == pytest.approx(2 * F_K - F_S, abs=1e-13)


@pytest.mark.parametrize("gamma", [0.3, 2.0, 2 * math.sqrt(2.0), 5.0])  # under-, critically near, over-damped
def test_viscous_slip_is_the_damped_harmonic_solution(gamma):
    M, kappa, F0, vd, x0 = 0.5, 1.0, 0.2, 0.05, 3.0
    p = Parameters(M, kappa, Viscous(F0=F0, gamma=gamma), Constant(F0=4.0))
    traj = Trajectory(p, x0, 0.0, v_drive=vd)  # v < vd: mode +1, the spring pulls the block back
    xc = (F0 + gamma * vd) / kappa
    rhs = lambda t, y: [y[1], (-kappa * y[0] - gamma * y[1] + F0 + gamma * vd) / M]
    ts = np.linspace(0, 4.0, 41)
    exact = solve_ivp(rhs, (0, 4.0), [x0, 0.0], t_eval=ts, rtol=1e-13, atol=1e-15, method="DOP853")
    for t, x_ref in zip(ts, exact.y[0]):
        traj.advance_to(t)
        if traj.n_events:
            break
        assert traj.x == pytest.approx(x_ref, abs=1e-11 * (1 + abs(x0 - xc)))


def test_damped_slip_ends_where_the_formula_says():
    """Underdamped viscous slip from rest: the end time solves v(t) = v_drive in closed form."""
    M, kappa, F0, gamma, vd, x0 = 1.0, 1.0, 0.3, 0.4, 0.1, 2.0
    traj = Trajectory(Parameters(M, kappa, Viscous(F0=F0, gamma=gamma), Constant(F0=1.0)), x0, 0.0, v_drive=vd)
    alpha, w = gamma / (2 * M), math.sqrt(kappa / M - (gamma / (2 * M)) ** 2)
    y0 = x0 - (F0 + gamma * vd) / kappa
    velocity = lambda t: -y0 * (kappa / M) / w * math.exp(-alpha * t) * math.sin(w * t)
    t_peak = (math.pi + math.atan(w / alpha)) / w  # the first positive velocity maximum
    t_end = brentq(lambda t: velocity(t) - vd, math.pi / w, t_peak)
    events = event_log(traj, 8.0, 0.01)
    assert events[0][0] == pytest.approx(t_end, rel=1e-12)


def test_logarithmic_aging_breakaway_time_solves_FS_equals_holding_force():
    F0, A, tau, vd = 1.0, 0.2, 0.5, 0.1
    p = Parameters(1.0, 1.0, Coulomb(F0=0.5), Logarithmic(F0=F0, A=A, tau=tau))
    traj = Trajectory(p, 0.0, vd, v_drive=vd)
    assert traj.mode == STUCK
    t_break = brentq(lambda t: F0 + A * math.log1p(t / tau) - vd * t, 1e-9, 100.0)
    events = event_log(traj, 25.0, 0.01)
    assert events[0] == (pytest.approx(t_break, rel=1e-13), FORWARD)


def test_sigmoid_aging_tangential_dip_is_not_missed():
    """With a non-convex F_S the holding force may exceed it only briefly: breakaway there."""
    law = Sigmoid(F0=1.0, F_inf=3.0, tau=10.0, n=4.0)
    vd = 0.1
    # holding force x(t) = x0 + vd t; choose x0 so it touches F_S near the inflection from below, then crosses
    dip = lambda x0: min(law.force(t) - (x0 + vd * t) for t in np.linspace(0, 20, 20001))
    x0 = brentq(lambda x0: dip(x0) + 1e-7, 0.0, 1.0)
    traj = Trajectory(Parameters(1.0, 1.0, Coulomb(F0=0.5), law), x0, vd, v_drive=vd)
    events = event_log(traj, 30.0, 0.05)

    # the expected breakaway from SPEC's formula: the margin F_S(t) - (x0 + vd t) has its minimum where
    # F_S'(t) = vd past the inflection (brentq); the breakaway is the margin's first root before it
    def margin(t):
        return 1.0 + 2.0 * t**4 / (1e4 + t**4) - (x0 + vd * t)

    def margin_slope(t):
        return 8e4 * t**3 / (1e4 + t**4) ** 2 - vd

    t_min = brentq(margin_slope, 4.0, 8.0, xtol=1e-15)  # margin_slope(4) < 0 < margin_slope(8): a minimum
    assert margin(t_min) < 0 < margin(0.5 * t_min)
    t_first_negative = brentq(margin, 0.5 * t_min, t_min, xtol=1e-15)
    assert events[0][1] == FORWARD
    assert events[0][0] == pytest.approx(t_first_negative, abs=1e-11)  # measured error 5e-14 s


def test_graze_inside_one_step_is_found_on_the_dense_output():
    """v peaks just above v_drive in mid-step: the step-end signs agree, the crossing is still found."""
    cv = [0.0, 0.4, -0.4]  # v(theta) peaks at 0.1 at theta = 0.5
    vd = 0.1 - 1e-12
    assert vd - poly.evaluate(cv, 0.0) > 0 and vd - poly.evaluate(cv, 1.0) > 0  # a sign-only check sees nothing
    theta = _slip_end(cv, FORWARD, vd)
    assert theta is not None and 0.49 < theta < 0.5
    assert _slip_end(cv, FORWARD, 0.1 + 1e-12) is None


def test_graze_in_a_numeric_slip_sticks():
    """Stribeck slip whose velocity maximum exceeds v_drive by 1e-9 for a moment: the block sticks."""
    law = Stribeck(F0=0.3, F_stribeck=0.2, v_stribeck=0.3, delta=2.0, gamma=0.05)
    x0 = -2.5  # released behind the spring's rest length: pushed forward towards the surface speed

    def peak(vd):
        """(time, velocity) of the first velocity maximum of the forward slip from rest."""
        rhs = lambda t, y: [y[1], -y[0] + law.force(vd - y[1])]
        sol = solve_ivp(rhs, (0, 3.0), [x0, 0.0], rtol=1e-13, atol=1e-15, method="DOP853", dense_output=True)
        t_peak = brentq(lambda t: rhs(t, sol.sol(t))[1], 0.5, 3.0, xtol=1e-15)
        return t_peak, sol.sol(t_peak)[1]

    vd = brentq(lambda vd: peak(vd)[1] - vd - 1e-9, 1.0, 5.0, xtol=1e-14)
    t_peak, v_peak = peak(vd)
    assert 0 < v_peak - vd < 2e-9  # v_rel < 0 for only ~1e-4 s around t_peak
    traj = Trajectory(Parameters(1.0, 1.0, law, Constant(F0=3.0)), x0, 0.0, v_drive=vd, rtol=1e-12)
    traj.advance_to(t_peak + 0.01)
    assert traj.n_stick_events == 1 and traj.mode == STUCK
    # it sticks where v first reaches vd, ~2.6e-5 s before the peak (brentq on the DOP853 solution); a
    # velocity error dv moves that crossing by dv / |a| with |a| ~ 7.6e-5 m/s^2 there: 1e-6 s allows
    # dv <= 7.6e-11 m/s (measured: 1.5e-7 s)
    rhs = lambda t, y: [y[1], -y[0] + law.force(vd - y[1])]
    sol = solve_ivp(rhs, (0, t_peak), [x0, 0.0], rtol=1e-13, atol=1e-15, method="DOP853", dense_output=True)
    t_cross = brentq(lambda t: sol.sol(t)[1] - vd, t_peak - 0.01, t_peak, xtol=1e-15)
    assert traj.t_last_event == pytest.approx(t_cross, abs=1e-6)
    assert traj.t_last_event < t_peak - 0.5 * (t_peak - t_cross)


def test_overshoot_is_not_mistaken_for_sticking():
    """F_S/F_K = 20 and a far-stretched spring: the block swings through v_rel = 0 without sticking."""
    p = Parameters(1.0, 1.0, Coulomb(F0=0.045), Constant(F0=1.0))
    traj = Trajectory(p, 5.0, 0.0, v_drive=0.0)  # released 5 F_S/kappa away on a still surface
    events = event_log(traj, 150.0, 0.01)
    # each half swing (pi s) loses 2 F_K/kappa = 0.09 of amplitude: turning points 5, -4.91, 4.82, ...
    # overshoot while |x| > F_S/kappa = 1, stick at the first turning point inside: |x| = 5 - 45 * 0.09 = 0.95
    assert [mode for _, mode in events] == [BACKWARD, FORWARD] * 22 + [STUCK]
    for k, (t, _) in enumerate(events):
        assert t == pytest.approx((k + 1) * math.pi, rel=1e-12)
    assert traj.x == pytest.approx(-0.95, abs=1e-12)


def test_drive_velocity_jump_while_stuck_carries_the_block():
    p = Parameters(1.0, 1.0, Coulomb(F0=0.5), Constant(F0=1.0))
    traj = Trajectory(p, 0.0, 0.1, v_drive=0.1)
    traj.advance_to(1.0)
    traj.set_inputs(0.3, 0.0)
    assert traj.mode == STUCK and traj.v == 0.3
    traj.advance_to(2.0)
    assert traj.x == pytest.approx(0.1 + 0.3, abs=1e-15)
    assert traj.n_events == 0


def test_force_jump_breaks_the_stick_and_drive_reversal_flips_the_slip():
    p = Parameters(1.0, 1.0, Coulomb(F0=0.5), Constant(F0=1.0))
    traj = Trajectory(p, 0.0, 0.1, v_drive=0.1)
    traj.set_inputs(0.1, 1.5)  # external force beyond F_S pushes the block forward
    assert traj.mode == BACKWARD and traj.n_slip_events == 1
    traj.advance_to(0.5)
    traj.set_inputs(5.0, 1.5)  # the surface now runs faster than the block
    assert traj.mode == FORWARD and traj.n_overshoots == 1


def test_result_does_not_depend_on_the_communication_step():
    for law in (Coulomb(F0=0.5), Lubricated()):
        p = Parameters(40.0 if isinstance(law, Lubricated) else 1.0, 1.0, law, Constant(F0=1.0))
        fine, coarse = Trajectory(p, 0.0, 0.0, v_drive=0.3), Trajectory(p, 0.0, 0.0, v_drive=0.3)
        for k in range(1, 30001):
            fine.advance_to(k * 1e-2)
            if k % 1000 == 0:
                coarse.advance_to(k * 1e-2)
                assert (fine.x, fine.v, fine.mode) == (coarse.x, coarse.v, coarse.mode)


@pytest.mark.parametrize("law", [Coulomb(F0=0.045), Lubricated()])
def test_a_step_that_stops_at_each_event_stops_at_every_one_and_changes_nothing(law):
    """communicate_to_event (FMI 3's early return): each stop is the next event of the uninterrupted run (record_events),
    in the mode before it, at v_rel = 0 for a stick; apply_events gives the mode after it; the state on the
    communication points is that of the uninterrupted run, bit for bit."""
    p = Parameters(1.0 if isinstance(law, Coulomb) else 40.0, 1.0, law, Constant(F0=1.0))
    start = (5.0, 0.0, 0.0) if isinstance(law, Coulomb) else (0.0, 0.1, 0.1)  # overshoots; stick-slip
    whole = Trajectory(p, *start[:2], v_drive=start[2], record_events=True)
    stopping = Trajectory(p, *start[:2], v_drive=start[2])
    stops, points = [], []
    for k in range(1, 431):  # communication points every 0.7 s: no event falls on one
        point = 0.7 * k
        whole.advance_to(point)
        while stopping.communicate_to_event(stopping.t, point - stopping.t):
            mode_before = stopping.mode
            stopping.apply_events()
            stops.append((stopping.t, mode_before, stopping.mode))
            if stopping.mode == STUCK:
                assert stopping.v == start[2]
        points.append(stopping.t == point and (stopping.x, stopping.v, stopping.mode) == (whole.x, whole.v, whole.mode))
    assert len(stops) >= 8 and stops == [event for event in whole.events if event[0] > 0.0]
    assert all(points)


def test_snapshot_restores_the_continuation_bit_for_bit():
    p = Parameters(40.0, 1.0, Lubricated(), Constant(F0=1.0))
    traj = Trajectory(p, 0.0, 0.0, v_drive=0.3)
    traj.advance_to(123.4)
    saved = json.loads(json.dumps(traj.snapshot()))
    traj.advance_to(300.0)
    restored = Trajectory.from_snapshot(p, saved)
    restored.advance_to(300.0)
    assert (restored.x, restored.v, restored.mode, restored.n_events) == (traj.x, traj.v, traj.mode, traj.n_events)


def test_state_restored_in_place_or_resumed_continues_bit_for_bit_mid_stick_and_mid_slip():
    """Trajectory.state: restored into the same trajectory (its step record replayed), resumed in a new one, and
    through its snapshot's JSON, each continues exactly as the original did, inputs and a force rate changed after
    it included; the event record loses the events after the state."""
    p = Parameters(40.0, 1.0, Lubricated(), Constant(F0=1.0))
    traj = Trajectory(p, 0.0, 0.1, v_drive=0.1, record_events=True)
    for t_save, mode in ((47.0, STUCK), (160.0, FORWARD)):  # a numeric slip: its steps in the memo
        traj.advance_to(t_save)
        state, events = traj.state(), list(traj.events)
        assert traj.mode == mode

        def continuation(run):
            out = [run.communicate(t_save, 0.37)]
            run.set_inputs(0.12, 0.05, 0.001)
            return out + [run.communicate(run.t, 0.37) for _ in range(150)] + [run.outputs()]

        original = continuation(traj)
        traj.restore(state)
        assert traj.events == events and traj.t == t_save
        assert continuation(traj) == original
        traj.restore(state)
        assert continuation(Trajectory.resumed(state)) == original
        snapshot = json.loads(json.dumps(state_snapshot(state)))
        assert continuation(Trajectory.from_snapshot(p, snapshot)) == original
    with pytest.raises(ValueError, match="Trajectory.resumed"):
        Trajectory(p, 0.0, 0.1, v_drive=0.1).restore(state)


def test_the_places_of_a_saved_trajectory_state_hold_its_saved_fields():
    """The places the FMUs' loader packs a trajectory's fields from and unpacks them to (``trajectory.STATE_PLACES``,
    derived from ``STATE_LAYOUT``, in ``BlockStateFormat.loader_plan``) hold the very values ``state_fields`` gives,
    in their order, mid slip, and ``checked_state`` puts each value it takes at its place."""
    traj = Trajectory(Parameters(40.0, 1.0, Lubricated(), Constant(F0=1.0)), 0.0, 0.1, v_drive=0.1)
    traj.advance_to(20.0)
    state = traj.state()

    def at(state, place):
        value = state
        for index in place:
            value = value[index]
        return value

    fields = state_fields(state)
    assert len(STATE_PLACES) == len(fields) == len(STATE_FIELDS)
    assert len(STATE_LAYOUT) == len(state) and state[SEGMENT_PLACE].KIND == "step"
    assert all(at(state, place) is value for place, value in zip(STATE_PLACES, fields))
    checked = checked_state(state[1], state[SEGMENT_PLACE], *fields)
    assert all(at(checked, place) is value for place, value in zip(STATE_PLACES, fields))


def test_stiff_overdamped_slip_switches_method_and_stays_accurate():
    """|F_K'| = 1000 sqrt(kappa M): fast relaxation onto kappa x = F_K(v_rel), then slow drift."""
    M, vd = 1e-4, 0.3
    law = Stribeck(F0=0.3, F_stribeck=0.2, v_stribeck=0.1, delta=2.0, gamma=10.0)
    traj = Trajectory(Parameters(M, 1.0, law, Constant(F0=1.0)), 0.8, 0.0, v_drive=vd, rtol=1e-8)
    rhs = lambda t, y: [y[1], (-y[0] + law.force(vd - y[1])) / M]
    ref = solve_ivp(rhs, (0, 1.0), [0.8, 0.0], method="Radau", rtol=1e-12, atol=1e-14, dense_output=True)
    for t in np.linspace(0.01, 1.0, 100):
        traj.advance_to(t)
        assert traj.mode == FORWARD
        assert traj.x == pytest.approx(ref.sol(t)[0], abs=1e-7)
    assert traj._stepper.stiff
    assert traj.n_steps < 2000  # an explicit method would need > 1e4 steps (h < 3.3e-4 by stability)


def test_dopri5_step_and_dense_output_converge_at_fifth_order():
    accel = SlipAccelerator(1, 10.0, 0.0, Parameters(1.0, 1.0, Coulomb(F0=0.0), Constant(F0=1.0)))  # a = -x
    errors = []
    for h in (0.2, 0.1):
        step = dopri5_step(accel, 1.0, 0.0, -1.0, h)
        errors.append((abs(step.x1 - math.cos(h)), abs(poly.evaluate(step.cx, 0.37) - math.cos(0.37 * h))))
    assert math.log2(errors[0][0] / errors[1][0]) == pytest.approx(6, abs=0.3)  # local error O(h^6)
    assert math.log2(errors[0][1] / errors[1][1]) >= 5 - 0.3  # dense output local error O(h^5) or better


def test_backwards_time_is_refused():
    traj = Trajectory(Parameters(1.0, 1.0, Coulomb(F0=0.5), Constant(F0=1.0)), 0.0, 0.0, v_drive=0.1)
    traj.advance_to(1.0)
    with pytest.raises(SolverError, match="back"):
        traj.advance_to(0.5)


def test_a_step_beyond_the_time_resolution_is_followed_only_into_a_lasting_phase():
    """sqrt(M/kappa) = 2 s: floats space times by more than that beyond 2 s / 2**-52 = 2**53 s. A block at rest
    without drive (one stick for ever) is followed to 1e300 s; a driven block (stick-slip for ever, a step to
    1e300 s ran for ever) stops after 1000 segments, each ending in an event, with an error naming the cause."""
    p = Parameters(4.0, 1.0, Coulomb(F0=0.5), Constant(F0=1.0))
    resting = Trajectory(p, 0.3, 0.0, v_drive=0.0)
    resting.advance_to(1e300)
    assert (resting.t, resting.x, resting.v, resting.mode, resting.n_events) == (1e300, 0.3, 0.0, STUCK, 0)
    driven = Trajectory(p, 0.0, 0.0, v_drive=0.1)
    with pytest.raises(SolverError, match=r"to t = 9007199254740994.0 s: time resolution lost: floats space times "
                                          r"there by 2 s, more than the block's time scale sqrt\(M/kappa\) = 2 s, "
                                          r"and the block did not come to a lasting phase within 1000 segments"):
        driven.advance_to(math.nextafter(2.0 ** 53, math.inf))
    assert driven.n_events == 1000 and driven.t == driven.t_last_event > 0.0


def test_an_advance_through_too_many_segments_stops_at_a_state_to_go_on_from():
    """Every advance_to ends (a step to 1e300 s ran for ever, 7e298 stick-slip cycles): after max_segments
    segments (here each ends in an event) it stops at the last event with an error naming the count, in the state
    an unlimited trajectory has there, and goes on from it bit for bit."""
    p = Parameters(1.0, 1.0, Coulomb(F0=0.5), Constant(F0=1.0))
    limited, unlimited = (Trajectory(p, 0.0, 0.0, v_drive=0.1, max_segments=n) for n in (50, 10 ** 6))
    with pytest.raises(SolverError, match=r"from t = 0.0 s to t = 10000.0 s: the step would need more than 50 "
                                          r"segments \(events and integrator steps\); stopped at t = .* after 50 "
                                          r"events in all; take shorter steps"):
        limited.advance_to(1e4)
    assert limited.n_events == 50 and limited.t == limited.t_last_event > 0.0
    unlimited.advance_to(limited.t)
    assert limited.outputs() == unlimited.outputs()
    for step in (100.0, 200.0):  # shorter steps: 15 and 30 events
        t = limited.t + step
        limited.advance_to(t)
        unlimited.advance_to(t)
        assert limited.outputs() == unlimited.outputs()


def test_stribeck_with_fractional_exponent_runs_through_its_slip_ends():
    """Stages near a slip's end probe v_rel slightly past 0, where (u/v_s)^1.5 has no real value."""
    law = Stribeck(F0=0.4, F_stribeck=0.3, v_stribeck=0.1, delta=1.5, gamma=0.05)
    traj = Trajectory(Parameters(1.0, 1.0, law, Constant(F0=1.0)), 0.0, 0.0, v_drive=0.2)
    traj.advance_to(60.0)
    assert traj.n_stick_events >= 3 and math.isfinite(traj.x)


def test_breakaway_after_the_holding_force_changes_sign_in_a_convex_stretch():
    """The kink of |kappa x - F_ext| inside a convex stretch of F_S must not hide the breakaway."""
    from stickslip.core.stuck import breakaway_delay

    law = Sigmoid(F0=0.8, F_inf=1.5, tau=5.0, n=4.0)
    p = Parameters(1.0, 1.0, Coulomb(F0=0.5), law)
    x0, vd = -0.06147859922112879, 0.4  # the holding force crosses 0 at tau = x0 / vd to rounding
    taus = np.linspace(0.0, 10.0, 1_000_001)
    margin = np.array([law.force(t) for t in taus]) - np.abs(x0 + vd * taus)
    first_negative = taus[np.argmax(margin < 0)]
    assert breakaway_delay(x0, vd, 0.0, 0.0, p, 1e4) == pytest.approx(first_negative, abs=2e-5)


PERIODIC = [  # stick-slip scenes whose slips start from bit-identical states once the cycle has settled,
    # with the largest fraction of steps that may still be integrated (an aging stick settles more slowly)
    ("lubricated-constant", Parameters(40.0, 1.0, Lubricated(), Constant(F0=1.0)), 0.1, 0.2),
    ("stribeck-aging", Parameters(1.0, 1.0, Stribeck(F0=0.4, F_stribeck=0.3, v_stribeck=0.1, delta=2.0, gamma=0.05),
                                  Logarithmic(F0=1.0, A=0.1, tau=1.0)), 0.2, 0.7),
]


@pytest.mark.parametrize("p, vd, integrated_fraction", [c[1:] for c in PERIODIC], ids=[c[0] for c in PERIODIC])
def test_replayed_steps_give_exactly_the_integrated_numbers(p, vd, integrated_fraction):
    """The step memo is an exact shortcut: the same trajectory, bit for bit, with most steps replayed."""
    integrated = Trajectory(p, 0.0, vd, v_drive=vd, rtol=1e-9, reuse_steps=False)
    replayed = Trajectory(p, 0.0, vd, v_drive=vd, rtol=1e-9)
    for t in np.arange(1, 3001) * 0.1:
        integrated.advance_to(t)
        replayed.advance_to(t)
        assert (replayed.x, replayed.v, replayed.mode) == (integrated.x, integrated.v, integrated.mode)
    assert replayed.n_steps == integrated.n_steps and replayed.n_stick_events >= 5
    work = replayed._stepper._recorded  # steps integrated and recorded (the memo never filled up here)
    assert work < min(integrated_fraction * replayed.n_steps, MEMO_SIZE), (work, replayed.n_steps)


def test_a_slide_longer_than_the_memo_records_a_prefix_and_integrates_on_with_the_same_numbers():
    """Continuous sliding never repeats a slip: the memo records the slip's first MEMO_SIZE steps, then stops
    recording, and the trajectory is the integrated one bit for bit."""
    p = Parameters(40.0, 1.0, Lubricated(), Constant(F0=1.0))  # elmer-fig3 at v_drive 1.0: it never sticks
    integrated = Trajectory(p, 0.0, 1.0, v_drive=1.0, rtol=1e-10, reuse_steps=False)
    replayed = Trajectory(p, 0.0, 1.0, v_drive=1.0, rtol=1e-10)
    for t in np.arange(1, 201) * 10.0:
        integrated.advance_to(t)
        replayed.advance_to(t)
        assert (replayed.x, replayed.v, replayed.mode) == (integrated.x, integrated.v, integrated.mode)
    assert replayed.n_stick_events == 0 and replayed.n_steps == integrated.n_steps > MEMO_SIZE
    assert replayed._stepper._recorded == MEMO_SIZE


def test_a_stick_before_a_numeric_slip_ends_in_the_same_state_whenever_it_starts():
    """Before a numeric slip the end of a stuck phase does not carry the rounding of its absolute start time;
    before a closed-form slip it is the motion at the rounded end time (no drift over many cycles)."""
    from stickslip.core.segments import StuckSegment

    starts, x0, vd, duration = (0.0, 12.345, 1e6 + 0.1), -0.3, 0.1, 13.0
    assert len({StuckSegment(t0, duration, True, x0, vd, 0.0, True).end_state() for t0 in starts}) == 1
    consistent = [StuckSegment(t0, duration, True, x0, vd, 0.0, False) for t0 in starts]
    assert len({s.end_state() for s in consistent}) > 1  # the motion at each rounded end time
    assert all(s.end_state()[0] == x0 + vd * (s.t1 - s.t0) for s in consistent)


def test_sample_is_advance_to_at_each_time_and_records_the_events():
    p = Parameters(40.0, 1.0, Lubricated(), Constant(F0=1.0))
    grid = np.linspace(0.0, 200.0, 2001)
    stepped = Trajectory(p, 0.0, 0.1, v_drive=0.1)
    rows = []
    for t in grid:
        stepped.advance_to(t)
        rows.append((stepped.x, stepped.v))
    sampled = Trajectory(p, 0.0, 0.1, v_drive=0.1, record_events=True)
    assert list(zip(*sampled.sample(grid))) == rows
    assert len(sampled.events) == sampled.n_events == stepped.n_events >= 8
    assert [after for _, _, after in sampled.events[:2]] == [FORWARD, STUCK]
    assert sampled.events[-1][0] == sampled.t_last_event
    with pytest.raises(SolverError, match="back"):
        sampled.sample([100.0])


@pytest.mark.parametrize("x, F_ext", [(1.0, 0.0), (-1.0, 0.0), (1.7, 0.7), (-0.25, 0.75)])
def test_the_stick_test_holds_at_the_limit(x, F_ext):
    """SPEC: v_rel reaching 0 sticks where |kappa x - F_ext| <= F_S(0), the limit included (here exactly
    F_S(0) = 1 N in binary: kappa = 1 and x - F_ext = -+1), and overshoots a hair beyond it, away from F_ext."""
    from stickslip.core.model import mode_at_zero_v_rel
    from stickslip.reference import parameters_from_values
    from stickslip.reference.rules import hold_or_break

    p = Parameters(1.0, 1.0, Coulomb(F0=0.5), Constant(F0=1.0))
    ref = parameters_from_values({"M": 1.0, "kappa": 1.0, "kinetic.law": 1, "kinetic.F0": 0.5, "static.law": 1,
                                  "static.F0": 1.0})
    assert abs(x - F_ext) == 1.0
    assert mode_at_zero_v_rel(x, F_ext, p) == STUCK
    assert hold_or_break(ref, x, F_ext, 0.0) == STUCK
    beyond = x + math.copysign(1e-12, x - F_ext)
    direction = FORWARD if F_ext - beyond < 0 else BACKWARD
    assert mode_at_zero_v_rel(beyond, F_ext, p) == direction
    assert hold_or_break(ref, beyond, F_ext, 0.0) == direction
