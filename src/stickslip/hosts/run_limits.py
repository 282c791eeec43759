"""What one run may ask for, checked before it starts: a run that cannot finish, or cannot write its files, is
refused with the reason instead of failing (or running on) after its simulation work.

- :data:`MAX_OUTPUT_POINTS`: the output grid ``stop_time / output_interval`` (FMPy and the masters hold every
  output of every point in memory, the reference evaluates at each);
- :data:`MAX_PERIODS`: the run's length in free periods of its fastest oscillation, summed over its blocks (the
  FMU, the masters and the reference all resolve that period: their work grows with it);
- :data:`MAX_STEPS`: a fixed-step co-simulation's ``doStep`` calls, its steps times its blocks;
- :func:`output_folder`: the output folder exists or can be made, and can hold the run's file names.

The scenario and system loaders turn a reason into an error naming the file and the key.
"""

import math
import os
from pathlib import Path

from ..core.errors import StickSlipError

MAX_OUTPUT_POINTS = 1_000_000
MAX_PERIODS = 100_000
MAX_STEPS = 10_000_000


def free_period(mass, stiffness):
    """The free period ``2 pi sqrt(mass / stiffness)`` (s) of a mass (kg) on a spring (N/m), without overflow."""
    return 2.0 * math.pi * math.sqrt(mass) / math.sqrt(stiffness)


def too_many_points(stop_time, output_interval):
    """Why ``stop_time / output_interval`` output points (times in s) are refused, or "" if they are not."""
    points = stop_time / output_interval
    if points <= MAX_OUTPUT_POINTS:
        return ""
    return (f"stop_time / output_interval = {points:.3g} output points: allowed is at most {MAX_OUTPUT_POINTS:g} "
            f"(raise the output interval or shorten the run)")


def too_many_periods(stop_time, period, blocks=1):
    """Why a run of ``stop_time`` s whose fastest free oscillation has the period ``period`` (s), for each of
    ``blocks`` blocks, is refused, or "" if it is not."""
    periods = blocks * stop_time / period if period > 0.0 else math.inf
    if periods <= MAX_PERIODS:
        return ""
    per_block = "" if blocks == 1 else f", times {blocks} blocks"
    return (f"the run is {periods:.3g} free periods long (stop_time over the shortest free period {period:.3g} s"
            f"{per_block}): allowed is at most {MAX_PERIODS:g}, as longer runs take hours (shorten the run, or "
            f"soften the springs)")


def too_many_steps(stop_time, step, blocks):
    """Why a run of ``stop_time`` s in fixed steps of ``step`` s, each a ``doStep`` of each of ``blocks`` blocks, is
    refused, or "" if it is not."""
    calls = blocks * stop_time / step
    if calls <= MAX_STEPS:
        return ""
    return (f"{calls:.3g} doStep calls (stop_time / step times {blocks} blocks): allowed is at most {MAX_STEPS:g} "
            f"(raise the step)")


def output_folder(folder, names, option="--out"):
    """``folder`` (a Path), made if missing, after checking that it can hold files named ``names``; StickSlipError
    naming ``option`` and the folder if not."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        longest = os.pathconf(folder, "PC_NAME_MAX")
    except OSError as exc:
        raise StickSlipError(f"{option} {folder}: cannot make or use the folder: {exc.strerror or exc}") from None
    if not os.access(folder, os.W_OK | os.X_OK):
        raise StickSlipError(f"{option} {folder}: the folder is not writable")
    for name in names:
        if len(os.fsencode(name)) > longest:
            raise StickSlipError(f"{option} {folder}: the output file name {name!r} is {len(os.fsencode(name))} "
                                 f"bytes long: allowed is at most {longest} in this folder")
    return folder
