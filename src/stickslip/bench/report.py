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
}
MARKERS = {"RK45": "o", "DOP853": "s", "LSODA": "^", "Radau": "D"}


def ok(record):
    """True for a configuration that ran and was compared with the reference."""
    return record.get("error") is None and math.isfinite(record.get("rel_dx", math.nan))


def comparable(record, scene):
    """Configurations with outputs on the whole common grid: every peer, and the FMU at ``h = grid_step``."""
    return ok(record) and (record["family"] != "fmu" or record["settings"]["comm_step"] == scene.grid_step)


def fastest(records, family, threshold, scene, any_grid=False):
    """The fastest comparable record of ``family`` with ``rel_dx <= threshold`` (None: not reached);
    ``any_grid`` also admits the FMU at communication steps coarser than the grid (compared on its own points)."""
    hits = [r for r in records if r["family"] == family and (ok(r) if any_grid else comparable(r, scene))
            and r["rel_dx"] <= threshold]
    return min(hits, key=lambda r: r["median_s"], default=None)


def per_step_cost(records, family, scene):
    """Seconds per communication step of ``family`` ("fmu" or "floor"): slope of the median time over the
    number of steps in the communication-step sweep (events and start-up go to the intercept)."""
    steps = set(scene.comm_steps())
    points = [(r["n_comm_steps"], r["median_s"]) for r in records
              if r["family"] == family and r.get("error") is None and r["settings"]["comm_step"] in steps
              and r["settings"].get("rtol", scene.sweep.comm_rtol) == scene.sweep.comm_rtol]
    if len(points) < 2:
        return None
    n, t = np.array(points).T
    return float(np.polyfit(n, t, 1)[0])


def write_json(path, meta, scenes, records):
    """``meta`` and, per scene, its setup and every record (times in s, errors in m, m/s, s)."""
    data = {"meta": meta, "scenes": {s.name: {
        "scenario_file": s.scenario_file, "stop_time_s": s.stop_time, "grid_step_s": s.grid_step,
        "amplitude_m": s.amplitude, "reference_events": len(s.reference.events), "records": records[s.name],
    } for s in scenes}}
    path.write_text(json.dumps(data, indent=1))


def _ms(record):
    return f"{1e3 * record['median_s']:.3g} ms"


def _cell(record):
    return "not reached" if record is None else f"{_ms(record)} ({record['label']})"


def _ratio(ours, peer):
    return "–" if ours is None or peer is None else f"{ours['median_s'] / peer['median_s']:.2g}"


def _table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return lines + ["| " + " | ".join(map(str, row)) + " |" for row in rows]


