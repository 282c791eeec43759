"""The main job: run every scenario through the FMU and the reference, compare, and report.

For each scenario: the FMU under FMPy (:func:`~stickslip.hosts.fmpy_host.run_fmu`: the FMI 2
FMU's co-simulation, the FMI 3 FMU's co-simulation or model exchange),
the reference on the FMU's output grid with the inputs the FMU actually saw,
:func:`~stickslip.suite.compare.compare`, then ``OUT/<name>.csv`` (FMU result),
``OUT/<name>.png`` and finally ``OUT/report.md``.
"""

import signal
import time
from dataclasses import dataclass, replace
from multiprocessing import get_context
from pathlib import Path

from tqdm import tqdm

from .compare import compare
from ..core.errors import StickSlipError
from ..fmu import ensure_fmu, variables
from ..hosts import interrupts
from ..hosts.fmpy_host import read_model_description, run_fmu
from ..hosts.run_limits import output_folder
from .inputs import held_input_table
from .scenario_plots import plot_scenario
from ..reference import ReferenceFailure, parameters_from_values, simulate_reference
from .report import Outcome, console_summary, tally, write_report, write_result_csv
from .scenario import ScenarioError, load_scenarios

#: FMU variables recorded for every scenario: every output (SPEC section 4 and the extra counters), then the inputs
OUTPUTS = variables.OUTPUTS + variables.INPUTS


@dataclass(frozen=True)
class SuiteResult:
    """Outcomes in scenario order and the wall time (s)."""

    outcomes: tuple
    seconds: float

    @property
    def ok(self):
        return all(o.passed for o in self.outcomes)


def simulate(scenario, fmu_path, interface=None):
    """Run the FMU and the reference for ``scenario``: ``(fmu_result, ref_result, fmu_s, ref_s)``.

    ``interface``: None for the FMI 2 FMU's co-simulation; "cs" for the FMI 3 FMU's (driven as the FMI 2 one);
    "me" for either FMU's model exchange (FMPy's CVode at the scenario's ``model_exchange.rtol``, the inputs held
    between the breakpoints the co-simulation sees, so the reference is the same).

    The reference's laws are its own, built from the scenario file's numbers (``scenario.law_values``).
    """
    start = time.perf_counter()
    args = (scenario.start_values(), scenario.stop_time, scenario.output_interval)
    if interface is None:
        fmu = run_fmu(fmu_path, *args, input_signal=scenario.input_table(), outputs=list(OUTPUTS))
    elif interface == "cs":
        fmu = run_fmu(fmu_path, *args, "cs", input_signal=scenario.input_table(), outputs=list(OUTPUTS))
    else:
        inputs = held_input_table(scenario.breakpoints(), scenario.stop_time)
        fmu = run_fmu(fmu_path, *args, "me", input_signal=inputs, outputs=list(OUTPUTS),
                       rtol=model_exchange(scenario).rtol)
    middle = time.perf_counter()
    ref = reference_on(scenario, fmu["time"])
    return fmu, ref, middle - start, time.perf_counter() - middle


def reference_on(scenario, times):
    """The reference integrator's result for ``scenario`` at ``times`` (s; the FMU's output grid), with the laws
    built from the scenario file's numbers and the inputs the FMU sees."""
    return simulate_reference(parameters_from_values(scenario.law_values), scenario.x0, scenario.v0,
                              scenario.breakpoints(), times)


def model_exchange(scenario):
    """The scenario's ``[model_exchange]`` settings (a ScenarioError if the file has none)."""
    if scenario.model_exchange is None:
        raise ScenarioError(f"{scenario.path}: no [model_exchange] section (CVode rtol and tolerances)")
    return scenario.model_exchange


def run_scenario(scenario, fmu_path, out_dir=None, interface=None):
    """Simulate and compare one scenario; write its CSV and PNG into ``out_dir`` if given.

    ``interface``: as :func:`simulate`; "me" is checked against the ``[model_exchange]`` tolerances.
    """
    try:
        fmu, ref, fmu_s, ref_s = simulate(scenario, fmu_path, interface)
    except (StickSlipError, ReferenceFailure) as exc:
        return Outcome(scenario.name, scenario.expected_attractor, error=f"{type(exc).__name__}: {exc}")
    known_miss = ""
    if interface == "me":
        known_miss = scenario.model_exchange.known_miss
        scenario = replace(scenario, tolerance=scenario.model_exchange.tolerance)
    if out_dir is not None:
        write_result_csv(Path(out_dir) / f"{scenario.name}.csv", fmu, OUTPUTS)
        plot_scenario(Path(out_dir) / f"{scenario.name}.png", scenario.name, fmu, ref,
                      scenario.tolerance.max_abs_dx)
    return Outcome(scenario.name, scenario.expected_attractor, compare(fmu, ref, scenario), fmu_s, ref_s,
                   known_miss=known_miss)


