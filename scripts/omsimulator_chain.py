"""A system file's chain in OMSimulator (built by scripts/build_omsimulator.sh, run by hand: CI cannot get it): its
fixed-step master oms-ma at each step and its variable-step masters oms-mav and oms-mav2 at each tolerance, every
run compared with the chain's reference as `stickslip system run` does (stickslip.systems.compare); one table row
per run: error (max |dx| of any block over the amplitude), events, wall time.

    python scripts/omsimulator_chain.py OMSIMULATOR SYSTEM.toml [--steps 0.1,0.01,0.001]
        [--tolerances 1e-2,1e-3,1e-4] [--masters ma,mav,mav2] [--input-extrapolation]
        [--max-step H] [--initial-step H] [--min-step H] [--out DIR]

The SSP is `stickslip system ssp`'s (stickslip.systems.ssp.write_ssp, FMUs from `stickslip build`) with
OMSimulator's vendor annotation added to its system, which names the master and its step sizes: without it
OMSimulator refuses the system ("[NewSystem] internal error"), and it overrides the command line's --stepSize,
--initialStepSize and --minimumStepSize. The block FMU declares its output x independent of its inputs (without
that OMSimulator finds an algebraic loop through the coupling FMUs and oms-mav stops after one step), so oms-ma
sets each force from the positions of the same communication point and equals the `zoh` master in FMPy (printed),
whose force F(x(t_k)) has no delay, unlike the SSP engines' (docs/systems.md). --block-order declares the block's
maxOutputDerivativeOrder in the SSP's copy (see declared_output_order). Results come from OMSimulator's MAT file
(its CSV has 12 digits), every communication point (the default logging interval 0, --emitEvents=false); oms-ma is
sampled on the system's output grid, the variable-step masters on their own communication points, where the
reference is evaluated.
"""

import argparse
import io
import re
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np
import scipy.io

from stickslip.fmu import ensure_fmu
from stickslip.fmu.coupling import ensure_coupling_fmu
from stickslip.reference import simulate_chain
from stickslip.systems.compare import compare
from stickslip.systems.master import SystemResult, step_events
from stickslip.systems.ssp import BLOCK_FILE, SSD, write_ssp
from stickslip.systems.system_file import load_system
from stickslip.systems.zoh import ZohMaster

OMS_NAMESPACE = "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd"
#: the masters: (OMSimulator's name, its annotation element)
MASTERS = {"ma": ("oms-ma", "FixedStepMaster"), "mav": ("oms-mav", "VariableStepMaster"),
           "mav2": ("oms-mav2", "VariableStepMaster")}
#: the block's columns read from the result file
COLUMNS = ("x", "v", "mode", "n_events", "t_last_event")
MA_TOLERANCE = 1e-12  # OMSimulator's --tolerance for oms-ma


def simulation_annotation(element, description, settings):
    """OMSimulator's ``ssd:Annotations`` element of a system: its SimulationInformation holds
    ``<oms:{element} description=...>`` with ``settings`` ({attribute: number}) as attributes. The element chooses the
    system's kind: FixedStepMaster or VariableStepMaster a weakly coupled system (co-simulation), VariableStepSolver
    a strongly coupled one (model exchange, OMSimulator's own solver)."""
    attributes = " ".join(f'{key}="{value!r}"' for key, value in settings.items())
    return (f'<ssd:Annotations><ssc:Annotation type="org.openmodelica"><oms:Annotations><oms:SimulationInformation>'
            f'<oms:{element} description="{description}" {attributes} /></oms:SimulationInformation></oms:Annotations>'
            f'</ssc:Annotation></ssd:Annotations>')


def master_annotation(master, steps):
    """OMSimulator's ``ssd:Annotations`` element choosing ``master`` (a key of MASTERS) with ``steps`` (s):
    ``{"stepSize": h}`` for ma, ``initialStepSize``, ``minimumStepSize``, ``maximumStepSize`` for mav, mav2."""
    name, element = MASTERS[master]
    return simulation_annotation(element, name, steps)


