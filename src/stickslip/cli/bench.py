"""``stickslip bench``: the work-precision benchmark (:mod:`stickslip.bench`); ``add_bench_parser(subparsers)`` adds
it, ``run_bench(args)`` runs it. Also ``bench-c-hosts``, ``bench-systems`` and ``bench-versus``."""

import sys

from ..fmu.variables import START_VALUES


def add_bench_parser(subparsers):
    p = subparsers.add_parser("bench", help="work-precision benchmark of the FMU and the stepper against peers")
    p.add_argument("--quick", action="store_true",
                   help="20 s scenes, a few configurations, one timed run each (a smoke test, not a measurement)")
    p.add_argument("--out", default="bench-results", help="output directory (default: bench-results)")
    p.add_argument("--scenes", nargs="+", metavar="NAME", help="scenes to run (default: all; see benchmarks/README.md)")
    p.add_argument("--fmu", help="FMU to measure (default: SpringBlockFriction.fmu of the FMU folder, built if missing "
                                 "or stale; the folder: stickslip build --help)")
    p.add_argument("--fmu3", help="FMI 3 FMU whose model exchange is measured (default: "
                                  "SpringBlockFriction-fmi3.fmu of the FMU folder, built if missing or stale)")
    p.set_defaults(handler=run_bench)


def run_bench(args):
    """Run the benchmark; write ``bench.json``, ``bench.md`` and ``<scene>.png`` into ``args.out``. Exit code."""
    import datetime
    import os
    import platform
    from pathlib import Path

    import fmpy
    import numpy
    import scipy

    from ..bench.c_host_family import ensure_host
    from ..bench.fmus import BUILD_DIR, ExtractedFMU, ensure_floor_fmu
    from ..bench.harness import run_scenes
    from ..bench.implementations import compiled_vs_pure
    from ..bench.results import markdown, plot, write_json
    from ..bench.runtimes import ensure_pure_fmu
    from ..bench.scenes import select_scenes
    from ..fmu import ensure_fmu

    try:
        scenes = select_scenes(args.scenes, args.quick)
    except ValueError as exc:
        print(f"stickslip bench: {exc}", file=sys.stderr)
        return 2
    meta = {
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "machine": f"{platform.platform()}, {os.cpu_count()} CPUs",
        "python": platform.python_version(),
        "versions": f"numpy {numpy.__version__}, scipy {scipy.__version__}, fmpy {fmpy.__version__}",
        "repeats": sorted({s.sweep.repeats for s in scenes}),
        "load": [round(x, 2) for x in os.getloadavg()],
        "quick": args.quick,
    }
    fmu_path = Path(args.fmu) if args.fmu else ensure_fmu()
    fmu3_path = Path(args.fmu3) if args.fmu3 else ensure_fmu(fmi_version=3)
    with ExtractedFMU(fmu_path) as fmu, ExtractedFMU(ensure_floor_fmu()) as floor, ExtractedFMU(fmu3_path) as fmu3, \
            ExtractedFMU(ensure_pure_fmu(BUILD_DIR)) as pure_fmu:
        records = run_scenes(scenes, fmu, floor, ensure_host(), fmu3, pure_fmu)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "bench.json", meta, scenes, records)
    (out / "bench.md").write_text(markdown(meta, scenes, records) + "\n".join(compiled_vs_pure(scenes, records)) + "\n")
    for scene in scenes:
        plot(out / f"{scene.name}.png", scene, records[scene.name], quick=args.quick)
    print(f"wrote {out / 'bench.json'}, {out / 'bench.md'} and {len(scenes)} plots")
    return 0


def add_c_hosts_parser(subparsers):
    p = subparsers.add_parser("bench-c-hosts", help="C hosts per step and start-up, the "
                                                    "compiled peer at matched error, the .fmu file against DOP853")
    p.add_argument("--peer", help="the compiled peer, SpringFrictionPendulum1D.fmu of FMIZoo.jl (Dymola 2023x); "
                                  "without it the peer's columns are left out")
    p.add_argument("--fmusim", help="fmusim of Reference-FMUs (scripts/build_fmusim.sh); Feedthrough.fmu and "
                                    "Dahlquist.fmu beside it are measured too")
    p.add_argument("--out", default="bench-c-hosts", help="output directory (default: bench-c-hosts)")
    p.add_argument("--fmu", help="our FMI 2 FMU (default: SpringBlockFriction.fmu of the FMU folder, built if missing "
                                 "or stale; the folder: stickslip build --help)")
    p.add_argument("--steps", type=int, default=50_000, help="steps of 0.01 s in a long host run (default: 50000)")
    p.add_argument("--repeats", type=int, default=5, help="timed runs of each measurement (default: 5)")
    p.set_defaults(handler=run_c_hosts)


def run_c_hosts(args):
    """Run :func:`stickslip.bench.c_hosts_run.run_all`; write c-hosts.json, .md and .png into ``args.out``."""
    from pathlib import Path

    from ..bench.c_hosts_report import write
    from ..bench.c_hosts_run import Inputs, run_all
    from ..bench.fmus import BUILD_DIR, ensure_floor_fmu
    from ..fmu import ensure_fmu
    from ..hosts.c_host import HostBuildError, compile_host

    missing = [path for path in (args.peer, args.fmusim, args.fmu) if path and not Path(path).is_file()]
    if missing or args.steps < 2 or args.repeats < 1:
        print(f"stickslip bench-c-hosts: no such file {missing}" if missing else
              "stickslip bench-c-hosts: --steps must be at least 2 and --repeats at least 1", file=sys.stderr)
        return 2
    try:
        host = compile_host(BUILD_DIR)
    except HostBuildError as exc:
        print(f"stickslip bench-c-hosts: {exc}", file=sys.stderr)
        return 1
    inputs = Inputs(Path(args.fmu) if args.fmu else ensure_fmu(), ensure_floor_fmu(), host, BUILD_DIR,
                    args.peer and Path(args.peer).resolve(), args.fmusim and Path(args.fmusim).resolve())
    results = run_all(inputs, args.steps, args.repeats, lambda text: print(text, file=sys.stderr, flush=True))
    paths = write(Path(args.out), results)
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


