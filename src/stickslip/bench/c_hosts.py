"""The C-host family of the benchmarks: FMUs in our C host (:mod:`stickslip.hosts.c_host`, mode ``bench``) and in
fmusim (Reference-FMUs), per step and at start-up, each run a child process timed from outside.

A :class:`Subject` is an FMU file as a host runs it: the output read after every step and the start values.
Per step: ``fmi2DoStep`` + ``fmi2GetReal`` of that output (fmusim also records it and writes it to a CSV
file at the end), the slope of wall and CPU time over a 1-step and an ``n_long``-step run
(:mod:`.process_timing`). Start-up: the 1-step run, plus for our C host (which runs an extracted FMU)
extracting the FMU with :mod:`zipfile`; fmusim unzips the FMU itself.
"""

import shutil
import statistics
import tempfile
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..hosts.c_host import host_command, host_env, run_host
from .process_timing import Timings, slope, startup, timed_child


@dataclass(frozen=True)
class Subject:
    """An FMU file run by a host: ``output`` read each step; ``x = output - offset`` (m) on a scene."""

    name: str
    fmu: Path
    output: str = "x"
    start_values: dict = field(default_factory=dict)
    offset: float = 0.0


class CHost:
    """Our C host (FMI 2, ``bench`` mode) on FMUs it extracts once into ``work`` (a folder)."""

    name = "C host"

    def __init__(self, executable, work):
        self.executable, self.work, self._folders = executable, Path(work), {}

    def folder(self, subject):
        if subject.fmu not in self._folders:
            self._folders[subject.fmu] = extract(subject.fmu, Path(tempfile.mkdtemp(dir=self.work)))
        return self._folders[subject.fmu]

    def command(self, subject, stop_time, step):
        return host_command(self.executable, self.folder(subject), "bench", stop_time, step, subject.start_values,
                            subject.output)

    def env(self):
        return host_env()

    def extra_startup(self, subject):
        """Wall and CPU time (s) of extracting the FMU, which this host leaves to its caller."""
        target = Path(tempfile.mkdtemp(dir=self.work))
        wall, cpu = time.perf_counter(), time.process_time()
        extract(subject.fmu, target)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        shutil.rmtree(target)
        return wall, cpu

    def trajectory(self, subject, stop_time, step):
        """``(t s, output)`` at every communication point of one run."""
        run = run_host(self.executable, self.folder(subject), "run", stop_time, step, subject.start_values,
                       subject.output)
        if not run.completed:
            raise RuntimeError(f"C host failed on {subject.name}: {run.lines[-2:]} {run.stderr[-300:]}")
        return tuple(np.array(series) for series in run.series("x"))


class Fmusim:
    """fmusim (Reference-FMUs) on FMU files: FMI 2 co-simulation, one output variable written to a CSV file."""

    name = "fmusim"

    def __init__(self, executable, work):
        self.executable, self.work = executable, Path(work)

    def command(self, subject, stop_time, step, output_file=None):
        starts = [word for name, value in subject.start_values.items() for word in ("--start-value", name, repr(value))]
        return [str(self.executable), "--interface-type", "cs", "--stop-time", repr(stop_time), "--output-interval",
                repr(step), "--output-variable", subject.output, *starts, "--output-file",
                str(output_file or self.work / "fmusim-out.csv"), str(subject.fmu)]

    def env(self):
        return host_env()

    def extra_startup(self, subject):
        return None

    def trajectory(self, subject, stop_time, step):
        out = self.work / f"trajectory-{subject.name}.csv"
        timed_child(self.command(subject, stop_time, step, out), self.env())
        table = np.genfromtxt(out, delimiter=",", names=True)
        return table["time"], table[table.dtype.names[1]]


def extract(fmu, target):
    """Extract the FMU file ``fmu`` into the folder ``target``; return it."""
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(target)
    return target


def measure(host, subjects, step, n_long, repeats, progress=print):
    """``{subject name: record}`` of ``host``: per step (``wall_us``, ``cpu_us``), start-up (``wall_ms``,
    ``cpu_ms``), the C host's own CPU time per step of its long runs (``in_host_cpu_us``, µs, median; None in
    fmusim) and the raw times; the subjects alternate in every one of ``repeats`` rounds."""
    runs = {s.name: {"short": Timings([], []), "long": Timings([], []), "extra": Timings([], [])} for s in subjects}
    in_host = {s.name: [] for s in subjects}
    for round_number in range(1, repeats + 1):
        progress(f"{host.name}: round {round_number}/{repeats} of {len(subjects)} FMUs")
        for subject in subjects:
            timings = runs[subject.name]
            for length, n in (("short", 1), ("long", n_long)):
                wall, cpu, stdout = timed_child(host.command(subject, n * step, step), host.env())
                timings[length].wall.append(wall)
                timings[length].cpu.append(cpu)
            in_host[subject.name].extend(_in_host_cpu_us(stdout))
            extra = host.extra_startup(subject)
            if extra is not None:
                timings["extra"].wall.append(extra[0])
                timings["extra"].cpu.append(extra[1])
    return {name: {"per_step": slope(t["short"], t["long"], 1, n_long),
                   "startup": startup(t["short"], t["extra"] if t["extra"].wall else None),
                   "in_host_cpu_us": statistics.median(in_host[name]) if in_host[name] else None,
                   "times_s": {length: vars(t[length]) for length in t if t[length].wall}}
            for name, t in runs.items()}


def _in_host_cpu_us(stdout):
    """The C host's own CPU time per step of its loop (µs), from its "cpu_us_per_step" line (none in fmusim)."""
    return [float(line.split()[1]) for line in stdout.splitlines() if line.startswith("cpu_us_per_step ")]


def scene_error(host, subject, scene):
    """Max |x - reference| (m) of ``subject`` in ``host`` on ``scene``'s grid (communication step = grid step)."""
    t, output = host.trajectory(subject, scene.stop_time, scene.grid_step)
    k = np.rint(t / scene.grid_step).astype(int)
    return float(np.abs(output - subject.offset - scene.reference.x[k]).max())