def oms_ssp(system, master, steps, dest, block_order=None):
    """The system's SSP (fixed step: the largest of ``steps``) written to ``dest`` with ``master_annotation`` added
    as the system's last element, the block's ``maxOutputDerivativeOrder`` declared ``block_order`` unless None; its
    path."""
    plain = write_ssp(system, max(steps.values()), ensure_fmu(fmi_version=2), ensure_coupling_fmu(),
                      Path(dest).with_suffix(".plain.ssp"))
    with zipfile.ZipFile(plain) as source, zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as archive:
        for entry in source.infolist():
            data = source.read(entry.filename)
            if entry.filename == SSD:
                text = data.decode().replace("<ssd:SystemStructureDescription ",
                                             f'<ssd:SystemStructureDescription xmlns:oms="{OMS_NAMESPACE}" ', 1)
                end = text.rindex("</ssd:System>")
                data = (text[:end] + master_annotation(master, steps) + text[end:]).encode()
            elif entry.filename == f"resources/{BLOCK_FILE}" and block_order is not None:
                data = declared_output_order(data, block_order)
            archive.writestr(entry, data)
    plain.unlink()
    return Path(dest)


def declared_output_order(fmu, order):
    """The FMU archive ``fmu`` (bytes) with ``maxOutputDerivativeOrder`` declared ``order``. OMSimulator asks an FMU
    for the derivative of its declared order only, never the lower ones (``fmi2GetRealOutputDerivatives`` with one
    order for one variable, and ``fmi2SetRealInputDerivatives`` with it as is); with the block's order 2 its
    coupling inputs get accelerations and no velocities, so the coupling's ``dF/dt`` stays 0. The block answers
    order 1 as it is (``v``)."""
    source, out = zipfile.ZipFile(io.BytesIO(fmu)), io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as archive:
        for entry in source.infolist():
            data = source.read(entry.filename)
            if entry.filename == "modelDescription.xml":
                data, count = re.subn(rb'maxOutputDerivativeOrder="\d+"', f'maxOutputDerivativeOrder="{order}"'.encode(),
                                      data)
                if count != 1:
                    raise ValueError("the block's model description declares no maxOutputDerivativeOrder")
            archive.writestr(entry, data)
    return out.getvalue()


def run_omsimulator(omsimulator, ssp, system, tolerance, input_extrapolation):
    """OMSimulator on ``ssp`` to ``system.stop_time`` (s): ``(result file, wall time (s), its standard output)``;
    RuntimeError with its output if it fails."""
    result = Path(ssp).with_suffix(".mat")
    command = [str(Path(omsimulator).resolve()), f"--stopTime={system.stop_time!r}", f"--tolerance={tolerance!r}",
               f"--inputExtrapolation={'true' if input_extrapolation else 'false'}", "--emitEvents=false",
               f"--resultFile={result.name}", Path(ssp).name]
    start = time.perf_counter()
    run = subprocess.run(command, capture_output=True, text=True, timeout=3600, cwd=Path(ssp).parent)
    wall = time.perf_counter() - start
    if run.returncode != 0 or not result.exists() or "error:" in run.stdout:
        raise RuntimeError(f"{' '.join(command)}: exit {run.returncode}\n{run.stdout[-3000:]}{run.stderr[-2000:]}")
    return result, wall, run.stdout