#: ``bench-systems`` defaults: zoh's step h (s), adaptive's and me's rtol
ZOH_STEPS = (0.1, 0.01, 0.001, 1e-4)
ADAPTIVE_RTOLS = (1e-5, 1e-7, 1e-9, 3e-10, 1e-11)
ME_RTOLS = (1e-6, 1e-8, 1e-10, 1e-12)


def add_systems_parser(subparsers):
    p = subparsers.add_parser("bench-systems", help="the masters on chain scenes: error against wall time, "
                                                    "orders, zoh's wall against adaptive's at matched error")
    p.add_argument("files", nargs="+", metavar="FILE.toml", help="system files (e.g. systems/chain2-coulomb.toml)")
    p.add_argument("--out", default="bench-systems", help="output directory (default: bench-systems)")
    p.add_argument("--stop-time", type=float, help="simulate this long instead of each file's stop_time (s; a "
                                                   "multiple of its output_interval)")
    p.add_argument("--zoh-steps", type=float, nargs="*", default=list(ZOH_STEPS), metavar="H",
                   help=f"zoh's steps in s, each dividing the output interval (default: {ZOH_STEPS})")
    p.add_argument("--adaptive-rtols", type=float, nargs="*", default=list(ADAPTIVE_RTOLS), metavar="RTOL",
                   help=f"adaptive's rtol values (default: {ADAPTIVE_RTOLS})")
    p.add_argument("--adaptive-fmi3-rtols", type=float, nargs="*", default=list(ADAPTIVE_RTOLS), metavar="RTOL",
                   help="adaptive's rtol values on the FMI 3 FMU with early return, beside the FMI 2 runs (default: "
                        "as --adaptive-rtols)")
    p.add_argument("--me-rtols", type=float, nargs="*", default=list(ME_RTOLS), metavar="RTOL",
                   help=f"me's rtol values (default: {ME_RTOLS})")
    p.set_defaults(handler=run_systems)


def run_systems(args):
    """Run :func:`stickslip.bench.systems_bench.bench_system` on each file; write systems.json, .md and .png into
    ``args.out``; progress on stderr. Exit code."""
    import datetime
    import os
    import platform
    from pathlib import Path

    from ..bench.systems_bench import bench_system, with_stop_time
    from ..bench.systems_bench_report import write
    from ..fmu import ensure_fmu
    from ..systems import load_system

    systems = [with_stop_time(load_system(path), args.stop_time) for path in args.files]
    bad = [s.name for s in systems if abs(round(s.stop_time / s.output_interval) * s.output_interval
                                          - s.stop_time) > 1e-9 * s.stop_time]
    if bad or (args.stop_time is not None and args.stop_time <= 0.0):
        print(f"stickslip bench-systems: --stop-time {args.stop_time} is not a positive multiple of the output "
              f"interval of {bad}", file=sys.stderr)
        return 2
    settings = {master: values for master, values in
                (("zoh", args.zoh_steps), ("adaptive", args.adaptive_rtols),
                 ("adaptive-fmi3", args.adaptive_fmi3_rtols), ("me", args.me_rtols)) if values}
    meta = {"date": datetime.datetime.now().isoformat(timespec="seconds"),
            "machine": f"{platform.platform()}, {os.cpu_count()} CPUs",
            "load_start": [round(x, 2) for x in os.getloadavg()], "settings": settings}
    fmu_paths = {2: ensure_fmu(), 3: ensure_fmu(fmi_version=3)}
    records = [bench_system(system, fmu_paths, settings, lambda text: print(text, file=sys.stderr, flush=True))
               for system in systems]
    meta["load_end"] = [round(x, 2) for x in os.getloadavg()]
    print("wrote " + ", ".join(str(p) for p in write(Path(args.out), meta, records)))
    return 0


def add_versus_parser(subparsers):
    p = subparsers.add_parser("bench-versus", help="time FMU files side by side on one benchmark scene")
    p.add_argument("fmus", nargs="+", metavar="FMU", help="FMU files; ratios are to the first")
    p.add_argument("--scene", default="elmer-fig3-v1.0-long", help="benchmark scene (default: elmer-fig3-v1.0-long)")
    p.add_argument("--comm-step", type=float, default=1.0, help="communication step in s (default: 1)")
    p.add_argument("--rtol", type=float, default=START_VALUES["solver.rtol"],
                   help=f"the FMUs' solver.rtol (default: the FMU's, {START_VALUES['solver.rtol']:g})")
    p.add_argument("--rounds", type=int, default=3, help="alternating rounds (default: 3)")
    p.add_argument("--repeats", type=int, default=5, help="timed calls per FMU and round (default: 5)")
    p.set_defaults(handler=_versus)


def _versus(args):
    from ..bench.versus import run_versus

    return run_versus(args)
