"""The commands of ``stickslip``: their parser and :func:`dispatch`, which runs the one named.

Each command is a function ``add_<command>(subparsers)`` that adds its parser and
sets ``handler``, a function of the parsed arguments returning the exit code. Parsers are built from light
modules only; a handler imports what its command needs (NumPy, SciPy, FMPy, Matplotlib) when it runs.
"""

import argparse
import sys
from pathlib import Path

from ..core.errors import StickSlipError
from .analysis import add_bifurcation, add_chart, add_map, add_slow_manifold, add_vc
from .bench import add_bench_parser, add_c_hosts_parser, add_systems_parser, add_versus_parser
from .chain import add_chain
from .stress import add_stress_parser
from .system import add_system


def add_run(subparsers):
    p = subparsers.add_parser("run", help="run scenarios through the FMU and the reference and report")
    p.add_argument("paths", nargs="*", metavar="PATH",
                   help="scenario files, directories of *.toml files, or names of the scenarios shipped with stickslip "
                        "(e.g. elmer-fig3-v0.1); none: every shipped scenario")
    p.add_argument("--out", default="results", help="output directory (default: results)")
    p.add_argument("--jobs", type=int, default=2, help="worker processes (default: 2)")
    p.add_argument("--fmu", help="FMU to test (default: SpringBlockFriction.fmu of the FMU folder, built if missing or "
                                 "stale; the folder: stickslip build --help)")
    p.add_argument("--interface", choices=("cs", "me"),
                   help="test the FMU of --fmu (default: the FMI 3 FMU SpringBlockFriction-fmi3.fmu of the FMU "
                        "folder) through "
                        "co-simulation or model exchange (FMPy's CVode, tolerances from each scenario's "
                        "[model_exchange]); the FMI 2 FMU has both too")
    p.set_defaults(handler=_run)


def _run(args):
    from ..suite.runner import run_suite
    from .named_files import SCENARIOS, local_paths, resolve, shipped

    files = [resolve(path, SCENARIOS) for path in args.paths] or list(shipped(SCENARIOS).values())
    with local_paths(files) as paths:
        return 0 if run_suite(paths, args.out, jobs=args.jobs, fmu_path=args.fmu, interface=args.interface).ok else 1


def add_build(subparsers):
    p = subparsers.add_parser("build", aliases=["build-fmu"],
                              help="build SpringBlockFriction.fmu (FMI 2), SpringBlockFriction-fmi3.fmu (FMI 3) "
                                   "and ChainCoupling.fmu (a chain's coupling springs, FMI 2) into DIR if missing or "
                                   "stale, and print their paths")
    p.add_argument("--out", metavar="DIR",
                   help="output folder (default: the FMU folder that every command builds its FMUs in when none is "
                        "named: $STICKSLIP_DIST if set, else in a checkout its dist/, else the user's cache "
                        "$XDG_CACHE_HOME/stickslip/fmus/<tag of the sources>/, default ~/.cache/...)")
    p.set_defaults(handler=_build)


def _build(args):
    from ..fmu import FILE_NAMES, FMI_VERSIONS, default_fmu_path, ensure_fmu

    from ..fmu.coupling import COUPLING_FILE, ensure_coupling_fmu

    for version in FMI_VERSIONS:
        dest = default_fmu_path(version) if args.out is None else Path(args.out).resolve() / FILE_NAMES[version]
        print(ensure_fmu(dest, version))
    print(ensure_coupling_fmu(None if args.out is None else Path(args.out).resolve() / COUPLING_FILE))
    return 0


COMMANDS = (add_run, add_build, add_bench_parser, add_c_hosts_parser, add_systems_parser, add_versus_parser,
            add_bifurcation, add_vc, add_map, add_slow_manifold, add_chart, add_stress_parser, add_system, add_chain)


def build_parser():
    """The ``stickslip`` parser with every command's; building it imports no numerical module (each handler
    imports what its command needs), so that ``--help`` answers at once."""
    parser = argparse.ArgumentParser(
        prog="stickslip", description="Spring-block dry friction: FMU, reference integrator and scenario suite.")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in COMMANDS:
        add(subparsers)
    return parser


def dispatch(argv=None):
    """Run the command that ``argv`` (default ``sys.argv[1:]``) names; its exit code (0 success, 1 failure, 2
    usage). KeyboardInterrupt goes to the caller (:func:`stickslip.cli.main`)."""
    args = build_parser().parse_args(argv)
    try:
        return args.handler(args)
    except (StickSlipError, OSError) as exc:
        print(f"stickslip {args.command}: {exc}", file=sys.stderr)
        return 1
