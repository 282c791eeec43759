"""The FMU under FMPy in Pythons other than the one that built it (pyenv's CPython 3.8-3.13), each in a venv of its
own with FMPy and numpy: the runtime compiled for a Python runs only in that Python version, every other version runs
the runtime's Python sources.

    python scripts/other_pythons.py compile [--venvs .venv-pythons]

compiles the FMUs' runtime for each pyenv CPython newer than this one, and for Windows (x86_64) with pyenv's CPython of
the version the FMUs run with there, cross-compiled with MinGW-w64 (``scripts/setup.sh`` does): the FMUs built
after it carry those compiled files too (:data:`stickslip.fmu.staging.OTHER_PYTHONS`).

    python scripts/other_pythons.py measure [--fmu dist/SpringBlockFriction.fmu] [--venvs .venv-pythons] [--repeats 5]

times elmer-fig3 at v = 0.1 m/s over 2000 s in 1 s communication steps (``fmpy.simulate_fmu`` of the extracted FMU,
CPU time of the process, median of the repeats) per Python version, compiled where the FMU carries the runtime
compiled for it and then also pure (``STICKSLIP_PURE_PYTHON``), and prints x(2000 s) with its difference from the
build's compiled run.

    python other_pythons.py simulate REQUEST.json RESULT.npz

is what runs inside a venv (only the standard library, FMPy and numpy): each request's run, ``fmpy.simulate_fmu``
as the suite's host calls it, saved under the request's name; the tests and ``measure`` call it.
"""

import json
import os
import statistics
import subprocess
import sys
import sysconfig
import time
from pathlib import Path

HERE = Path(__file__).resolve()
PYENV_VERSIONS = Path(os.environ.get("PYENV_ROOT") or Path.home() / ".pyenv") / "versions"
#: what each venv gets (FMPy's newest release for that Python)
PACKAGES = ("fmpy", "numpy")
#: the variable that makes the FMU's runtime run its sources although it is compiled for the Python
PURE_VARIABLE = "STICKSLIP_PURE_PYTHON"
#: the scene :func:`measure` times: elmer-fig3 at v = 0.1 m/s from its scenario file, over 2000 s in 1 s steps
ELMER_FIG3 = (HERE.parents[1] / "scenarios" / "elmer-fig3-v0.1.toml", 2000.0, 1.0)


def pyenv_pythons():
    """{"3.X": interpreter path} of pyenv's CPython 3.8 and newer (the newest patch release of each)."""
    found = {}
    for folder in sorted(PYENV_VERSIONS.glob("3.*"), key=lambda p: [int(n) for n in p.name.split(".") if n.isdigit()]):
        parts = folder.name.split(".")
        if len(parts) == 3 and all(p.isdigit() for p in parts) and int(parts[1]) >= 8 and \
                (folder / "bin" / "python3").is_file():
            found[".".join(parts[:2])] = folder / "bin" / "python3"
    return found


def fmpy_venv(python, folder, timeout=900):
    """The interpreter of a venv at ``folder`` made from ``python`` with :data:`PACKAGES`."""
    return made_venv(python, folder, PACKAGES, "fmpy, numpy", timeout)


def made_venv(python, folder, packages, modules, timeout=900):
    """The interpreter of a venv at ``folder`` made from ``python`` with ``packages`` (pip requirements), made once:
    kept if it imports ``modules`` (a comma-separated list); RuntimeError with pip's last lines if it cannot be
    made."""
    venv_python = Path(folder) / "bin" / "python"
    check = [str(venv_python), "-c", f"import {modules}"]
    if venv_python.is_file() and subprocess.run(check, capture_output=True).returncode == 0:
        return venv_python
    steps = ([str(python), "-m", "venv", "--clear", str(folder)],
             [str(venv_python), "-m", "pip", "install", "--quiet", *packages], check)
    for step in steps:
        run = subprocess.run(step, capture_output=True, text=True, timeout=timeout)
        if run.returncode != 0:
            tail = "\n".join((run.stderr or run.stdout).strip().splitlines()[-5:])
            raise RuntimeError(f"{' '.join(step[:4])} failed (exit {run.returncode}): {tail}")
    return venv_python


