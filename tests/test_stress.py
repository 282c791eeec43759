"""Stress matrix, CI subset: the quick cases of ``stickslip stress`` through the FMU (about 20 s).

Each quick case is one test: invariants at every sample, the independent
reference, a second communication grid where the case has one, the energy
balance, and the case's own expectations (see ``stickslip.stress``). The full
matrix is ``stickslip stress`` (about 2 minutes). The bugs the full matrix shows
are reproduced below, minimally and on the Python runtime, as strict xfails.
"""

import math

import numpy as np
import pytest

from stickslip.cli import main
from stickslip.core import Constant, Coulomb, Parameters, Saturating, Sigmoid, SolverError, Trajectory
from stickslip.stress.cases import GROUPS, stress_cases
from stickslip.stress.checks import coulomb_cycle
from stickslip.stress.case_runs import run_case, summary_table
from stickslip.stress.session import FmuSession

QUICK = stress_cases(quick=True)


@pytest.fixture(scope="module")
def session(fmu_path):
    with FmuSession(fmu_path) as s:
        yield s


def test_the_quick_subset_covers_every_group():
    assert {c.group for c in QUICK} == set(GROUPS)
    assert not any(c.known_bug for c in QUICK)


@pytest.mark.parametrize("case", QUICK, ids=[c.name for c in QUICK])
def test_quick_stress_case(session, case):
    outcome = run_case(session, case)
    assert outcome.passed, "; ".join(outcome.failures)
    assert outcome.n_steps > 0


def test_full_matrix_spans_the_regimes_of_the_issue():
    cases = stress_cases()
    by_name = {c.name: c for c in cases}
    masses = {c.start.get("M", 1.0) for c in cases if c.group == "scale"}
    stiffnesses = {c.start.get("kappa", 1.0) for c in cases if c.group == "scale"}
    assert max(masses) / min(masses) >= 1e12 and max(stiffnesses) / min(stiffnesses) >= 1e12
    drives = {c.start.get("v_drive") for c in cases if c.group == "drive" and not c.inputs}
    assert {0.0, 1e-9, 1e-3, 1.0, 1e3} <= drives
    assert any(min(v for _, v, _ in c.inputs) < 0 < max(v for _, v, _ in c.inputs) for c in cases if c.inputs)
    steps = [min(np.diff(c.grid)) for c in cases if c.group == "comm-step"]
    assert min(steps) <= 1e-9 * 1.000001 and max(max(np.diff(c.grid)) for c in cases if c.group == "comm-step") >= 1e4
    assert by_name["ratio-coulomb-1+1e-9"].start["kinetic.F0"] == 1.0 / (1 + 1e-9)
    assert by_name["overdamped-viscous-1e+06"].start["kinetic.gamma"] == 1e6
    assert {c.long["kind"] for c in cases if c.long} == {"time", "events"}
    assert {c.long["amount"] for c in cases if c.long} >= {1e6, 1_000_000}
    names = {c.name for c in cases}
    assert len(names) == len(cases)


def test_stress_cli_lists_cases_and_builds_a_table(capsys):
    assert main(["stress", "--list", "--group", "grazing"]) == 0
    listed = capsys.readouterr().out.splitlines()
    assert len(listed) == len(stress_cases(groups=["grazing"])) and all("grazing" in line for line in listed)


def test_summary_table_counts_passes_and_known_bugs(session):
    case = next(c for c in QUICK if c.group == "chatter")
    outcome = run_case(session, case)
    table = summary_table([outcome])
    header, _, row, total = table.splitlines()
    assert "worst error" in header and "worst time/step (ms)" in header
    assert row.split("|")[1].strip() == "chatter" and row.split("|")[2].strip() == "1"
    assert total.split("|")[1].strip() == "total"


# ---------------------------------------------------------------------------
# bugs the stress tests found, minimal reproductions on the Python runtime (the FMU's copy).
# Fixed ones stay as regression tests; open ones are strict xfails naming the bug.
# ---------------------------------------------------------------------------


def test_breakaway_later_than_a_million_periods_is_found():
    """Was a bug (fixed in f13ede0): with a constant static law the stuck segment became infinite."""
    # M = kappa = 1: natural period 2 pi s; breakaway at kappa x = F_S after 1e7 s of stick
    p = Parameters(1.0, 1.0, Coulomb(F0=0.5), Constant(F0=1.0))
    traj = Trajectory(p, 0.0, 1e-7, v_drive=1e-7)
    traj.advance_to(2e7)
    assert traj.n_slip_events >= 1
    assert traj.mode != 0 or abs(traj.x) <= 1.0


def test_breakaway_within_a_million_periods_is_found():
    p = Parameters(1.0, 1.0, Coulomb(F0=0.5), Constant(F0=1.0))
    traj = Trajectory(p, 0.0, 1e-5, v_drive=1e-5)
    traj.advance_to(2e5)
    assert traj.n_slip_events >= 1


