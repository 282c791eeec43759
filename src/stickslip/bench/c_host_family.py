"""The C host family: our FMU and the trivial floor FMU in a plain C importer (:mod:`stickslip.hosts.c_host`).

Each run is one child process of the C host in its ``bench`` mode: instantiate,
initialize, then every communication step as ``fmi2DoStep`` + ``fmi2GetReal`` of
``x``; the host reports the process CPU time of those steps alone (start-up of
Python excluded). The records carry ``cpu_s``, that time in s; the report takes
the slope of ``cpu_s`` over the number of steps (the per-step cost).
"""

from ..hosts.c_host import HostBuildError, compile_host, run_host
from . import fmus


def ensure_host(build_dir=None):
    """The compiled C host, or None (after a notice) if no C compiler works here."""
    try:
        return compile_host(build_dir or fmus.BUILD_DIR)
    except HostBuildError as exc:
        print(f"note: the C host family is left out: {exc}")
        return None


def _cpu_seconds(host, folder, start_values, stop_time, comm_step):
    run = run_host(host, folder, "bench", stop_time, comm_step, start_values)
    if not run.completed:
        raise RuntimeError(f"C host exit {run.returncode}: {run.lines[-2:]} {run.logs[-2:]} {run.stderr[-500:]}")
    return float(run.value("cpu_us_per_step")[0]) * 1e-6 * int(run.value("steps")[0])


def _cpu_field(cpu_s):
    return {"cpu_s": cpu_s}


def configs(scene, fmu, floor, host, config_type):
    """``config_type`` records "c-host" (our FMU at the sweep's comm_rtol) and "c-host-floor" at every
    communication step of the sweep; ``fmu`` and ``floor`` are :class:`~.fmus.ExtractedFMU`."""
    if host is None:
        return []
    out = []
    rtol, T = scene.sweep.comm_rtol, scene.stop_time
    for h in scene.comm_steps():
        out.append(config_type("c-host", f"C host, FMU h={h:g}", {"rtol": rtol, "comm_step": h},
                               lambda h=h: _cpu_seconds(host, fmu.folder, scene.start_values(rtol), T, h), None,
                               _cpu_field))
        out.append(config_type("c-host-floor", f"C host, floor h={h:g}", {"comm_step": h},
                               lambda h=h: _cpu_seconds(host, floor.folder, {}, T, h), None, _cpu_field))
    return out