def run_suite(paths, out_dir, jobs=2, fmu_path=None, interface=None):
    """Run the scenarios in ``paths`` (files or directories) with ``jobs`` worker processes.

    ``fmu_path``: the FMU to test; by default ``SpringBlockFriction.fmu`` at
    :func:`~stickslip.fmu.default_fmu_path`, built if missing or stale (an explicit path is used as it is).
    ``interface`` "cs" or "me" tests the FMU at ``fmu_path`` (default: the FMI 3 FMU there, built if missing or stale)
    through that interface (an FMI 2 FMU's "cs" is its default); None (default) the FMU at ``fmu_path`` through
    co-simulation.

    Writes the per-scenario files and ``report.md`` into ``out_dir``, prints a summary
    within 100 columns (:func:`~stickslip.suite.report.console_summary`), and returns a :class:`SuiteResult` (``.ok`` is False if any
    scenario missed its tolerance or its attractor). A malformed scenario file, an FMU that is not a
    SpringBlockFriction FMU and an output folder that cannot take the files raise a StickSlipError before anything
    runs; the previous run's ``report.md`` is removed then (it is written last: a run that stops, e.g. on
    Ctrl-C, which raises KeyboardInterrupt saying how far it got, leaves none).
    """
    start = time.perf_counter()
    scenarios = load_scenarios(paths)
    interface = interface_of(fmu_path, interface)
    if interface == "me":
        for scenario in scenarios:
            model_exchange(scenario)
    out_dir = output_folder(out_dir, ["report.md", *(f"{s.name}{suffix}" for s in scenarios for suffix in
                                                     (".csv", ".png"))])
    (out_dir / "report.md").unlink(missing_ok=True)
    if fmu_path is None:
        fmu_path = ensure_fmu(fmi_version=2 if interface is None else 3)
    fmu_path = Path(fmu_path)
    progress = tqdm(total=len(scenarios), desc="scenarios", unit="scenario")
    try:
        outcomes = _run_all(scenarios, fmu_path, out_dir, interface, jobs, progress.update)
    except KeyboardInterrupt:
        raise interrupts.Interrupted(f"{progress.n} of {len(scenarios)} scenarios finished, no report written") from None
    finally:
        progress.close()
    result = SuiteResult(tuple(outcomes), time.perf_counter() - start)
    write_report(out_dir / "report.md", result.outcomes, result.seconds)
    print(console_summary(result.outcomes))
    print(f"{tally(result.outcomes)} in {result.seconds:.1f} s")
    print(f"report: {out_dir / 'report.md'}")
    return result


def _run_all(scenarios, fmu_path, out_dir, interface, jobs, done):
    """The outcomes of :func:`run_scenario` in scenario order, run here (``jobs`` <= 1) or by ``jobs`` spawned
    worker processes; ``done()`` is called after each scenario.

    The workers ignore SIGINT (Ctrl-C reaches the whole process group): this process handles it, and ends them at
    once (``terminate``) instead of letting them run the scenarios still queued.
    """
    if jobs <= 1:
        outcomes = []
        for scenario in scenarios:
            outcomes.append(run_scenario(scenario, fmu_path, out_dir, interface))
            done()
        return outcomes
    outcomes = [None] * len(scenarios)
    with interrupts.ignored():
        pool = get_context("spawn").Pool(jobs, initializer=signal.signal, initargs=(signal.SIGINT, signal.SIG_IGN))
    try:
        tasks = [(i, scenario, fmu_path, out_dir, interface) for i, scenario in enumerate(scenarios)]
        for i, outcome in pool.imap_unordered(_run_task, tasks):
            outcomes[i] = outcome
            done()
    finally:
        pool.terminate()  # idle workers once every outcome is in; on Ctrl-C or an error, the ones still running
        pool.join()
    return outcomes


def _run_task(task):
    """``(index, outcome)`` of ``task``, :func:`run_scenario`'s arguments after the scenario's index."""
    return task[0], run_scenario(*task[1:])


def interface_of(fmu_path, interface):
    """The interface to drive: None for an FMI 2 FMU's co-simulation, "cs" for an FMI 3 one's (its default), "me"
    for either's model exchange.

    Without ``fmu_path``, ``interface`` None means the default FMI 2 FMU and "cs"/"me" the default FMI 3 one.
    """
    if fmu_path is None:
        return interface
    description = read_model_description(fmu_path, needs=(*OUTPUTS, *variables.START_VALUES))
    if interface == "me" and description.modelExchange is None:
        raise StickSlipError(f"{fmu_path} is an FMI {description.fmiVersion} co-simulation FMU: it has no model "
                             f"exchange")
    if description.fmiVersion.startswith("3"):
        return interface or "cs"
    return "me" if interface == "me" else None
