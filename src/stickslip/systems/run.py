"""``stickslip system run``: a system file through a master and the chain's reference, compared, with the files.

Writes ``<out>/<run>.csv`` (the master's samples), ``<out>/<run>.md`` (the report), ``<out>/<run>.png``
(each block's ``x(t)``, master against reference) and ``<out>/<run>-spacetime.png`` (which block slips when),
``<run>`` being the file's stem, the master and its engine or FMI version (``chain2-coulomb-zoh-libcosim``,
``chain2-coulomb-adaptive-fmi3``, ``chain2-coulomb-me``):
runs of different masters share a folder. The ``native`` master also writes ``<out>/<run>-block_events.csv``
(every block event: ``time,block,kind,x``). Where the master is judged, ``<out>/<run>-lyapunov.png`` shows the
chain's largest Lyapunov exponent over the run, which decides how it is judged (:mod:`.chaos`). Without the
reference (``reference=False``) nothing is compared and the report says so.
"""

import time
from dataclasses import dataclass, replace

import numpy as np

from ..fmu import ensure_fmu
from ..fmu.variables import START_VALUES
from ..hosts.fmpy_host import read_model_description
from ..hosts.progress import TimeProgress
from ..hosts.run_limits import output_folder
from .chaos import REFERENCE_RTOLS, judge_by_statistics, measure_divergence, plot_exponent
from .compare import Comparison, amplitude_floor, compare
from .master import SystemResult
from .masters import MASTERS, make_master
from .plots import plot_positions, plot_space_time
from .report import summary, write_csv, write_report
from .system_file import load_system


@dataclass(frozen=True)
class SystemOutcome:
    """The run (:class:`~.master.SystemResult`), its comparison (None: the reference was not run), the console's
    summary and the files written; ``ok``: within the tolerance, or (where the master is not judged or nothing is
    compared) every position finite."""

    result: SystemResult
    comparison: Comparison | None
    summary: str
    files: tuple

    @property
    def ok(self):
        if self.comparison is None:
            return bool(np.all(np.isfinite(self.result.x)))
        return self.comparison.ok


def run_system(path, master, out_dir, options=None, fmu_path=None, show_progress=True, reference=True):
    """Run the system file ``path`` through the master named ``master`` (with ``options``, e.g. ``{"step": 0.01}``)
    and, unless ``reference`` is False, the reference; write the files into ``out_dir``; return a
    :class:`SystemOutcome`.

    ``fmu_path``: the FMU the master runs (default: the built FMU of its FMI version, built if missing or stale); a
    master that runs either FMI version (option ``fmi``) runs the one of ``fmu_path`` unless ``fmi`` is given; the
    ``native`` master runs no FMU. A long run is refused unless the native master runs it without the reference.
    """
    run_reference = reference
    system = load_system(path, check_run_length=run_reference or master != "native")
    options = with_fmi_of(master, options or {}, fmu_path)
    runner = make_master(master, **options)
    variant = options.get("engine") or ("fmi3" if options.get("fmi") == 3 else None)
    files = output_files(out_dir, run_name(system.name, master, variant), events=master == "native")
    if runner.FMI_VERSION is not None:
        fmu_path = fmu_path or ensure_fmu(fmi_version=runner.FMI_VERSION)
    if "events" in files:
        runner.events_path = files["events"]
    with TimeProgress(f"{system.name} {master}", system.stop_time, show_progress) as step:
        result = runner.run(system, fmu_path, step)
    reference, reference_seconds, comparison = None, None, None
    if run_reference:
        reference, reference_seconds, comparison = against_reference(system, master, result, files.get("events"),
                                                                     show_progress)
    write_csv(files["csv"], result)
    title = f"{system.name} ({result.master})"
    plot_positions(files["positions"], title, result, reference)
    plot_space_time(files["space-time"], title, result, reference)
    figures = {"x of each block, master against reference": files["positions"].name,
               "which block slips when": files["space-time"].name}
    if comparison is not None and comparison.divergence is not None and comparison.divergence.estimate is not None:
        plot_exponent(files["exponent"], title, comparison.divergence.estimate)
        figures["the largest Lyapunov exponent over the run"] = files["exponent"].name
    write_report(files["report"], system, result, comparison, reference_seconds, figures)
    return SystemOutcome(result, comparison, summary(system, result, comparison),
                         tuple(path for path in files.values() if path.exists()))


def against_reference(system, master, result, events_file, show_progress):
    """``(reference, its wall time in s, comparison)`` of a master's run: where the master is judged, the largest
    Lyapunov exponent says first whether the chain's trajectory diverges (:mod:`.chaos`); if it does, the reference
    runs at both tolerances of :data:`~.chaos.REFERENCE_RTOLS` and the run is judged by its slip events'
    statistics, else the reference runs once and the amplitude judges."""
    from ..reference import simulate_chain  # here: a run without the reference does not load SciPy's integrators

    tolerance = system.tolerances[master]
    divergence = None
    if tolerance is not None:
        with TimeProgress(f"{system.name} Lyapunov exponent", system.stop_time, show_progress) as step:
            divergence = measure_divergence(system, tolerance, progress=step)
    rtols = REFERENCE_RTOLS if divergence is not None and divergence.diverges else REFERENCE_RTOLS[:1]
    start, references = time.perf_counter(), {}
    for rtol in rtols:
        with TimeProgress(f"{system.name} reference (rtol {rtol:g})", system.stop_time, show_progress) as step:
            references[rtol] = simulate_chain(system.chain_blocks(), system.coupling, system.v_drive, system.times(),
                                              rtol=rtol, progress=step)
    reference_seconds = time.perf_counter() - start
    reference = references[rtols[0]]
    comparison = replace(compare(result, reference, tolerance, amplitude_floor(system)), divergence=divergence)
    if len(references) > 1:
        comparison = replace(comparison, statistics=judge_by_statistics(system, result, events_file, references))
    return reference, reference_seconds, comparison


def with_fmi_of(master, options, fmu_path):
    """``options`` with ``fmi`` set to the FMI version of the FMU at ``fmu_path`` (from its model description) where
    the master ``master`` takes that option, an FMU is given and ``fmi`` is not (an ``fmi`` given wins); FMUError
    naming the file if it is no SpringBlockFriction FMU."""
    if fmu_path is None or options.get("fmi") is not None or "fmi" not in getattr(MASTERS.get(master), "OPTIONS", ()):
        return options
    version = int(read_model_description(fmu_path, needs=START_VALUES).fmiVersion[0])
    return {**options, "fmi": version}


def run_name(system_name, master, variant=None):
    """The stem of a run's files: the system's name, the master and, if given, its variant: zoh's engine (``None``:
    the master's own stepping) or ``fmi3`` for adaptive on the FMI 3 FMU."""
    return "-".join(part for part in (system_name, master, variant) if part)


def output_files(out_dir, name, events=False):
    """``{kind: path}`` of the files the run ``name`` (:func:`run_name`) writes into ``out_dir`` (``events``: the
    block events' CSV too): checked before the run (the folder made, the names fit), the previous run's report
    removed (it is written last: a run that stops leaves none)."""
    suffixes = {"csv": ".csv", "report": ".md", "positions": ".png", "space-time": "-spacetime.png",
                "exponent": "-lyapunov.png"}
    if events:
        suffixes["events"] = "-block_events.csv"
    out = output_folder(out_dir, [name + suffix for suffix in suffixes.values()])
    files = {kind: out / f"{name}{suffix}" for kind, suffix in suffixes.items()}
    for kind in ("report", "exponent"):  # the exponent's figure is written only where it was measured
        files[kind].unlink(missing_ok=True)
    return files
