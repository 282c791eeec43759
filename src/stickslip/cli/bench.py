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
    p = subparsers.add_parser("bench-c-hosts", help="C hosts per step and start-up, the compiled peer at matched "
                                                    "error, the .fmu file against DOP853 (plain and hand-tuned), FMU "
                                                    "states beside a doStep")
    p.add_argument("--peer", help="the compiled peer, SpringFrictionPendulum1D.fmu of FMIZoo.jl (Dymola 2023x); "
                                  "without it the peer's columns are left out")
    p.add_argument("--fmusim", help="fmusim of Reference-FMUs (scripts/build_fmusim.sh); Feedthrough.fmu and "
                                    "Dahlquist.fmu beside it are measured too")
    p.add_argument("--out", default="bench-c-hosts", help="output directory (default: bench-c-hosts)")
    p.add_argument("--fmu", help="our FMI 2 FMU (default: SpringBlockFriction.fmu of the FMU folder, built if missing "
                                 "or stale; the folder: stickslip build --help)")
    p.add_argument("--fmu3", help="our FMI 3 FMU, for the FMU states' costs (default: SpringBlockFriction-fmi3.fmu of "
                                  "the FMU folder, built if missing or stale)")
    p.add_argument("--steps", type=int, default=50_000, help="steps of 0.01 s in a long host run (default: 50000)")
    p.add_argument("--repeats", type=int, default=5, help="timed runs of each measurement (default: 5)")
    p.add_argument("--no-carried-python", dest="carried_python", action="store_false",
                   help="leave out the FMUs against the same FMUs built without their carried CPython (which this "
                        "builds, about 20 s)")
    p.add_argument("--state-rounds", type=int, default=1000,
                   help="calls per block of the FMU-state costs beside a doStep (default: 1000)")
    p.set_defaults(handler=run_c_hosts)


def run_c_hosts(args):
    """Run :func:`stickslip.bench.c_hosts_run.run_all`; write c-hosts.json, .md and .png into ``args.out``."""
    from pathlib import Path

    from ..bench.c_hosts_report import write
    from ..bench.c_hosts_run import Inputs, run_all
    from ..bench.fmus import BUILD_DIR, ensure_floor_fmu
    from ..fmu import ensure_fmu
    from ..hosts.c_host import HostBuildError, compile_host

    missing = [path for path in (args.peer, args.fmusim, args.fmu, args.fmu3) if path and not Path(path).is_file()]
    if missing or args.steps < 2 or args.repeats < 1 or args.state_rounds < 1:
        print(f"stickslip bench-c-hosts: no such file {missing}" if missing else
              "stickslip bench-c-hosts: --steps must be at least 2, --repeats and --state-rounds at least 1",
              file=sys.stderr)
        return 2
    try:
        host, host3 = compile_host(BUILD_DIR), compile_host(BUILD_DIR, 3)
    except HostBuildError as exc:
        print(f"stickslip bench-c-hosts: {exc}", file=sys.stderr)
        return 1
    inputs = Inputs(Path(args.fmu) if args.fmu else ensure_fmu(),
                    Path(args.fmu3) if args.fmu3 else ensure_fmu(fmi_version=3), ensure_floor_fmu(), host, host3,
                    BUILD_DIR, args.peer and Path(args.peer).resolve(), args.fmusim and Path(args.fmusim).resolve(),
                    args.carried_python)
    results = run_all(inputs, args.steps, args.repeats, lambda text: print(text, file=sys.stderr, flush=True),
                      args.state_rounds)
    paths = write(Path(args.out), results)
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


#: ``bench-systems`` defaults: zoh's step h (s), adaptive's and me's rtol
ZOH_STEPS = (0.1, 0.01, 0.001, 1e-4)
ADAPTIVE_RTOLS = (1e-5, 1e-7, 1e-9, 3e-10, 1e-11)
ME_RTOLS = (1e-6, 1e-8, 1e-10, 1e-12)
PEER_RTOLS = (1e-8, 1e-10, 1e-11, 1e-12)
#: the chain part's defaults: the engine's and the peer's rtol, the template chains' sizes, the large chain
CHAIN_RTOLS = (1e-6, 1e-8, 1e-10, 1e-12)
CHAIN_FILES = ("systems/bk10-velocity-weakening.toml",)
CHAIN_SIZES = (30, 100)
LARGE_RTOLS = (1e-6, 1e-8)


def add_systems_parser(subparsers):
    p = subparsers.add_parser("bench-systems", help="the masters on chain scenes: error against wall time, "
                                                    "orders, zoh's wall against adaptive's and each master's against "
                                                    "a scipy peer's at matched error")
    p.add_argument("files", nargs="*", metavar="FILE.toml", help="system files (e.g. systems/chain2-coulomb.toml)")
    p.add_argument("--out", default="bench-systems", help="output directory (default: bench-systems)")
    _add_chain_options(p)
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
    p.add_argument("--peer-rtols", type=float, nargs="*", default=list(PEER_RTOLS), metavar="RTOL",
                   help="rtol values of the scipy peer (solve_ivp over the whole chain with events), which each "
                        f"master's run is set beside at matched error (default: {PEER_RTOLS})")
    p.set_defaults(handler=run_systems)


