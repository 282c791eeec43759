"""The outputs of ``stickslip bench-c-hosts``: ``c-hosts.json`` (every number), ``c-hosts.md`` (tables of
costs and ratios, all from the same run) and ``c-hosts.png`` (per-step cost and start-up of each FMU in each
host)."""

import json

from . import state_costs
from .fmu_file_runs import TUNED_ATOL_PER_RTOL


def write(out_dir, results):
    """Write the three files into ``out_dir`` (a Path, created if missing); return their paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / name for name in ("c-hosts.json", "c-hosts.md", "c-hosts.png")]
    paths[0].write_text(json.dumps(results, indent=1) + "\n")
    paths[1].write_text(markdown(results))
    plot(paths[2], results)
    return paths


def _ratio(a, b):
    return f"{a / b:.3g}" if a and b and b > 0 else "-"


def markdown(results):
    """The report: header (machine, load at start and end), host costs, ratios, FMPy, dense grid, one step."""
    meta = results["meta"]
    lines = [f"# C-host benchmarks ({meta['date']})", "",
             f"{meta['machine']}; load average (1, 5, 15 min) at the start {meta['load_start']}, at the end "
             f"{meta['load_end']}. Per step: slope over runs of 1 and {meta['steps']} steps of {meta['step']:g} s "
             f"(medians of {meta['repeats']}); start-up: the 1-step run (our C host: plus extracting the FMU).", ""]
    for name, value in meta.get("files", {}).items():
        lines.append(f"- {name}: `{value}`")
    if meta.get("peer_mismatches"):
        lines.append(f"- the peer's parameters differ from msl-pendulum: {meta['peer_mismatches']}")
    lines += ["", *_matched_lines(results["matched"]), "", *_host_lines(results["hosts"])]
    if "fmpy" in results:
        lines += ["", "## FMPy `simulate_fmu`, msl-pendulum 5 s (extracted FMUs), ours at the peer's error", "",
                  *_matched_table(results["fmpy"], "peer tolerance")]
    lines += ["", "## `simulate_fmu` of the .fmu file, elmer-fig3 v = 0.1, 2000 s, 1 s outputs, against DOP853", "",
              *_matched_table(results["dense_grid"], "DOP853 rtol")]
    if "dense_grid_tuned" in results:
        lines += ["", f"## The same against a hand-tuned DOP853 with events (sticks in closed form, atol = "
                  f"{TUNED_ATOL_PER_RTOL:g} rtol)", "", *_matched_table(results["dense_grid_tuned"], "its rtol")]
    one = results["one_step"]
    lines += ["", "## One-step `simulate_fmu` of the .fmu file", "",
              f"ours {one['fmu']['wall_ms']:.1f} ms wall, {one['fmu']['cpu_ms']:.1f} ms CPU; the PythonFMU floor "
              f"{one['floor']['wall_ms']:.1f} ms, {one['floor']['cpu_ms']:.1f} ms: ours / floor "
              f"{one['ratio_wall']:.3g} (wall), {one['ratio_cpu']:.3g} (CPU)."]
    if "carried_python" in results:
        lines += ["", *_carried_lines(results["carried_python"])]
    if "states" in results:
        lines += ["", *state_costs.markdown_lines(results["states"])]
    return "\n".join(lines) + "\n"


def _carried_lines(rows):
    """The table of what the carried CPython costs (:mod:`.carried_cost`)."""
    lines = ["## What the carried CPython costs: each FMU against the same FMU built without it", "",
             "simulate_fmu: the .fmu file, elmer-fig3 from rest, v = 0.1 m/s, 2000 s, 1 s outputs, rtol 1e-10; C host: "
             "a fresh process's one-step run, the whole .fmu extracted first (ours: its CPython in the cache from an "
             "earlier run; first run: into an empty cache). Medians (ms) of alternating rounds; CPU: the process's and "
             "the host processes'.", "",
             "| FMU | clock | size ours / without (MB) | simulate_fmu ours / without | ratio | C host ours / without | "
             "ratio | C host first run |", "|---|---|---|---|---|---|---|---|"]
    for name, r in rows.items():
        size = r["size_mb"]
        for clock in ("wall", "cpu"):
            fmpy, host = r["fmpy_ms"][clock], r["c_host_ms"][clock]
            lines.append(f"| {name} | {clock} | {size['ours']:.2f} / {size['without']:.2f} | {fmpy['ours']:.1f} / "
                         f"{fmpy['without']:.1f} | {fmpy['ratio']:.3g} | {host['ours']:.1f} / {host['without']:.1f} | "
                         f"{host['ratio']:.3g} | {host['first']:.0f} |")
    return lines


def _matched_lines(found):
    text = [f"Error on msl-pendulum (max |x - reference|, 0.01 s grid over 5 s): ours at solver.rtol "
            f"{found['our_rtol']:g}: " + ", ".join(f"{e:.2g} m in {h}" for h, e in found["our_error"].items())]
    if found["peer_error"]:
        text.append("; the peer at its default tolerance: "
                    + ", ".join(f"{e:.2g} m in {h}" for h, e in found["peer_error"].items()))
    return ["".join(text) + "."]


def _host_lines(hosts):
    lines = ["## C hosts: per step (fmi2DoStep + fmi2GetReal of one output) and start-up", "",
             "| host | FMU | per step wall (µs) | per step CPU (µs) | the host's own CPU per step (µs) | "
             "start-up wall (ms) | start-up CPU (ms) |", "|---|---|---|---|---|---|---|"]
    for host, records in hosts.items():
        for name, r in records.items():
            s, u, own = r["per_step"], r["startup"], r.get("in_host_cpu_us")
            lines.append(f"| {host} | {name} | {s['wall_us']:.3g} | {s['cpu_us']:.3g} | "
                         f"{'-' if own is None else format(own, '.3g')} | {u['wall_ms']:.3g} | {u['cpu_ms']:.3g} |")
    lines += ["", "Ratios (< 1: ours is cheaper), per step wall / CPU, start-up wall / CPU; own cost: CPU per step "
              "(µs) above the C floor's in the same host:", "",
              "| host | ours / peer per step | ours / C floor | ours / PythonFMU floor | peer / C floor | "
              "ours / peer start-up | own cost: ours, peer |", "|---|---|---|---|---|---|---|"]
    for host, records in hosts.items():
        cells = [host]
        pairs = (("ours", "peer (Dymola)", "per_step", ("wall_us", "cpu_us")),
                 ("ours", "C floor", "per_step", ("wall_us", "cpu_us")),
                 ("ours", "PythonFMU floor", "per_step", ("wall_us", "cpu_us")),
                 ("peer (Dymola)", "C floor", "per_step", ("wall_us", "cpu_us")),
                 ("ours", "peer (Dymola)", "startup", ("wall_ms", "cpu_ms")))
        for a, b, field, keys in pairs:
            ra, rb = records.get(a), records.get(b)
            cells.append(" / ".join(_ratio(ra[field][k], rb[field][k]) for k in keys) if ra and rb else "-")
        floor = records.get("C floor")
        cells.append(", ".join(f"{records[n]['per_step']['cpu_us'] - floor['per_step']['cpu_us']:.3g}"
                               if floor and n in records else "-" for n in ("ours", "peer (Dymola)")))
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _matched_table(rows, peer_label):
    lines = [f"| {peer_label} | its error (m) | its CPU (ms) | its wall (ms) | our rtol | our error (m) | "
             "our CPU (ms) | our wall (ms) | ours / it, CPU | wall |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['peer_tolerance']:g} | {r['peer_error']:.2g} | {r['peer_cpu_ms']:.3g} | "
                     f"{r['peer_wall_ms']:.3g} | {r['our_rtol']:g} | {r['our_error']:.2g} | {r['our_cpu_ms']:.3g} | "
                     f"{r['our_wall_ms']:.3g} | {r['ratio_cpu']:.3g} | {r['ratio_wall']:.3g} |")
    return lines


def plot(path, results):
    """Two panels: per-step CPU cost (µs) and start-up wall time (ms) of each FMU, grouped by host."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    hosts = results["hosts"]
    names = list(next(iter(hosts.values())))
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    width = 0.8 / len(hosts)
    for i, (host, records) in enumerate(hosts.items()):
        positions = [k + i * width for k in range(len(names))]
        for ax, field, key in ((axes[0], "per_step", "cpu_us"), (axes[1], "startup", "wall_ms")):
            ax.bar(positions, [max(records[n][field][key], 1e-3) for n in names], width, label=host)
    for ax, title in ((axes[0], "per step, CPU (µs)"), (axes[1], "start-up, wall (ms)")):
        ax.set_xticks([k + 0.4 - width / 2 for k in range(len(names))], names, rotation=30, ha="right")
        ax.set_yscale("log")
        ax.set_title(title)
        ax.legend()
    meta = results["meta"]
    fig.suptitle(f"C hosts, {meta['steps']} steps of {meta['step']:g} s; load {meta['load_start'][0]:g} "
                 f"at the start")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
