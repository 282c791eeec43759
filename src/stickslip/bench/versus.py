"""``stickslip bench-versus``: FMU files side by side on one scene, e.g. two builds of our FMU.

Each FMU is timed in a process of its own (two builds of our FMU share the slave's module name and cannot
share a process): extracted once, a warm-up call, then ``repeats`` timed calls of ``fmpy.simulate_fmu``
(outputs ``x`` and ``v``, the scene's start values at ``solver.rtol``, the garbage collector off during
each call), wall and CPU time. The processes run alternately for ``rounds`` rounds, so both FMUs see the
same machine; the table gives each FMU's medians (ms) and their ratio to the first FMU's.
"""

import json
import statistics
import subprocess
import sys

from .fmus import ExtractedFMU
from .process_timing import timed_call
from .scenes import select_scenes


def time_fmu(fmu_path, scene_name, comm_step, rtol, repeats):
    """``{"wall": [s...], "cpu": [s...], "x_end": m}`` of ``repeats`` calls after a warm-up, in this process."""
    scene = select_scenes([scene_name])[0]
    with ExtractedFMU(fmu_path) as fmu:
        start = {name: value for name, value in scene.start_values(rtol).items() if name in fmu.variables}
        timings = timed_call(lambda: fmu.simulate(start, scene.stop_time, comm_step, ("x", "v")), repeats)
    return {"wall": timings.wall, "cpu": timings.cpu, "x_end": float(timings.first["x"][-1])}


def run_versus(args):
    """Time ``args.fmus`` alternately in separate processes; print the medians and ratios. Exit code."""
    try:
        select_scenes([args.scene])
    except ValueError as exc:
        print(f"stickslip bench-versus: {exc}", file=sys.stderr)
        return 2
    if args.rounds < 1 or args.repeats < 1:
        print("stickslip bench-versus: --rounds and --repeats must be at least 1", file=sys.stderr)
        return 2
    runs = [{"path": path, "wall": [], "cpu": [], "x_end": None} for path in args.fmus]  # in the given order
    for round_number in range(1, args.rounds + 1):
        for run in runs:
            done = subprocess.run(
                [sys.executable, "-m", __name__, run["path"], args.scene, repr(args.comm_step), repr(args.rtol),
                 str(args.repeats)], capture_output=True, text=True)
            if done.returncode != 0:
                print(f"stickslip bench-versus: {run['path']} failed:\n{done.stderr}", file=sys.stderr)
                return 1
            times = json.loads(done.stdout.splitlines()[-1])
            for clock in ("wall", "cpu"):
                run[clock].append(statistics.median(times[clock]))
            run["x_end"] = times["x_end"]
            print(f"round {round_number}/{args.rounds}: {run['path']}: {1e3 * run['wall'][-1]:.1f} ms wall",
                  file=sys.stderr)
    print(versus_table(args, runs))
    return 0


def versus_table(args, runs):
    """Markdown: per FMU the per-round medians (ms) and the ratio of its median of them to the first FMU's."""
    lines = [f"{args.scene}, h = {args.comm_step:g} s, solver.rtol = {args.rtol:g}: {args.rounds} alternating rounds "
             f"of the median of {args.repeats} calls", "",
             "| FMU | wall (ms), per round | CPU (ms), per round | wall / first | CPU / first | x at the end (m) |",
             "|---|---|---|---|---|---|"]
    for run in runs:
        cells = [run["path"]]
        for clock in ("wall", "cpu"):
            cells.append(", ".join(f"{1e3 * t:.1f}" for t in run[clock]))
        for clock in ("wall", "cpu"):
            cells.append(f"{statistics.median(run[clock]) / statistics.median(runs[0][clock]):.3g}")
        cells.append(repr(run["x_end"]))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


if __name__ == "__main__":  # one FMU's timing, for run_versus: FMU scene comm_step rtol repeats
    fmu_path, scene_name, comm_step, rtol, repeats = sys.argv[1:]
    print(json.dumps(time_fmu(fmu_path, scene_name, float(comm_step), float(rtol), int(repeats))))
