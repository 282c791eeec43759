"""``stickslip system run FILE.toml|NAME --master MASTER --out DIR``: a chain of blocks through a master, against the
chain's reference; ``stickslip system ssp FILE.toml|NAME --out DIR``: the chain as an SSP file (docs/systems.md). A NAME
is that of a system file shipped with the package (e.g. chain2-coulomb)."""

import argparse
import math

from ..systems.names import ENGINES, MASTER_NAMES

FILE_HELP = "system file, or the name of a system shipped with stickslip (e.g. chain2-coulomb)"


def add_system(subparsers):
    p = subparsers.add_parser("system", help="systems of coupled blocks (chains) described by a TOML file")
    commands = p.add_subparsers(dest="system_command", required=True, metavar="COMMAND")
    run = commands.add_parser(
        "run", help="run a system file through a master and the chain's reference; write DIR/<stem>-<master>.csv, "
                    ".md and plots (zoh with --engine: <stem>-zoh-<engine>.*); exit 1 if the error exceeds the file's "
                    "tolerance for the master (zoh is judged only where the file sets one; a chain whose trajectory "
                    "diverges, by its largest Lyapunov exponent, is judged by two-sample tests of its slip events "
                    "against the reference at two tolerances instead) or the run fails")
    run.add_argument("file", metavar="FILE.toml", help=FILE_HELP)
    run.add_argument("--master", required=True, choices=sorted(MASTER_NAMES),
                     help="zoh: fixed step, held inputs (FMI 2 co-simulation); me: FMI 3 model exchange of all "
                          "blocks in one solver; adaptive: FMI 2 co-simulation (--fmi 3: FMI 3 with early return) "
                          "with events landed, step rejection and iterated coupling; native: the compiled chain "
                          "engine, no FMU (also writes DIR/<stem>-native-block_events.csv)")
    run.add_argument("--out", default="results", metavar="DIR", help="output folder (default: results)")
    run.add_argument("--step", type=step_seconds,
                     help="zoh: communication step in s (default: the file's output_interval)")
    run.add_argument("--engine", choices=ENGINES,
                     help="zoh: write the system as an SSP file (block and coupling FMUs) and step it in this engine "
                          "(default: FMPy with the coupling computed by the master)")
    run.add_argument("--rtol", type=float, help="me, native: the solver's relative tolerance (default 1e-10); "
                     "adaptive: error per second as a fraction of the largest F_S/kappa (default 3e-10)")
    run.add_argument("--no-reference", action="store_true",
                     help="do not run the reference: nothing is compared (the report says so), the exit status says "
                          "only whether the run failed; with --master native no run is refused for its length")
    run.add_argument("--fmi", type=int, choices=(2, 3),
                     help="adaptive: the FMU it runs: 2 (events landed by root search) or 3 (early return from doStep "
                          "at each event); default: the FMI version of --fmu, else 2")
    run.add_argument("--fmu", help="the FMU to run (default: the built FMU of the master's FMI version); adaptive "
                                   "runs the scheme of its FMI version unless --fmi is given")
    run.add_argument("--quiet", action="store_true", help="no progress bars")
    run.set_defaults(handler=_run)
    ssp = commands.add_parser("ssp", help="write the system as DIR/<stem>.ssp: the block FMUs, one coupling FMU per "
                                          "block, their values and connections, the fixed step")
    ssp.add_argument("file", metavar="FILE.toml", help=FILE_HELP)
    ssp.add_argument("--out", default="results", metavar="DIR", help="output folder (default: results)")
    ssp.add_argument("--step", type=step_seconds, help="the fixed step in s (default: the file's output_interval)")
    ssp.add_argument("--fmu", help="the block FMU (default: the built FMI 2 FMU)")
    ssp.set_defaults(handler=_ssp)


def step_seconds(text):
    """The value of a ``--step`` option: a finite time step > 0 (s); argparse names the option if not."""
    return positive_seconds(text, "step")


def positive_seconds(text, what="time"):
    """A finite ``what`` > 0 (s) from an option's text; argparse names the option if not."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f"allowed is a finite {what} > 0 s, got {text!r}")
    return value


def _run(args):
    from ..systems.run import run_system
    from .named_files import SYSTEMS, local_paths, resolve

    options = {"step": args.step, "rtol": args.rtol, "engine": args.engine, "fmi": args.fmi}
    with local_paths([resolve(args.file, SYSTEMS)]) as (path,):
        outcome = run_system(path, args.master, args.out, options, args.fmu, show_progress=not args.quiet,
                             reference=not args.no_reference)
    print(outcome.summary)
    print(f"report: {outcome.files[1]}")
    return 0 if outcome.ok else 1


def _ssp(args):
    from ..fmu import ensure_fmu
    from ..fmu.coupling import ensure_coupling_fmu
    from ..fmu.variables import START_VALUES
    from ..hosts.fmpy_host import read_model_description
    from ..hosts.run_limits import output_folder
    from ..systems import load_system
    from ..systems.ssp import write_ssp
    from .named_files import SYSTEMS, local_paths, resolve

    with local_paths([resolve(args.file, SYSTEMS)]) as (path,):
        system = load_system(path)
    step = system.output_interval if args.step is None else args.step
    if args.fmu is not None:
        read_model_description(args.fmu, needs=START_VALUES)
    dest = output_folder(args.out, [f"{system.name}.ssp"]) / f"{system.name}.ssp"
    print(write_ssp(system, step, args.fmu or ensure_fmu(), ensure_coupling_fmu(), dest))
    return 0