def markdown(meta, scenes, records):
    """The Markdown report: matched-accuracy ratios, per-step costs, communication steps, best accuracies."""
    out = ["# Work-precision benchmark", "",
           f"{meta['date']}, {meta['machine']}, Python {meta['python']}, {meta['versions']}; "
           f"median of {meta['repeats']} runs after a warm-up; load average at start {meta['load']}.", "",
           "Error: max |dx| on the scene's common grid over the amplitude A (half the reference's range of x). "
           "Times: one whole simulation call. Ratios are ours / peer (< 1: ours is faster), each side at its "
           "fastest configuration reaching the accuracy. The FMU column counts the grid's communication step "
           "only; \"FMU, any h\" also admits coarser communication steps, whose error is measured on their own "
           "points of the grid (the peers always return the whole grid).", "",
           "## Matched accuracy", ""]
    rows = []
    for s in scenes:
        for thr in THRESHOLDS:
            best = {f: fastest(records[s.name], f, thr, s) for f in ("fmu", "stepper", *PEERS)}
            coarse = fastest(records[s.name], "fmu", thr, s, any_grid=True)
            integrating = fastest(records[s.name], "stepper-integrating", thr, s)
            rows.append([s.name, f"{thr:g}", *(_cell(best[f]) for f in best), _cell(coarse),
                         _ratio(best["fmu"], best["solve_ivp"]), _ratio(coarse, best["solve_ivp"]),
                         _ratio(best["stepper"], best["solve_ivp"]), _ratio(integrating, best["solve_ivp"]),
                         _ratio(best["fmu"], best["regularized"]), _ratio(best["stepper"], best["regularized"])])
    out += _table(["scene", "max\\|dx\\|/A ≤", "FMU", "stepper", "solve_ivp", "regularized", "FMU, any h",
                   "FMU / solve_ivp", "FMU any h / solve_ivp", "stepper / solve_ivp",
                   "stepper no replay / solve_ivp", "FMU / regularized", "stepper / regularized"], rows)
    out += ["", "## Cost per communication step (slope over the communication-step sweep)", ""]
    rows = []
    for s in scenes:
        fmu, floor = (per_step_cost(records[s.name], f, s) for f in ("fmu", "floor"))
        if fmu is not None and floor is not None:
            rows.append([s.name, f"{1e6 * fmu:.3g}", f"{1e6 * floor:.3g}", f"{fmu / floor:.2g}"])
    out += _table(["scene", "FMU µs/step", "trivial FMU µs/step", "ratio"], rows)
    out += ["", "## FMU across communication steps (at the sweep's comm_rtol, default 1e-10)", ""]
    rows = []
    for s in scenes:
        floor = {r["settings"]["comm_step"]: r for r in records[s.name]
                 if r["family"] == "floor" and r.get("error") is None}
        for r in records[s.name]:
            h = r["settings"].get("comm_step")
            if r["family"] == "fmu" and ok(r) and r["settings"]["rtol"] == s.sweep.comm_rtol and h in floor:
                rows.append([s.name, f"{h:g}", r["n_comm_steps"], _ms(r), _ms(floor[h]), f"{r['max_abs_dx']:.2g}",
                             _fmt(r.get("event_time_error")), f"{r['final_abs_dx']:.2g}"])
    out += _table(["scene", "h (s)", "steps", "FMU", "trivial FMU", "max\\|dx\\| (m)", "event-time error (s)",
                   "final \\|dx\\| (m)"], rows)
    out += ["", "## Best accuracy of each family", ""]
    rows = []
    for s in scenes:
        for family in STYLE:
            done = [r for r in records[s.name] if r["family"] == family and ok(r)]
            if done:
                best = min(done, key=lambda r: r["rel_dx"])
                rows.append([s.name, family, f"{best['rel_dx']:.2g}", _cell(best), _fmt(best.get("event_time_error")),
                             best.get("events_unmatched", "–")])
    out += _table(["scene", "family", "best max\\|dx\\|/A", "at", "event-time error (s)", "unmatched events"], rows)
    failed = [(s.name, r) for s in scenes for r in records[s.name] if r.get("error")]
    if failed:
        out += ["", "## Failed configurations", ""]
        out += [f"- {name}: {r['label']}: {r['error'].splitlines()[-1]}" for name, r in failed]
    return "\n".join(out) + "\n"


def _fmt(value):
    return "–" if value is None else f"{value:.2g}"


def plot(path, scene, records):
    """Log-log work-precision plot: relative max |dx| over median time, Pareto front per family."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 6))
    for family, (color, legend) in STYLE.items():
        done = sorted((r for r in records if r["family"] == family and ok(r)), key=lambda r: r["median_s"])
        for r in done:
            marker = MARKERS.get(r["settings"].get("method"), "x" if not comparable(r, scene) else "o")
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
    ax.set(xlabel="median time of one simulation call (s)", ylabel="max |dx| / amplitude",
           title=f"{scene.name}: {scene.stop_time:g} s, grid {scene.grid_step:g} s\n"
                 "markers: o RK45/stepper/FMU, s DOP853, ^ LSODA, D Radau, x FMU at other communication steps")
    ax.title.set_fontsize(9)
    ax.legend(fontsize=8)
    ax.grid(True, which="major", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
