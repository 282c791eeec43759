"""``stickslip bench-systems``: each master of ``stickslip system run`` on chain scenes, error against wall time.

For every system file: the chain's reference once (rtol 1e-12), then ``zoh`` at each step ``h``, ``adaptive`` and
``me`` at each ``rtol``, every run timed around the master's ``run`` (FMU extraction and instantiation included) and
compared with the reference (the largest ``max |dx|`` of any block as a fraction of the amplitude). From the runs:
the measured order of each master (the least-squares slope of ``log10(error)`` against ``log10(h)`` for ``zoh``,
against ``log10(rtol)`` for ``adaptive`` and ``me``, and the slope between neighbouring settings), and the wall-time
ratio at matched error: for each ``zoh`` run, ``adaptive``'s wall at an error at most ``zoh``'s, interpolated on
``adaptive``'s measured curve (``log10`` wall against ``log10`` error between its two runs that bracket the error;
beyond its loosest run, that run's wall: nothing extrapolated), against ``zoh``'s wall; and for each run of
``adaptive``, ``adaptive-fmi3`` and ``me``, the wall of the scipy peer (:mod:`.scipy_chain_peer`: ``solve_ivp`` over
the whole chain with events, timed the same way at each of its ``rtol``) at the master's error, interpolated the same
way on the peer's curve, and the master's wall over it.
"""

import dataclasses
import math
import os
import time

import numpy as np

from ..reference import ChainEvent, simulate_chain
from ..systems.compare import compare
from ..systems.master import SystemResult, event_kind
from ..systems.masters import make_master
from .scipy_chain_peer import run_scipy_peer

#: run label: (the master, its option varied, the option's name in the report, the master's other options);
#: ``adaptive`` runs the FMI 2 FMU (events landed by root search), ``adaptive-fmi3`` the FMI 3 FMU with early return
SETTINGS = {"zoh": ("zoh", "step", "h", {}), "adaptive": ("adaptive", "rtol", "rtol", {}),
            "adaptive-fmi3": ("adaptive", "rtol", "rtol", {"fmi": 3}), "me": ("me", "rtol", "rtol", {}),
            "scipy-peer": (None, "rtol", "rtol", {})}
#: the runs that are set beside the scipy peer's at matched error
PEER_MATCHED = ("adaptive", "adaptive-fmi3", "me")


def bench_system(system, fmu_paths, settings, progress=print):
    """The record of one system (a :class:`~stickslip.systems.system_file.System`): ``{"scene", "stop_time",
    "amplitude", "reference_wall", "runs": {master: [run]}, "orders": {master: order}, "matched": [row]}``;
    ``settings``: ``{master: [values of its option]}``; ``fmu_paths``: ``{FMI version: path}``."""
    start = time.perf_counter()
    reference = simulate_chain(system.chain_blocks(), system.coupling, system.v_drive, system.times())
    record = {"scene": system.name, "stop_time": system.stop_time, "amplitude": reference.amplitude(),
              "reference_wall": time.perf_counter() - start, "runs": {}}
    progress(f"{system.name}: reference in {record['reference_wall']:.2f} s, amplitude {record['amplitude']:.3g} m")
    for master, values in settings.items():
        record["runs"][master] = [timed_run(system, master, value, fmu_paths, reference, progress)
                                  for value in values]
    record["orders"] = {master: order(runs) for master, runs in record["runs"].items()}
    record["matched"] = matched(record["runs"].get("zoh", []), record["runs"].get("adaptive", []))
    record["early_return"] = side_by_side(record["runs"].get("adaptive", []), record["runs"].get("adaptive-fmi3", []))
    record["peer"] = against_peer(record["runs"])
    return record


def timed_run(system, master, value, fmu_paths, reference, progress):
    """One run labelled ``master`` (a key of :data:`SETTINGS`) with its option at ``value``: ``{"setting", "error",
    "wall", "events_paired"}`` (``error``: of the amplitude; ``events_paired``: every block's events pair with the
    reference's)."""
    name, option, label, others = SETTINGS[master]
    if name is None:
        start = time.perf_counter()
        result = peer_result(system, value)
        wall = time.perf_counter() - start
    else:
        runner = make_master(name, **{option: value}, **others)
        start = time.perf_counter()
        result = runner.run(system, fmu_paths[runner.FMI_VERSION])
        wall = time.perf_counter() - start
    comparison = compare(result, reference, math.inf)
    run = {"setting": value, "error": comparison.max_rel_dx, "wall": wall,
           "events_paired": bool(np.all(np.isfinite(comparison.max_event_dt))),
           "max_event_dt": float(np.max(comparison.max_event_dt))}
    progress(f"{system.name}: {master} {label} = {value:g}: error {run['error']:.3g} of the amplitude, "
             f"{wall:.2f} s (load {os.getloadavg()[0]:.2f})")
    return run


