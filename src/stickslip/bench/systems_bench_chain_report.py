"""The outputs of the chain part of ``stickslip bench-systems``: ``chain.json`` (every number), ``chain.csv`` (one
row per timed run), ``chain.md`` (per chain the runs side by side and the engine's wall over the peer's at matched
error; the growth with N) and ``chain.png`` (error against wall time per chain, and wall against N)."""

import csv
import json

from .systems_bench_chain import growth

#: one colour per subject in every panel
COLORS = {"engine": "C0", "peer": "C1", "reference": "C2"}
CSV_COLUMNS = ("chain", "n", "stop_time", "subject", "rtol", "error", "wall_s", "walls_s", "events", "max_event_dt_s",
               "truth")


def write(out_dir, meta, records):
    """Write the four files into ``out_dir`` (a Path, created if missing); return their paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / name for name in ("chain.json", "chain.csv", "chain.md", "chain.png")]
    summary = growth(records)
    paths[0].write_text(json.dumps({"meta": meta, "chains": records, "growth": summary}, indent=1) + "\n")
    with open(paths[1], "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(CSV_COLUMNS)
        writer.writerows(csv_rows(records))
    paths[2].write_text(markdown(meta, records, summary))
    plot(paths[3], records, summary)
    return paths


def csv_rows(records):
    """One row per timed run, in :data:`CSV_COLUMNS` order."""
    for r in records:
        for subject, runs in r["runs"].items():
            for run in runs:
                yield (r["chain"], r["n"], r["stop_time"], subject, run["setting"], run["error"], run["wall"],
                       " ".join(f"{w:.6g}" for w in run["walls"]), run["events"],
                       "" if run["max_event_dt"] is None else run["max_event_dt"], r["truth"])


def _g(value, digits=2):
    return "-" if value is None else f"{value:.{digits}g}"


def markdown(meta, records, summary):
    """The report: conditions, then per chain the runs and the matched-error ratios, then the growth with N."""
    lines = [f"# The chain engine against the numba peer ({meta['date']})", "",
             f"{meta['machine']}; load average (1, 5, 15 min) at the start {meta['load_start']}, at the end "
             f"{meta['load_end']}. Walls: the median of {meta['repeats']} call(s) of a whole run (one call for the large "
             "chain), both subjects warmed up first, taking turns at each rtol; one run of a shared, noisy machine. "
             "Error: max |x - x_ref| over every block and output time, as a fraction of the amplitude.", ""]
    for r in records:
        lines += _chain_section(r)
    lines += ["## Growth with N", "",
              "Walls per simulated second, at the tightest peer rtol the engine matches (a large chain's errors are "
              "against the engine at a tighter tolerance).", "",
              "| N | chain | rtol (peer) | peer wall (s/s) | engine wall at that error (s/s) | engine / peer |",
              "|---|---|---|---|---|---|"]
    lines += [f"| {g['n']} | {g['chain']} | {g['rtol']:g} | {g['peer_wall']:.3g} | {g['engine_wall']:.3g} | "
              f"{g['ratio']:.3g} |" for g in summary["rows"]]
    exponents = summary["exponents"]
    lines += ["", f"Wall against N (least-squares slope in log-log, at one rtol): peer N^{_g(exponents['peer'], 3)}, "
                  f"engine N^{_g(exponents['engine'], 3)}.", ""]
    return "\n".join(lines) + "\n"


def _chain_section(r):
    warm = ", ".join(f"{name} {wall:.3g} s" for name, wall in r["warm_up"].items())
    lines = [f"## {r['chain']} (N = {r['n']}, {r['stop_time']:g} s, amplitude {r['amplitude']:.3g} m)", "",
             f"Truth: {r['truth']}, {r['truth_wall']:.3g} s, {r['truth_events']} block events. First call on a "
             f"short run (numba compile or cache load): {warm}.", "",
             "| subject | rtol | error | wall (s) | block events | max event-time difference (s) |",
             "|---|---|---|---|---|---|"]
    for subject, runs in r["runs"].items():
        lines += [f"| {subject} | {run['setting']:g} | {_g(run['error'])} | {run['wall']:.3g} | {run['events']} | "
                  f"{_g(run['max_event_dt'])} |" for run in runs]
    if r["matched"]:
        lines += ["", "| peer rtol | peer error | peer wall (s) | engine at that error | engine wall (s) | "
                      "engine / peer |", "|---|---|---|---|---|---|"]
        lines += [f"| {m['rtol']:g} | {_g(m['peer_error'])} | {m['peer_wall']:.3g} | {_g(m['engine_error'])} | "
                  f"{_g(m['engine_wall'], 3)} | {_g(m['ratio'], 3)} |" for m in r["matched"]]
    return lines + [""]


def plot(path, records, summary):
    """Error against wall (log-log) per chain, one curve per subject; then wall against N at matched error."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(records) + 1, figsize=(4.6 * (len(records) + 1), 4.2), squeeze=False)
    for ax, r in zip(axes[0], records):
        for subject, runs in r["runs"].items():
            shown = [run for run in runs if 0.0 < run["error"] < float("inf")]
            ax.loglog([run["wall"] for run in shown], [run["error"] for run in shown], "o-", label=subject,
                      color=COLORS[subject])
            for run in shown:
                ax.annotate(f"{run['setting']:g}", (run["wall"], run["error"]), fontsize=7, xytext=(3, 3),
                            textcoords="offset points")
        ax.set_title(f"N = {r['n']}, {r['stop_time']:g} s", fontsize=10)
        ax.set_xlabel("wall time (s)")
        ax.set_ylabel("max |dx| / amplitude")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    ax, rows = axes[0][-1], summary["rows"]
    for name in ("peer", "engine"):
        ax.loglog([g["n"] for g in rows], [g[f"{name}_wall"] for g in rows], "o-", label=name,
                  color=COLORS[name])
    ax.set_title("wall against N at matched error", fontsize=10)
    ax.set_xlabel("blocks N")
    ax.set_ylabel("wall time per simulated second (s/s)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
