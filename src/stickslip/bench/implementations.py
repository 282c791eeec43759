"""The benchmark report's section on the two implementations: compiled (mypyc) against pure Python.

Pairs of records with the same settings (FMU at the grid step, stepper with and without
step replay) are compared in one run: time ratio compiled / pure, and the cost of one
Runge-Kutta step where every step is integrated (median time over the steps taken).
"""

import statistics

PAIRS = (("fmu", "fmu-pure"), ("stepper", "stepper-pure"), ("stepper-integrating", "stepper-integrating-pure"))


def _key(record):
    return tuple(sorted((k, v) for k, v in record["settings"].items()))


def _ok(record):
    return record.get("error") is None


def compiled_vs_pure(scenes, records):
    """Markdown lines of the section (empty if the run has no pure-Python family)."""
    rows = []
    for scene in scenes:
        recs = records[scene.name]
        for compiled_family, pure_family in PAIRS:
            pure = {_key(r): r for r in recs if r["family"] == pure_family and _ok(r)}
            pairs = [(r, pure[_key(r)]) for r in recs if r["family"] == compiled_family and _ok(r) and _key(r) in pure]
            if not pairs:
                continue
            ratios = [c["median_s"] / p["median_s"] for c, p in pairs]
            same = all(c.get("max_abs_dx") == p.get("max_abs_dx") for c, p in pairs)
            step = [(c["median_s"] / c["n_steps"], p["median_s"] / p["n_steps"]) for c, p in pairs
                    if compiled_family == "stepper-integrating" and c.get("n_steps")]
            cost = (f"{min(s[0] for s in step) * 1e6:.2f} / {min(s[1] for s in step) * 1e6:.2f}"
                    if step else "–")
            rows.append([scene.name, compiled_family, str(len(pairs)), f"{statistics.median(ratios):.2g}",
                         f"{min(ratios):.2g}–{max(ratios):.2g}", "yes" if same else "no", cost])
    if not rows:
        return []
    header = ["scene", "family", "pairs", "compiled / pure (median)", "range", "same errors",
              "µs per integrated step, compiled / pure"]
    return ["", "## Compiled and pure Python (same sources)", "",
            "Each pair: one configuration run by the compiled runtime (mypyc) and by the pure-Python one, side by "
            "side in this run. Same errors: the max |dx| of every pair is identical. µs per integrated step: the "
            "fastest of the no-replay stepper's configurations, median time over the Runge-Kutta steps taken.", "",
            "| " + " | ".join(header) + " |", "|" + "---|" * len(header),
            *("| " + " | ".join(row) + " |" for row in rows)]
