"""What a one-step ``fmpy.simulate_fmu`` of an FMI 2 FMU file costs, part by part (issue 21, "cheaper start").

A profile, not a test: each FMU runs in fresh child processes (``python -X importtime``), each doing FMPy's
steps by hand, timed with ``time.perf_counter``: reading the model description, extracting ``resources/`` and
``binaries/`` (per file), loading the binary, ``fmi2Instantiate`` (which imports the FMU's Python modules:
listed with ``-X importtime``'s self and cumulative times), initialization, one ``fmi2DoStep`` with one
``fmi2GetReal``, ``fmi2Terminate`` + ``fmi2FreeInstance``, and deleting the extracted folder. "warm" repeats
the same in the child after the first round (modules imported, files in the page cache), as a benchmark that
calls ``simulate_fmu`` many times in one process sees it. The FMUs default to ours
(``dist/SpringBlockFriction.fmu``, built if stale) and the benchmark's do-nothing PythonFMU FMU.

    .venv/bin/python scripts/startup_profile.py [--runs 5] [--top 12] [FMU ...]
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

STAGES = ("model description", "extract", "load binary", "instantiate", "initialize", "step + get", "free",
          "delete folder")
MARK = "##stage "


def _child(path, rounds):
    """Run ``rounds`` one-step simulations of the FMU at ``path``; print a JSON list, one dict per round."""
    import shutil
    import tempfile
    import zipfile

    from fmpy import read_model_description
    from fmpy.fmi2 import FMU2Slave

    out = []
    for _ in range(rounds):
        times, files = {}, []
        clock = time.perf_counter()

        def lap(stage):
            nonlocal clock
            now = time.perf_counter()
            times[stage] = now - clock
            print(f"{MARK}{stage}", file=sys.stderr, flush=True)  # closes the importtime lines of that stage
            clock = time.perf_counter()

        description = read_model_description(path)
        lap("model description")
        folder = tempfile.mkdtemp()
        with zipfile.ZipFile(path) as archive:
            for info in archive.infolist():
                if info.filename.startswith(("resources", "binaries/")):
                    start = time.perf_counter()
                    archive.extract(info, folder)
                    files.append((info.filename, info.file_size, time.perf_counter() - start))
        lap("extract")
        fmu = FMU2Slave(guid=description.guid, unzipDirectory=folder, instanceName="profile",
                        modelIdentifier=description.coSimulation.modelIdentifier)
        lap("load binary")
        fmu.instantiate()
        lap("instantiate")
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        lap("initialize")
        output = next(v for v in description.modelVariables if v.causality == "output" and v.type == "Real")
        fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-3)
        fmu.getReal([output.valueReference])
        lap("step + get")
        fmu.terminate()
        fmu.freeInstance()
        lap("free")
        shutil.rmtree(folder, ignore_errors=True)
        lap("delete folder")
        out.append({"times": times, "files": files})
    print(json.dumps(out))


def _run_child(path, rounds):
    """One fresh process: ``(rounds, importtime lines by stage of the first round)``."""
    run = subprocess.run([sys.executable, "-X", "importtime", __file__, "--child", path, "--rounds", str(rounds)],
                         capture_output=True, text=True, check=True)
    imports, pending = {}, []
    for line in run.stderr.splitlines():
        if line.startswith(MARK):
            imports.setdefault(line[len(MARK):], pending)
            pending = []
        elif line.startswith("import time:") and "|" in line:
            self_us, cumulative_us, name = (part.strip() for part in line[len("import time:"):].split("|"))
            if self_us.isdigit():
                pending.append((name, int(self_us), int(cumulative_us)))
    return json.loads(run.stdout), imports


def _kind(name):
    """Who a module belongs to: ours, the FMI library, or the standard library / FMPy's process."""
    top = name.strip().split(".")[0]
    if top.startswith(("sbf_runtime_", "sbf_slave_", "springblockfriction", "TrivialFloor")):
        return "ours"
    return "pythonfmu" if top.startswith("pythonfmu") else "stdlib/other"


def _report(path, runs, top):
    """Print the profile of the FMU at ``path`` from ``runs`` fresh processes of two rounds each."""
    results = [_run_child(path, 2) for _ in range(runs)]
    cold = [rounds[0] for rounds, _ in results]
    warm = [rounds[1] for rounds, _ in results]
    files = cold[0]["files"]
    print(f"\n== {path}: {len(files)} files extracted, {sum(size for _, size, _ in files)} bytes "
          f"(medians of {runs} fresh processes, ms)")
    print(f"{'stage':<20}{'cold':>9}{'warm':>9}")
    for stage in STAGES:
        print(f"{stage:<20}{_median_ms(cold, stage):>9.2f}{_median_ms(warm, stage):>9.2f}")
    print(f"{'total':<20}{sum(_median_ms(cold, s) for s in STAGES):>9.2f}{sum(_median_ms(warm, s) for s in STAGES):>9.2f}")
    per_file = sorted(files, key=lambda item: -item[2])[:top]
    print(f"slowest files to extract (cold, first process): " + ", ".join(
        f"{name} {size} B {seconds * 1e3:.2f} ms" for name, size, seconds in per_file))
    imports = results[0][1].get("instantiate", [])
    for kind in ("ours", "pythonfmu", "stdlib/other"):
        mine = [item for item in imports if _kind(item[0]) == kind]
        print(f"imported at instantiate, {kind}: {len(mine)} modules, {sum(s for _, s, _ in mine) / 1e3:.2f} ms "
              f"self: " + ", ".join(f"{name.strip()} {s / 1e3:.2f}" for name, s, _ in
                                    sorted(mine, key=lambda item: -item[1])[:top]))


def _median_ms(rounds, stage):
    return statistics.median(r["times"][stage] for r in rounds) * 1e3


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("fmus", nargs="*", help="FMI 2 co-simulation FMU files (default: ours and the floor FMU)")
    parser.add_argument("--runs", type=int, default=5, help="fresh processes per FMU")
    parser.add_argument("--top", type=int, default=12, help="files and modules listed")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--rounds", type=int, default=2, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        return _child(args.child, args.rounds)
    if not args.fmus:
        from stickslip.bench.fmus import ensure_floor_fmu
        from stickslip.fmu.build import ensure_fmu
        args.fmus = [str(ensure_fmu()), str(ensure_floor_fmu())]
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores, {time.strftime('%Y-%m-%d %H:%M')}")
    for path in args.fmus:
        _report(path, args.runs, args.top)


if __name__ == "__main__":
    main()
