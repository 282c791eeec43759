"""``fmpy.simulate_fmu`` of an ``.fmu`` file, as a scientist calls it (extraction and instantiation in every
call), against what they would write instead and against the do-nothing PythonFMU FMU.

- :func:`dense_grid`: elmer-fig3 at v = 0.1 m/s over 2000 s, outputs every 1 s: for each tolerance of the
  hybrid ``solve_ivp`` DOP853 with events (:func:`.peers.hybrid_solve_ivp`), ours at matched error
  (:func:`.matched_error.matched`); :func:`dense_grid_tuned`: the same against the hand-tuned DOP853 with events
  (:func:`.peers.tuned_solve_ivp`).
- :func:`one_step`: one 1 s communication step of ours (elmer-fig3 start values) and of the floor FMU.
"""

from dataclasses import replace

import fmpy

from ..fmu.python_path import preserved_sys_path
from .matched_error import matched
from .peers import hybrid_solve_ivp, tuned_solve_ivp
from .process_timing import timed_call
from .scenes import SCENES

DENSE_SCENE = replace(SCENES["elmer-fig3-v0.1"], stop_time=2000.0, grid_step=1.0)
DOP853_RTOLS = (1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13)
#: the hand-tuned peer's rtols; its atol (m, m/s) is :data:`TUNED_ATOL_PER_RTOL` times the rtol
TUNED_RTOLS = (1e-9, 1e-10, 3e-11, 1e-11)
TUNED_ATOL_PER_RTOL = 1e-2


def simulate_file(fmu_path, start_values, stop_time, step, outputs=("x",)):
    """``fmpy.simulate_fmu`` of the file (FMPy extracts it into a temporary folder and removes it)."""
    with preserved_sys_path():  # PythonFMU puts the FMU's resources on sys.path
        return fmpy.simulate_fmu(str(fmu_path), stop_time=stop_time, output_interval=step,
                                 start_values=start_values, output=list(outputs))


def dense_grid(fmu_path, repeats, progress=print, scene=DENSE_SCENE):
    """:func:`~.matched_error.matched` rows, DOP853 as the peer (wall and CPU, medians of ``repeats``)."""
    return _against_file(fmu_path, DOP853_RTOLS, lambda p, x0, v0, v_drive, F_ext, grid, rtol: hybrid_solve_ivp(
        p, x0, v0, v_drive, F_ext, grid, "DOP853", rtol, rtol), repeats, progress, scene, "DOP853")


def dense_grid_tuned(fmu_path, repeats, progress=print, scene=DENSE_SCENE):
    """:func:`~.matched_error.matched` rows, the hand-tuned DOP853 as the peer (its rtol the peer tolerance)."""
    return _against_file(fmu_path, TUNED_RTOLS, lambda p, x0, v0, v_drive, F_ext, grid, rtol: tuned_solve_ivp(
        p, x0, v0, v_drive, F_ext, grid, rtol, TUNED_ATOL_PER_RTOL * rtol), repeats, progress, scene,
                         "hand-tuned DOP853")


def _against_file(fmu_path, tolerances, peer, repeats, progress, scene, label):
    """:func:`~.matched_error.matched` rows of ``peer(p, x0, v0, v_drive, F_ext, grid, tolerance)`` (a
    :class:`~.peers.Run`) against ``simulate_fmu`` of the file on ``scene``."""
    v_drive, F_ext = scene.inputs
    grid, p, x0, v0 = scene.grid(), scene.params, scene.scenario.x0, scene.scenario.v0
    return matched(
        scene, tolerances, lambda tol: peer(p, x0, v0, v_drive, F_ext, grid, tol).x,
        lambda rtol: simulate_file(fmu_path, scene.start_values(rtol), scene.stop_time, scene.grid_step)["x"],
        repeats, progress, f"elmer-fig3 v = 0.1, {scene.stop_time:g} s: {label}")


def one_step(fmu_path, floor_path, repeats, progress=print, scene=DENSE_SCENE):
    """``{"fmu": {"wall_ms", "cpu_ms"}, "floor": {...}, "ratio_wall", "ratio_cpu"}``: medians of one-step
    ``simulate_fmu`` calls of the two files (ratios ours / floor)."""
    progress("one-step simulate_fmu: ours and the PythonFMU floor")
    start = scene.start_values(1e-10)
    out = {}
    for side, call in (("fmu", lambda: simulate_file(fmu_path, start, 1.0, 1.0)),
                       ("floor", lambda: simulate_file(floor_path, {}, 1.0, 1.0))):
        timings = timed_call(call, repeats)
        out[side] = {"wall_ms": 1e3 * timings.median("wall"), "cpu_ms": 1e3 * timings.median("cpu")}
    for clock in ("wall", "cpu"):
        out[f"ratio_{clock}"] = out["fmu"][f"{clock}_ms"] / out["floor"][f"{clock}_ms"]
    return out
