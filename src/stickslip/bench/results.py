"""The benchmark's outputs: raw numbers (JSON), ratio tables (Markdown), work-precision plots (PNG)."""

import json
import math

import numpy as np

THRESHOLDS = (1e-4, 1e-6, 1e-8)  # max |dx| relative to the amplitude
PEERS = ("solve_ivp", "regularized")
STYLE = {  # family -> (color, legend)
    "fmu": ("tab:red", "our FMU via fmpy.simulate_fmu"),
    "stepper": ("tab:orange", "our stepper (Trajectory) from Python"),
    "stepper-integrating": ("tab:brown", "our stepper, every step integrated (no replay)"),
    "fmu-pure": ("tab:pink", "our FMU, runtime in pure Python"),
    "stepper-pure": ("tab:olive", "our stepper in pure Python"),
    "solve_ivp": ("tab:blue", "solve_ivp hybrid with events"),
    "regularized": ("tab:green", "regularized friction, solve_ivp"),
    "fmi3-me": ("tab:purple", "FMI 3 model exchange, FMPy CVode"),
    "cvode-bare": ("tab:gray", "FMPy's CVode on the model in Python, no FMU"),
}
MARKERS = {"RK45": "o", "DOP853": "s", "LSODA": "^", "Radau": "D"}


def ok(record):
    """True for a configuration that ran and was compared with the reference."""
    return record.get("error") is None and math.isfinite(record.get("rel_dx", math.nan))


def output_step(record, scene):
    """The step (s) of the grid a record returned: the FMU's communication step, a coarse peer's ``out_step``,
    else the scene's grid step."""
    settings = record["settings"]
    return settings.get("comm_step", settings.get("out_step", scene.grid_step))


def comparable(record, scene):
    """Configurations with outputs on the whole common grid (the FMU at ``h = grid_step``, the peers on it)."""
    return ok(record) and output_step(record, scene) == scene.grid_step


def fastest(records, family, threshold, scene, step=None):
    """The fastest record of ``family`` with ``rel_dx <= threshold`` on the grid of ``step`` s (default: the
    scene's common grid; a coarser one is compared on its own points). None: not reached."""
    step = scene.grid_step if step is None else step
    hits = [r for r in records if r["family"] == family and ok(r) and output_step(r, scene) == step
            and r["rel_dx"] <= threshold]
    return min(hits, key=lambda r: r["median_s"], default=None)


def failures(records, family, scene, step=None):
    """Records of ``family`` on the grid of ``step`` s (default: the common grid) that raised."""
    step = scene.grid_step if step is None else step
    return [r for r in records if r["family"] == family and r.get("error") and output_step(r, scene) == step]


MIN_COST_POINTS = 3  # a straight line through two points cannot show whether the time is linear in the steps


def per_step_cost(records, family, scene, time="median_s"):
    """``(seconds per communication step, seconds per call, note)`` of ``family`` ("fmu", "floor", "c-host",
    "c-host-floor") over the communication-step sweep: the slope and the intercept of the record's ``time``
    (median wall time; "cpu_s" for the C host) against the number of steps, fitted with both non-negative.
    The intercept is the fixed cost of a whole call (instantiate, initialize, terminate, free, and the
    events). Both are None, with the note saying why, from fewer than :data:`MIN_COST_POINTS` sweep points."""
    from scipy.optimize import nnls

    steps = set(scene.comm_steps())
    points = [(r["n_comm_steps"], r[time]) for r in records
              if r["family"] == family and r.get("error") is None and r["settings"]["comm_step"] in steps
              and r["settings"].get("rtol", scene.sweep.comm_rtol) == scene.sweep.comm_rtol]
    if len(points) < MIN_COST_POINTS:
        return None, None, f"cannot be estimated from {len(points)} communication steps (needs {MIN_COST_POINTS})"
    n, t = np.array(points, float).T
    scale = n.max()  # fit in units of the largest step count: both columns of order 1
    (slope, intercept), _ = nnls(np.column_stack([n / scale, np.ones_like(n)]), t)
    return slope / scale, intercept, f"fit over {len(points)} communication steps"


def _cost_columns(cost, floor, unit=1e6):
    """Table cells ``(ours, floor, ratio)`` of two costs (s) in ``unit`` (1e6: µs); "–" where one is unknown."""
    if cost is None or floor is None:
        return ["–"] * 3
    return [f"{unit * cost:.3g}", f"{unit * floor:.3g}", f"{cost / floor:.2g}" if floor > 0 else "–"]


