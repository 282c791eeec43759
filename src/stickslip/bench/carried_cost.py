"""What the CPython an FMU carries costs: each FMU against the same FMU built without it
(``build(carry_python=False)``), side by side in alternating rounds of one run:

- the files' sizes (MB);
- ``fmpy.simulate_fmu`` of the ``.fmu`` file (elmer-fig3 from rest, v = 0.1 m/s, 2000 s, 1 s outputs, rtol 1e-10):
  FMPy extracts ``binaries/`` and ``resources/`` and starts nothing of the carried CPython;
- a fresh C-host process's one-step run (1 s), extracting the whole ``.fmu`` first (Python's ``zipfile``): ours
  with its CPython unpacked in the cache by an earlier run (every run after the first on a machine), the other
  starting the build's CPython; and ours into an empty cache (the first run on a machine, which unpacks it).

Medians of wall and CPU times (CPU: this process's and its children's, the hosts' processes); ratios ours /
without.
"""

import resource
import statistics
import subprocess
import tempfile
import time
import zipfile
from pathlib import Path

from ..fmu.build import build
from ..hosts.c_host import host_command, host_env
from .fmu_file_runs import DENSE_SCENE, simulate_file

#: the C host's communication step (s) and stop time of its one-step run
ONE_STEP = 1.0


def without_python(fmu, fmi_version, build_dir):
    """The FMU of ``fmi_version`` built without a carried CPython into ``build_dir`` (once: kept while current),
    named as ``fmu``."""
    dest = Path(build_dir) / "without-python" / Path(fmu).name
    if not dest.is_file() or dest.stat().st_mtime < Path(fmu).stat().st_mtime:
        build(dest, fmi_version, carry_python=False)
    return dest


def measure(fmus, hosts, build_dir, repeats, progress=print):
    """``{"fmi<N>": row}`` for each ``fmus`` {FMI version: path} with its C host in ``hosts`` {FMI version: path}:
    row = {"size_mb": {"ours", "without"}, "fmpy_ms": {"wall": {...}, "cpu": {...}}, "c_host_ms": (the same, with
    "first")}, each with "ratio" ours / without."""
    out = {}
    for version, fmu in fmus.items():
        progress(f"the carried CPython's cost, FMI {version}: simulate_fmu and fresh C-host runs, {repeats} rounds")
        other = without_python(fmu, version, build_dir)
        sides = {"ours": fmu, "without": other}
        row = {"size_mb": {side: path.stat().st_size / 1e6 for side, path in sides.items()}}
        start = DENSE_SCENE.start_values(1e-10)
        row["fmpy_ms"] = _alternating({side: (lambda p=path: simulate_file(p, start, DENSE_SCENE.stop_time,
                                                                             DENSE_SCENE.grid_step))
                                       for side, path in sides.items()}, repeats)
        with tempfile.TemporaryDirectory(prefix="sbf_cache_") as cache:
            _fresh_run(hosts[version], fmu, cache)  # unpacks into the cache, as a machine's first run does
            calls = {side: (lambda p=path: _fresh_run(hosts[version], p, cache)) for side, path in sides.items()}
            calls["first"] = lambda: _fresh_run(hosts[version], fmu, None)
            row["c_host_ms"] = _alternating(calls, repeats)
        for field in ("fmpy_ms", "c_host_ms"):
            for clock in row[field].values():
                clock["ratio"] = clock["ours"] / clock["without"]
        out[f"fmi{version}"] = row
    return out


def _alternating(calls, repeats):
    """{"wall": {name: median (ms)}, "cpu": {...}} of ``repeats`` rounds, each calling every one of ``calls`` once in
    turn, in reversed order every other round."""
    times = {clock: {name: [] for name in calls} for clock in ("wall", "cpu")}
    for round_ in range(repeats):
        for name, call in list(calls.items())[::1 if round_ % 2 == 0 else -1]:
            wall, cpu = time.perf_counter(), _cpu()
            call()
            times["wall"][name].append(1e3 * (time.perf_counter() - wall))
            times["cpu"][name].append(1e3 * (_cpu() - cpu))
    return {clock: {name: statistics.median(values) for name, values in found.items()}
            for clock, found in times.items()}


def _cpu():
    """CPU seconds of this process and of its waited-for children."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def _fresh_run(host, fmu, cache):
    """Extract ``fmu`` into a new folder and run ``host`` on it for one step in a new process; the carried CPython
    unpacked into ``cache`` (None: a new empty folder)."""
    with tempfile.TemporaryDirectory(prefix="sbf_fresh_") as folder:
        with zipfile.ZipFile(fmu) as archive:
            archive.extractall(folder)
        command = host_command(host, folder, "run", ONE_STEP, ONE_STEP, DENSE_SCENE.start_values(1e-10))
        unpacked = cache or str(Path(folder) / "cache")
        run = subprocess.run(command, capture_output=True, text=True, env=host_env({"SBF_PYTHON_CACHE": unpacked}))
    if run.returncode != 0:
        raise RuntimeError(f"the C host failed on {fmu}: {run.stdout[-1000:]} {run.stderr[-1000:]}")
