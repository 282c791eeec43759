"""Where one ``fmpy.simulate_fmu`` of an ``.fmu`` file spends its time: the request's run (elmer-fig3 from rest,
v_drive = 0.1 m/s, 2000 s, 1 s outputs, ``x`` recorded, ``solver.rtol`` 1e-12 by default), each FMU in turn in one
process, ``--rounds`` rounds after a warm-up call (modules imported, as a user's repeated calls see it).

A profile, not a test: FMPy's own functions are wrapped with wall-clock timers while ``simulate_fmu`` runs, so the
parts are FMPy's (listing the zip's platforms, reading the model description, extracting ``binaries/`` and
``resources/``, loading the binary, ``fmi2Instantiate``, initialization, the steps with the recorder, terminate,
free, deleting the extracted folder), the rest of ``simulate_fmu`` the remainder. Medians (ms) per part.

    .venv/bin/python scripts/fmu_file_profile.py [--rounds 15] [--rtol 1e-12] [FMU ...]
"""

import argparse
import gc
import os
import statistics
import time

import fmpy
import fmpy.model_description
import fmpy.simulation
from fmpy.fmi2 import FMU2Slave

#: (object, attribute, part): the functions timed, by the part of the run they are
TIMED = ((fmpy, "supported_platforms", "platforms (zip listing)"),
         (fmpy.model_description, "read_model_description", "model description"),
         (fmpy.simulation, "extract", "extract"), (FMU2Slave, "__init__", "load binary"),
         (FMU2Slave, "instantiate", "instantiate"), (fmpy.simulation, "apply_start_values", "initialize"),
         (FMU2Slave, "setupExperiment", "initialize"), (FMU2Slave, "enterInitializationMode", "initialize"),
         (FMU2Slave, "exitInitializationMode", "initialize"), (FMU2Slave, "terminate", "terminate"),
         (FMU2Slave, "freeInstance", "free"), (fmpy.simulation.shutil, "rmtree", "delete folder"),
         (fmpy.simulation, "simulateCS", "simulateCS"), (fmpy, "simulate_fmu", "total"))


def _wrap(owner, name, part, times):
    """Replace ``owner.name`` by a function adding its wall time (s) to ``times[part]``."""
    function = getattr(owner, name)

    def timed(*args, **kwargs):
        start = time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            times[part] = times.get(part, 0.0) + time.perf_counter() - start

    setattr(owner, name, timed)


def profile(paths, rounds, rtol):
    """``{path: {part: median ms}}`` of ``rounds`` alternating rounds after a warm-up call of each FMU."""
    from stickslip.bench.fmu_file_runs import DENSE_SCENE, simulate_file

    times = {}
    for owner, name, part in TIMED:
        _wrap(owner, name, part, times)
    found = {path: [] for path in paths}
    for round_ in range(rounds + 1):
        for path in paths:
            times.clear()
            gc.collect()
            gc.disable()
            simulate_file(path, DENSE_SCENE.start_values(rtol), DENSE_SCENE.stop_time, DENSE_SCENE.grid_step)
            gc.enable()
            times["steps + recorder"] = times.pop("simulateCS") - times["initialize"] - times["terminate"]
            times["rest of simulate_fmu"] = 2 * times["total"] - sum(times.values())
            if round_:
                found[path].append(dict(times))
    return {path: {part: 1e3 * statistics.median(r[part] for r in rows) for part in rows[0]}
            for path, rows in found.items()}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("fmus", nargs="*", help="FMI 2 co-simulation FMU files of the block (default: ours)")
    parser.add_argument("--rounds", type=int, default=15, help="timed rounds (default: 15)")
    parser.add_argument("--rtol", type=float, default=1e-12, help="solver.rtol (default: 1e-12)")
    args = parser.parse_args()
    if not args.fmus:
        from stickslip.fmu.build import ensure_fmu
        args.fmus = [str(ensure_fmu())]
    print(f"load average {os.getloadavg()} at the start, {os.cpu_count()} cores, {time.strftime('%Y-%m-%d %H:%M')}")
    found = profile(args.fmus, args.rounds, args.rtol)
    print(f"load average {os.getloadavg()} at the end; medians (ms) of {args.rounds} rounds")
    print("| part | " + " | ".join(args.fmus) + " |\n|---|" + "---|" * len(args.fmus))
    for part in next(iter(found.values())):
        print(f"| {part} | " + " | ".join(f"{found[path][part]:.2f}" for path in args.fmus) + " |")


if __name__ == "__main__":
    main()
