"""``stickslip chain``: a chain of blocks (from a template, or a system file) run by the chain engine over any length
of time, with its earthquake catalogue, statistics and figures written to ``--out`` (docs/chains.md).

The template options make ``N`` like blocks (:func:`stickslip.chain.template.chain_system`); ``--kinetic`` and
``--static`` take a law by name or code with its parameters, ``LAW[:NAME=VALUE,...]``: parameters left out take the
default chain's values where the law is the default's (stribeck, constant), else the FMU's start values.
"""

import argparse
import math
from pathlib import Path

from ..core import KINETIC_LAWS, STATIC_LAWS
from ..core.errors import ParameterError
from .chain_ensemble import add_ensemble_options, is_ensemble, run_ensemble_command
from .system import positive_seconds

#: the run's length (s) of a template chain without --stop-time: three loading cycles of the default chain
DEFAULT_STOP_TIME = 300.0
#: the engine's tolerances (run_chain's range)
RTOL_RANGE = (1e-14, 1e-2)
#: the template options: (option, keyword of chain_system, type, help)
TEMPLATE_OPTIONS = (
    ("--n", "n", lambda text: whole_number(text, 1), "number of blocks (default 10)"),
    ("--M", "M", float, "each block's mass, kg (default 1)"),
    ("--kappa", "kappa", float, "each block's spring to its wall, N/m (default 1)"),
    ("--kc", "kc", float, "the coupling springs between neighbours, N/m (default 4)"),
    ("--v-drive", "v_drive", float, "the surface's speed, m/s (default 0.01); the blocks start stuck on it"),
    ("--x-start", "x_start", float, "every block's start position before its offset, m (default 0)"),
    ("--offset-spread", "offset_spread", float,
     "random start offsets, uniform in [-s, s] m, drawn with --seed (default 0.01)"),
    ("--seed", "seed", lambda text: whole_number(text, 0), "seed of the start offsets (default 0)"),
)


