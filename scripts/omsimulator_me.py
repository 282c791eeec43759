"""The FMI 2 FMU's model exchange in OMSimulator (built by scripts/build_omsimulator.sh, run by hand: CI cannot get it):
one block (SpringBlockFriction.fmu from `stickslip build`) alone in a strongly coupled system, which OMSimulator
integrates with its own CVODE (BDF, dense Newton, root finding on the FMU's event indicators), on elmer-fig3 at
v_drive 0.1 m/s from x_start 1 m, v_start 0.1 m/s (stick-slip) and from rest (it settles into steady sliding); each
run compared with the project's reference (stickslip.reference, as `stickslip run` compares) on its output grid.
One table row per scene: max |x - reference| over the amplitude (half the reference's range of x) and in m, events
(OMSimulator's block / reference, their kinds paired in order, the largest event-time error), OMSimulator's
warnings and errors (a CVODE failure stops the run with an error, and the script exits 1), wall time.

    python scripts/omsimulator_me.py OMSIMULATOR [--tolerance 1e-10] [--stop-time 2000] [--interval 1]
        [--initial-step H] [--min-step H] [--scenes stick-slip,from-rest] [--out DIR]

The SSP holds the block as component ``b1`` with its start values in ``resources/b1.ssv``
(stickslip.systems.ssp.parameter_set) and OMSimulator's vendor annotation with a VariableStepSolver ("cvode"),
which makes the system strongly coupled (omsimulator_chain.simulation_annotation). OMSimulator then loads the
FMU's ModelExchange interface (a strongly coupled system takes FMI 2 model exchange only), sets the start values
before fmi2EnterInitializationMode, and gives CVODE the absolute tolerance relativeTolerance times each state's
nominal. Its largest step is also its communication interval: CVODE returns at every multiple of it (the output
grid) and at every event, where OMSimulator writes the left limit (--emitEvents=false leaves out the right one);
the MAT file's rows at the grid times are compared, its event rows time the events (stickslip.suite.compare).
"""

import argparse
import dataclasses
import re
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np
from omsimulator_chain import OMS_NAMESPACE, first_error, read_mat, run_omsimulator, simulation_annotation

from stickslip.fmu import ensure_fmu
from stickslip.fmu.variables import INTEGER_OUTPUTS
from stickslip.suite.compare import FMU_COUNTERS, fmu_events, match_events, reference_events
from stickslip.suite.runner import reference_on
from stickslip.suite.scenario import load_scenario
from stickslip.systems.ssp import BLOCK_FILE, NAMESPACES, SSD, parameter_file, parameter_set

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "elmer-fig3-v0.1.toml"
#: the scenes: (x_start (m), v_start (m/s)) on the scenario at v_drive 0.1 m/s
STARTS = {"stick-slip": (1.0, 0.1), "from-rest": (0.0, 0.0)}
COMPONENT = "b1"
#: the block's outputs the result file holds (the SSD's connectors)
OUTPUTS = ("x", "v", "mode", "n_events", "t_last_event", *FMU_COUNTERS.values())
#: the counts OMSimulator ends its output with ("info:    1 warnings"); a CVODE failure is an error, a step that
#: returns one a warning ("Bad return code at time ...")
DIAGNOSTICS = ("warnings", "errors")
#: the DefaultExperiment's (empty) vendor annotation: without one OMSimulator warns of "Wrong/deprecated content"
EXPERIMENT_ANNOTATION = ('<ssd:Annotations><ssc:Annotation type="org.openmodelica"><oms:Annotations />'
                         '</ssc:Annotation></ssd:Annotations>')
EVENT_WINDOW = 1.0  # s: how far apart an event of OMSimulator's and the reference's may be to be paired


def scene(name, stop_time, interval):
    """The elmer-fig3 scenario (v_drive 0.1 m/s) from the start ``STARTS[name]``, run to ``stop_time`` (s) with
    output every ``interval`` (s)."""
    x0, v0 = STARTS[name]
    return dataclasses.replace(load_scenario(SCENARIO), name=name, x0=x0, v0=v0, stop_time=stop_time,
                               output_interval=interval)


