"""``stickslip stress``: run the stress matrix (:mod:`stickslip.stress`) through the FMU and print the table."""

from pathlib import Path


def add_stress_parser(subparsers):
    p = subparsers.add_parser(
        "stress", help="run the stress matrix (extreme parameters, grazing, long runs) through the FMU",
        description="Run every stress case through the FMU, check it against the reference, the invariants and "
                    "the energy balance, and print a table by group (cases, passes, worst errors, time per step).")
    p.add_argument("--quick", action="store_true", help="only the CI subset (about 30 s)")
    p.add_argument("--group", action="append", metavar="GROUP",
                   help="only this group (repeatable): scale, ratio, drive, overdamped, grazing, chatter, "
                        "comm-step, input-jumps, long")
    p.add_argument("--case", action="append", metavar="NAME", help="only the case(s) whose name contains NAME")
    p.add_argument("--list", action="store_true", help="list the cases and exit")
    p.add_argument("--fmu", help="FMU to test (default: dist/SpringBlockFriction.fmu, built if missing or stale)")
    p.add_argument("--report", metavar="FILE", help="also write the tables and failures as Markdown to FILE")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(handler=run_stress)


def run_stress(args):
    """Handler of ``stickslip stress``; returns 0 unless a case failed unexpectedly (known bugs are listed)."""
    from ..fmu import ensure_fmu
    from ..stress import case_runs
    from ..stress.cases import stress_cases

    cases = stress_cases(quick=args.quick, groups=args.group)
    if args.case:
        cases = [c for c in cases if any(name in c.name for name in args.case)]
    if args.list:
        for c in cases:
            print(f"{c.group:12s} {c.name:45s} {'quick' if c.quick else '':5s} {c.note}")
        return 0
    fmu_path = ensure_fmu() if args.fmu is None else Path(args.fmu)
    outcomes = case_runs.run_stress(fmu_path, cases, progress=not args.no_progress)
    table = case_runs.summary_table(outcomes)
    failures = case_runs.failure_lines(outcomes)
    n_passed = sum(o.passed for o in outcomes)
    n_known = sum(bool(o.known_bug) and not o.passed for o in outcomes)
    n_unexpected = sum(o.unexpected for o in outcomes)
    print(table)
    for line in failures:
        print(line)
    print(f"{n_passed}/{len(outcomes)} stress cases passed, {n_known} failed with known bugs, "
          f"{n_unexpected} unexpected")
    if args.report:
        text = ["# Stress matrix", "", "Errors are normalized: state error vs the reference (|dx|/x_scale, "
                "|dv|/v_scale), difference to a refined communication grid, and the largest energy-balance residual "
                "of a smooth piece relative to the run's energy scale. Time per step is the wall time of one "
                "fmi2DoStep.", "", table, "", "## Cases", "", case_runs.case_table(outcomes), ""]
        if failures:
            text += ["## Failures", "", *failures, ""]
        text += ["## Details", ""]
        for o in outcomes:
            if o.details:
                text.append(f"- {o.name}: " + "; ".join(f"{k}: {v}" for k, v in o.details.items()))
        Path(args.report).write_text("\n".join(text) + "\n")
    return 0 if n_unexpected == 0 else 1

