"""``stickslip system run FILE.toml --master MASTER --out DIR``: a chain of blocks through a master, against the
chain's reference (docs/systems.md)."""

from ..systems.masters import MASTERS


def add_system(subparsers):
    p = subparsers.add_parser("system", help="systems of coupled blocks (chains) described by a TOML file")
    commands = p.add_subparsers(dest="system_command", required=True, metavar="COMMAND")
    run = commands.add_parser(
        "run", help="run a system file through a master and the chain's reference; write DIR/<stem>.csv, .md and "
                    "plots; exit 1 if the error exceeds the file's tolerance for the master")
    run.add_argument("file", metavar="FILE.toml", help="system file")
    run.add_argument("--master", required=True, choices=sorted(MASTERS),
                     help="zoh: fixed step, held inputs (FMI 2 co-simulation); me: FMI 3 model exchange of all "
                          "blocks in one solver; adaptive: FMI 2 co-simulation with events landed, step rejection and "
                          "iterated coupling")
    run.add_argument("--out", default="results", metavar="DIR", help="output folder (default: results)")
    run.add_argument("--step", type=float, help="zoh: communication step in s (default: the file's output_interval)")
    run.add_argument("--rtol", type=float, help="me: the solver's relative tolerance (default 1e-10); "
                     "adaptive: error per second as a fraction of the largest F_S/kappa (default 1e-9)")
    run.add_argument("--fmu", help="the FMU to run (default: the built FMU of the master's FMI version)")
    run.add_argument("--quiet", action="store_true", help="no progress bars")
    run.set_defaults(handler=_run)


def _run(args):
    from ..systems.run import run_system

    outcome = run_system(args.file, args.master, args.out, {"step": args.step, "rtol": args.rtol}, args.fmu,
                         show_progress=not args.quiet)
    print(outcome.summary)
    print(f"report: {outcome.files[1]}")
    return 0 if outcome.ok else 1
