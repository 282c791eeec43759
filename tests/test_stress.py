"""Stress matrix: the quick cases of ``stickslip stress`` through the FMU, one test each (about 20 s), and the
whole matrix through the command line (about 45 s on the project's 2-core machine, the long runs included).

Each quick case is one test: invariants at every sample, the independent
reference, a second communication grid where the case has one, the energy
balance, and the case's own expectations (see ``stickslip.stress``). The bugs
the full matrix showed are reproduced below, minimally and on the Python
runtime, as regression tests.
"""

import math
import subprocess
import sys

import numpy as np
import pytest

from stickslip.cli import main
from stickslip.core import Constant, Coulomb, Parameters, Saturating, Sigmoid, SolverError, Trajectory
from stickslip.stress.cases import GROUPS, stress_cases
from stickslip.stress.checks import coulomb_cycle
from stickslip.stress.case_runs import TABLE_COLUMNS, Outcome, console_summary, run_case, summary_table
from stickslip.suite.report import CONSOLE_WIDTH
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


def _case_results(report):
    """``{case: result}`` from the "Cases" table of the report ``stickslip stress --out DIR`` writes."""
    cases = report.split("\n## Cases\n", 1)[1].split("\n## ", 1)[0]
    lines = [line for line in cases.splitlines() if line.startswith("|")]
    rows = [[cell.strip() for cell in line.strip("|").split("|")] for line in lines]
    assert rows[0][:2] == ["case", "result"] and set(rows[1][0]) == {"-"}
    return {row[0]: row[1] for row in rows[2:]}