def peer_result(system, rtol):
    """The scipy peer's run of ``system`` at ``rtol`` as a :class:`~stickslip.systems.master.SystemResult`."""
    run = run_scipy_peer(system, rtol)
    events = [ChainEvent(t, block, event_kind(before, after), before, after) for t, block, before, after in run.events]
    counts = np.bincount([e.block for e in events], minlength=system.n)
    return SystemResult("scipy-peer", run.t, run.x, run.v, run.mode, events, True, counts, 0.0)


def against_peer(runs):
    """Per run of the masters :data:`PEER_MATCHED`: ``{"master", "setting", "error", "wall", "peer_error",
    "peer_wall", "ratio"}``: :func:`wall_at_error` of the scipy peer at the run's error and the run's wall over it
    (None where no peer run is that accurate)."""
    rows = []
    for master in PEER_MATCHED:
        for r in runs.get(master, []):
            found = wall_at_error(runs.get("scipy-peer", []), r["error"])
            error, wall = found if found else (None, None)
            rows.append({"master": master, "setting": r["setting"], "error": r["error"], "wall": r["wall"],
                         "peer_error": error, "peer_wall": wall, "ratio": r["wall"] / wall if wall else None})
    return rows


def side_by_side(fmi2_runs, fmi3_runs):
    """Per ``rtol`` run by both ``adaptive`` schemes: ``{"rtol", "fmi2_error", "fmi3_error", "fmi2_wall", "fmi3_wall",
    "ratio"}``, ``ratio`` the FMI 3 (early return) wall over the FMI 2 wall."""
    by_rtol = {r["setting"]: r for r in fmi2_runs}
    return [{"rtol": r["setting"], "fmi2_error": by_rtol[r["setting"]]["error"], "fmi3_error": r["error"],
             "fmi2_wall": by_rtol[r["setting"]]["wall"], "fmi3_wall": r["wall"],
             "ratio": r["wall"] / by_rtol[r["setting"]]["wall"]} for r in fmi3_runs if r["setting"] in by_rtol]


def order(runs):
    """``{"fit": slope, "steps": [slope between neighbours]}`` of ``log10(error)`` against ``log10(setting)``
    (None where fewer than two runs have a positive, finite error)."""
    points = [(math.log10(r["setting"]), math.log10(r["error"])) for r in runs if 0.0 < r["error"] < math.inf]
    if len(points) < 2:
        return {"fit": None, "steps": []}
    s, e = np.array(points).T
    steps = [float((e[k + 1] - e[k]) / (s[k + 1] - s[k])) for k in range(len(points) - 1)]
    return {"fit": float(np.polyfit(s, e, 1)[0]), "steps": steps}


def matched(zoh_runs, adaptive_runs):
    """Per ``zoh`` run: ``{"h", "zoh_error", "zoh_wall", "adaptive_error", "adaptive_wall", "ratio"}``:
    :func:`wall_at_error` of ``adaptive`` at ``zoh``'s error and ``zoh_wall / adaptive_wall`` (None where no
    ``adaptive`` run is that accurate)."""
    rows = []
    for z in zoh_runs:
        found = wall_at_error(adaptive_runs, z["error"])
        error, wall = found if found else (None, None)
        rows.append({"h": z["setting"], "zoh_error": z["error"], "zoh_wall": z["wall"], "adaptive_error": error,
                     "adaptive_wall": wall, "ratio": z["wall"] / wall if wall else None})
    return rows


def wall_at_error(runs, target):
    """``(error, wall)`` of the master whose ``runs`` are given at an error of at most ``target``: interpolated
    (``log10`` wall against ``log10`` error) between the most accurate run above ``target`` and the cheapest run
    at or below it; the latter alone when ``target`` is beyond every run's error; None when no run reaches it."""
    finite = [r for r in runs if 0.0 < r["error"] < math.inf]
    below = [r for r in finite if r["error"] <= target]
    if not below:
        return None
    cheapest = min(below, key=lambda r: r["wall"])
    above = [r for r in finite if target < r["error"] and r["wall"] < cheapest["wall"]]
    if not above:
        return cheapest["error"], cheapest["wall"]
    near = min(above, key=lambda r: r["error"])
    u = (math.log10(target) - math.log10(cheapest["error"])) / (math.log10(near["error"])
                                                                 - math.log10(cheapest["error"]))
    wall = 10.0 ** ((1.0 - u) * math.log10(cheapest["wall"]) + u * math.log10(near["wall"]))
    return target, wall


def with_stop_time(system, stop_time):
    """``system`` over ``stop_time`` s instead (None: unchanged)."""
    return system if stop_time is None else dataclasses.replace(system, stop_time=float(stop_time))
