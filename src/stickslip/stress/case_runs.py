"""Run the stress matrix through the FMU, check every case, and tabulate the results.

For a standard case (:func:`run_case`):

1. the FMU steps through the case's grid (FMPy ``FMU2Slave``, one ``doStep`` per
   grid interval), inputs set at their grid times, every output read after
   each step; ``fmi2GetRealStatus(fmi2LastSuccessfulTime)`` must be the
   requested communication point exactly;
2. invariants at every sample (:func:`.checks.check_invariants`);
3. the independent reference on the same times with the same inputs: normalized
   state error and the number of mode changes;
4. a second run on a refined grid (when the case has one): the samples at the
   common times must agree to ``grid_tol``;
5. the energy balance on every smooth piece (:func:`.checks.energy_balance`);
6. the case's own expectations (event counts, final mode, or a clean error).

Long cases (:func:`run_long`) check memory, linear event counts and drift of
the cycle instead (see there). :func:`run_stress` runs a list of cases with a
progress bar and returns the outcomes; :func:`summary_table` groups them.
"""

import gc
import math
import os
import resource
import textwrap
import time
from dataclasses import dataclass, field

import numpy as np
from tqdm import tqdm

from ..core.errors import StickSlipError
from ..suite.report import CONSOLE_WIDTH
from . import checks
from .cases import stress_cases
from .session import FmuCallError, FmuSession, as_columns


@dataclass
class Outcome:
    """What one case gave. Errors are normalized (see :mod:`.checks`); times in s."""

    name: str
    group: str
    failures: list = field(default_factory=list)
    ref_error: float = math.nan
    grid_error: float = math.nan
    energy_error: float = math.nan
    n_steps: int = 0
    n_events: int = 0
    max_step_s: float = math.nan
    mean_step_s: float = math.nan
    seconds: float = 0.0
    details: dict = field(default_factory=dict)
    known_bug: str = ""

    @property
    def passed(self):
        return not self.failures

    @property
    def unexpected(self):
        """Failed without a known bug, or passed although a known bug was expected (fixed: update the case)."""
        return self.passed == bool(self.known_bug)

    @property
    def worst_error(self):
        values = [e for e in (self.ref_error, self.grid_error, self.energy_error) if not math.isnan(e)]
        return max(values) if values else math.nan


def simulate(session, values, grid, inputs, outcome=None):
    """Step a fresh instance through ``grid``; returns ``(samples, breakpoints, step_seconds, time_errors)``.

    ``breakpoints`` are the inputs as the FMU got them, ``[(t, v_drive, F_ext), ...]``
    with the FMU's own times; ``time_errors`` counts steps whose end time
    (``fmi2LastSuccessfulTime``) differs from the requested point.
    """
    steps = {float(t): (vd, F) for t, vd, F in inputs}
    inst = session.instantiate(values)
    try:
        rows = [inst.read()]
        breakpoints = [(inst.time, float(values["v_drive"]), float(values["F_ext"]))]
        time_errors = 0
        for t in grid[1:]:
            inst.step_to(t)
            if inst.last_successful_time() != inst.time:
                time_errors += 1
            if t in steps:
                inst.set_inputs(*steps[t])
                breakpoints.append((inst.time, *map(float, steps[t])))
            rows.append(inst.read())
        return as_columns(rows), breakpoints, list(inst.step_seconds), time_errors
    finally:
        inst.free()


def _common(samples, other, times):
    """Indices into ``samples`` and ``other`` of the requested ``times`` that both reached.

    A run reaches ``time + (t - time)``, which may differ from ``t`` in the last bits when
    the step before it differs; times within 4 ulps are the same communication point.
    """
    wanted = np.array(sorted(times))
    theirs = other["time"]
    pairs = []
    for i, t in enumerate(samples["time"]):
        k = np.searchsorted(wanted, t)
        near = [wanted[m] for m in (k - 1, k) if 0 <= m < len(wanted)]
        if not any(abs(t - w) <= 4 * math.ulp(w) for w in near):
            continue
        j = int(np.searchsorted(theirs, t))
        for m in (j - 1, j):
            if 0 <= m < len(theirs) and abs(theirs[m] - t) <= 4 * math.ulp(t):
                pairs.append((i, m))
                break
    return np.array([p[0] for p in pairs], int), np.array([p[1] for p in pairs], int)


