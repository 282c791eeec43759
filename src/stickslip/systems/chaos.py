"""Chaotic chains judged by statistics in ``stickslip system run`` (docs/systems.md).

A chain whose trajectory diverges cannot be held to the reference's positions: any difference, even the rounding
of the last digit, grows until the two runs are unrelated. Whether it diverges is measured: the largest Lyapunov
exponent ``lambda`` over the run of ``T`` seconds (:func:`stickslip.chain.lyapunov.largest_lyapunov`) so large that
a difference at the reference's own tolerance (``1e-12`` of the amplitude) grows past the tolerance ``tol`` the
master is held to (a fraction of the amplitude) within the run: ``lambda T > ln(tol / 1e-12)`` (:func:`efoldings`;
13.8 for the default 1e-6). No solver, the reference included, can then be held to ``tol``. (A chain that does not
diverge gets nowhere near: on a stick-slip cycle a small difference becomes a shift along the cycle, which grows
at most by the ratio of the slip speed to the drive's.) Such a run is judged by its
statistics instead: the slip events of the master's run (:mod:`stickslip.chain.catalogue`) against those of the
reference run at the two tolerances :data:`REFERENCE_RTOLS`, by two-sample Kolmogorov-Smirnov tests on their sizes,
durations and (where the master knows each event's position) moments. The run passes when no test rejects at the
family significance :data:`SIGNIFICANCE` (each test at that over the number of tests, Bonferroni's bound).

Values are compared to :data:`DIGITS` significant digits: a chain's small slips repeat with nearly the same moment
and duration, and the solvers' last digits would otherwise sort one run's copies all below the other's.
"""

import math
from dataclasses import dataclass

import numpy as np

#: the reference's tolerances: its usual one (every run), and the second of a diverging chain's check
REFERENCE_RTOLS = (1e-12, 1e-10)
#: the family significance of the two-sample tests
SIGNIFICANCE = 0.01
#: the fewest slip events in each run that the tests judge
MIN_EVENTS = 20
#: significant digits at which values are compared (module docstring)
DIGITS = 6
#: the quantities tested, in the report's order
QUANTITIES = ("size", "duration", "moment")


@dataclass(frozen=True)
class Divergence:
    """Whether the chain's trajectory diverges over the run: the :class:`~stickslip.chain.lyapunov.LyapunovEstimate`
    (None where it was not measured) and why, in words."""

    estimate: object
    diverges: bool
    why: str


def efoldings(tolerance):
    """The e-foldings over the run past which a difference at the reference's tolerance outgrows ``tolerance`` (a
    fraction of the amplitude): ``ln(tolerance / REFERENCE_RTOLS[0])``."""
    return math.log(tolerance / REFERENCE_RTOLS[0])


def measure_divergence(system, tolerance, progress=None):
    """The :class:`Divergence` of the chain of ``system`` over its ``stop_time``, measured with the chain engine
    (``progress(t)`` after each renormalisation), for a master held to ``tolerance`` (a fraction of the amplitude).
    Chains with aging static friction are not measured: the method restarts the runs, which would restart the
    aging."""
    from ..chain.lyapunov import largest_lyapunov
    from ..chain.spec import ChainSpec

    spec = ChainSpec.from_system(system)
    aging = np.flatnonzero(spec.static_law != 1)
    if aging.size:
        return Divergence(None, False, f"the largest Lyapunov exponent is not measured: block b{aging[0] + 1} has an "
                                       "aging static law (the method restarts the runs, which would reset it)")
    estimate = largest_lyapunov(spec, system.stop_time, progress=progress)
    growth = estimate.growth()
    text = (f"the largest Lyapunov exponent over the run is {estimate.exponent:.3g} +- {estimate.uncertainty:.2g} "
            f"1/s: a difference of {REFERENCE_RTOLS[0]:g} of the amplitude (the reference's tolerance) grows by "
            f"e^{growth:.3g} over the {estimate.stop_time:g} s")
    if growth <= efoldings(tolerance):
        return Divergence(estimate, False, f"{text}, not past the tolerance {tolerance:g}: the trajectory does not "
                                           "diverge")
    return Divergence(estimate, True, f"{text}, past the tolerance {tolerance:g}: the trajectory diverges")


@dataclass(frozen=True)
class StatisticalCheck:
    """The two-sample tests of a diverging chain's run: ``counts`` {run: slip events}, ``p_values`` {(reference
    label, quantity): p} of the master against each reference, ``between_references`` {quantity: p} of the two
    references (shown, not judged), ``reference_spread``: max |x| difference of the two references over the
    amplitude; ``quantities`` tested, the family ``significance``; ``cannot``: why the master's run cannot be
    judged ("" where it can)."""

    counts: dict
    p_values: dict
    between_references: dict
    reference_spread: float
    quantities: tuple
    significance: float = SIGNIFICANCE
    cannot: str = ""

    @property
    def threshold(self):
        """Each test's significance (Bonferroni)."""
        return self.significance / max(1, len(self.p_values))

    @property
    def enough_events(self):
        return min(self.counts.values()) >= MIN_EVENTS

    @property
    def ok(self):
        return not self.cannot and self.enough_events and all(p >= self.threshold for p in self.p_values.values())


def rounded(values):
    """``values`` to :data:`DIGITS` significant digits."""
    return np.array([float(f"{v:.{DIGITS}g}") for v in np.asarray(values, float).tolist()])


