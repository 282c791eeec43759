"""Suite outputs: the FMU result as a CSV file, the summary for the terminal (at most 100 columns) and
``report.md`` (every column, the failures, the figures)."""

import textwrap
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
    def result(self):
        """PASS, FAIL or KNOWN MISS; why a run failed is in :attr:`problems`."""
        if self.known_miss and self.passed:
            return "KNOWN MISS"
        return "PASS" if self.passed else "FAIL"

    @property
    def verdict(self):
        """:attr:`result`, saying also when a known miss fails because it met its checks."""
        return "FAIL (known miss met its checks)" if self.known_miss and not self.passed else self.result

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


def _errors(c):
    """The key error figures of the comparison ``c`` as printed: largest |dx| (m), |dv| (m/s), event dt (s)."""
    return f"{c.max_abs_dx:.2e}", f"{c.max_abs_dv:.2e}", f"{c.events.max_time_error:.2e}"


def _times(o):
    """The run times of the outcome ``o`` as printed: FMU, reference (s)."""
    return f"{o.fmu_seconds:.2f}", f"{o.ref_seconds:.2f}"


def _row(o):
    c = o.comparison
    if c is None:
        return (o.name, "-", "-", "-", "-", "-", o.expected_attractor, "-", *_times(o), o.verdict)
    max_dx, max_dv, event_dt = _errors(c)
    found = c.attractor_fmu if c.attractor_fmu == c.attractor_ref else f"{c.attractor_fmu} (ref: {c.attractor_ref})"
    return (o.name, max_dx, max_dv, f"{c.final_abs_dx:.2e}", event_dt, f"{c.events.n_matched}/{c.events.n_unmatched}",
            o.expected_attractor, found, *_times(o), o.verdict)


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


#: the width of the console summary (characters); ``report.md`` has every column
CONSOLE_WIDTH = 100
CONSOLE_COLUMNS = ("scenario", "result", "max|dx| m", "max|dv| m/s", "event dt s", "FMU s", "ref s")


def _console_row(o):
    errors = ("-", "-", "-") if o.comparison is None else _errors(o.comparison)
    return (o.name, o.result, *errors, *_times(o))


def _cut(text, width):
    """``text``, cut to ``width`` characters with ``..`` at the end if longer."""
    return text if len(text) <= width else text[:width - 2] + ".."


def console_summary(outcomes, width=CONSOLE_WIDTH):
    """The outcomes for the terminal within ``width`` characters a line: a table (scenario, result, the largest
    position, velocity and event-time errors, the run times; names cut to fit), then the failures, wrapped."""
    rows = [CONSOLE_COLUMNS] + [_console_row(o) for o in outcomes]
    widths = [max(len(r[i]) for r in rows) for i in range(len(CONSOLE_COLUMNS))]
    widths[0] = max(len(CONSOLE_COLUMNS[0]), min(widths[0], width - sum(widths[1:]) - 2 * (len(widths) - 1)))
    lines = ["  ".join([_cut(r[0], widths[0]).ljust(widths[0]), r[1].ljust(widths[1]),
                        *(cell.rjust(w) for cell, w in zip(r[2:], widths[2:]))]).rstrip() for r in rows]
    lines.insert(1, "-" * (sum(widths) + 2 * (len(widths) - 1)))
    for line in failure_lines(outcomes):
        lines += textwrap.wrap(line, width, subsequent_indent="  ", break_on_hyphens=False)
    return "\n".join(lines)


def tally(outcomes):
    """How many scenarios met their checks, e.g. ``19/20 passed, 1 known miss``: a known miss that passes
    (it missed its checks as expected) is counted as a known miss, not as passed."""
    n_known = sum(bool(o.known_miss) and o.passed for o in outcomes)
    n_met = sum(o.passed for o in outcomes) - n_known
    text = f"{n_met}/{len(outcomes)} passed"
    return text + (f", {n_known} known miss" + ("es" if n_known > 1 else "") if n_known else "")


def write_report(path, outcomes, seconds):
    """Write ``report.md``: the summary table, the failures and links to the figures."""
    text = [
        "# Scenario suite: FMU vs reference",
        "",
        f"{tally(outcomes)} in {seconds:.1f} s wall time. Errors are FMU - reference"
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