def _check_expectations(case, samples, outcome):
    expect = case.expect
    n = int(samples["n_events"][-1])
    if "min_events" in expect and n < expect["min_events"]:
        outcome.failures.append(f"{n} events < expected {expect['min_events']}")
    if "max_events" in expect and n > expect["max_events"]:
        outcome.failures.append(f"{n} events > expected {expect['max_events']}")
    if "min_overshoots" in expect and samples["n_overshoots"][-1] < expect["min_overshoots"]:
        outcome.failures.append(f"{samples['n_overshoots'][-1]} overshoots < expected {expect['min_overshoots']}")
    if "final_mode" in expect and samples["mode"][-1] != expect["final_mode"]:
        outcome.failures.append(f"final mode {samples['mode'][-1]} != expected {expect['final_mode']}")


def _fmu_error_text(exc):
    """An FMU error (its message and the FMU's log lines) on one line."""
    return " | ".join(str(exc).splitlines())


def run_case(session, case):
    """Run and check one case; returns an :class:`Outcome`."""
    if case.long:
        return run_long(session, case)
    outcome = Outcome(case.name, case.group, known_bug=case.known_bug)
    start = time.perf_counter()
    values = session.start_values(case.start)
    p = checks.params_from_start(values)
    try:
        samples, breakpoints, step_s, time_errors = simulate(session, values, case.grid, case.inputs)
    except FmuCallError as exc:
        outcome.seconds = time.perf_counter() - start
        if "error" in case.expect and case.expect["error"] in str(exc):
            return outcome
        outcome.failures.append(f"FMU error: {_fmu_error_text(exc)}")
        return outcome
    if "error" in case.expect:
        outcome.failures.append(f"expected an FMU error containing {case.expect['error']!r}, the run succeeded")
    outcome.n_steps = len(step_s)
    outcome.max_step_s = max(step_s)
    outcome.mean_step_s = sum(step_s) / len(step_s)
    outcome.n_events = int(samples["n_events"][-1])
    if time_errors:
        outcome.failures.append(f"{time_errors} steps did not end exactly at the requested communication point")

    violations = checks.check_invariants(samples, p, t0=case.grid[0])
    if violations:
        outcome.failures.append(f"invariants: {violations.summary()}")
    run = _CaseRun(session, case, values, p, samples, breakpoints)
    if case.reference:
        run.check_reference(outcome)
    if case.refine:
        run.check_grid(outcome)
    if case.energy:
        run.check_energy(outcome)
    _check_expectations(case, samples, outcome)
    outcome.seconds = time.perf_counter() - start
    return outcome


@dataclass
class _CaseRun:
    """A standard case's run and what its checks need: the session, the case, the FMU start ``values`` and their
    ``Parameters`` ``p``, the ``samples`` and the ``breakpoints`` (the inputs as the FMU got them)."""

    session: FmuSession
    case: object
    values: dict
    p: object
    samples: dict
    breakpoints: list

    def check_reference(self, outcome):
        """The independent reference on the same times with the same inputs: state error and mode changes."""
        values, samples = self.values, self.samples
        try:
            ref = checks.reference_for(values, values["x_start"], values["v_start"], self.breakpoints,
                                       samples["time"])
            outcome.ref_error, where = checks.compare_reference(samples, ref, self.p)
            outcome.details["reference"] = where
            if outcome.ref_error > self.case.tol:
                outcome.failures.append(f"reference: {where} > {self.case.tol:g}")
            n_ref = checks.mode_changes(ref)
            if n_ref != outcome.n_events:
                outcome.failures.append(f"events: FMU {outcome.n_events}, reference {n_ref}")
        except StickSlipError as exc:
            outcome.failures.append(f"reference failed: {exc}")

    def check_grid(self, outcome):
        """A second run on the case's other grid agrees at the common times (to ``grid_tol``, same events)."""
        case, samples = self.case, self.samples
        other, _, _, _ = simulate(self.session, self.values, case.refine, case.inputs)
        i, j = _common(samples, other, set(case.grid) & set(case.refine))
        x_scale, v_scale, _ = checks.scales(self.p, samples)
        expected = min(len(set(case.grid)), len(set(case.refine)))
        if len(i) < expected:
            outcome.failures.append(f"second grid: only {len(i)} of {expected} times in common")
        dx = np.abs(samples["x"][i] - other["x"][j]).max() / x_scale
        dv = np.abs(samples["v"][i] - other["v"][j]).max() / v_scale
        outcome.grid_error = float(max(dx, dv))
        if outcome.grid_error > case.grid_tol:
            outcome.failures.append(f"grid dependence {outcome.grid_error:.2e} > {case.grid_tol:g}")
        if not np.array_equal(samples["n_events"][i], other["n_events"][j]):
            outcome.failures.append("grid dependence: event counts differ at common times")

    def check_energy(self, outcome):
        """The energy balance on every smooth piece (:func:`.checks.energy_balance`), through fresh instances."""
        p, values = self.p, self.values
        t0, t_end = self.case.grid[0], self.samples["time"][-1]

        def make_instance():
            return self.session.instantiate(values)

        allowed = checks.energy_tolerance(values["solver.rtol"], self.case.affine, t_end, math.sqrt(p.M / p.kappa))
        try:
            result = checks.energy_balance(make_instance, p, self.breakpoints, t_end, (t_end - t0) / 100.0,
                                           quad_rel=max(0.01 * allowed, 2e-12))
        except FmuCallError as exc:
            outcome.failures.append(f"energy passes: FMU error: {_fmu_error_text(exc)}")
            return
        outcome.energy_error = result.worst
        outcome.details["energy"] = f"{result.where}; {result.cells} cells"
        allowed += result.quadrature
        if result.worst > allowed:
            outcome.failures.append(f"energy balance {result.worst:.2e} > {allowed:.1e}: {result.where}")
        if result.n_events != outcome.n_events:
            outcome.failures.append(f"energy pass found {result.n_events} events, the run {outcome.n_events}")