def _add_chain_options(p):
    g = p.add_argument_group("the chain engine against the numba peer (--chain)")
    g.add_argument("--chain", action="store_true", help="run the chain part: engine and peer at matched error, "
                                                        "writes chain.csv, .md, .png and .json")
    g.add_argument("--chain-files", nargs="*", default=list(CHAIN_FILES), metavar="FILE.toml",
                   help=f"system files of chains (default: {' '.join(CHAIN_FILES)})")
    g.add_argument("--chain-sizes", type=int, nargs="*", default=list(CHAIN_SIZES), metavar="N",
                   help=f"template chains of N like blocks, bk10's values (default: {CHAIN_SIZES})")
    g.add_argument("--chain-seed", type=int, default=1, help="seed of the template chains' start offsets (default 1)")
    g.add_argument("--chain-stop-time", type=float, default=300.0, help="simulated time of every chain (s, default "
                                                                        "300)")
    g.add_argument("--chain-rtols", type=float, nargs="+", default=list(CHAIN_RTOLS), metavar="RTOL",
                   help=f"the engine's and the peer's rtol (default: {CHAIN_RTOLS})")
    g.add_argument("--chain-reference-rtols", type=float, nargs="*", default=[1e-10], metavar="RTOL",
                   help="also time the reference (scipy DOP853) at these rtol on chains of at most 10 blocks "
                        "(default: 1e-10)")
    g.add_argument("--repeats", type=int, default=3, help="timed calls per run, the median kept (default 3)")
    g.add_argument("--large-n", type=int, default=1000, help="blocks of the large chain, 0: none (default 1000)")
    g.add_argument("--large-stop-time", type=float, default=1000.0, help="its simulated time (s, default 1000)")
    g.add_argument("--large-rtols", type=float, nargs="+", default=list(LARGE_RTOLS), metavar="RTOL",
                   help=f"its rtol values (default: {LARGE_RTOLS})")
    g.add_argument("--large-truth-rtol", type=float, default=1e-10,
                   help="its errors are against the engine at this rtol (default 1e-10)")
    g.add_argument("--large-no-peer", action="store_true", help="run the large chain with the engine alone")


def run_chain_part(args, meta, progress):
    """The chain part of ``bench-systems`` (:mod:`stickslip.bench.systems_bench_chain`); returns the paths
    written."""
    import os
    from pathlib import Path

    from ..bench.systems_bench_chain import bench_chain, bench_large, template_chains, with_stop_time
    from ..bench.systems_bench_chain_report import write
    from ..systems import load_system

    chains = [with_stop_time(load_system(path), args.chain_stop_time) for path in args.chain_files]
    chains += template_chains(args.chain_sizes, args.chain_seed, args.chain_stop_time, 0.1)
    jobs = [lambda c=c: bench_chain(c, tuple(args.chain_rtols), args.repeats,
                                    tuple(args.chain_reference_rtols) if c.n <= 10 else (), progress)
            for c in chains]
    if args.large_n > 0:
        large = template_chains([args.large_n], args.chain_seed, args.large_stop_time, 1.0)[0]
        jobs.append(lambda: bench_large(large, tuple(args.large_rtols), args.large_truth_rtol, not args.large_no_peer, progress))
    records, paths = [], []
    for job in jobs:  # the files are rewritten after each chain: a stopped run keeps the chains it finished
        records.append(job())
        meta |= {"repeats": args.repeats, "load_end": [round(x, 2) for x in os.getloadavg()]}
        paths = write(Path(args.out), meta, records)
    return paths


def run_systems(args):
    """Run :func:`stickslip.bench.systems_bench.bench_system` on each file (systems.json, .md and .png) and, with
    ``--chain``, the chain part (chain.csv, .md, .png, .json), into ``args.out``; progress on stderr. Exit code."""
    import datetime
    import os
    import platform

    problem = _chain_option_problem(args) if args.chain else None
    if problem or not (args.files or args.chain):
        print(f"stickslip bench-systems: {problem or 'give system files, --chain, or both'}", file=sys.stderr)
        return 2
    meta = {"date": datetime.datetime.now().isoformat(timespec="seconds"),
            "machine": f"{platform.platform()}, {os.cpu_count()} CPUs",
            "load_start": [round(x, 2) for x in os.getloadavg()]}

    def progress(text):
        print(text, file=sys.stderr, flush=True)

    paths = []
    if args.files:
        paths = _run_masters(args, dict(meta), progress)
        if paths is None:
            return 2
    if args.chain:
        paths += run_chain_part(args, dict(meta), progress)
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


def _chain_option_problem(args):
    """What is wrong with the chain part's options (a sentence naming the option), or None."""
    for name in ("chain_rtols", "chain_reference_rtols", "large_rtols", "large_truth_rtol"):
        values = getattr(args, name)
        bad = [r for r in (values if isinstance(values, list) else [values]) if not 1e-14 <= r <= 1e-2]
        if bad:
            return f"--{name.replace('_', '-')} {bad}: allowed is 1e-14 <= rtol <= 1e-2"
    for name in ("chain_stop_time", "large_stop_time"):
        if not getattr(args, name) > 0.0:
            return f"--{name.replace('_', '-')} {getattr(args, name)}: allowed is a time > 0 s"
    if args.repeats < 1 or args.large_n < 0 or any(n < 2 for n in args.chain_sizes):
        return "--repeats must be >= 1, --large-n >= 0 and every --chain-sizes N >= 2"
    return None


def _run_masters(args, meta, progress):
    """The FMU masters on the system files: the paths written, or None (and a message) for a bad --stop-time."""
    import os
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
        return None
    settings = {master: values for master, values in
                (("zoh", args.zoh_steps), ("adaptive", args.adaptive_rtols),
                 ("adaptive-fmi3", args.adaptive_fmi3_rtols), ("me", args.me_rtols),
                 ("scipy-peer", args.peer_rtols)) if values}
    meta["settings"] = settings
    fmu_paths = {2: ensure_fmu(), 3: ensure_fmu(fmi_version=3)}
    records = [bench_system(system, fmu_paths, settings, progress) for system in systems]
    meta["load_end"] = [round(x, 2) for x in os.getloadavg()]
    return write(Path(args.out), meta, records)


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
