"""The chain part of ``stickslip bench-systems``: the chain engine against the numba peer at matched error.

For each chain (system files such as ``systems/bk10-velocity-weakening.toml``, and template chains of ``N`` like
blocks with seeded start offsets): the reference once (``simulate_chain`` at rtol 1e-13, timed), then the engine
(:func:`stickslip.chain.run_chain`), the peer (:mod:`.numba_chain_peer`) and, where asked, the reference itself at
looser tolerances (the package's scipy route, DOP853), each at every rtol. Every subject is warmed up first on a
short run of the same chain (numba's compilation, or loading its cache, is timed there and reported apart); a
timed run is the median of ``repeats`` calls of the whole run (positions on the chain's output grid, events kept
in memory), the subjects taking turns at each rtol. Error: max |x - x_ref| over every block and grid time, as a
fraction of the reference's amplitude. At matched error: for each peer run, the engine's wall at that error on its
measured curve (:func:`.systems_bench.wall_at_error`) over the peer's wall.

A large chain (``N = 1000`` over 1000 s) has no reference run (it would take hours): its errors are against the
engine at a tighter tolerance, and the record says so.
"""

import math
import os
import statistics
import time

import numpy as np

from ..chain.engine import run_chain
from ..chain.output import MemorySink
from ..chain.spec import ChainSpec
from ..chain.template import chain_system
from ..reference import simulate_chain
from .numba_chain_peer import chain_arrays, run_peer
from .systems_bench import wall_at_error, with_stop_time

REFERENCE_RTOL = 1e-13
#: the warm-up run's length in output intervals
WARM_UP_INTERVALS = 20


def subjects(system, reference_rtols=()):
    """``{name: run(rtol) -> (x on the system's grid (m, shape (len(t), N)), event times (s))}`` for the engine,
    the peer and (with ``reference_rtols``) the reference; each subject's arrays are built here, outside timing."""
    spec = ChainSpec.from_system(system)
    peer_chain = chain_arrays(system.blocks, system.coupling, system.v_drive)
    t, blocks = system.times(), system.chain_blocks()

    def engine(rtol):
        sink = MemorySink()
        run_chain(spec, system.stop_time, rtol=rtol, output_interval=system.output_interval, sink=sink)
        sink.arrays()
        return sink.x, sink.event_t

    def peer(rtol):
        run = run_peer(peer_chain, t, rtol)
        return run.x, run.event_t

    def reference(rtol):
        result = simulate_chain(blocks, system.coupling, system.v_drive, t, rtol=rtol)
        return result.x, np.array([e.t for e in result.events])

    named = {"engine": engine, "peer": peer}
    return named | ({"reference": reference} if reference_rtols else {})


def warm_up(system, reference_rtols=()):
    """``{subject: wall (s) of its first call}`` on the chain's first :data:`WARM_UP_INTERVALS` output intervals
    (numba compiles, or loads its cache, there)."""
    short = with_stop_time(system, min(system.stop_time, WARM_UP_INTERVALS * system.output_interval))
    out = {}
    for name, run in subjects(short, reference_rtols).items():
        start = time.perf_counter()
        run(1e-6)
        out[name] = time.perf_counter() - start
    return out


def timed(call, repeats):
    """``(result of the first call, median wall (s), every wall)`` of ``repeats`` calls of ``call()``."""
    walls, result = [], None
    for k in range(max(1, repeats)):
        start = time.perf_counter()
        value = call()
        walls.append(time.perf_counter() - start)
        result = value if k == 0 else result
    return result, statistics.median(walls), walls


def score(x, events, truth):
    """``{"error", "events", "max_event_dt"}`` of a run against ``truth`` (``{"x", "events", "amplitude"}``):
    ``error`` max |dx| / amplitude (inf where the grids differ), ``max_event_dt`` (s) the largest difference of
    event times where the runs have as many events (else None)."""
    x = np.asarray(x)
    error = float(np.abs(x - truth["x"]).max()) / truth["amplitude"] if x.shape == truth["x"].shape else math.inf
    same = len(events) == len(truth["events"])
    dt = float(np.abs(np.asarray(events) - truth["events"]).max()) if same and len(events) else None
    return {"error": error, "events": int(len(events)), "max_event_dt": dt}


def bench_chain(system, rtols, repeats, reference_rtols=(), progress=print):
    """The record of one chain: ``{"chain", "n", "stop_time", "amplitude", "truth", "truth_wall", "warm_up",
    "runs": {subject: [run]}, "matched": [row]}``, a run ``{"setting", "error", "wall", "walls", "events",
    "max_event_dt"}``; the truth is the reference at :data:`REFERENCE_RTOL`."""
    start = time.perf_counter()
    result = simulate_chain(system.chain_blocks(), system.coupling, system.v_drive, system.times(),
                            rtol=REFERENCE_RTOL)
    truth = {"x": result.x, "events": np.array([e.t for e in result.events]), "amplitude": result.amplitude()}
    record = {"chain": system.name, "n": system.n, "stop_time": system.stop_time,
              "amplitude": truth["amplitude"], "truth": f"reference (simulate_chain) at rtol {REFERENCE_RTOL:g}",
              "truth_wall": time.perf_counter() - start, "truth_events": len(result.events)}
    progress(f"{system.name}: reference at rtol {REFERENCE_RTOL:g} in {record['truth_wall']:.1f} s, "
             f"{len(result.events)} block events, amplitude {truth['amplitude']:.3g} m")
    record["warm_up"] = warm_up(system, reference_rtols)
    settings = {"engine": rtols, "peer": rtols, "reference": reference_rtols}
    record["runs"] = side_by_side(system, subjects(system, reference_rtols), settings, truth, repeats, progress)
    record["matched"] = matched(record["runs"]["engine"], record["runs"]["peer"])
    return record