# ---------------------------------------------------------------------------
# long runs
# ---------------------------------------------------------------------------


def rss_bytes():
    """Resident set size of this process (bytes); peak RSS where /proc is missing."""
    try:
        with open("/proc/self/statm") as statm:
            return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except OSError:
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


MEMORY_GROWTH_LIMIT = 8 * 2**20  # bytes of RSS growth allowed between 10 % and 100 % of a long run
OBJECT_GROWTH_LIMIT = 2000  # garbage-collected Python objects, same window


def _fine_events(inst, duration, h):
    """Step on ``h`` for ``duration`` s; return ``[(kind, t, x, count), ...]`` at every lone event, exactly.

    A step with one event is redone up to the event time (``t_last_event``), so
    ``x`` is the state right at the event (results do not depend on the grid);
    ``count`` is the counter of that kind of event after it.
    """
    events = []
    t_stop = inst.time + duration
    while inst.time < t_stop:
        state = inst.get_state()
        t_a = inst.time
        before = inst.read()
        inst.step_to(t_a + h)
        row = inst.read()
        if row["n_events"] - before["n_events"] == 1 and row["t_last_event"] > t_a:
            kind = next(k for k in ("n_stick_events", "n_slip_events", "n_overshoots") if row[k] > before[k])
            te = row["t_last_event"]
            t_b = inst.time
            inst.set_state(state, t_a)
            inst.step_to(te)
            at = inst.read()
            events.append((kind, at["time"], at["x"], at[kind]))
            if t_b > inst.time:
                inst.step_to(t_b)
        inst.free_state(state)
    return events


def _coulomb_exact(values):
    M, kappa = values["M"], values["kappa"]
    F_K, F_S, vd = values["kinetic.F0"], values["static.F0"], values["v_drive"]
    period, x_max, x_min, t_slip = checks.coulomb_cycle(M, kappa, F_K, F_S, vd)
    t_first_slip = (F_S / kappa - values["x_start"]) / vd  # start stuck at x_start
    return {"period": period, "t_slip": t_slip, "t_first_slip": t_first_slip,
            "x_stick": (2 * F_K - F_S) / kappa, "x_slip": F_S / kappa}


def _reference_cycle(p, values, n_cycles=6):
    """Period (s) and stick position (m) of the limit cycle from the reference integrator."""
    vd = values["v_drive"]
    t_guess = 2 * p.static.force(0.0) / (p.kappa * vd) + 2 * math.pi * math.sqrt(p.M / p.kappa)
    t_end = n_cycles * t_guess
    ref = checks.reference_for(values, values["x_start"], values["v_start"], [(0.0, vd, values["F_ext"])],
                               np.linspace(0.0, t_end, 200))
    sticks = [e.t for e in ref.events if e.kind == "stick"]
    period = float(np.mean(np.diff(sticks[1:])))
    at = checks.reference_for(values, values["x_start"], values["v_start"], [(0.0, vd, values["F_ext"])],
                              np.array([0.0, sticks[-1]]))
    return period, float(at.x[-1]), sticks