def test_the_whole_matrix_passes_through_the_command_line(fmu_path, tmp_path):
    """``stickslip stress`` in run mode: every case of the matrix, the three long runs (1e6 s, 1e6 events,
    numeric slips over 1e5 s) included, in a child process with a time limit (a crash or a hang of the FMU
    fails this test, not pytest). Measured: 78 of 78 cases passed in 42 s alone, 54-56 s in the whole test run."""
    report = tmp_path / "stress.md"
    code = "import sys; from stickslip.cli import main; sys.exit(main(sys.argv[1:]))"
    run = subprocess.run([sys.executable, "-c", code, "stress", "--fmu", str(fmu_path), "--no-progress",
                          "--out", str(tmp_path)], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, f"{run.stdout[-4000:]}\n{run.stderr[-2000:]}"
    cases = stress_cases()
    assert {c.group for c in cases} == set(GROUPS) and sum(bool(c.long) for c in cases) == 3
    assert f"{len(cases)}/{len(cases)} stress cases passed, 0 failed with known bugs, 0 unexpected" in run.stdout
    assert _case_results(report.read_text()) == {c.name: "PASS" for c in cases}


def test_stress_cli_lists_cases_and_builds_a_table(capsys):
    assert main(["stress", "--list", "--group", "grazing"]) == 0
    listed = capsys.readouterr().out.splitlines()
    assert len(listed) == len(stress_cases(groups=["grazing"])) and all("grazing" in line for line in listed)


def test_stress_writes_its_report_into_out_and_prints_within_100_columns(fmu_path, tmp_path, capsys):
    """``--out DIR`` like every other command: DIR/stress.md with every column and every case; the console shows
    fewer columns, within 100."""
    out = tmp_path / "out"
    assert main(["stress", "--case", "ratio-coulomb-1e3", "--case", "drive-1e3", "--fmu", str(fmu_path), "--no-progress",
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert max(len(line) for line in printed) <= CONSOLE_WIDTH
    assert printed[-2:] == ["2/2 stress cases passed, 0 failed with known bugs, 0 unexpected",
                            f"report: {out / 'stress.md'}"]
    assert "max step (ms)" in printed[0] and "mean time/step" not in printed[0]
    report = (out / "stress.md").read_text()
    assert all(column in report.splitlines()[4] for column in TABLE_COLUMNS)
    assert _case_results(report) == {"ratio-coulomb-1e3": "PASS", "drive-1e3": "PASS"}


def test_the_console_summary_of_every_group_stays_within_100_columns():
    """The widest numbers every column can hold, in every group, and failures longer than a line: every console
    line within 100 columns, the failures wrapped with nothing lost."""
    why = "energy balance |dE - W| 1.23e+300 above 1e-08 of the energy scale " * 3
    outcomes = [Outcome(f"{group}-a-case-name-as-long-as-they-come", group, failures=[why], ref_error=1.23e300,
                        grid_error=math.inf, energy_error=9.99e-300, n_steps=10 ** 9, n_events=10 ** 9,
                        max_step_s=1234.5, mean_step_s=1234.5, seconds=1e6, known_bug="a known limit" * (i % 2))
                for i, group in enumerate(GROUPS)]
    lines = console_summary(outcomes).splitlines()
    assert max(len(line) for line in lines) <= CONSOLE_WIDTH
    assert len(summary_table(outcomes).splitlines()[0]) > CONSOLE_WIDTH  # the report's table: every column
    assert [line.split("|")[1].strip() for line in lines[2:3 + len(GROUPS)]] == [*GROUPS, "total"]
    wrapped = " ".join(line.strip() for line in lines[3 + len(GROUPS):])
    assert wrapped.count("energy balance |dE - W| 1.23e+300") == 3 * len(GROUPS)


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


@pytest.mark.parametrize("v_drive", [1e-5, 1e-7], ids=["1e5-periods", "1e7-periods"])
def test_breakaway_after_a_million_periods_is_found_at_its_time(v_drive):
    """Was a bug (fixed in f13ede0): with a constant static law the stuck segment became infinite."""
    # M = kappa = 1 (natural period 2 pi s), F_K = 0.5 N, F_S = 1 N, stuck at x = 0 moving at v_drive: Coulomb
    # breakaway when kappa x reaches F_S, at t_b = F_S / (kappa v_drive); the slip about x_e = F_K / kappa
    # starts at x - x_e = A = (F_S - F_K) / kappa with v = v_drive and sticks when v = v_drive again,
    # tan(s / 2) = -A / v_drive (s = omega * slip time); then stuck at x = 2 F_K - F_S = 0 until 2 t_b + s.
    p = Parameters(1.0, 1.0, Coulomb(F0=0.5), Constant(F0=1.0))
    traj = Trajectory(p, 0.0, v_drive, v_drive=v_drive, record_events=True)
    traj.advance_to(1.5 / v_drive)
    t_b = 1.0 / v_drive
    t_s = t_b + 2.0 * math.pi - 2.0 * math.atan(0.5 / v_drive)
    (t_slip, *slip), (t_stick, *stick) = traj.events
    assert (slip, stick) == ([0, 1], [1, 0])
    # measured: t_b exact, t_s within 1 ulp (1.5e-16 relative), x within 1 ulp
    assert t_slip == pytest.approx(t_b, rel=1e-14) and t_stick == pytest.approx(t_s, rel=1e-14)
    assert traj.mode == 0 and traj.x == pytest.approx(v_drive * (1.5 / v_drive - t_s), rel=1e-14)


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


def test_balanced_block_with_weakening_contact_fails_cleanly():
    """Was a bug (fixed in f13ede0): the block reported a slip (mode -1) whose v_rel stayed exactly 0."""
    # F_ext = F_S(0) = F_K(0+) = 1 N, F_S falls after any stick, v_drive = 0: stick and slip cannot be
    # decided; the runtime raises a clear SolverError (as the stress case chatter-degenerate-balance
    # expects of the FMU) instead of reporting a slip whose v_rel stays exactly 0
    p = Parameters(1.0, 1.0, Coulomb(F0=1.0), Saturating(F0=1.0, F_inf=0.5, tau=1.0))
    with pytest.raises(SolverError, match="event chain at t = 0.0 s.*cannot decide between sticking and slipping"):
        Trajectory(p, 0.0, 0.0, v_drive=0.0, F_ext=1.0).advance_to(1.0)


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
