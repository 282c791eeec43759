"""``stickslip stress``: run the stress matrix (:mod:`stickslip.stress`) through the FMU, print the table by group and
write the full tables into ``DIR/stress.md``."""

from pathlib import Path

#: the report's name inside ``--out``
REPORT_NAME = "stress.md"


def add_stress_parser(subparsers):
    p = subparsers.add_parser(
        "stress", help="run the stress matrix (extreme parameters, grazing, long runs) through the FMU",
        description="Run every stress case through the FMU, check it against the reference, the invariants and "
                    "the energy balance, print a table by group (cases, passes, worst error, time per step) and "
                    f"write every column and every case into DIR/{REPORT_NAME}.")
    p.add_argument("--quick", action="store_true", help="only the CI subset (about 30 s)")
    p.add_argument("--group", action="append", metavar="GROUP",
                   help="only this group (repeatable): scale, ratio, drive, overdamped, grazing, chatter, "
                        "comm-step, input-jumps, long")
    p.add_argument("--case", action="append", metavar="NAME", help="only the case(s) whose name contains NAME")
    p.add_argument("--list", action="store_true", help="list the cases and exit")
    p.add_argument("--fmu", help="FMU to test (default: SpringBlockFriction.fmu of the FMU folder, built if missing or "
                                 "stale; the folder: stickslip build --help)")
    p.add_argument("--out", default="results", metavar="DIR",
                   help=f"output folder (default: results): DIR/{REPORT_NAME}, the tables by group and by case with "
                        "every column, the failures and the details")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(handler=run_stress)


def run_stress(args):
    """Handler of ``stickslip stress``; returns 0 unless a case failed unexpectedly (known bugs are listed)."""
    from ..fmu import ensure_fmu
    from ..hosts.run_limits import output_folder
    from ..stress import case_runs
    from ..stress.cases import stress_cases

    cases = stress_cases(quick=args.quick, groups=args.group)
    if args.case:
        cases = [c for c in cases if any(name in c.name for name in args.case)]
    if args.list:
        for c in cases:
            print(f"{c.group:12s} {c.name:45s} {'quick' if c.quick else '':5s} {c.note}")
        return 0
    report = output_folder(args.out, [REPORT_NAME]) / REPORT_NAME
    report.unlink(missing_ok=True)  # written last: a run that stops leaves none
    fmu_path = ensure_fmu() if args.fmu is None else Path(args.fmu)
    outcomes = case_runs.run_stress(fmu_path, cases, progress=not args.no_progress)
    n_passed = sum(o.passed for o in outcomes)
    n_known = sum(bool(o.known_bug) and not o.passed for o in outcomes)
    n_unexpected = sum(o.unexpected for o in outcomes)
    print(case_runs.console_summary(outcomes))
    print(f"{n_passed}/{len(outcomes)} stress cases passed, {n_known} failed with known bugs, "
          f"{n_unexpected} unexpected")
    report.write_text(_report(outcomes))
    print(f"report: {report}")
    return 0 if n_unexpected == 0 else 1


def _report(outcomes):
    """The Markdown report: the table by group and the table by case with every column, the failures, the
    details."""
    from ..stress import case_runs

    failures = case_runs.failure_lines(outcomes)
    text = ["# Stress matrix", "", "Errors are normalized: state error vs the reference (|dx|/x_scale, "
            "|dv|/v_scale), difference to a refined communication grid, and the largest energy-balance residual "
            "of a smooth piece relative to the run's energy scale. Time per step is the wall time of one "
            "fmi2DoStep.", "", case_runs.summary_table(outcomes), "", "## Cases", "", case_runs.case_table(outcomes),
            ""]
    if failures:
        text += ["## Failures", "", *failures, ""]
    text += ["## Details", ""]
    text += [f"- {o.name}: " + "; ".join(f"{k}: {v}" for k, v in o.details.items()) for o in outcomes if o.details]
    return "\n".join(text) + "\n"