def start_values(sc):
    """The block's start values: the scenario's and its (constant) inputs; ValueError if they change."""
    inputs = {(v_drive, force) for _, v_drive, force in sc.breakpoints()}
    if len(inputs) != 1:
        raise ValueError(f"{sc.name}: the inputs change during the run; a scene here holds them constant")
    ((v_drive, force),) = inputs
    return {**sc.start_values(), "v_drive": v_drive, "F_ext": force}


def system_description(name, solver, stop_time):
    """The SSD (text) of a strongly coupled system ``name`` holding the block: the connectors :data:`OUTPUTS`, its
    parameter set, and OMSimulator's CVODE with ``solver`` (relativeTolerance, initialStepSize, minimumStepSize,
    maximumStepSize)."""
    connectors = "".join(f'<ssd:Connector name="{output}" kind="output"><ssc:'
                         f'{"Integer" if output in INTEGER_OUTPUTS else "Real"} /></ssd:Connector>'
                         for output in OUTPUTS)
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<ssd:SystemStructureDescription xmlns:ssd="{NAMESPACES["ssd"]}" '
            f'xmlns:ssc="{NAMESPACES["ssc"]}" xmlns:oms="{OMS_NAMESPACE}" version="1.0" name="{name}">'
            f'<ssd:System name="{name}"><ssd:Elements><ssd:Component name="{COMPONENT}" '
            f'source="resources/{BLOCK_FILE}" type="application/x-fmu-sharedlibrary">'
            f'<ssd:Connectors>{connectors}</ssd:Connectors><ssd:ParameterBindings>'
            f'<ssd:ParameterBinding source="{parameter_file(COMPONENT)}" /></ssd:ParameterBindings></ssd:Component>'
            f'</ssd:Elements>{simulation_annotation("VariableStepSolver", "cvode", solver)}</ssd:System>'
            f'<ssd:DefaultExperiment startTime="0.0" stopTime="{stop_time!r}">{EXPERIMENT_ANNOTATION}'
            f'</ssd:DefaultExperiment></ssd:SystemStructureDescription>')


def write_ssp(sc, solver, fmu, dest):
    """The SSP of the block on scene ``sc`` (its start values, the FMU file ``fmu``, ``solver`` as in
    :func:`system_description`) written to ``dest``; its path."""
    name = re.sub(r"\W", "_", sc.name)
    with zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr(SSD, system_description(name, solver, sc.stop_time))
        archive.writestr(parameter_file(COMPONENT), parameter_set(start_values(sc)))
        archive.write(fmu, f"resources/{BLOCK_FILE}")
    return Path(dest)


def block_signals(signals):
    """``{"time": times, output: values}`` of the block's :data:`OUTPUTS` in a result file's ``signals``
    (:func:`omsimulator_chain.read_mat`; named ``<model>.<system>.b1.<output>``)."""
    found = {}
    for output in OUTPUTS:
        names = [name for name in signals if name.endswith(f".{COMPONENT}.{output}")]
        if len(names) != 1:
            raise KeyError(f"the result file has no single column for the block's {output}: {names}")
        found[output] = signals[names[0]]
    return {"time": np.asarray(signals["time"], float), **found}


def grid_rows(t, grid):
    """The row of ``t`` (s, sorted) at each time of ``grid`` (the last of rows within 1 ns of it); RuntimeError
    naming the first grid time without one."""
    rows = np.searchsorted(t, np.asarray(grid) + 1e-9, side="right") - 1
    missing = (rows < 0) | (np.abs(t[np.maximum(rows, 0)] - grid) > 1e-9)
    if np.any(missing):
        raise RuntimeError(f"the result has no row at t = {float(grid[np.argmax(missing)])!r} s (last row at "
                           f"{float(t[-1])!r} s)")
    return rows


def measure(sc, columns):
    """``{quantity: value}`` of a run's ``columns`` (:func:`block_signals`) against the reference on the scene's
    output grid: max |x - reference| (m) and over the amplitude, the events of the block and of the reference and
    their pairing (stickslip.suite.compare.match_events)."""
    grid = np.linspace(0.0, sc.stop_time, round(sc.stop_time / sc.output_interval) + 1)
    ref = reference_on(sc, grid)
    x = columns["x"][grid_rows(columns["time"], grid)]
    error = float(np.max(np.abs(x - ref.x)))
    amplitude = 0.5 * float(np.ptp(ref.x))
    match = match_events(fmu_events(columns), reference_events(ref), EVENT_WINDOW)
    return {"max_abs_dx": error, "relative": error / amplitude, "amplitude": amplitude,
            "events": int(columns["n_events"][-1]), "reference_events": len(ref.events), "match": match}


