"""A system run's files: the master's samples as CSV and a readable markdown report (format: docs/systems.md)."""

import math

import numpy as np

from .chaos import report_lines


def columns(n):
    """CSV column names: ``time``, every ``b<i>.x``, then every ``b<i>.v`` and ``b<i>.mode``."""
    return ["time", *(f"b{i}.{q}" for q in ("x", "v", "mode") for i in range(1, n + 1))]


def write_csv(path, result):
    """``path``: one row per grid time, :func:`columns` (positions m, velocities m/s, modes -1/0/+1)."""
    n = result.x.shape[1]
    table = np.column_stack([result.t, result.x, result.v, result.mode])
    formats = ["%.17g"] * (1 + 2 * n) + ["%d"] * n
    np.savetxt(path, table, delimiter=",", header=",".join(columns(n)), comments="", fmt=formats)


def _seconds(value):
    return "n/a" if math.isnan(value) else f"{value:.2e}"


#: why a master without a tolerance (zoh, unless its file sets one) is reported and not judged
NOT_JUDGED = ("not judged against the tolerance (a held-input coupling of order 1: its error is the step's; "
              "use --master me or adaptive for exact results, or a smaller --step)")


#: what the report and the console say when the reference was not run
NOT_COMPARED = "the reference was not run (--no-reference): nothing compared"


def summary(system, result, comparison):
    """The console's text: one line with the file, the master with its settings, the error against the
    tolerance, the verdict and the wall time; a second line with :data:`NOT_JUDGED` where the run is not judged
    (comparison None: :data:`NOT_COMPARED` instead of the error)."""
    settings = ", ".join(f"{k} {_shown(v)}" for k, v in result.settings.items())
    if comparison is None:
        return (f"{system.name}: {result.master} ({settings}): {NOT_COMPARED}; {int(np.sum(result.event_counts))} "
                f"block events; {result.wall_time:.2f} s")
    line = (f"{system.name}: {result.master} ({settings}): max |dx| {np.max(comparison.max_abs_dx):.3g} m = "
            f"{comparison.max_rel_dx:.3g} of {_scale(comparison)} {verdict(comparison)}; {result.wall_time:.2f} s")
    return line if comparison.judged else f"{line}\n{result.master}: {NOT_JUDGED}"


def verdict(comparison):
    """``(tolerance 0.1): PASS`` or ``FAIL``; ``(not judged)`` where there is no tolerance, with ``: FAIL`` if an
    error is not finite (the run itself failed); a diverging chain's: its statistics' verdict."""
    if comparison.statistics is not None:
        return (f"(not held to the tolerance: the trajectory diverges; statistics at significance "
                f"{comparison.statistics.significance:g}): {'PASS' if comparison.ok else 'FAIL'}")
    if comparison.judged:
        return f"(tolerance {comparison.tolerance:g}): {'PASS' if comparison.ok else 'FAIL'}"
    return "(not judged)" if comparison.ok else "(not judged): FAIL, an error is not finite"


def _scale(comparison):
    """What the errors are a fraction of, in words: the amplitude, or the floor where the amplitude is smaller."""
    if comparison.amplitude >= comparison.floor:
        return f"the amplitude {comparison.amplitude:.3g} m"
    return f"the floor {comparison.floor:.3g} m (the amplitude is {comparison.amplitude:.3g} m)"


def write_report(path, system, result, comparison, reference_seconds, figures):
    """``path``: the markdown report of one run; ``figures``: {caption: file name beside the report}; comparison
    None: the reference was not run."""
    lines = [f"# {system.name}: master `{result.master}`", ""]
    if system.description:
        lines += [system.description, ""]
    lines += [
        f"{system.n} blocks, coupling {list(system.coupling)} N/m, v_drive = {system.v_drive:g} m/s, "
        f"{system.stop_time:g} s sampled every {system.output_interval:g} s (file `{system.path}`).", ""]
    lines += _uncompared(result) if comparison is None else _compared(system, result, comparison, reference_seconds)
    if not result.events_complete:
        lines += ["", "Some steps held more than one event of a block: those events are counted, not timed."]
    lines += [""] + [f"![{caption}]({name})" for caption, name in figures.items()]
    path.write_text("\n".join(lines) + "\n")


def _uncompared(result):
    """The report's lines of a run without the reference: the settings and counts, each block's events."""
    return [f"**NOT COMPARED**: {NOT_COMPARED}.", "", "| | |", "|---|---|",
            *(f"| {label} | {_shown(value)} |" for label, value in {**result.settings, **result.stats}.items()),
            f"| wall time of the master (s) | {result.wall_time:.3f} |", "", "| block | events |", "|---|---|",
            *(f"| b{i + 1} | {count} |" for i, count in enumerate(result.event_counts))]


def _compared(system, result, comparison, reference_seconds):
    """The report's lines of a run against the reference: the verdict, settings and counts, each block's errors."""
    lines = [
        f"**{_headline(comparison)}**: max |dx| = {np.max(comparison.max_abs_dx):.3e} m, "
        f"{comparison.max_rel_dx:.3e} of {_scale(comparison)} {verdict(comparison)}.", "",
        *([] if comparison.judged else [f"{result.master}: {NOT_JUDGED}.", ""]),
        *([] if comparison.divergence is None else report_lines(comparison.divergence, comparison.statistics)),
        "| | |", "|---|---|",
        *(f"| {label} | {_shown(value)} |" for label, value in {**result.settings, **result.stats}.items()),
        f"| wall time of the master (s) | {result.wall_time:.3f} |",
        f"| wall time of the reference (s) | {reference_seconds:.3f} |", "",
        "| block | max abs(dx) (m) | of the amplitude (or floor) | events (master / reference) | max event-time error (s) |",
        "|---|---|---|---|---|",
    ]
    for i in range(system.n):
        lines.append(f"| b{i + 1} | {comparison.max_abs_dx[i]:.3e} | {comparison.max_abs_dx[i] / comparison.scale:.3e} "
                     f"| {comparison.master_events[i]} / {comparison.reference_events[i]} "
                     f"| {_seconds(comparison.max_event_dt[i])} |")
    return lines


def _headline(comparison):
    """The report's verdict in one word: PASS, FAIL or NOT JUDGED (an unjudged run with a non-finite error: FAIL)."""
    if comparison.judged or not comparison.ok:
        return "PASS" if comparison.ok else "FAIL"
    return "NOT JUDGED"


def _shown(value):
    """A setting or count as the report shows it: a number in ``%g``, text as it is."""
    return value if isinstance(value, str) else f"{value:g}"