def add_chain(subparsers):
    p = subparsers.add_parser(
        "chain", help="run a chain of blocks with the compiled chain engine (a template of N like blocks, or "
                      "--system FILE) over any length of time; write the block events, the catalogue of slip "
                      "events, statistics and figures into --out")
    template = p.add_argument_group("the chain from a template (Burridge-Knopoff defaults)")
    for option, dest, kind, text in TEMPLATE_OPTIONS:
        template.add_argument(option, dest=dest, type=kind, help=text)
    template.add_argument("--kinetic", type=law_option, metavar="LAW[:NAME=VALUE,...]",
                          help="kinetic law by name or code (" + _names(KINETIC_LAWS) + ") and parameters, e.g. "
                               "carlson-langer:F0=1,sigma=0.01,alpha=2.5 (default stribeck:F0=0.5,F_stribeck=0.4,"
                               "v_stribeck=0.05,delta=1,gamma=0)")
    template.add_argument("--static", type=law_option, metavar="LAW[:NAME=VALUE,...]",
                          help="static law by name or code (" + _names(STATIC_LAWS) + ") and parameters (default "
                               "constant:F0=1)")
    p.add_argument("--system", metavar="FILE.toml", help="a system file, or the name of one shipped with stickslip "
                                                         "(e.g. bk100-velocity-weakening), instead of a template")
    p.add_argument("--stop-time", type=positive_seconds,
                   help=f"simulated time, s (default: the system file's, else {DEFAULT_STOP_TIME:g}); no limit")
    p.add_argument("--output-interval", type=interval_option, metavar="SECONDS|none",
                   help="positions.csv every so many s (default: the system file's, else none: no positions)")
    p.add_argument("--rtol", type=rtol_option, default=1e-10,
                   help=f"the engine's relative tolerance, in [{RTOL_RANGE[0]:g}, {RTOL_RANGE[1]:g}] (default 1e-10)")
    p.add_argument("--out", metavar="DIR", help="output folder (default: results/<name>, the name being "
                                                "chain<N>-seed<seed> or the system file's stem)")
    p.add_argument("--reference", action="store_true",
                   help="also run the independent reference (rtol 1e-12; keeps its run in memory: for short runs) "
                        "and compare events, catalogue and positions (reference.json)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_ensemble_options(p)
    p.set_defaults(handler=_chain)


def _names(laws):
    return ", ".join(f"{code} {cls.NAME}" for code, cls in sorted(laws.items()))


def law_option(text):
    """``LAW[:NAME=VALUE,...]`` as ``(LAW, {NAME: VALUE})``; argparse names the option if malformed."""
    law, _, rest = text.partition(":")
    values = {}
    for item in filter(None, rest.split(",")):
        name, sep, value = item.partition("=")
        try:
            values[name.strip()] = float(value)
        except ValueError:
            sep = ""
        if not sep or not math.isfinite(values.get(name.strip(), math.nan)):
            raise argparse.ArgumentTypeError(f"allowed is LAW[:NAME=VALUE,...] with finite values, got {text!r}")
    return law.strip(), values


def whole_number(text, low):
    """A whole number >= ``low``."""
    try:
        value = int(text)
    except ValueError:
        value = low - 1
    if value < low:
        raise argparse.ArgumentTypeError(f"allowed is a whole number >= {low}, got {text!r}")
    return value


def rtol_option(text):
    """A relative tolerance in :data:`RTOL_RANGE`."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not RTOL_RANGE[0] <= value <= RTOL_RANGE[1]:
        raise argparse.ArgumentTypeError(f"allowed is a tolerance in [{RTOL_RANGE[0]:g}, {RTOL_RANGE[1]:g}], "
                                         f"got {text!r}")
    return value


def interval_option(text):
    """``none`` (no positions) or a finite interval > 0 (s)."""
    return "none" if text.strip().lower() == "none" else positive_seconds(text)


def _chain(args):
    from ..chain.folder_run import FolderRun, run_into_folder, slipping_at_start, summarise_folder
    from ..hosts.interrupts import Interrupted
    from ..hosts.progress import TimeProgress
    from ..hosts.run_limits import output_folder

    if is_ensemble(args):
        return run_ensemble_command(args, *_template(args))
    system, stop_time, interval = _system(args)
    out = Path(args.out or Path("results") / system.name)
    output_folder(out, [])
    progress = TimeProgress(system.name, stop_time, not args.quiet)
    with progress as step:
        try:
            run = run_into_folder(system, out, stop_time=stop_time, output_interval=interval, rtol=args.rtol,
                                  progress=step)
        except KeyboardInterrupt:
            kept = ", ".join(p.name for p in FolderRun(out, None, None, 0).files)
            raise Interrupted(f"at t = {progress.reached:.6g} s; kept what was written in {out}: {kept}") \
                from None
    settings = {"system": system.name, "stop_time": stop_time, "output_interval": interval, "rtol": args.rtol,
                "v_drive": system.v_drive, "block_events": run.grouper.n_block_events,
                "open_event": run.grouper.open_event and run.grouper.open_event.summary(),
                "wall_time": run.summary.wall_time, "compile_time": run.summary.compile_time,
                "compiled": run.summary.compiled}
    files = run.files + summarise_folder(out, system, system.name, settings)
    print(_summary_line(system, stop_time, run))
    if args.reference:
        line, written = _reference(system, out, stop_time, interval, slipping_at_start(system), not args.quiet)
        print(line)
        files.append(written)
    print(f"files in {out}: " + ", ".join(p.name for p in files))
    return 0


def _system(args):
    """The chain (a System), its stop time and output interval (None: no positions) from the options."""
    from ..chain.template import chain_system
    from ..systems.system_file import load_system
    from .named_files import SYSTEMS, local_paths, resolve

    interval = None if args.output_interval == "none" else args.output_interval
    given = [option for option, dest, _, _ in TEMPLATE_OPTIONS if getattr(args, dest) is not None]
    given += [f"--{kind}" for kind in ("kinetic", "static") if getattr(args, kind) is not None]
    if args.system is not None:
        if given:
            raise ParameterError(f"{given[0]}: a template option, allowed only without --system")
        with local_paths([resolve(args.system, SYSTEMS)]) as (path,):
            system = load_system(path, check_run_length=False)
        interval = system.output_interval if args.output_interval is None else interval
        return system, args.stop_time or system.stop_time, interval
    values, stop_time, interval = _template(args)
    # the System's own grid is for the FMU masters: the engine takes the interval as it is
    system = chain_system(values.pop("n"), seed=values.pop("seed"), stop_time=stop_time, output_interval=stop_time,
                          **values)
    return system, stop_time, interval


def _template(args):
    """The template's values (keyword arguments of ``chain_system``, ``n`` and ``seed`` included), the stop time
    and the output interval (None: no positions) from the options; ParameterError with --system and ensembles."""
    if args.system is not None and is_ensemble(args):
        raise ParameterError("--seeds, --sweep: an ensemble of the template, allowed only without --system")
    values = {dest: getattr(args, dest) for _, dest, _, _ in TEMPLATE_OPTIONS if getattr(args, dest) is not None}
    values.setdefault("n", 10)
    values.setdefault("seed", 0)
    for kind, laws in (("kinetic", KINETIC_LAWS), ("static", STATIC_LAWS)):
        if getattr(args, kind) is not None:
            values[kind] = _law(kind, laws, *getattr(args, kind))
    interval = None if args.output_interval == "none" else args.output_interval
    return values, args.stop_time or DEFAULT_STOP_TIME, interval


def _law(kind, laws, name, values):
    """``{"law": code, parameter: value}`` of ``--kinetic``/``--static``: the default chain's values under the given
    ones where the law is the default's."""
    from ..chain.template import BK_KINETIC, BK_STATIC

    by_name = {cls.NAME: code for code, cls in laws.items()} | {str(code): code for code in laws}
    if name not in by_name:
        raise ParameterError(f"--{kind} {name!r}: allowed is a {kind} law by name or code: {_names(laws)}")
    code = by_name[name]
    unknown = sorted(set(values) - set(laws[code].PARAMETERS))
    if unknown:
        raise ParameterError(f"--{kind} {laws[code].NAME}: {unknown[0]!r} is not one of its parameters: allowed are "
                             + ", ".join(laws[code].PARAMETERS))
    default = BK_KINETIC if kind == "kinetic" else BK_STATIC
    return (default if default["law"] == code else {"law": code}) | values


def _summary_line(system, stop_time, run):
    """One line: what ran, how long it took, what it found."""
    s = run.summary
    how = "compiled" if s.compiled else "plain Python"
    compile_note = f", compiling {s.compile_time:.1f} s" if s.compile_time else ""
    return (f"{system.name}: {system.n} blocks over {stop_time:g} s in {s.wall_time:.3g} s ({how}{compile_note}): "
            f"{run.grouper.n_block_events} block events, {run.slip_events} slip events"
            + ("; one still open at the end, left out" if run.grouper.open_event else ""))


def _reference(system, out, stop_time, interval, starting, shown):
    """Run the reference: one line saying how the engine compares, and the file written."""
    from ..chain.reference_check import REFERENCE_JSON, compare_with_reference
    from ..hosts.progress import TimeProgress

    with TimeProgress(f"{system.name} reference", stop_time, shown) as step:
        result = compare_with_reference(system, out, stop_time, interval, slipping_at_start=starting, progress=step)
    counts = result["events"]
    paired = (f"paired within {result['max_event_dt']:.2g} s" if result["max_event_dt"] is not None else
              f"not paired: they differ from event {result['first_difference']['event']} on")
    catalogue = result["slip_events"]
    line = (f"reference (rtol {result['rtol']:g}): {sum(c[1] for c in counts.values())} block events, {paired}; "
            f"{catalogue['reference']} slip events against {catalogue['engine']}"
            + (", the same sizes" if catalogue["same_sizes"] else ", sizes differ"))
    if result["max_rel_dx"] is not None:
        line += f"; max |x - x_ref| {result['max_rel_dx']:.2g} of the amplitude"
    return line, Path(out) / REFERENCE_JSON