def run_long(session, case):
    """A long run: 1e6 time units (``kind`` "time") or 1e6 events (``kind`` "events") in big steps.

    Checks: RSS and the number of live Python objects stay flat (from 10 % of
    the run to its end); the event count grows linearly (at each of 10
    checkpoints it matches the closed form within 1 event, or a straight line
    through the checkpoints within 2 events); the cycle does not drift: over
    the last cycles, located exactly, the period and the stick / breakaway
    positions match the closed form (Coulomb) or the reference (other laws),
    and the absolute time of the last stick matches ``t_1 + (N - 1) T``.
    """
    outcome = Outcome(case.name, case.group)
    start = time.perf_counter()
    values = session.start_values(case.start)
    p = checks.params_from_start(values)
    settings = case.long
    inst = session.instantiate(values)
    try:
        checkpoints = _long_steps(inst, settings)
        outcome.n_steps = len(inst.step_seconds)
        outcome.max_step_s = max(inst.step_seconds)
        outcome.mean_step_s = sum(inst.step_seconds) / outcome.n_steps
        last = inst.read()
        outcome.n_events = int(last["n_events"])
        violations = checks.check_invariants(as_columns([last]), p)
        if violations:
            outcome.failures.append(f"invariants at the end: {violations.summary()}")
        _check_memory(outcome, checkpoints)
        _check_cycle_at_end(outcome, inst, values, p, settings["closed_form"])
        _check_event_counts(outcome, checkpoints, values, settings["closed_form"])
    except FmuCallError as exc:
        outcome.failures.append(f"FMU error: {_fmu_error_text(exc)}")
    finally:
        inst.free()
    outcome.seconds = time.perf_counter() - start
    return outcome


def _long_steps(inst, settings):
    """Step ``inst`` by ``settings["step"]`` s through the long run; returns the 10 checkpoints ``(t s,
    n_events, RSS bytes, live Python objects)`` at each tenth of its time or events (after a collection)."""
    H = settings["step"]
    checkpoints = []
    if settings["kind"] == "time":
        n_steps = int(round(settings["amount"] / H))
        marks = {int(round(n_steps * k / 10)) for k in range(1, 11)}
        for k in range(1, n_steps + 1):
            inst.step_to(k * H)
            if k in marks:
                gc.collect()
                checkpoints.append((inst.time, inst.read()["n_events"], rss_bytes(), len(gc.get_objects())))
        return checkpoints
    target = settings["amount"]
    next_mark, k = target / 10, 0
    while True:
        k += 1
        inst.step_to(k * H)
        n = inst.read()["n_events"]
        if n >= next_mark:
            gc.collect()
            checkpoints.append((inst.time, n, rss_bytes(), len(gc.get_objects())))
            next_mark += target / 10
            if n >= target:
                return checkpoints


def _check_memory(outcome, checkpoints):
    """RSS and live Python objects grow by at most their limits from the first checkpoint to the last."""
    rss = [c[2] for c in checkpoints]
    objects = [c[3] for c in checkpoints]
    outcome.details["rss MB (10%..100%)"] = f"{rss[0] / 2**20:.1f} .. {rss[-1] / 2**20:.1f}"
    outcome.details["gc objects"] = f"{objects[0]} .. {objects[-1]}"
    if rss[-1] - rss[0] > MEMORY_GROWTH_LIMIT:
        outcome.failures.append(f"RSS grew by {(rss[-1] - rss[0]) / 2**20:.1f} MB")
    if objects[-1] - objects[0] > OBJECT_GROWTH_LIMIT:
        outcome.failures.append(f"live Python objects grew by {objects[-1] - objects[0]}")


def _expected_cycle(values, p, closed_form):
    """``(period s, stick x m, breakaway x m, time of the first stick s)`` of the limit cycle: the closed form
    (Coulomb) or the reference integrator's."""
    if closed_form:
        exact = _coulomb_exact(values)
        return exact["period"], exact["x_stick"], exact["x_slip"], exact["t_first_slip"] + exact["t_slip"]
    period, x_stick, sticks_ref = _reference_cycle(p, values)
    return period, x_stick, p.static.force(0.0) / p.kappa, sticks_ref[0]


