"""The runtime follows every valid scene to the limits of floats, and refuses what it cannot represent (issue 20,
items 6-9 and 13, and the errors that must name their cause).

- Item 6: ``F_K(0+) = F_S(0)`` (and ``F_S - F_K`` of 1e-15 and 1e-12 N): after the first breakaway every slip
  returns to ``v_rel = 0`` tangentially where the holding force is at ``F_S``; the stepper follows the closed
  form for 1e4 s, one stick and one breakaway at each return, as the reference does.
- Items 7, 8: the static laws at extreme (documented) parameters against the SPEC formula in 50-digit decimal
  arithmetic, and runs with them that stay finite and break away where ``F_S`` says.
- Item 9: friction far below the spring's force scale: a free harmonic oscillator whose friction direction
  follows the sign of ``v_rel`` at every sample, against the closed form and the reference.
- Kinetic laws steeper than floats and the solver resolve: refused by name; slips that creep below the solver's
  resolution: an error, not a hang.
- Item 13: forged saved states (runtime snapshots and serialized FMU states of both FMUs) refused by field.
"""

import json
import math
from decimal import Decimal, localcontext

import numpy as np
import pytest

from stickslip.core import (CallableKinetic, Constant, Coulomb, Logarithmic, ParameterError, Parameters, Saturating,
                            Sigmoid, StickSlipError, Stribeck, Trajectory, Viscous)
from stickslip.hosts.fmpy_host import run_fmu
from stickslip.reference import parameters_from_values, simulate_reference

from fmu_probe import run_probe

# ---------------------------------------------------------------------------
# item 6: F_K(0+) = F_S(0), tangential returns at the holding limit
# ---------------------------------------------------------------------------

V_DRIVE = 0.1  # m/s; M = kappa = 1: omega = 1/s, the first breakaway at kappa x = F_S = 1 N, t = 10 s


def _edge_coulomb(gap):
    """Coulomb block with ``F_S(0) - F_K(0+) = gap`` (N), stuck at the relaxed spring, driven at 0.1 m/s."""
    return Parameters(M=1.0, kappa=1.0, kinetic=Coulomb(F0=1.0 - gap), static=Constant(F0=1.0))


def _edge_reference(gap, times):
    p = parameters_from_values({"M": 1.0, "kappa": 1.0, "kinetic.law": 1, "kinetic.F0": 1.0 - gap,
                                "static.law": 1, "static.F0": 1.0})
    return simulate_reference(p, 0.0, V_DRIVE, [(0.0, V_DRIVE, 0.0)], times)