def side_by_side(system, runners, settings, truth, repeats, progress):
    """``{subject: [run]}``: at each rtol, every subject that has it in ``settings`` in turn (so that the
    machine's load falls on all alike)."""
    runs = {name: [] for name in runners}
    for rtol in sorted({r for name in runners for r in settings[name]}, reverse=True):
        for name, run in runners.items():
            if rtol not in settings[name]:
                continue
            (x, events), wall, walls = timed(lambda: run(rtol), repeats)
            entry = {"setting": rtol, "wall": wall, "walls": walls} | score(x, events, truth)
            runs[name].append(entry)
            progress(f"{system.name}: {name} rtol {rtol:g}: error {entry['error']:.3g} of the amplitude, "
                     f"{wall:.3g} s, {entry['events']} block events (load {os.getloadavg()[0]:.2f})")
    return runs


def matched(engine_runs, peer_runs):
    """Per peer run: ``{"rtol", "peer_error", "peer_wall", "engine_error", "engine_wall", "ratio"}``, the engine at
    the peer's error (:func:`.systems_bench.wall_at_error`; None where no engine run is that accurate) and
    ``ratio`` = engine wall / peer wall."""
    rows = []
    for p in peer_runs:
        found = wall_at_error(engine_runs, p["error"])
        error, wall = found if found else (None, None)
        rows.append({"rtol": p["setting"], "peer_error": p["error"], "peer_wall": p["wall"], "engine_error": error,
                     "engine_wall": wall, "ratio": wall / p["wall"] if wall else None})
    return rows


def bench_large(system, rtols, tight_rtol, with_peer, progress=print):
    """The record of a chain too large for the reference, as :func:`bench_chain`'s: the truth is the engine at
    ``tight_rtol``; one timed run per subject and rtol; the peer only ``with_peer``."""
    runners = subjects(system)
    record = {"chain": system.name, "n": system.n, "stop_time": system.stop_time,
              "truth": f"the engine at rtol {tight_rtol:g} (no reference run at this size)",
              "warm_up": warm_up(system)}
    (x, events), wall, _ = timed(lambda: runners["engine"](tight_rtol), 1)
    truth = {"x": x, "events": np.asarray(events), "amplitude": float(np.max(np.ptp(x, axis=0)))}
    record |= {"amplitude": truth["amplitude"], "truth_wall": wall, "truth_events": len(events)}
    progress(f"{system.name}: the engine at rtol {tight_rtol:g} (the truth here) in {wall:.1f} s, "
             f"{len(events)} block events")
    if not with_peer:
        del runners["peer"]
    record["runs"] = side_by_side(system, runners, {"engine": rtols, "peer": rtols}, truth, 1, progress)
    record["matched"] = matched(record["runs"]["engine"], record["runs"].get("peer", []))
    return record


def template_chains(sizes, seed, stop_time, output_interval):
    """Chains of ``N`` like blocks (:func:`stickslip.chain.template.chain_system`, the Burridge-Knopoff defaults
    of bk10, start offsets drawn with ``seed``) over ``stop_time`` s."""
    return [chain_system(n, seed=seed, stop_time=stop_time, output_interval=output_interval) for n in sizes]


def growth(records):
    """How the walls grow with ``N``: per record ``{"n", "chain", "rtol", "peer_wall", "engine_wall", "ratio"}`` at
    the tightest peer rtol where the engine matches the peer's error, walls per simulated second (s/s), and the
    fitted exponents ``{"peer", "engine"}`` of that wall against N over the rows of the most common rtol
    (least squares in log-log; None below two sizes)."""
    rows = []
    for record in records:
        usable = [m for m in record["matched"] if m["engine_wall"]]
        if usable:
            m = min(usable, key=lambda row: row["rtol"])
            rows.append({"n": record["n"], "chain": record["chain"], "rtol": m["rtol"], "ratio": m["ratio"],
                         "peer_wall": m["peer_wall"] / record["stop_time"],
                         "engine_wall": m["engine_wall"] / record["stop_time"]})
    fits = {}
    for name in ("peer", "engine"):
        same = {}
        for row in rows:
            same.setdefault(row["rtol"], []).append((math.log10(row["n"]), math.log10(row[f"{name}_wall"])))
        best = max(same.values(), key=len, default=[])
        fits[name] = float(np.polyfit(*np.array(best).T, 1)[0]) if len({p[0] for p in best}) >= 2 else None
    return {"rows": rows, "exponents": fits}