def write_json(path, meta, scenes, records):
    """``meta`` and, per scene, its setup and every record (times in s, errors in m, m/s, s)."""
    data = {"meta": meta, "scenes": {s.name: {
        "scenario_file": s.scenario_file, "stop_time_s": s.stop_time, "grid_step_s": s.grid_step,
        "amplitude_m": s.amplitude, "reference_events": len(s.reference.events), "records": records[s.name],
    } for s in scenes}}
    path.write_text(json.dumps(data, indent=1))


def _ms(record):
    return f"{1e3 * record['median_s']:.3g} ms"


def _cell(record, failed=()):
    """The fastest record reaching an accuracy (or "not reached"), and the failed configurations with reasons."""
    named = _failed_text(failed)
    if record is not None:
        return f"{_ms(record)} ({record['label']})" + (f"; failed: {named}" if failed else "")
    return f"not reached; failed: {named}" if failed else "not reached"


def _failed_text(failed, shown=2):
    """Failed configurations grouped by exception: ``"RK45 rtol=1e-04, RK45 rtol=1e-05 +3 more (OverflowError:
    math range error)"``; the report's last section lists every one."""
    by_reason = {}
    for r in failed:
        by_reason.setdefault(_reason(r), []).append(r["label"])
    return "; ".join(", ".join(labels[:shown]) + (f" +{len(labels) - shown} more" if len(labels) > shown else "")
                     + f" ({reason})" for reason, labels in by_reason.items())


def _reason(record):
    """The last line of a failed record's exception, e.g. ``OverflowError: math range error``."""
    return record["error"].splitlines()[-1].replace("|", "\\|")


def coarse_step(scene):
    """The communication step (s) of the like-with-like column: the sweep's coarsest one above the grid's
    step, where the FMU and solve_ivp both return only that grid's points (None: the sweep has none)."""
    coarser = [h for h in scene.comm_steps() if h > scene.grid_step]
    return max(coarser, default=None)


def _ratio(ours, peer):
    return "–" if ours is None or peer is None else f"{ours['median_s'] / peer['median_s']:.2g}"


def _table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return lines + ["| " + " | ".join(map(str, row)) + " |" for row in rows]


SMOKE_NOTE = ("**Smoke run (`stickslip bench --quick`)**: 20 s scenes, a few configurations, one timed run each. "
              "It shows that the benchmark runs; its numbers are not measurements.")


def markdown(meta, scenes, records):
    """The Markdown report: matched-accuracy ratios, per-step costs, communication steps, best accuracies."""
    out = ["# Work-precision benchmark" + (" (smoke run, not a measurement)" if meta.get("quick") else ""), ""]
    if meta.get("quick"):
        out += [SMOKE_NOTE, ""]
    out += [f"{meta['date']}, {meta['machine']}, Python {meta['python']}, {meta['versions']}; "
            f"median of {meta['repeats']} runs after a warm-up; load average at start {meta['load']}.", "",
            "Error: max |dx| on the scene's common grid over the amplitude A (half the reference's range of x). "
            "Times: one whole simulation call. Ratios are ours / peer (< 1: ours is faster), each side at its "
            "fastest configuration reaching the accuracy. The FMU, stepper, solve_ivp and regularized columns "
            "return the whole common grid (the FMU at the grid's communication step). The coarse columns compare "
            "like with like on the sweep's coarsest communication step H (e.g. 10 s): the FMU at h = H and "
            "solve_ivp asked for the same H-spaced output times, both measured on those points of the grid. "
            "A cell also names the configurations of its family that failed, with the exception.", ""]
    out += matched_accuracy_section(scenes, records)
    out += cost_section(scenes, records)
    out += comm_step_section(scenes, records)
    out += model_exchange_section(scenes, records)
    out += best_accuracy_section(scenes, records)
    failed = [(s.name, r) for s in scenes for r in records[s.name] if r.get("error")]
    if failed:
        out += ["", "## Failed configurations", ""]
        out += [f"- {name}: {r['label']}: {_reason(r)}" for name, r in failed]
    return "\n".join(out) + "\n"