def read_mat(path):
    """``{signal name: values over time}`` of an OpenModelica result file (MAT v4, ``binTrans``) as OMSimulator
    writes it: ``name`` and ``dataInfo`` hold a column per signal; a signal is row ``|dataInfo[1]| - 1`` of
    ``data_<dataInfo[0]>`` (``data_1``: parameters, two values; ``data_2``: one row per signal, first ``time``),
    negated if the index is negative."""
    mat = scipy.io.loadmat(str(path), chars_as_strings=False)
    names = ["".join(column).rstrip("\x00 ") for column in np.asarray(mat["name"]).T]
    info = np.asarray(mat["dataInfo"]).astype(int)
    signals = {}
    for j, name in enumerate(names):
        data = mat[f"data_{info[0, j] or 2}"]
        row = abs(info[1, j]) - 1
        signals[name] = np.sign(info[1, j] or 1) * np.asarray(data[row], float)
    return signals


def block_columns(signals, n):
    """``{column: array (times, n)}`` of COLUMNS for blocks b1..bN (signals named ``<root>.b<i>.<column>``) and the
    times; of points less than 1 ns apart only the last is kept (OMSimulator adds its step to the time, so oms-ma
    ends with a step of about 1e-12 s to the stop time, which it writes twice)."""
    t = signals["time"]
    keep = np.append(np.diff(t) > 1e-9, True)
    columns = {"time": t[keep]}
    for column in COLUMNS:
        found = [[name for name in signals if name.endswith(f".b{i}.{column}")] for i in range(1, n + 1)]
        if any(len(names) != 1 for names in found):
            raise KeyError(f"the result file has no single column for each block's {column}: {found}")
        columns[column] = np.stack([signals[names[0]][keep] for names in found], axis=1)
    return columns


def to_result(master, columns, grid, wall_time):
    """The :class:`SystemResult` of a run's ``columns`` (:func:`block_columns`): events from every communication
    point, samples on ``grid`` (s) if every grid time is a communication point, else on the points themselves."""
    events, complete = [], True
    count, mode = columns["n_events"].astype(int), columns["mode"].astype(int)
    for k in range(1, len(columns["time"])):
        found, whole = step_events(columns["t_last_event"][k], mode[k - 1], mode[k], count[k - 1], count[k])
        events, complete = events + found, complete and whole
    t = columns["time"]
    if t[-1] < grid[-1] - 1e-9:
        raise RuntimeError(f"{master} stopped at t = {float(t[-1])!r} s, before the stop time {float(grid[-1])!r} s")
    rows = np.searchsorted(t, np.asarray(grid) - 1e-9)
    on_grid = bool(np.all(rows < t.size)) and np.allclose(t[np.minimum(rows, t.size - 1)], grid, rtol=0, atol=1e-9)
    rows = rows if on_grid else np.arange(t.size)
    return SystemResult(master, t[rows], columns["x"][rows], columns["v"][rows], mode[rows], events, complete,
                        count[-1], wall_time, stats={"communication points": t.size - 1})


def measure(system, result):
    """The comparison of ``result`` with the chain's reference on its times, as ``stickslip system run`` does."""
    reference = simulate_chain(system.chain_blocks(), system.coupling, system.v_drive, result.t)
    return compare(result, reference, system.tolerances["zoh"])


def zoh_difference(system, result, step):
    """max |x_OMSimulator - x_zoh| (m) on the output grid: the ``zoh`` master in FMPy at ``step`` (s)."""
    zoh = ZohMaster(step=step).run(system, ensure_fmu(fmi_version=2))
    return float(np.max(np.abs(result.x - zoh.x)))


def row(label, setting, comparison, result, extra=""):
    """One table row: master, step or tolerance, error of the amplitude, events (master / reference and the largest
    event-time error, s), communication points, wall time (s)."""
    dt = np.nanmax(comparison.max_event_dt) if np.any(np.isfinite(comparison.max_event_dt)) else float("nan")
    return (f"| {label} | {setting} | {comparison.max_rel_dx:.3g} | {int(np.sum(comparison.master_events))} / "
            f"{int(np.sum(comparison.reference_events))}, dt {dt:.2g} s | {result.stats['communication points']} | "
            f"{result.wall_time:.2f} | {extra} |")