def test_weakening_sigmoid_static_friction_breaks_away():
    """Was a bug (fixed in f13ede0): Sigmoid.rate(0) was +inf for weakening n < 1, no breakaway was found."""
    # F_S falls from 1 N towards 0.6 N; the stuck block's holding force 0.1 t N passes it near t = 7 s
    p = Parameters(1.0, 1.0, Coulomb(F0=0.5), Sigmoid(F0=1.0, F_inf=0.6, tau=1.0, n=0.5))
    traj = Trajectory(p, 0.0, 0.1, v_drive=0.1)
    traj.advance_to(20.0)
    assert traj.n_slip_events >= 1


def test_sigmoid_rate_at_zero_has_the_sign_of_the_aging():
    strengthening = Sigmoid(F0=1.0, F_inf=2.0, tau=1.0, n=0.5)
    weakening = Sigmoid(F0=1.0, F_inf=0.5, tau=1.0, n=0.5)
    assert strengthening.rate(0.0) == math.inf and strengthening.rate(1e-12) > 0
    assert weakening.rate(0.0) == -math.inf and weakening.rate(1e-12) < 0


def test_balanced_block_with_weakening_contact_rests_or_fails_cleanly():
    """Was a bug (fixed in f13ede0): the block reported a slip (mode -1) whose v_rel stayed exactly 0."""
    # F_ext = F_S(0) = F_K(0+) = 1 N, F_S falls after any stick, v_drive = 0: the block has no
    # reason to move; the runtime must say stuck, or raise a clear SolverError, but not report
    # a slip (mode -1) whose v_rel stays exactly 0
    p = Parameters(1.0, 1.0, Coulomb(F0=1.0), Saturating(F0=1.0, F_inf=0.5, tau=1.0))
    try:
        traj = Trajectory(p, 0.0, 0.0, v_drive=0.0, F_ext=1.0)
        traj.advance_to(1.0)
    except SolverError:
        return
    assert traj.mode == 0 or traj.mode * traj.v_rel > 0.0


def test_kink_of_the_holding_force_right_after_the_start_with_sigmoid_aging():
    """Was a bug: Sigmoid.curvature divided by t * t, which underflowed to 0 for t < 1e-154 s."""
    # found by hypothesis: stuck at x = 1e-229 m moving at -1 m/s, the holding force kappa x changes sign
    # after 1e-229 s; breakaway_delay evaluates Sigmoid.curvature there and t * t underflows to 0
    p = Parameters(1.0, 1.0, Coulomb(F0=0.0), Sigmoid(F0=1.0, F_inf=0.5, tau=1.0, n=1.0))
    traj = Trajectory(p, 1e-229, -1.0, v_drive=-1.0)
    traj.advance_to(3.0)
    assert traj.n_slip_events == 1


def test_stick_against_the_drive_under_weakening_aging_breaks_away():
    """Was a bug (fixed in edbf5be): at the kink of |kappa x - F_ext| the holding force rounded to -5.6e-17,
    the derivative was taken on the wrong side and the convex search found no breakaway."""
    # found by hypothesis (STICKSLIP_EXPLORE): stuck at kappa x = -0.384 N moving at +0.368 m/s; the holding
    # force passes 0 after 1.04 s (where it rounds to -5.6e-17) and exceeds F_S (falling to 0.5 N) near 2.8 s
    p = Parameters(1.0, 1.0, Coulomb(F0=0.125), Sigmoid(F0=1.0, F_inf=0.5, tau=1.0, n=1.0))
    traj = Trajectory(p, -0.3842606550925819, 0.36787944117144233, v_drive=0.36787944117144233)
    traj.advance_to(10.0)
    assert traj.n_slip_events >= 1
    assert traj.mode != 0 or abs(traj.x) <= p.static.force(traj.t_stick)


def test_stick_against_the_drive_under_strengthening_sigmoid_breaks_away_in_time():
    """Was a bug (fixed in edbf5be): same cause as the previous test, with a strengthening sigmoid."""
    # found by hypothesis: the holding force kappa x passes 0 after 9.5 ms and reaches F_S ~ 1.0 N after
    # 0.64 s; the runtime skips the convex piece before the sigmoid's inflection (4.27 s) and breaks late
    p = Parameters(1.0, 1.0, Coulomb(F0=0.5), Sigmoid(F0=1.0, F_inf=2.0, tau=math.exp(2.0), n=2.0))
    traj = Trajectory(p, -0.015112811684831473, 1.59375, v_drive=1.59375)
    traj.advance_to(1.0)
    assert traj.n_slip_events == 1


def test_coulomb_cycle_closed_form_matches_the_runtime():
    period, x_max, x_min, t_slip = coulomb_cycle(1.0, 1.0, 0.5, 1.0, 0.1)
    p = Parameters(1.0, 1.0, Coulomb(F0=0.5), Constant(F0=1.0))
    traj = Trajectory(p, 0.0, 0.1, v_drive=0.1)
    sticks = []
    t = 0.0
    while len(sticks) < 4:
        t += 0.01
        before = traj.n_stick_events
        traj.advance_to(t)
        if traj.n_stick_events > before:
            sticks.append(traj.t_last_event)
    assert np.allclose(np.diff(sticks), period, rtol=1e-12)
    assert sticks[0] == pytest.approx(10.0 + t_slip, rel=1e-12)
    assert x_max == pytest.approx(0.5 + math.hypot(0.5, 0.1), rel=1e-15)
