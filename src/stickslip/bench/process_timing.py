"""Wall and CPU time of child processes, and the cost per step as the slope over two run lengths.

A run is one child process (a C host or fmusim) from its start to its exit: wall time around it in this
process (s), CPU time (user + system, s) from the resource usage of the waited-for children. Runs of
``n_short`` and ``n_long`` steps alternate for ``repeats`` rounds; the cost per step is the difference of the
medians over the difference of the step counts, so start-up (process, unzip, instantiate, initialize)
cancels, and the short run's medians are the start-up.
"""

import gc
import resource
import statistics
import subprocess
import time
from dataclasses import dataclass


class ChildFailed(RuntimeError):
    """A timed child process exited with a non-zero code."""


def timed_child(command, env=None, timeout=600):
    """``(wall s, CPU s, stdout)`` of ``command`` run to its exit; :class:`ChildFailed` on a non-zero exit."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, env=env, timeout=timeout)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise ChildFailed(f"{command[0]} exited with {done.returncode}: {(done.stdout + done.stderr)[-500:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, done.stdout


@dataclass
class Timings:
    """Times (s) of the repeated runs of one length: ``wall`` and ``cpu`` lists; ``first``: what a timed call's
    warm-up returned (:func:`timed_call`)."""

    wall: list
    cpu: list
    first: object = None

    def median(self, clock):
        return statistics.median(getattr(self, clock))


def slope(short, long, n_short, n_long):
    """``{"wall_us", "cpu_us"}``: the cost of one step (µs) from the two lengths' medians."""
    return {f"{clock}_us": 1e6 * (long.median(clock) - short.median(clock)) / (n_long - n_short)
            for clock in ("wall", "cpu")}


def startup(short, extra=None):
    """``{"wall_ms", "cpu_ms"}``: the short run's medians (ms), plus the medians of ``extra`` (another
    :class:`Timings`, e.g. extracting the FMU before a host that does not unzip)."""
    return {f"{clock}_ms": 1e3 * (short.median(clock) + (extra.median(clock) if extra else 0.0))
            for clock in ("wall", "cpu")}


def timed_call(call, repeats):
    """:class:`Timings` of ``repeats`` calls of ``call()`` in this process after one warm-up call (its result in
    ``first``), the garbage collector off during each (one collection before them)."""
    timings = Timings([], [], call())
    gc.collect()
    for _ in range(repeats):
        gc.disable()
        try:
            wall, cpu = time.perf_counter(), time.process_time()
            call()
            timings.wall.append(time.perf_counter() - wall)
            timings.cpu.append(time.process_time() - cpu)
        finally:
            gc.enable()
    return timings
