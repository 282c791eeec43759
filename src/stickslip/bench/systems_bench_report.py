"""The outputs of ``stickslip bench-systems``: ``systems.json`` (every number), ``systems.md`` (per scene the runs,
the orders and the wall-time ratio at matched error) and ``systems.png`` (error against wall time, one panel per
scene, one curve per master)."""

import json

from .systems_bench import SETTINGS


def write(out_dir, meta, records):
    """Write the three files into ``out_dir`` (a Path, created if missing); return their paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / name for name in ("systems.json", "systems.md", "systems.png")]
    paths[0].write_text(json.dumps({"meta": meta, "scenes": records}, indent=1) + "\n")
    paths[1].write_text(markdown(meta, records))
    plot(paths[2], records)
    return paths


def _g(value, digits=2):
    return "-" if value is None else f"{value:.{digits}g}"


def markdown(meta, records):
    """The report: the machine and its load, then per scene the runs, orders and matched-error ratios."""
    lines = [f"# Masters on chains: error against wall time ({meta['date']})", "",
             f"{meta['machine']}; load average (1, 5, 15 min) at the start {meta['load_start']}, at the end "
             f"{meta['load_end']}. Error: the largest `max |dx|` of any block against the chain's reference, as a "
             "fraction of the amplitude; wall: one run of the master (FMU extraction and instantiation included).", ""]
    for record in records:
        lines += [f"## {record['scene']} ({record['stop_time']:g} s, amplitude {record['amplitude']:.3g} m)", "",
                  "| master | setting | error | wall (s) | events paired | max event-time error (s) |",
                  "|---|---|---|---|---|---|"]
        for master, runs in record["runs"].items():
            for run in runs:
                lines.append(f"| {master} | {SETTINGS[master][2]} = {run['setting']:g} | {_g(run['error'])} | "
                             f"{run['wall']:.3g} | {'yes' if run['events_paired'] else 'no'} | "
                             f"{_g(run['max_event_dt'])} |")
        lines += ["", "Orders (slope of log10 error against log10 of the setting; fit, then between neighbours): "
                  + "; ".join(f"{master} {_g(o['fit'], 3)} ({', '.join(_g(s, 3) for s in o['steps'])})"
                              for master, o in record["orders"].items()) + ".", ""]
        if record["matched"]:
            lines += ["| zoh h (s) | zoh error | zoh wall (s) | adaptive at that error | adaptive wall (s) | "
                      "zoh wall / adaptive wall |", "|---|---|---|---|---|---|"]
            lines += [f"| {m['h']:g} | {_g(m['zoh_error'])} | {m['zoh_wall']:.3g} | {_g(m['adaptive_error'])} | "
                      f"{_g(m['adaptive_wall'], 3)} | {_g(m['ratio'], 3)} |" for m in record["matched"]]
            lines.append("")
        if record.get("early_return"):
            lines += ["adaptive's two schemes at the same rtol: FMI 2 (events landed by root search) and FMI 3 "
                      "(early return).", "", "| rtol | FMI 2 error | FMI 3 error | FMI 2 wall (s) | FMI 3 wall (s) | "
                      "FMI 3 wall / FMI 2 wall |", "|---|---|---|---|---|---|"]
            lines += [f"| {r['rtol']:g} | {_g(r['fmi2_error'])} | {_g(r['fmi3_error'])} | {r['fmi2_wall']:.3g} | "
                      f"{r['fmi3_wall']:.3g} | {_g(r['ratio'], 3)} |" for r in record["early_return"]]
            lines.append("")
        if record.get("peer"):
            lines += ["Each master's run against the scipy peer (`solve_ivp` over the whole chain with events) at the "
                      "run's error, the peer's wall interpolated on its measured runs.", "",
                      "| master | setting | error | wall (s) | peer at that error | peer wall (s) | wall / peer wall |",
                      "|---|---|---|---|---|---|---|"]
            lines += [f"| {r['master']} | {SETTINGS[r['master']][2]} = {r['setting']:g} | {_g(r['error'])} | "
                      f"{r['wall']:.3g} | {_g(r['peer_error'])} | {_g(r['peer_wall'], 3)} | {_g(r['ratio'], 3)} |"
                      for r in record["peer"]]
            lines.append("")
    return "\n".join(lines) + "\n"


def plot(path, records):
    """Error against wall time, log-log, one panel per scene."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(records), figsize=(5.0 * len(records), 4.2), squeeze=False)
    for ax, record in zip(axes[0], records):
        for master, runs in record["runs"].items():
            shown = [r for r in runs if r["error"] > 0.0]
            ax.loglog([r["wall"] for r in shown], [r["error"] for r in shown], "o-", label=master)
            for r in shown:
                ax.annotate(f"{r['setting']:g}", (r["wall"], r["error"]), fontsize=7, xytext=(3, 3),
                            textcoords="offset points")
        ax.set_title(f"{record['scene']} ({record['stop_time']:g} s)")
        ax.set_xlabel("wall time (s)")
        ax.set_ylabel("max |dx| / amplitude")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
