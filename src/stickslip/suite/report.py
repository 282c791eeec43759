"""Suite outputs: the FMU result as a CSV file and the summary table (terminal and ``report.md``)."""

from dataclasses import dataclass

from fmpy.util import write_csv


@dataclass(frozen=True)
class Outcome:
    """What one scenario gave: its comparison (None if a run failed), run times (s), error text.

    ``known_miss``: why this run is known to miss its checks (e.g. a limit of the host's solver); such a
    run passes while it misses them and fails, like a strict xfail, once it meets them.
    """

    name: str
    expected_attractor: str
    comparison: object = None
    fmu_seconds: float = float("nan")
    ref_seconds: float = float("nan")
    error: str = ""
    known_miss: str = ""

    @property
    def met_checks(self):
        return not self.error and self.comparison is not None and self.comparison.passed

    @property
    def passed(self):
        if self.known_miss:
            return not self.error and self.comparison is not None and not self.comparison.passed
        return self.met_checks

    @property
    def verdict(self):
        if self.known_miss:
            return "KNOWN MISS" if self.passed else "FAIL (known miss met its checks)"
        return "PASS" if self.passed else "FAIL"

    @property
    def problems(self):
        """Why the scenario failed (empty if it passed)."""
        if self.error:
            return (self.error,)
        if self.known_miss and self.met_checks:
            return (f"marked as a known miss ({self.known_miss}) but met every check: remove the mark",)
        return self.comparison.failures


COLUMNS = ("scenario", "max abs dx (m)", "max abs dv (m/s)", "final abs dx (m)", "event dt (s)",
           "events matched/unmatched", "attractor expected", "attractor found", "FMU (s)", "reference (s)",
           "result")


def write_result_csv(path, result, columns):
    """Write the FMU result's ``columns`` in the FMI cross-check format: quoted header, ``time`` first, commas."""
    write_csv(str(path), result, columns=list(columns))


def _row(o):
    c = o.comparison
    if c is None:
        return (o.name, "-", "-", "-", "-", "-", o.expected_attractor, "-", f"{o.fmu_seconds:.2f}",
                f"{o.ref_seconds:.2f}", o.verdict)
    found = c.attractor_fmu if c.attractor_fmu == c.attractor_ref else f"{c.attractor_fmu} (ref: {c.attractor_ref})"
    return (o.name, f"{c.max_abs_dx:.2e}", f"{c.max_abs_dv:.2e}", f"{c.final_abs_dx:.2e}",
            f"{c.events.max_time_error:.2e}", f"{c.events.n_matched}/{c.events.n_unmatched}",
            o.expected_attractor, found, f"{o.fmu_seconds:.2f}", f"{o.ref_seconds:.2f}", o.verdict)


def summary_table(outcomes):
    """The outcomes as a Markdown table (one row per scenario)."""
    rows = [COLUMNS] + [_row(o) for o in outcomes]
    widths = [max(len(r[i]) for r in rows) for i in range(len(COLUMNS))]
    lines = ["| " + " | ".join(cell.ljust(w) for cell, w in zip(r, widths)) + " |" for r in rows]
    lines.insert(1, "|" + "|".join("-" * (w + 2) for w in widths) + "|")
    return "\n".join(lines)


def failure_lines(outcomes):
    """One line per failed scenario: its name and what missed."""
    return [f"- {o.name}: {'; '.join(o.problems)}" for o in outcomes if not o.passed]


def write_report(path, outcomes, seconds):
    """Write ``report.md``: the summary table, the failures and links to the figures."""
    n_passed = sum(o.passed for o in outcomes)
    text = [
        "# Scenario suite: FMU vs reference",
        "",
        f"{n_passed} of {len(outcomes)} scenarios passed in {seconds:.1f} s wall time. Errors are FMU - reference"
        " on the FMU's output grid; event dt is the largest event-time difference over the events the FMU"
        " times exactly (one mode change in a communication step).",
        "",
        summary_table(outcomes),
        "",
    ]
    failures = failure_lines(outcomes)
    if failures:
        text += ["## Failures", "", *failures, ""]
    known = [f"- {o.name}: {o.known_miss} ({'; '.join(o.comparison.failures)})"
             for o in outcomes if o.known_miss and o.passed]
    if known:
        text += ["## Known misses (they pass while they miss, like strict xfails)", "", *known, ""]
    text += ["## Figures", "", *(f"- [{o.name}]({o.name}.png)" for o in outcomes if o.comparison is not None), ""]
    path.write_text("\n".join(text))