def diagnostics(output):
    """``{"warnings": count, "errors": count}`` (:data:`DIAGNOSTICS`) from OMSimulator's ``output``, which prints
    them only if one is not 0."""
    counts = {name: re.search(rf"info: +(\d+) {name}\n", output) for name in DIAGNOSTICS}
    return {name: int(found.group(1)) if found else 0 for name, found in counts.items()}


def row(name, numbers, counts, wall):
    """One table row of :func:`measure`'s ``numbers``, OMSimulator's :func:`diagnostics` ``counts`` and the wall
    time (s)."""
    match = numbers["match"]
    return (f"| {name} | {numbers['relative']:.3g} | {numbers['max_abs_dx']:.3g} | {numbers['events']} / "
            f"{numbers['reference_events']} ({match.n_matched} paired, {match.n_unmatched} unpaired, "
            f"dt {match.max_time_error:.2g} s) | " + " / ".join(str(counts[name]) for name in DIAGNOSTICS)
            + f" | {wall:.2f} |")


def main(argv=None):
    args = parse(argv)
    solver = {"relativeTolerance": args.tolerance, "initialStepSize": args.initial_step,
              "minimumStepSize": args.min_step, "maximumStepSize": args.interval}
    print(f"the block's model exchange in OMSimulator's strongly coupled system ({args.omsimulator}): CVODE at "
          f"relative tolerance {args.tolerance:g}, steps {solver['minimumStepSize']:g} to "
          f"{solver['maximumStepSize']:g} s, elmer-fig3 at v_drive 0.1 m/s over {args.stop_time:g} s")
    print("| scene | max abs(dx) / amplitude | max abs(dx) (m) | events (OMSimulator / reference) "
          "| OMSimulator's warnings / errors | wall (s) |\n|---|---|---|---|---|---|")
    folder = Path(args.out or tempfile.mkdtemp(prefix="oms_me_"))
    folder.mkdir(parents=True, exist_ok=True)
    fmu = ensure_fmu(fmi_version=2)
    failed = 0
    for name in args.scenes:
        sc = scene(name, args.stop_time, args.interval)
        ssp = write_ssp(sc, solver, fmu, folder / f"{name}.ssp")
        try:
            mat, wall, output = run_omsimulator(args.omsimulator, ssp, sc, args.tolerance, False)
            numbers = measure(sc, block_signals(read_mat(mat)))
        except RuntimeError as exc:
            failed += 1
            print(f"| {name} | failed: {first_error(str(exc))} | | | | |", flush=True)
            continue
        print(row(name, numbers, diagnostics(output), wall), flush=True)
    return 1 if failed else 0


def positive(text):
    """A number > 0 from the command line (argparse's type)."""
    value = float(text)
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"{text!r}: allowed is a finite number > 0")
    return value


def scene_names(text):
    """Comma-separated names of :data:`STARTS` (argparse's type)."""
    names = text.split(",")
    unknown = [name for name in names if name not in STARTS]
    if unknown:
        raise argparse.ArgumentTypeError(f"{unknown[0]!r}: allowed are {list(STARTS)}")
    return names


def parse(argv):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("omsimulator", help="the OMSimulator binary")
    parser.add_argument("--scenes", type=scene_names, default=list(STARTS), help=f"comma-separated, of {list(STARTS)}")
    for option, default, text in (("--tolerance", 1e-10, "CVODE's relative tolerance"), ("--stop-time", 2000.0, "s"),
                                  ("--interval", 1.0, "the output grid's interval and CVODE's largest step (s)"),
                                  ("--initial-step", 1e-6, "CVODE's first step (s)"),
                                  ("--min-step", 1e-12, "CVODE's smallest step (s)")):
        parser.add_argument(option, type=positive, default=default, help=f"{text} (default {default:g})")
    parser.add_argument("--out", help="folder for the SSP and result files (default: a new temporary folder)")
    args = parser.parse_args(argv)
    if abs(args.stop_time / args.interval - round(args.stop_time / args.interval)) > 1e-9:
        parser.error(f"--stop-time {args.stop_time!r}: allowed is a whole number of --interval ({args.interval!r} s)")
    return args


if __name__ == "__main__":
    sys.exit(main())
