"""A system run's files: the master's samples as CSV and a readable markdown report (format: docs/systems.md)."""

import math

import numpy as np


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


def summary_line(system, result, comparison):
    """One line: the file, the master with its settings, the error against the tolerance, the verdict."""
    settings = ", ".join(f"{k} {_shown(v)}" for k, v in result.settings.items())
    verdict = "PASS" if comparison.ok else "FAIL"
    return (f"{system.name}: {result.master} ({settings}): max |dx| {np.max(comparison.max_abs_dx):.3g} m = "
            f"{comparison.max_rel_dx:.3g} of {_scale(comparison)} (tolerance {comparison.tolerance:g}): {verdict}; "
            f"{result.wall_time:.2f} s")


def _scale(comparison):
    """What the errors are a fraction of, in words: the amplitude, or the floor where the amplitude is smaller."""
    if comparison.amplitude >= comparison.floor:
        return f"the amplitude {comparison.amplitude:.3g} m"
    return f"the floor {comparison.floor:.3g} m (the amplitude is {comparison.amplitude:.3g} m)"


def write_report(path, system, result, comparison, reference_seconds, figures):
    """``path``: the markdown report of one run; ``figures``: {caption: file name beside the report}."""
    n = system.n
    lines = [f"# {system.name}: master `{result.master}`", ""]
    if system.description:
        lines += [system.description, ""]
    lines += [
        f"{n} blocks, coupling {list(system.coupling)} N/m, v_drive = {system.v_drive:g} m/s, "
        f"{system.stop_time:g} s sampled every {system.output_interval:g} s (file `{system.path}`).", "",
        f"**{'PASS' if comparison.ok else 'FAIL'}**: max |dx| = {np.max(comparison.max_abs_dx):.3e} m, "
        f"{comparison.max_rel_dx:.3e} of {_scale(comparison)} (tolerance {comparison.tolerance:g}).", "",
        "| | |", "|---|---|",
        *(f"| {label} | {_shown(value)} |" for label, value in {**result.settings, **result.stats}.items()),
        f"| wall time of the master (s) | {result.wall_time:.3f} |",
        f"| wall time of the reference (s) | {reference_seconds:.3f} |", "",
        "| block | max abs(dx) (m) | of the amplitude (or floor) | events (master / reference) | max event-time error (s) |",
        "|---|---|---|---|---|",
    ]
    for i in range(n):
        lines.append(f"| b{i + 1} | {comparison.max_abs_dx[i]:.3e} | {comparison.max_abs_dx[i] / comparison.scale:.3e} "
                     f"| {comparison.master_events[i]} / {comparison.reference_events[i]} "
                     f"| {_seconds(comparison.max_event_dt[i])} |")
    if not result.events_complete:
        lines += ["", "Some steps held more than one event of a block: those events are counted, not timed."]
    lines += [""] + [f"![{caption}]({name})" for caption, name in figures.items()]
    path.write_text("\n".join(lines) + "\n")


def _shown(value):
    """A setting or count as the report shows it: a number in ``%g``, text as it is."""
    return value if isinstance(value, str) else f"{value:g}"