def _check_cycle_at_end(outcome, inst, values, p, closed_form):
    """The cycle at the end of the run, located exactly, has not drifted in period, phase or amplitude."""
    period, x_stick, x_slip, t1 = _expected_cycle(values, p, closed_form)
    events = _fine_events(inst, 3.2 * period, period / 400.0)
    sticks = [(t, x, n) for kind, t, x, n in events if kind == "n_stick_events"]
    slips = [(t, x, n) for kind, t, x, n in events if kind == "n_slip_events"]
    if len(sticks) < 2 or not slips:
        outcome.failures.append(f"end of run: {len(sticks)} sticks, {len(slips)} slips located in 3.2 periods")
        return
    t_last, _, n_sticks = sticks[-1]
    period_end = (t_last - sticks[0][0]) / (n_sticks - sticks[0][2])
    phase = abs(t_last - (t1 + (n_sticks - 1) * period))
    x_err = max(max(abs(x - x_stick) for _, x, _ in sticks), max(abs(x - x_slip) for _, x, _ in slips))
    x_scale = p.static.force(0.0) / p.kappa
    outcome.details["period"] = f"{period_end!r} (expected {period!r})"
    outcome.details["phase drift (s)"] = f"{phase:.3g} after {n_sticks} cycles"
    outcome.details["stick/slip position error (m)"] = f"{x_err:.3g}"
    # Absolute times are doubles: each event time is a sum rounded to half an ulp of t, so the
    # phase may wander by up to one ulp per event (a naive double accumulation of the exact
    # Coulomb cycle drifts 1.4e-6 s over 1e6 s); period and positions carry that rounding only.
    ulp = math.ulp(max(t_last, 1.0))
    n_all = int(inst.read()["n_events"])
    rounding = 4 * ulp / max(n_sticks - sticks[0][2], 1) + 64 * checks.EPS * period
    # numeric laws: the FMU's cycle and the reference's differ by the integrators' errors (rtol 1e-10
    # and 1e-12), measured 6e-11 of a period; 1e-9 per cycle is allowed
    period_tol = (1e-12 if closed_form else 1e-9) * period + rounding
    phase_tol = n_all * ulp + (0.0 if closed_form else 1e-9 * period * n_sticks)
    outcome.details["phase tolerance (s)"] = f"{phase_tol:.3g}"
    outcome.ref_error = max(abs(period_end - period) / period, x_err / x_scale)
    if abs(period_end - period) > period_tol:
        outcome.failures.append(f"period drifted: {period_end!r} vs {period!r}")
    if phase > phase_tol:
        outcome.failures.append(f"phase drifted by {phase:.3g} s (allowed {phase_tol:.2g})")
    v_scale = max(abs(values["v_drive"]), math.sqrt(p.kappa / p.M) * x_scale)
    if x_err > (1e-12 if closed_form else 1e-8) * x_scale + v_scale * 8 * ulp:
        outcome.failures.append(f"amplitude drifted: stick/slip positions off by {x_err:.3g} m")


def _check_event_counts(outcome, checkpoints, values, closed_form):
    """The event count grows linearly: the closed form's within 1 event, or a straight line within 2."""
    ts = np.array([c[0] for c in checkpoints])
    ns = np.array([c[1] for c in checkpoints], float)
    if closed_form:
        exact = _coulomb_exact(values)
        cycles = np.floor((ts - exact["t_first_slip"]) / exact["period"])
        phase_in = (ts - exact["t_first_slip"]) - cycles * exact["period"]
        predicted = 2 * cycles + 1 + (phase_in >= exact["t_slip"])
        off = np.abs(ns - predicted).max()
        outcome.details["event count vs closed form"] = f"max off {off:g}"
        if off > 1:
            outcome.failures.append(f"event counts off the closed form by {off:g}")
    else:
        slope, intercept = np.polyfit(ts, ns, 1)
        off = np.abs(ns - (slope * ts + intercept)).max()
        outcome.details["event count vs straight line"] = f"max off {off:.2f}"
        if off > 2:
            outcome.failures.append(f"event counts not linear in time (off by {off:.1f})")


# ---------------------------------------------------------------------------
# the matrix
# ---------------------------------------------------------------------------


def run_stress(fmu_path, cases=None, quick=False, groups=None, progress=True):
    """Run ``cases`` (default: :func:`.cases.stress_cases`) with a progress bar; returns the outcomes."""
    cases = stress_cases(quick=quick, groups=groups) if cases is None else cases
    outcomes = []
    with FmuSession(fmu_path) as session:
        bar = tqdm(cases, desc="stress", unit="case", disable=not progress)
        for case in bar:
            bar.set_postfix_str(case.name)
            try:
                outcomes.append(run_case(session, case))
            except Exception as exc:  # a crash of the checking code must not hide the other cases
                outcomes.append(Outcome(case.name, case.group, failures=[f"{type(exc).__name__}: {exc}"]))
        bar.close()
    return outcomes