def runs(args, system):
    """Every requested run: ``(label, setting, steps annotation, tolerance)``."""
    for master in args.masters:
        if master == "ma":
            for h in args.steps:
                yield master, f"h = {h:g} s", {"stepSize": h}, MA_TOLERANCE
        else:
            steps = {"initialStepSize": args.initial_step, "minimumStepSize": args.min_step,
                     "maximumStepSize": args.max_step or system.output_interval}
            for tolerance in args.tolerances:
                yield master, f"tol = {tolerance:g}", steps, tolerance


def main(argv=None):
    args = parse(argv)
    system = load_system(args.system)
    print(f"{system.name} in {args.omsimulator}, input extrapolation {'on' if args.input_extrapolation else 'off'}"
          + ("" if args.block_order is None else f", the block's declared output derivative order {args.block_order}"))
    print("| master | step / tolerance | max abs(dx) / amplitude | events (master / reference) "
          "| communication points | wall (s) | ma - zoh in FMPy (m) |\n|---|---|---|---|---|---|---|")
    folder = Path(args.out or tempfile.mkdtemp(prefix="oms_chain_"))
    folder.mkdir(parents=True, exist_ok=True)
    for k, (master, setting, steps, tolerance) in enumerate(runs(args, system)):
        ssp = oms_ssp(system, master, steps, folder / f"{system.name}-{master}-{k}.ssp", args.block_order)
        try:
            mat, wall, _ = run_omsimulator(args.omsimulator, ssp, system, tolerance, args.input_extrapolation)
            result = to_result(f"oms-{master}", block_columns(read_mat(mat), system.n), system.times(), wall)
        except RuntimeError as exc:
            print(f"| oms-{master} | {setting} | failed: {first_error(str(exc))} | | | | |", flush=True)
            continue
        extra = f"{zoh_difference(system, result, steps['stepSize']):.2g}" if master == "ma" and args.check else ""
        print(row(f"oms-{master}", setting, measure(system, result), result, extra), flush=True)


def first_error(text):
    """The first ``error:`` line of OMSimulator's output in ``text``, else its last line."""
    lines = [line for line in text.splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith("error:")]
    return (errors or lines[-1:] or ["?"])[0].strip()


def floats(text):
    return [float(value) for value in text.split(",")]


def parse(argv):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("omsimulator", help="the OMSimulator binary")
    parser.add_argument("system", help="a system file (systems/*.toml)")
    parser.add_argument("--masters", type=lambda s: s.split(","), default=list(MASTERS))
    parser.add_argument("--steps", type=floats, default=[0.1, 0.01, 0.001], help="oms-ma's steps (s)")
    parser.add_argument("--tolerances", type=floats, default=[1e-2, 1e-3, 1e-4], help="oms-mav's tolerances")
    parser.add_argument("--max-step", type=float, help="oms-mav's largest step (s; default: output interval)")
    parser.add_argument("--initial-step", type=float, default=1e-3, help="oms-mav's first step (s)")
    parser.add_argument("--min-step", type=float, default=1e-8, help="oms-mav's smallest step (s)")
    parser.add_argument("--input-extrapolation", action="store_true",
                        help="OMSimulator's --inputExtrapolation (needs the FMUs' derivatives)")
    parser.add_argument("--block-order", type=int, help="declare the block's maxOutputDerivativeOrder this in the SSP's "
                        "copy (OMSimulator asks for the declared order only; default: as built, 2)")
    parser.add_argument("--no-check", dest="check", action="store_false", help="skip oms-ma against zoh in FMPy")
    parser.add_argument("--out", help="folder for the SSP and result files (default: a new temporary folder)")
    args = parser.parse_args(argv)
    unknown = sorted(set(args.masters) - set(MASTERS))
    if unknown:
        parser.error(f"--masters {unknown[0]!r}: allowed are {sorted(MASTERS)}")
    return args


if __name__ == "__main__":
    sys.exit(main())