def matched_accuracy_section(scenes, records):
    """Markdown lines: per scene and accuracy, the fastest configuration of each family and the ratios."""
    rows = []
    for s in scenes:
        h_c = coarse_step(s)
        for thr in THRESHOLDS:
            best = {f: fastest(records[s.name], f, thr, s) for f in ("fmu", "stepper", *PEERS)}
            failed = {f: failures(records[s.name], f, s) for f in best}
            coarse_fmu = fastest(records[s.name], "fmu", thr, s, h_c) if h_c else None
            coarse_ivp = fastest(records[s.name], "solve_ivp", thr, s, h_c) if h_c else None
            integrating = fastest(records[s.name], "stepper-integrating", thr, s)
            rows.append([s.name, f"{thr:g}", *(_cell(best[f], failed[f]) for f in best),
                         "–" if h_c is None else f"{h_c:g}", _cell(coarse_fmu),
                         _cell(coarse_ivp, failures(records[s.name], "solve_ivp", s, h_c) if h_c else ()),
                         _ratio(best["fmu"], best["solve_ivp"]), _ratio(coarse_fmu, coarse_ivp),
                         _ratio(best["stepper"], best["solve_ivp"]), _ratio(integrating, best["solve_ivp"]),
                         _ratio(best["fmu"], best["regularized"]), _ratio(best["stepper"], best["regularized"])])
    return ["## Matched accuracy", ""] + _table(
        ["scene", "max\\|dx\\|/A ≤", "FMU", "stepper", "solve_ivp", "regularized", "coarse H (s)",
         "FMU at h = H", "solve_ivp on the H grid", "FMU / solve_ivp", "FMU / solve_ivp, both on the H grid",
         "stepper / solve_ivp", "stepper no replay / solve_ivp", "FMU / regularized", "stepper / regularized"], rows)


def cost_section(scenes, records):
    """Markdown lines: the cost per communication step and per call, FMU beside the trivial FMU (FMPy, C host)."""
    out = ["", "## Cost per communication step (slope over the communication-step sweep)", ""]
    out += ["FMPy: wall time of fmpy.simulate_fmu recording six outputs. C host: CPU time of fmi2DoStep + "
            "fmi2GetReal(x) in a plain C importer (stickslip.hosts.c_host), Python start-up excluded. Each cost is a "
            "least-squares line with a non-negative slope and intercept over the communication-step sweep (at the "
            "sweep's comm_rtol); a slope the data cannot resolve comes out 0. Per call: the intercept, the fixed "
            "cost of one simulate_fmu call (instantiate, initialize, terminate, free, and the scene's events).", ""]
    rows = []
    for s in scenes:
        (fmu, fmu_call, note), (floor, floor_call, _), (c_fmu, _, _), (c_floor, _, _) = (
            per_step_cost(records[s.name], family, s, time)
            for family, time in (("fmu", "median_s"), ("floor", "median_s"),
                                 ("c-host", "cpu_s"), ("c-host-floor", "cpu_s")))
        rows.append([s.name, *_cost_columns(fmu, floor), *_cost_columns(fmu_call, floor_call, unit=1e3),
                     *_cost_columns(c_fmu, c_floor), note])
    return out + _table(["scene", "FMPy: FMU µs/step", "FMPy: trivial FMU µs/step", "ratio", "FMPy: FMU ms/call",
                         "FMPy: trivial FMU ms/call", "ratio", "C host: FMU CPU µs/step",
                         "C host: trivial FMU CPU µs/step", "ratio", "estimate"], rows)


def comm_step_section(scenes, records):
    """Markdown lines: the FMU at each communication step of the sweep, beside the trivial FMU."""
    rows = []
    for s in scenes:
        floor = {r["settings"]["comm_step"]: r for r in records[s.name]
                 if r["family"] == "floor" and r.get("error") is None}
        for r in records[s.name]:
            h = r["settings"].get("comm_step")
            if r["family"] == "fmu" and ok(r) and r["settings"]["rtol"] == s.sweep.comm_rtol and h in floor:
                rows.append([s.name, f"{h:g}", r["n_comm_steps"], _ms(r), _ms(floor[h]), f"{r['max_abs_dx']:.2g}",
                             _fmt(r.get("event_time_error")), f"{r['final_abs_dx']:.2g}"])
    return ["", "## FMU across communication steps (at the sweep's comm_rtol, default 1e-10)", ""] + _table(
        ["scene", "h (s)", "steps", "FMU", "trivial FMU", "max\\|dx\\| (m)", "event-time error (s)",
         "final \\|dx\\| (m)"], rows)


def best_accuracy_section(scenes, records):
    """Markdown lines: the smallest error each family reached, where, and its event-time error."""
    rows = []
    for s in scenes:
        for family in STYLE:
            done = [r for r in records[s.name] if r["family"] == family and ok(r)
                    and (family == "fmu" or comparable(r, s))]  # the FMU at every h: same error on fewer points
            if done:
                best = min(done, key=lambda r: r["rel_dx"])
                rows.append([s.name, family, f"{best['rel_dx']:.2g}", _cell(best), _fmt(best.get("event_time_error")),
                             best.get("events_unmatched", "–")])
    return ["", "## Best accuracy of each family", ""] + _table(
        ["scene", "family", "best max\\|dx\\|/A", "at", "event-time error (s)", "unmatched events"], rows)