def test_kinetic_equal_to_static_friction_follows_the_closed_form_for_1e4_s():
    """Before the fix: SolverError('event chain ...') at t = 72.83 s."""
    traj = Trajectory(_edge_coulomb(0.0), 0.0, V_DRIVE, v_drive=V_DRIVE, record_events=True)
    times = np.arange(10.0, 1e4, 0.37)
    xs, vs = traj.sample(times)
    phase = times - 10.0
    assert np.max(np.abs(np.array(xs) - (1.0 + V_DRIVE * np.sin(phase)))) < 1e-13
    assert np.max(np.abs(np.array(vs) - V_DRIVE * np.cos(phase))) < 1e-13
    # each return to v_rel = 0 (every 2 pi s) is one stick and one breakaway at once, nothing else
    returns = int((1e4 - 10.0) // (2.0 * math.pi))
    assert (traj.n_stick_events, traj.n_slip_events, traj.n_overshoots) == (returns, returns + 1, 0)
    sticks = np.array([t for t, before, after in traj.events if after == 0])
    assert np.max(np.abs(sticks - (10.0 + 2.0 * math.pi * np.arange(1, returns + 1)))) < 1e-11


@pytest.mark.parametrize("gap", [1e-15, 1e-12])
def test_kinetic_just_below_static_friction_matches_the_reference_for_1e4_s(gap):
    """Before the fix: event chains after 280 s (1e-15 N; 32-280 s by the FMU's communication step) and at
    1.6e4 s (1e-12 N). The reference (which chained at 525 s) gives the same motion and events."""
    times = np.arange(0.0, 1e4, 0.37)
    traj = Trajectory(_edge_coulomb(gap), 0.0, V_DRIVE, v_drive=V_DRIVE, record_events=True)
    xs, _ = traj.sample(times)
    reference = _edge_reference(gap, times)
    assert np.max(np.abs(np.array(xs) - reference.x)) < 1e-12
    assert [(after, before) for _, before, after in traj.events] == [
        (e.mode_after, e.mode_before) for e in reference.events]


def test_kinetic_equal_to_static_friction_through_the_fmu(fmu_path):
    """The FMU (FMI 2, FMPy) steps past t = 72.83 s, where it stopped with an event chain."""
    start = {"M": 1.0, "kappa": 1.0, "kinetic.F0": 1.0, "static.F0": 1.0, "v_start": V_DRIVE, "v_drive": V_DRIVE}
    result = run_fmu(fmu_path, start, 300.0, 0.5, outputs=["x", "n_events", "n_overshoots"])
    t = result["time"]
    after = t >= 10.0
    assert np.max(np.abs(result["x"][after] - (1.0 + V_DRIVE * np.sin(t[after] - 10.0)))) < 1e-12
    assert result["n_events"][-1] == 1 + 2 * int((300.0 - 10.0) // (2.0 * math.pi))
    assert result["n_overshoots"][-1] == 0


def test_edge_friction_with_a_law_the_stepper_integrates_numerically():
    """The same block, its Coulomb law given as a callable (Runge-Kutta slips instead of the closed form)."""
    law = CallableKinetic(lambda u: 1.0, lambda u: 0.0)
    traj = Trajectory(Parameters(M=1.0, kappa=1.0, kinetic=law, static=Constant(F0=1.0)), 0.0, V_DRIVE,
                      v_drive=V_DRIVE, rtol=1e-10)
    times = np.arange(10.0, 2000.0, 0.37)
    xs, _ = traj.sample(times)
    assert np.max(np.abs(np.array(xs) - (1.0 + V_DRIVE * np.sin(times - 10.0)))) < 1e-7


# ---------------------------------------------------------------------------
# items 7 and 8: static laws at extreme parameters
# ---------------------------------------------------------------------------

TINY_TAU, HUGE_TAU = 5e-324, 1.7e308
EXTREME_TIMES = (0.0, 5e-324, 1e-300, 1e-12, 1e-3, 1.0, 17.0, 1e6, 1e150, 1e300)


def _decimal(value):
    return Decimal(float(value))  # exactly the float (repr would round a subnormal such as 5e-324)


def spec_static_decimal(law, t):
    """``(F_S, F_S', F_S'')`` at ``t`` (s) from SPEC section 2's formula, in 60-digit decimal arithmetic."""
    with localcontext() as ctx:
        ctx.prec = 60
        ctx.Emax, ctx.Emin = 10**6, -(10**6)
        p = {name: _decimal(value) for name, value in law.parameters().items()}
        t = _decimal(t)
        if isinstance(law, Logarithmic):
            s = p["tau"] + t
            return p["F0"] + p["A"] * (s / p["tau"]).ln(), p["A"] / s, -p["A"] / (s * s)
        jump, tau = p["F_inf"] - p["F0"], p["tau"]
        if isinstance(law, Saturating):
            decay = (-t / tau).exp()
            return p["F0"] + jump * (1 - decay), jump * decay / tau, -jump * decay / (tau * tau)
        n = p["n"]
        if t == 0:
            return p["F0"], None, None  # the derivatives at 0 are pinned in tests/test_law_formulas.py
        r = (t / tau) ** n  # t^n / (tau^n + t^n) = r / (1 + r)
        return (p["F0"] + jump * r / (1 + r), jump * n * r / (t * (1 + r) ** 2),
                jump * n * r * ((n - 1) - (n + 1) * r) / (t * t * (1 + r) ** 3))


def _close(value, exact, what):
    """``value`` (float) is ``exact`` (Decimal) to 1e-12 relative, or its overflow (inf, the sign of ``exact``) or
    underflow (0) where ``exact`` lies beyond the range of floats."""
    if abs(exact) > Decimal("1.7e308"):
        assert value == math.copysign(math.inf, exact), (what, value, exact)
    elif abs(exact) < Decimal("1e-290"):
        assert abs(value) < 1e-280, (what, value, exact)
    else:
        assert math.isfinite(value) and abs(_decimal(value) - exact) <= Decimal("1e-12") * abs(exact), (
            what, value, exact)


EXTREME_LAWS = [Sigmoid(F0=1.0, F_inf=1.5, tau=tau, n=n) for n in (0.5, 1.0, 12.0, 17.0, 20.0)
                for tau in (TINY_TAU, 1e-300, 1e-3, 1.0, 1e155, HUGE_TAU)]
EXTREME_LAWS += [Sigmoid(F0=1.5, F_inf=1.0, tau=tau, n=20.0) for tau in (TINY_TAU, 1.0, HUGE_TAU)]
EXTREME_LAWS += [Logarithmic(F0=1.0, A=0.1, tau=tau) for tau in (TINY_TAU, 1e-300, 1e-200, 1.0, 1e155, 1e300, HUGE_TAU)]
EXTREME_LAWS += [Saturating(F0=f0, F_inf=f_inf, tau=tau) for f0, f_inf in ((1.0, 1.5), (1.5, 1.0))
                 for tau in (TINY_TAU, 1e-300, 1.0, 1e300, HUGE_TAU)]


@pytest.mark.parametrize("law", EXTREME_LAWS, ids=repr)
def test_static_law_at_extreme_parameters_is_the_spec_formula(law):
    """Before the fix: OverflowError (sigmoid n >= 17 at tau = 1 s, n >= 12 at tau = 1 ms; the logarithmic law
    from tau = 1e155 s), F_S = inf (logarithmic, tau = 5e-324 s) or NaN (sigmoid, tau 1e-300 s and below)."""
    for t in EXTREME_TIMES:
        force, rate, curvature = spec_static_decimal(law, t)
        _close(law.force(t), force, f"F_S({t})")
        if rate is not None and t > 0.0:
            _close(law.rate(t), rate, f"F_S'({t})")
            sign = law.curvature(t)  # only its sign is used (convex or concave); it may underflow to 0
            assert sign == 0.0 if curvature == 0 else (sign > 0.0) == (curvature > 0) or (
                sign == 0.0 and abs(curvature) < Decimal("1e-300")), (t, sign, curvature)


def _stick_slip(static, stop=60.0):
    """A Coulomb block (F_K = 0.5 N) stuck at the relaxed spring, driven at 0.1 m/s, sampled every 0.5 s: the
    Trajectory and the outputs at each sample."""
    traj = Trajectory(Parameters(M=1.0, kappa=1.0, kinetic=Coulomb(F0=0.5), static=static), 0.0, V_DRIVE,
                      v_drive=V_DRIVE, record_events=True)
    rows = []
    for t in np.arange(0.5, stop, 0.5):
        traj.advance_to(float(t))
        rows.append(traj.outputs())
    return traj, rows


@pytest.mark.parametrize("static, breakaway", [
    (Sigmoid(F0=1.0, F_inf=1.5, tau=1.0, n=20.0), 15.0),  # F_S = F_inf from t_stick = 2 s on
    (Sigmoid(F0=1.0, F_inf=1.5, tau=1e-3, n=12.0), 15.0),
    (Sigmoid(F0=1.0, F_inf=1.5, tau=1e-300, n=2.0), 15.0),
    (Sigmoid(F0=1.0, F_inf=1.5, tau=TINY_TAU, n=2.0), 15.0),  # item 8: it stayed stuck at 5 N > F_S = 1.5 N
    (Logarithmic(F0=1.0, A=0.1, tau=1e155), 10.0),  # no aging within a run: F_S = F0
    (Saturating(F0=1.0, F_inf=1.5, tau=TINY_TAU), 15.0),
], ids=repr)
def test_runs_with_extreme_static_laws_stay_finite_and_break_away_at_F_S(static, breakaway):
    traj, rows = _stick_slip(static)
    assert all(math.isfinite(value) for row in rows for value in row)
    assert traj.events[0][:2] == (pytest.approx(breakaway, rel=1e-12), 0)


def test_logarithmic_aging_from_a_vanishing_time_scale_stays_finite():
    """Item 8: tau = 5e-324 s; F_S(t) = F0 + A ln(1 + t/tau) exceeds 75 N after a second: z_slip is that,
    finite (it was inf), and the block stays stuck."""
    traj, rows = _stick_slip(Logarithmic(F0=1.0, A=0.1, tau=TINY_TAU))
    z_slip = [row[7] for row in rows]
    assert all(math.isfinite(z) for z in z_slip) and traj.n_events == 0
    t_last = 0.5 * len(rows)
    expected = 1.0 + 0.1 * (math.log(t_last) - math.log(TINY_TAU)) - V_DRIVE * t_last
    assert z_slip[-1] == pytest.approx(expected, rel=1e-12)


def test_extreme_static_law_through_the_fmu(fmu_path):
    """The FMU's outputs stay finite with the documented extremes (n = 20, tau = 5e-324 s)."""
    for values in ({"static.law": 4, "static.n": 20.0, "static.tau": 1.0},
                   {"static.law": 4, "static.n": 2.0, "static.tau": TINY_TAU},
                   {"static.law": 2, "static.tau": TINY_TAU}):
        start = {"kinetic.F0": 0.5, "static.F0": 1.0, "static.F_inf": 1.5, "v_start": V_DRIVE, **values}
        result = run_fmu(fmu_path, start, 60.0, 0.5, outputs=["x", "v", "F_friction", "z_slip", "t_stick"])
        assert all(np.all(np.isfinite(result[name])) for name in ("x", "v", "F_friction", "z_slip", "t_stick"))


# ---------------------------------------------------------------------------
# item 9: friction negligible against the spring: a free oscillator, friction direction from v_rel
# ---------------------------------------------------------------------------

TINY_FRICTION = [  # (M kg, kappa N/m, F_S N); F_K = F_S / 2
    (1.0, 1.0, 1e-17), (1.0, 1.0, 1e-30), (1e-50, 1e-50, 1e-100),
]


@pytest.mark.parametrize("M, kappa, F_S", TINY_FRICTION)
@pytest.mark.parametrize("v_start", [0.1, 0.15, -0.05])
def test_negligible_friction_is_a_free_oscillator_whose_friction_follows_v_rel(M, kappa, F_S, v_start):
    """Before the fix the mode stayed -1 while v < v_drive (v_rel up to +0.18 m/s): the friction pushed the
    wrong way and no event came again. Here ``x = (v_start/omega) sin(omega t)`` and the mode is the sign of
    ``v_rel`` (0 only at ``v_rel = 0``) at every sample; the reference agrees."""
    p = Parameters(M=M, kappa=kappa, kinetic=Coulomb(F0=F_S / 2), static=Constant(F0=F_S))
    omega = math.sqrt(kappa / M)
    times = np.arange(0.0, 200.0, 0.013) / omega
    traj = Trajectory(p, 0.0, v_start, v_drive=V_DRIVE)
    modes, v_rels, xs = [], [], []
    for t in times:
        traj.advance_to(float(t))
        modes.append(traj.mode)
        v_rels.append(traj.v_rel)
        xs.append(traj.x)
    modes, v_rels = np.array(modes), np.array(v_rels)
    assert np.max(np.abs(np.array(xs) - v_start / omega * np.sin(omega * times))) < 1e-13 / omega
    assert np.all(modes * v_rels >= 0.0) and np.all((modes != 0) | (v_rels == 0.0))
    assert np.all(modes[np.abs(v_rels) > 1e-9] == np.sign(v_rels[np.abs(v_rels) > 1e-9]))
    values = {"M": M, "kappa": kappa, "kinetic.law": 1, "kinetic.F0": F_S / 2, "static.law": 1, "static.F0": F_S}
    reference = simulate_reference(parameters_from_values(values), 0.0, v_start, [(0.0, V_DRIVE, 0.0)], times)
    assert np.max(np.abs(np.array(xs) - reference.x)) < 1e-13 / omega
    assert np.array_equal(np.sign(modes), np.sign(reference.mode))


def test_a_slip_whose_excursion_from_v_rel_zero_is_below_rounding_ends_there():
    """``F_K = F_S``, a stuck block whose external force jumps 1e-12 N past the holding limit against the drive:
    the slip backward leaves ``v_rel = 0`` by 5e-25 m/s (below the resolution of ``v``) and the drive turns it
    back after 2e-11 s. Before the fix the slip was never seen to end: mode -1 with ``v < v_drive``."""
    p = Parameters(M=1.0, kappa=1.0, kinetic=Coulomb(F0=1.0), static=Constant(F0=1.0))
    traj = Trajectory(p, 0.5, V_DRIVE, v_drive=V_DRIVE, record_events=True)
    traj.advance_to(1.0)
    traj.set_inputs(V_DRIVE, traj.x + 1.0 + 1e-12)
    for t in np.arange(1.01, 20.0, 0.01):
        traj.advance_to(float(t))
        assert traj.mode * traj.v_rel >= 0.0, (t, traj.mode, traj.v_rel)
    assert [(before, after) for _, before, after in traj.events[:2]] == [(0, -1), (-1, 0)]
    assert traj.events[1][0] - 1.0 < 1e-10


# ---------------------------------------------------------------------------
# kinetic laws steeper than floats and the solver resolve: refused by name, or an error instead of a hang
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("kinetic, name", [
    (Viscous(F0=0.5, gamma=1e300), "kinetic.gamma = 1e+300 N s/m"),  # was: "state overflowed (x = nan)"
    (Viscous(F0=0.5, gamma=1e50), "kinetic.gamma = 1e+50 N s/m"),  # was: x = 0 where the block is at 5 m
    (Stribeck(v_stribeck=1e-300), "kinetic.v_stribeck = 1e-300 m/s"),  # was: "step size underflow ... too stiff"
    (Stribeck(v_stribeck=1e-12), "kinetic.v_stribeck = 1e-12 m/s"),  # was: 85,000 steps in 20 s at t = 10 s
    (Stribeck(gamma=1e10), "kinetic.gamma = 10000000000.0 N s/m"),  # was: a step every 5e-10 s, without end
], ids=["viscous-1e300", "viscous-1e50", "stribeck-v-1e-300", "stribeck-v-1e-12", "stribeck-gamma-1e10"])
def test_kinetic_law_too_steep_for_floats_is_refused_by_name(kinetic, name):
    p = Parameters(M=1.0, kappa=1.0, kinetic=kinetic, static=Constant(F0=1.0))
    with pytest.raises(ParameterError) as error:
        Trajectory(p, 0.0, V_DRIVE, v_drive=V_DRIVE)
    message = str(error.value)
    assert name in message and "steepest slope" in message and "allowed is at most" in message, message


CHATTER = r"""
import sys
from stickslip.core import Constant, Parameters, SolverError, Stribeck, Trajectory
p = Parameters(M=1.0, kappa=1.0, kinetic=Stribeck(gamma=1e6), static=Constant(F0=1.0))
traj = Trajectory(p, 0.0, 0.1, v_drive=0.1, rtol=float(sys.argv[1]))
try:
    traj.advance_to(50.0)
    print("RAN", traj.n_events)
except SolverError as error:
    print("ERROR", error)
"""


def test_slips_creeping_below_the_solver_resolution_are_an_error_not_a_hang():
    """A Stribeck law with gamma = 1e6 N s/m (within the damping bound) at rtol = 1e-6: its slips creep at
    2e-7 m/s, below the solver's resolution (1e-6 m/s), and stuck again every few steps: 500,000 steps in 20 s
    without reaching t = 11 s. Now an error names the cause within a second; at rtol = 1e-10 the same block runs."""
    import subprocess
    import sys

    for rtol, expected in (("1e-6", "ERROR more than 1000 mode changes"), ("1e-10", "RAN 1")):
        done = subprocess.run([sys.executable, "-c", CHATTER, rtol], capture_output=True, text=True, timeout=60)
        assert done.stdout.startswith(expected), done.stdout + done.stderr
    assert "below what the solver resolves" in done.stdout or expected == "RAN 1"


# ---------------------------------------------------------------------------
# item 13: saved states with non-finite or overflowing values are refused by field, through every interface
# ---------------------------------------------------------------------------


def _saved_trajectory():
    """A Coulomb stick-slip trajectory at t = 11.5 s (mid-slip) and its snapshot through JSON."""
    p = Parameters(M=1.0, kappa=1.0, kinetic=Coulomb(F0=0.5), static=Constant(F0=1.0))
    traj = Trajectory(p, 0.0, V_DRIVE, v_drive=V_DRIVE)
    traj.advance_to(11.5)
    return p, json.loads(json.dumps(traj.snapshot()))


FORGED = [  # (path in the snapshot, value, text the refusal holds)
    (["t"], 1e300, "saved state t = 1e+300 s lies outside its segment"),
    (["t"], math.nan, "saved state t = nan is not a finite real"),
    (["v_drive"], math.inf, "saved state v_drive = inf is not a finite real"),
    (["F_ext"], 1e200, "|F_ext| = 1e+200 N"),
    (["rtol"], 0.5, "saved state rtol = 0.5 is out of range"),
    (["t_last_event"], -math.inf, "saved state t_last_event = -inf is not a finite real"),
    (["counts", 2], -1, "saved state counts.n_overshoots = -1 is not an int >= 0"),
    (["stepper", 0], 0.0, "saved state stepper.h = 0.0 is not None or a finite real > 0"),
    (["segment", 0], "bogus", "is not a list that starts with one of"),
    (["segment", 5], 1e300, "kappa * |saved state x|"),
    (["segment", 6], math.inf, "saved state segment (harmonic).v0 = inf is not a finite real"),
    (["segment", 4], 0, "saved state segment (harmonic) is inconsistent: a slip in mode 0"),
]


@pytest.mark.parametrize("path, value, text", FORGED, ids=[f"{'.'.join(map(str, p))}={v!r}" for p, v, _ in FORGED])
def test_forged_trajectory_snapshot_is_refused_by_field(path, value, text):
    """Before the fix such snapshots were taken, and the outputs read +-inf or NaN."""
    p, snap = _saved_trajectory()
    target = snap
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = value
    with pytest.raises(StickSlipError) as error:
        Trajectory.from_snapshot(p, snap)
    assert text in str(error.value), str(error.value)


def test_snapshot_through_json_continues_bit_for_bit():
    p, snap = _saved_trajectory()
    restored = Trajectory.from_snapshot(p, snap)
    original = Trajectory(p, 0.0, V_DRIVE, v_drive=V_DRIVE)
    original.advance_to(11.5)
    for traj in (restored, original):
        traj.advance_to(40.0)
    assert restored.outputs() == original.outputs()


STEPPED = [["step", 0.0, 11.5]]


@pytest.mark.parametrize("interface, fmi, name, value, text", [
    ("cs", 2, "trajectory.t", 1e300, "saved state t = 1e+300 s"),
    ("cs", 2, "segment (harmonic).x0", "inf", "saved state segment (harmonic).x0 = inf"),
    ("cs", 2, "parameters.kinetic.gamma", -1.0, "kinetic.gamma = -1.0 N s/m is out of range"),
    ("cs", 2, "parameters.kinetic.gamma", "nan", "saved state kinetic.gamma = nan is not a finite real"),
    ("cs", 2, "head.start_time", "nan", "saved state start_time = nan"),
    ("cs", 3, "trajectory.v_drive", "-inf", "saved state v_drive = -inf"),
    ("cs", 3, "head.time", "inf", "saved state time = inf"),
    ("me", 3, "exchange._x", 1e300, "kappa * |saved state x| = 1e+300 N"),
    ("me", 3, "exchange.t_stuck", "nan", "saved state t_stuck = nan"),
    ("me", 2, "exchange._x", 1e300, "kappa * |saved state x| = 1e+300 N"),
    ("me", 2, "exchange.t_stuck", "nan", "saved state t_stuck = nan"),
    ("me", 2, "head.time", "inf", "saved state time = inf"),
], ids=["fmi2-t", "fmi2-segment-x0", "fmi2-unused-law-value", "fmi2-law-value-nan", "fmi2-start-time",
        "fmi3-cs-v_drive", "fmi3-cs-time", "fmi3-me-x", "fmi3-me-t_stuck", "fmi2-me-x", "fmi2-me-t_stuck",
        "fmi2-me-time"])
def test_forged_fmu_state_is_refused_by_field_and_the_instance_goes_on(fmu_path, fmu3_path, interface, fmi, name,
                                                                       value, text):
    """A well-formed serialized FMU state holding a non-finite or overflowing value: fmi2Error/fmi3Error from
    fmi2SetFMUstate/fmi3SetFMUState naming the field, and the instance keeps its state (each case in a child
    process). Before the fix the state was taken and the outputs read +-inf with status OK."""
    actions = (STEPPED if interface == "cs" else [["update"]]) + [["forge", name, value]]
    report = run_probe(fmu_path if fmi == 2 else fmu3_path, interface, {"v_start": V_DRIVE}, actions)
    assert report["failed"] is not None and report["failed"][0] == "forge", report
    assert any(text in message for message in report["messages"]), report["messages"]
    outputs = report["outputs"]
    assert all(isinstance(value, float) for value in outputs.values()), outputs
    if interface == "cs":  # still mid-slip at 11.5 s: x = F_K/kappa + (x_b - F_K/kappa) cos(1.5) + v_drive sin(1.5)
        assert outputs["x"] == pytest.approx(0.5 + 0.5 * math.cos(1.5) + V_DRIVE * math.sin(1.5), rel=1e-12)
        assert outputs["t_last_event"] == 10.0