def two_sample_tests(master, references, quantities=QUANTITIES):
    """``{(label, quantity): p}``: Kolmogorov-Smirnov p-values of the slip-event table ``master`` (``{column:
    array}``) against each table of ``references`` ({label: table}) on each of ``quantities`` (to :data:`DIGITS`
    digits; NaN where a table is empty)."""
    from scipy.stats import ks_2samp  # here: a run that is not judged by its statistics does not import it

    out = {}
    for label, table in references.items():
        for q in quantities:
            a, b = master[q], table[q]
            out[(label, q)] = float(ks_2samp(rounded(a), rounded(b)).pvalue) if a.size and b.size else math.nan
    return out


def statistical_check(master, references, spread, quantities=QUANTITIES):
    """The :class:`StatisticalCheck` of the master's slip events ``master`` against the references' (``{label:
    table}``, two of them); ``spread``: the references' max |x| difference over the amplitude."""
    first, second = references.values()
    between = {q: p for (_, q), p in two_sample_tests(first, {"": second}, quantities).items()}
    counts = {"master": int(master["size"].size)} | {label: int(t["size"].size) for label, t in references.items()}
    return StatisticalCheck(counts, two_sample_tests(master, references, quantities), between, float(spread),
                            tuple(quantities))


def report_lines(divergence, check):
    """The report's paragraph on which check ran and why, and the tests' table where they ran."""
    if check is None:
        return [f"**Check: the amplitude.** {divergence.why[0].upper()}{divergence.why[1:]}.", ""]
    verdict = "PASS" if check.ok else "FAIL"
    head = f"**Check: statistics, not the amplitude ({verdict}).** {divergence.why[0].upper()}{divergence.why[1:]}"
    if check.cannot:
        return [f"{head}. The master's run cannot be judged by its statistics: {check.cannot}.", ""]
    lines = [f"{head}; the reference itself moves {check.reference_spread:.3g} of the amplitude between its tolerances "
             f"{' and '.join(label.split()[-1] for label in list(check.counts)[1:])}. Two-sample Kolmogorov-Smirnov "
             f"tests of the slip events' {', '.join(check.quantities)} (to {DIGITS} significant digits), the master "
             f"against the reference at each tolerance, at a family significance {check.significance:g} (each test "
             f"at {check.threshold:.3g}):", ""]
    if not check.enough_events:
        lines += [f"Too few slip events for the tests (at least {MIN_EVENTS} in each run): FAIL.", ""]
    labels = list(check.counts)[1:]
    lines += ["| quantity | " + " | ".join(f"p, master against {label}" for label in labels) +
              " | p, reference against reference |", "|---" * (len(labels) + 2) + "|"]
    for q in check.quantities:
        lines.append(f"| {q} | " + " | ".join(f"{check.p_values[(label, q)]:.3g}" for label in labels) +
                     f" | {check.between_references[q]:.3g} |")
    lines += ["", "slip events: " + ", ".join(f"{label} {count}" for label, count in check.counts.items()) + ".", ""]
    return lines


def judge_by_statistics(system, result, events_file, references):
    """The :class:`StatisticalCheck` of a master's run of ``system`` (:class:`~.master.SystemResult`) against the
    reference runs ``references`` ({rtol: :class:`~stickslip.reference.ChainResult`}, two): the master's block
    events from ``events_file`` (CSV with positions, the native master's) or, without it, from the result (no
    positions: moments are not tested)."""
    from ..chain.catalogue import group_slip_events, read_block_events
    from ..chain.folder_run import slipping_at_start
    from ..chain.reference_check import reference_block_events

    if events_file is None and not result.events_complete:
        return StatisticalCheck({"master": 0}, {}, {}, math.nan, (),
                                cannot="it knows some block events only by count, not their times")
    starting = slipping_at_start(system)

    def table(events):
        return group_slip_events(*events, v_drive=system.v_drive, slipping_at_start=starting)[0]

    if events_file is not None:
        chunks = [np.concatenate(part) for part in zip(*read_block_events(events_file))]
        master = table(chunks or [np.zeros(0), np.zeros(0, int), [], np.zeros(0)])
        quantities = QUANTITIES
    else:
        events = result.events
        master = table([[e.t for e in events], [e.block + 1 for e in events], [e.kind for e in events],
                        np.zeros(len(events))])
        quantities = tuple(q for q in QUANTITIES if q != "moment")
    tables = {f"reference at rtol {rtol:g}": table(reference_block_events(run)) for rtol, run in references.items()}
    first, second = references.values()
    spread = float(np.max(np.abs(first.x - second.x))) / max(first.amplitude(), system.length_scale * 1e-6)
    return statistical_check(master, tables, spread, quantities)


def plot_exponent(png_path, title, estimate):
    """Write ``png_path``: the estimate of the largest Lyapunov exponent up to each time of the run (1/s), with the
    final value and its standard error."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 4), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    ax.plot(estimate.times, estimate.running, color="C0", label="estimate up to t")
    low, high = estimate.exponent - estimate.uncertainty, estimate.exponent + estimate.uncertainty
    ax.axhspan(low, high, color="C3", alpha=0.2, label=f"over the run: {estimate.exponent:.3g} +- "
                                                      f"{estimate.uncertainty:.2g} 1/s")
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set(xlabel="t (s)", ylabel="largest Lyapunov exponent (1/s)",
           title=f"{title}: largest Lyapunov exponent (renormalised every {estimate.interval:.3g} s)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    fig.savefig(png_path, dpi=100)