def _fmt(value, spec):
    return "-" if value is None or (isinstance(value, float) and math.isnan(value)) else format(value, spec)


TABLE_COLUMNS = ("group", "cases", "passed", "known bugs", "worst error", "worst ref", "worst grid", "worst energy",
                 "worst time/step (ms)", "mean time/step (ms)", "events", "wall (s)")


def summary_rows(outcomes):
    """One row per group, in order of first appearance, and a total row."""
    groups = {}
    for o in outcomes:
        groups.setdefault(o.group, []).append(o)
    rows = []

    def worst(items, attr):
        values = [getattr(o, attr) for o in items if not math.isnan(getattr(o, attr))]
        return max(values) if values else math.nan

    for name, items in list(groups.items()) + [("total", outcomes)]:
        known = [o for o in items if o.known_bug and not o.passed]
        counted = [o for o in items if o not in known]  # errors and times of known bugs are listed apart
        rows.append((
            name, str(len(items)), str(sum(o.passed for o in items)), str(len(known)),
            _fmt(worst(counted, "worst_error"), ".2e"), _fmt(worst(counted, "ref_error"), ".2e"),
            _fmt(worst(counted, "grid_error"), ".2e"), _fmt(worst(counted, "energy_error"), ".2e"),
            _fmt(1e3 * worst(counted, "max_step_s"), ".3f"),
            _fmt(1e3 * max((o.mean_step_s for o in counted if not math.isnan(o.mean_step_s)), default=math.nan), ".4f"),
            str(sum(o.n_events for o in items)), f"{sum(o.seconds for o in items):.1f}",
        ))
    return rows


def _table(header, rows):
    widths = [max(len(str(r[i])) for r in [header] + rows) for i in range(len(header))]
    lines = ["| " + " | ".join(str(c).ljust(w) for c, w in zip(r, widths)) + " |" for r in [header] + rows]
    lines.insert(1, "|" + "|".join("-" * (w + 2) for w in widths) + "|")
    return "\n".join(lines)


def summary_table(outcomes):
    """Markdown table by group: cases, passes, known-bug failures, worst errors (normalized; known-bug
    failures left out), worst single and worst mean wall time of one ``fmi2DoStep``."""
    return _table(TABLE_COLUMNS, summary_rows(outcomes))


#: the summary table's columns on the console, within :data:`CONSOLE_WIDTH` (the report has every column of
#: :data:`TABLE_COLUMNS`): {column: its header on the console}
CONSOLE_COLUMNS = {"group": "group", "cases": "cases", "passed": "passed", "known bugs": "known bugs",
                   "worst error": "worst error", "worst time/step (ms)": "max step (ms)", "events": "events",
                   "wall (s)": "wall (s)"}


def console_summary(outcomes, width=CONSOLE_WIDTH):
    """What the console shows, within ``width`` columns: the summary table's :data:`CONSOLE_COLUMNS`, then the
    failure lines (:func:`failure_lines`), wrapped."""
    keep = [TABLE_COLUMNS.index(column) for column in CONSOLE_COLUMNS]
    rows = [tuple(row[i] for i in keep) for row in summary_rows(outcomes)]
    lines = _table(tuple(CONSOLE_COLUMNS.values()), rows).splitlines()
    for line in failure_lines(outcomes):
        lines += textwrap.wrap(line, width, subsequent_indent="  ", break_on_hyphens=False)
    return "\n".join(lines)


def case_table(outcomes):
    """Markdown table with one row per case."""
    header = ("case", "result", "worst error", "ref", "grid", "energy", "events", "steps", "max step (ms)", "wall (s)")
    rows = [(o.name, "PASS" if o.passed else ("known bug" if o.known_bug else "FAIL"),
             _fmt(o.worst_error, ".2e"), _fmt(o.ref_error, ".2e"),
             _fmt(o.grid_error, ".2e"), _fmt(o.energy_error, ".2e"), str(o.n_events), str(o.n_steps),
             _fmt(1e3 * o.max_step_s, ".3f"), f"{o.seconds:.2f}") for o in outcomes]
    return _table(header, rows)


def failure_lines(outcomes):
    """One line per failed case (known bugs marked) and per known-bug case that now passes."""
    lines = []
    for o in outcomes:
        if not o.passed:
            mark = f" [known bug: {o.known_bug}]" if o.known_bug else ""
            lines.append(f"- {o.name}{mark}: {'; '.join(o.failures)}")
        elif o.known_bug:
            lines.append(f"- {o.name}: PASSED although marked with a known bug ({o.known_bug}): update the case")
    return lines