def compile_for_others(venvs, build_version):
    """Compile the FMUs' runtime with mypyc for every pyenv CPython newer than ``build_version``, and for Windows
    (x86_64) with the CPython version the FMUs run with there (``windows_runtime.WINDOWS_PYTHON``, cross-compiled
    with MinGW-w64), into :data:`stickslip.fmu.staging.OTHER_PYTHONS`, each with the build's mypy and setuptools in a
    venv of its own under ``venvs``; the builds then carry those files too. Says what it does; a version that cannot
    be compiled is said and left out."""
    import importlib.metadata

    from stickslip.fmu import compile_runtime, windows_runtime

    package = compile_runtime.RUNTIME_PREFIX + compile_runtime.runtime_tag()
    pins = [f"{name}=={importlib.metadata.version(name)}" for name in ("mypy", "setuptools")]
    pythons = pyenv_pythons()
    for version, python in pythons.items():
        if _key(version) > _key(build_version):
            name = f"{package}-cpython-{version.replace('.', '')}-{sysconfig.get_platform()}"
            compile_with(python, Path(venvs) / f"{version}-compile", pins, Path(compile_runtime.__file__), name,
                         f"CPython {version}")
    windows = ".".join(map(str, windows_runtime.WINDOWS_PYTHON))
    if windows in pythons:
        compile_with(pythons[windows], Path(venvs) / f"{windows}-compile", pins, Path(windows_runtime.__file__),
                     f"{package}-cpython-{windows.replace('.', '')}-{compile_runtime.WINDOWS_PLATFORM}",
                     f"CPython {windows} on Windows")
    else:
        print(f"other pythons: CPython {windows} on Windows: not compiled: pyenv has no CPython {windows}")


def compile_with(python, venv_folder, pins, script, name, label):
    """Run the compiling ``script`` (``SCRIPT CORE DEST``) of the FMUs' runtime in a venv of ``python`` at
    ``venv_folder`` with ``pins``, and keep its result as ``OTHER_PYTHONS/name``; says what it did (``label``: for
    which Python)."""
    import shutil
    import tempfile

    from stickslip.fmu import compile_runtime
    from stickslip.fmu.staging import OTHER_PYTHONS

    if (OTHER_PYTHONS / name / compile_runtime.COMPLETE).is_file():
        print(f"other pythons: {label}: {name} is compiled ({OTHER_PYTHONS / name})")
        return
    start = time.monotonic()
    try:
        venv = made_venv(python, venv_folder, pins, "mypyc, setuptools")
        with tempfile.TemporaryDirectory() as tmp:
            run = subprocess.run([str(venv), str(script), str(Path(compile_runtime.__file__).parents[1] / "core"), tmp],
                                 capture_output=True, text=True, timeout=1800)
            built = Path(tmp) / name
            if run.returncode != 0 or not (built / compile_runtime.COMPLETE).is_file():
                raise RuntimeError((run.stderr or run.stdout).strip()[-2000:])
            shutil.rmtree(OTHER_PYTHONS / name, ignore_errors=True)
            OTHER_PYTHONS.mkdir(parents=True, exist_ok=True)
            shutil.move(str(built), OTHER_PYTHONS / name)
    except (RuntimeError, OSError, subprocess.TimeoutExpired) as exc:
        print(f"other pythons: {label}: not compiled: {exc}")
        return
    print(f"other pythons: {label}: {name} compiled in {time.monotonic() - start:.0f} s")


def _key(version):
    return tuple(int(part) for part in version.split("."))


def run_in(venv_python, fmu, requests, folder, environment=None, timeout=1800):
    """Run ``requests`` (dicts: name, start_values, stop_time, output_interval, outputs, and optionally input:
    {"names": [...], "rows": [...]}, repeats) on the ``fmu`` in ``venv_python``; ``(results, seconds)``:
    {name: {"result": FMPy's array, "cpu": [CPU s of each repeat], "runtime": the FMU's runtime choice,
    "python": the child's Python version}} and the child's wall time. RuntimeError, with its output, if the child fails."""
    import numpy as np

    request = Path(folder) / "request.json"
    out = Path(folder) / "result.npz"
    request.write_text(json.dumps({"fmu": str(fmu), "runs": requests}))
    start = time.monotonic()
    run = subprocess.run([str(venv_python), str(HERE), "simulate", str(request), str(out)], capture_output=True,
                         text=True, timeout=timeout, env={**os.environ, **(environment or {})})
    if run.returncode != 0:
        raise RuntimeError(f"{venv_python} exited with {run.returncode}: {run.stderr[-3000:]}")
    with np.load(out, allow_pickle=False) as saved:
        meta = json.loads(str(saved["meta"]))
        results = {name: {**meta[name], "result": saved[name]} for name in meta}
    return results, time.monotonic() - start


