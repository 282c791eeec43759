"""Issue 21's two start-up targets, measured side by side in one run (the machine's load printed first).

1. A one-step ``fmpy.simulate_fmu`` of each FMU file (ours, and the benchmark's do-nothing PythonFMU FMU), in
   fresh processes taking turns: the first call (cold: FMPy imported, nothing of the FMU) and the median of the
   calls after it (warm); the ratio of ours to the floor's.
2. ``fmpy.simulate_fmu`` of the ``.fmu`` file on elmer-fig3 at v = 0.1 m/s, 2000 s, outputs ``x``, ``v`` every
   1 s (warm median, a fresh process per FMU), against scipy's DOP853 with events (the benchmark's hybrid
   ``solve_ivp`` peer) at the loosest of its tolerances whose error (max |dx| on the grid over the
   reference's half range) is at most ours; the ratio DOP853 / ours (the target: at least 1.25).

    .venv/bin/python scripts/startup_targets.py [--repeats 15] [--rounds 3] [FMU ...]
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

STOP, STEP, SCENE_FILE = 2000.0, 1.0, "elmer-fig3-v0.1.toml"


def _scene():
    from stickslip.bench.scenes import Scene
    return Scene("elmer-fig3-v0.1-2000", SCENE_FILE, STOP, STEP)


def _child(path, repeats, scene_run):
    """Print JSON ``{"cold": s, "warm": [s...], "rel_dx": ...}`` of one-step (or ``scene_run``) calls of ``path``."""
    import fmpy

    if scene_run:
        from stickslip.bench.harness import accuracy
        from stickslip.bench.peers import Run
        scene = _scene()
        start = {k: v for k, v in scene.start_values(None).items() if k != "solver.rtol"}
        call = lambda: fmpy.simulate_fmu(path, start_values=start, stop_time=STOP, output_interval=STEP,  # noqa: E731
                                         output=["x", "v"])
    else:
        call = lambda: fmpy.simulate_fmu(path, stop_time=1e-3, output_interval=1e-3)  # noqa: E731
    times = []
    for _ in range(repeats + 1):
        start_clock = time.perf_counter()
        result = call()
        times.append(time.perf_counter() - start_clock)
    out = {"cold": times[0], "warm": times[1:]}
    if scene_run:
        out["rel_dx"] = accuracy(Run(result["time"], result["x"], result["v"], None), scene, STEP)["rel_dx"]
    print(json.dumps(out))


def _in_child(path, repeats, scene_run=False):
    command = [sys.executable, __file__, "--child", path, "--repeats", str(repeats)] + (["--scene"] if scene_run else [])
    return json.loads(subprocess.run(command, capture_output=True, text=True, check=True).stdout)


def _dop853(target_error, repeats):
    """``(rtol, rel_dx, median s)`` of DOP853 with events at the loosest rtol whose error is at most ``target_error``."""
    from stickslip.bench.harness import accuracy
    from stickslip.bench.peers import hybrid_solve_ivp
    scene = _scene()
    p, (v_drive, F_ext), grid = scene.params, scene.inputs, scene.grid()
    for rtol in (1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13):
        run = lambda: hybrid_solve_ivp(p, scene.scenario.x0, scene.scenario.v0, v_drive, F_ext, grid,  # noqa: E731
                                       "DOP853", rtol, rtol)
        error = accuracy(run(), scene, STEP)["rel_dx"]
        if error <= target_error:
            times = []
            for _ in range(repeats):
                start = time.perf_counter()
                run()
                times.append(time.perf_counter() - start)
            return rtol, error, statistics.median(times)
    return None, None, None


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("fmus", nargs="*", help="our FMI 2 FMU files (default: dist/SpringBlockFriction.fmu)")
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--scene", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        return _child(args.child, args.repeats, args.scene)
    from stickslip.bench.fmus import ensure_floor_fmu
    from stickslip.fmu.build import ensure_fmu
    fmus = args.fmus or [str(ensure_fmu())]
    floor = str(ensure_floor_fmu())
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores, {time.strftime('%Y-%m-%d %H:%M')}")
    one_step = {path: [] for path in [floor, *fmus]}
    scene_runs = {path: [] for path in fmus}
    for _ in range(args.rounds):
        for path in one_step:
            one_step[path].append(_in_child(path, args.repeats))
        for path in scene_runs:
            scene_runs[path].append(_in_child(path, max(3, args.repeats // 3), scene_run=True))
    _print_one_step(one_step, floor)
    _print_scene(scene_runs, args.repeats)


def _print_one_step(one_step, floor):
    medians = {path: (statistics.median(r["cold"] for r in runs),
                      statistics.median(t for r in runs for t in r["warm"])) for path, runs in one_step.items()}
    print("one-step simulate_fmu of the file (ms): cold (first call in a process), warm (median); ratio to the floor")
    for path, (cold, warm) in medians.items():
        print(f"  {path}: cold {cold * 1e3:.2f} ({cold / medians[floor][0]:.2f}x), "
              f"warm {warm * 1e3:.2f} ({warm / medians[floor][1]:.2f}x)")


def _print_scene(scene_runs, repeats):
    print(f"elmer-fig3 v = 0.1 m/s, {STOP:g} s, outputs every {STEP:g} s: simulate_fmu of the file (warm median) vs "
          f"DOP853 with events at matched error")
    for path, runs in scene_runs.items():
        ours = statistics.median(t for r in runs for t in r["warm"])
        error = runs[0]["rel_dx"]
        rtol, dop_error, dop = _dop853(error, repeats)
        ratio = f"{dop / ours:.2f}x" if dop else "n/a"
        print(f"  {path}: {ours * 1e3:.2f} ms at rel. error {error:.2g}; DOP853 rtol={rtol} {dop_error}: "
              f"{dop * 1e3 if dop else float('nan'):.2f} ms; DOP853 / ours = {ratio}")


if __name__ == "__main__":
    main()