def model_exchange_section(scenes, records):
    """Markdown lines: the FMI 3 model exchange's error and time over CVode's tolerance beside the same CVode
    with no FMU (``cvode-bare``: their error ratio near 1 says the error is the solver's), and the ratio to
    our co-simulation at the grid's step at matched accuracy."""
    out = ["", "## FMI 3 model exchange (FMPy CVode) beside our co-simulation", "",
           "Bare CVode: the same solver, driven the same way, on the model written in Python from the "
           "reference's laws, no FMU. Error ratio FMU / bare near 1: the FMU adds no error of its own.", ""]
    rows = []
    for s in scenes:
        bare = {r["settings"]["rtol"]: r for r in records[s.name] if r["family"] == "cvode-bare" and ok(r)}
        for r in records[s.name]:
            if r["family"] == "fmi3-me" and ok(r):
                rows.append([s.name, f"{r['settings']['rtol']:.0e}", f"{r['rel_dx']:.2g}", _fmt(r.get("event_time_error")),
                             str(r.get("events_unmatched")), _ms(r), *_bare_columns(r, bare.get(r["settings"]["rtol"]))])
    out += _table(["scene", "CVode rtol", "max\\|dx\\|/A", "event-time error (s)", "unmatched events", "time",
                   "bare: max\\|dx\\|/A", "error FMU / bare", "bare: time", "time FMU / bare"], rows)
    rows = []
    for s in scenes:
        for thr in THRESHOLDS:
            me, cs = (fastest(records[s.name], f, thr, s) for f in ("fmi3-me", "fmu"))
            rows.append([s.name, f"{thr:g}", _cell(me), _cell(cs), _ratio(me, cs)])
    out += ["", "At matched accuracy (fastest configuration reaching it):", ""]
    out += _table(["scene", "max\\|dx\\|/A ≤", "model exchange", "co-simulation (FMU)", "ME / CS"], rows)
    return out


def _bare_columns(me, bare):
    """Cells beside an ``fmi3-me`` record: bare CVode's max|dx|/A, the error ratio FMU / bare, bare CVode's
    time and the time ratio FMU / bare ("–" where bare CVode has no record at that rtol)."""
    if bare is None:
        return ["–"] * 4
    error_ratio = f"{me['rel_dx'] / bare['rel_dx']:.3g}" if bare["rel_dx"] > 0.0 else "–"
    return [f"{bare['rel_dx']:.2g}", error_ratio, _ms(bare), _ratio(me, bare)]


def _fmt(value):
    return "–" if value is None else f"{value:.2g}"


def plot(path, scene, records, quick=False):
    """Log-log work-precision plot: relative max |dx| over median time, Pareto front per family
    (legend below the axes; ``quick`` stamps it as a smoke run)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 7), layout="constrained")
    for family, (color, legend) in STYLE.items():
        done = sorted((r for r in records if r["family"] == family and ok(r)), key=lambda r: r["median_s"])
        for r in done:
            marker = MARKERS.get(r["settings"].get("method"), "o") if comparable(r, scene) else "x"
            ax.loglog(r["median_s"], max(r["rel_dx"], 1e-17), marker, color=color, alpha=0.6, ms=5)
        front, best = [], math.inf
        for r in done:
            if comparable(r, scene) and r["rel_dx"] < best:
                best = r["rel_dx"]
                front.append((r["median_s"], max(best, 1e-17)))
        if front:
            ax.loglog(*zip(*front), "-", color=color, label=legend)
    floor = [r for r in records if r["family"] == "floor" and r.get("error") is None
             and r["settings"]["comm_step"] == scene.grid_step]
    if floor:
        ax.axvline(floor[0]["median_s"], color="gray", ls="--", label="trivial FMU, same steps")
    for thr in THRESHOLDS:
        ax.axhline(thr, color="lightgray", lw=0.8, zorder=0)
    smoke = "SMOKE RUN (--quick), not a measurement: " if quick else ""
    ax.set(xlabel="median time of one simulation call (s)", ylabel="max |dx| / amplitude",
           title=f"{smoke}{scene.name}: {scene.stop_time:g} s, grid {scene.grid_step:g} s\n"
                 "markers: o RK45/stepper/FMU, s DOP853, ^ LSODA, D Radau, x on a coarser output grid")
    ax.title.set_fontsize(9)
    fig.legend(loc="outside lower center", ncols=2, fontsize=8)
    ax.grid(True, which="major", alpha=0.3)
    fig.savefig(path, dpi=110)
    plt.close(fig)