def simulate(request_path, out_path):
    """The child: run each request of the JSON file ``request_path`` and save the results to ``out_path``."""
    import fmpy
    import numpy as np

    request = json.loads(Path(request_path).read_text())
    folder = fmpy.extract(request["fmu"])
    arrays, meta = {}, {}
    for run in request["runs"]:
        signal = None
        if run.get("input"):
            fields = [(name, np.float64) for name in run["input"]["names"]]
            signal = np.array([tuple(row) for row in run["input"]["rows"]], dtype=fields)
        cpu = []
        for _ in range(run.get("repeats", 1)):
            begin = time.process_time()
            arrays[run["name"]] = fmpy.simulate_fmu(
                folder, start_time=0.0, stop_time=run["stop_time"], output_interval=run["output_interval"],
                start_values=run["start_values"], output=run["outputs"], input=signal)
            cpu.append(time.process_time() - begin)
        meta[run["name"]] = {"cpu": cpu, "runtime": runtime_choice(), "python": sys.version.split()[0]}
    np.savez(out_path, meta=json.dumps(meta), **arrays)


def runtime_choice():
    """"compiled" or "pure": whether the FMU's runtime package in this process is its compiled modules."""
    loaded = [m for name, m in sys.modules.items() if name.startswith("sbf_runtime_") and name.endswith(".laws")]
    return "compiled" if loaded and str(getattr(loaded[0], "__file__", "")).endswith(".so") else "pure"


def measure(fmu, venvs, repeats, build_version):
    """Print the table of :data:`ELMER_FIG3` per Python version (see the module)."""
    import tempfile

    from stickslip.suite.scenario import load_scenario

    path, stop_time, step = ELMER_FIG3
    scene = {"name": "elmer-fig3", "start_values": load_scenario(path).start_values(), "stop_time": stop_time,
             "output_interval": step, "outputs": ["x", "v"], "repeats": repeats}
    pythons = pyenv_pythons()
    rows, reference = [], None
    for version in [build_version, *(v for v in pythons if v != build_version)]:
        venv = fmpy_venv(pythons[version], Path(venvs) / version)
        for environment in ({}, {PURE_VARIABLE: "1"}):
            with tempfile.TemporaryDirectory() as tmp:
                run = run_in(venv, fmu, [scene], tmp, environment)[0]["elmer-fig3"]
            x = float(run["result"]["x"][-1])
            reference = reference if reference is not None else x
            rows.append(f"{version:6} {run['runtime']:9} {1e3 * statistics.median(run['cpu']):8.1f} ms  "
                        f"x({stop_time:g} s) = {x!r:22} {x - reference:+.1e}")
            if run["runtime"] == "pure":
                break  # the version has no compiled runtime: a pure run again would tell nothing new
    print(f"elmer-fig3, v = 0.1 m/s, {stop_time:g} s in {step:g} s steps, FMPy, CPU per run (median of {repeats}):")
    print("\n".join(rows))


def main(argv):
    if argv[:1] == ["simulate"]:
        simulate(*argv[1:3])
        return 0
    import argparse

    parser = argparse.ArgumentParser(description="the FMU under FMPy in pyenv's Pythons")
    parser.add_argument("command", choices=["measure", "compile"])
    parser.add_argument("--fmu", default="dist/SpringBlockFriction.fmu")
    parser.add_argument("--venvs", default=".venv-pythons")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    build_version = f"{sys.version_info[0]}.{sys.version_info[1]}"
    if args.command == "compile":
        compile_for_others(args.venvs, build_version)
    else:
        measure(Path(args.fmu).resolve(), args.venvs, args.repeats, build_version)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
