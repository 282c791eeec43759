"""A chain run in a folder against the independent reference (:func:`stickslip.reference.simulate_chain`): block
events paired, the two catalogues, the positions on the output grid. The reference keeps its whole run in memory:
this is for runs of minutes, asked for (``stickslip chain --reference``)."""

import json
from pathlib import Path

import numpy as np

from ..reference import simulate_chain
from .catalogue import BLOCK_EVENTS_FILE, group_slip_events, read_block_events
from .output import EVENT_KINDS, POSITIONS_FILE

REFERENCE_JSON = "reference.json"


def compare_with_reference(system, folder, stop_time, output_interval=None, rtol=1e-12, slipping_at_start=None,
                           progress=None):
    """Run the reference over the chain of ``system`` to ``stop_time`` (s) at ``rtol`` (sampled at the times of the
    engine's ``positions.csv`` where ``output_interval`` is given) and compare it with the engine's files in
    ``folder``; write ``reference.json`` there and return its content: event counts by kind,
    ``max_event_dt`` (s, where both have the same events in the same order, else None and the first difference),
    the slip events of both, ``max_rel_dx`` (max |x - x_ref| over the amplitude on the output grid, with one)."""
    folder = Path(folder)
    grid = _grid(folder) if output_interval else None
    times = np.array([0.0, stop_time]) if grid is None else grid[:, 0]
    reference = simulate_chain(system.chain_blocks(), system.coupling, system.v_drive, times, rtol=rtol,
                               progress=progress)
    ours = [np.concatenate(parts) for parts in zip(*read_block_events(folder / BLOCK_EVENTS_FILE))] or \
        [np.zeros(0), np.zeros(0, int), np.zeros(0, str), np.zeros(0)]
    theirs = reference_block_events(reference)
    result = {"rtol": rtol, "events": {kind: [int(np.count_nonzero(ours[2] == kind)),
                                              int(np.count_nonzero(theirs[2] == kind))] for kind in EVENT_KINDS},
              **_paired(ours, theirs),
              "slip_events": _catalogues(ours, theirs, system.v_drive, slipping_at_start),
              "max_rel_dx": None if grid is None else _max_rel_dx(grid[:, 1:], reference)}
    (folder / REFERENCE_JSON).write_text(json.dumps(result, indent=2) + "\n")
    return result


def reference_block_events(reference):
    """The block events of a :class:`stickslip.reference.ChainResult` as the catalogue takes them: arrays of the
    times (s), blocks (1-based), kinds and positions (m, from its dense solution)."""
    events = reference.events
    return [np.array([e.t for e in events]), np.array([e.block + 1 for e in events], int),
            np.array([e.kind for e in events], str), np.array([reference.state(e.t)[0][e.block] for e in events])]


def _paired(ours, theirs):
    """The largest event-time difference (s) where both runs have the same events in the same order."""
    same = min(ours[0].size, theirs[0].size)
    differ = np.flatnonzero((ours[1][:same] != theirs[1][:same]) | (ours[2][:same] != theirs[2][:same]))
    if differ.size or ours[0].size != theirs[0].size:
        k = int(differ[0]) if differ.size else same
        return {"max_event_dt": None, "first_difference": {"event": k + 1, "engine": _event(ours, k),
                                                           "reference": _event(theirs, k)}}
    return {"max_event_dt": float(np.max(np.abs(ours[0] - theirs[0]))) if same else 0.0}


def _event(events, k):
    return None if k >= events[0].size else {"time": float(events[0][k]), "block": int(events[1][k]),
                                             "kind": str(events[2][k])}


def _catalogues(ours, theirs, v_drive, slipping_at_start):
    """The two catalogues' counts, whether their sizes agree event by event, and the largest moment difference."""
    a, _ = group_slip_events(*ours, v_drive=v_drive, slipping_at_start=slipping_at_start)
    b, _ = group_slip_events(*theirs, v_drive=v_drive, slipping_at_start=slipping_at_start)
    same = a["size"].size == b["size"].size
    return {"engine": int(a["size"].size), "reference": int(b["size"].size),
            "same_sizes": bool(same and np.array_equal(a["size"], b["size"])),
            "max_moment_difference": float(np.max(np.abs(a["moment"] - b["moment"]), initial=0.0)) if same else None}


def _grid(folder):
    """The engine's ``positions.csv`` as an array (rows ``t, x_1..x_N``), or None without rows."""
    grid = np.loadtxt(folder / POSITIONS_FILE, delimiter=",", skiprows=1, ndmin=2)
    return grid if grid.shape[0] else None


def _max_rel_dx(x, reference):
    """max |x - x_ref| on the grid over the reference's amplitude (m; the floor 1e-300 m)."""
    return float(np.max(np.abs(x - reference.x)) / max(reference.amplitude(), 1e-300))
