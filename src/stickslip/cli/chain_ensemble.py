"""The ensemble options of ``stickslip chain``: ``--seeds``, ``--sweep``, ``--workers`` and ``--dask`` run many
chains of the template, in parallel, with their catalogues merged and statistics combined
(:mod:`stickslip.chain.ensemble`, docs/chains.md)."""

import argparse


def add_ensemble_options(parser):
    """Add the ensemble options to the parser of ``stickslip chain``."""
    g = parser.add_argument_group("ensembles: many chains of the template, in parallel")
    g.add_argument("--seeds", type=_parsed("parse_seeds"), metavar="LIST",
                   help="one chain per seed of the start offsets: 0-9 or 0,1,2 (or a mix, 0-4,10); each chain into "
                        "--out/seed<k>/, every catalogue merged into --out/slip_events.csv (a first column member, "
                        "members.csv says which is which), the statistics combined (ensemble.md)")
    g.add_argument("--sweep", type=_parsed("parse_sweep"), metavar="NAME=V1,V2,...",
                   help="the template with NAME (M, kappa, kc, v_drive, x_start, offset_spread, kinetic.<p> or "
                        "static.<p>) at each value, for every seed (--seeds, else --seed); each into "
                        "--out/NAME=V-seed<k>/, the statistics combined per value")
    g.add_argument("--workers", type=_workers, metavar="N",
                   help="worker processes on this machine (default: one per core; 1: one chain after another), or "
                        "the workers of --dask local")
    g.add_argument("--dask", metavar="ADDRESS",
                   help="run the chains on this Dask scheduler (e.g. tcp://host:8786; its workers must see --out, "
                        "a shared file system), or 'local': a Dask cluster of --workers processes on this machine")


def _parsed(name):
    """An argparse type of the ensemble module's parser ``name``: its error becomes argparse's message."""
    def parse(text):
        from ..chain import ensemble

        try:
            return getattr(ensemble, name)(text)
        except ensemble.EnsembleError as exc:
            raise argparse.ArgumentTypeError(str(exc).split(": ", 1)[-1]) from None

    parse.__name__ = name.removeprefix("parse_")
    return parse


def _workers(text):
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"allowed is a whole number >= 1, got {text!r}")
    return value


def is_ensemble(args):
    """Whether the options ask for an ensemble."""
    return args.seeds is not None or args.sweep is not None


def run_ensemble_command(args, values, stop_time, interval):
    """Run the ensemble of the template ``values`` (keyword arguments of
    :func:`stickslip.chain.template.chain_system`, ``n`` and ``seed`` included) over ``stop_time`` (s), positions
    every ``interval`` s (None: none); print what finished and where; return the exit code."""
    from pathlib import Path

    from ..chain.ensemble import ensemble_members, run_ensemble
    from ..core.errors import ParameterError

    for option, clash in (("--seed", args.seeds is not None and args.seed is not None),
                          ("--reference", args.reference)):
        if clash:
            raise ParameterError(f"{option}: not with --seeds or --sweep (give the seeds with --seeds)"
                                 if option == "--seed" else f"{option}: a single chain's check, not an ensemble's")
    values = dict(values)
    n, seed = values.pop("n"), values.pop("seed")
    members = ensemble_members(values, args.seeds or [seed], args.sweep)
    out = Path(args.out or Path("results") / f"chain{n}-ensemble")
    run = run_ensemble(n, members, stop_time, out, rtol=args.rtol, output_interval=interval,
                       workers=args.workers, dask=args.dask, progress=not args.quiet)
    print(f"{len(run.finished)} chains of {n} blocks over {stop_time:g} s in {run.wall_time:.3g} s; "
          f"merged catalogue {run.files['slip_events']}, statistics {run.files.get('md', 'none')}")
    return 0
