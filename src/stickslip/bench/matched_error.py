"""Ours against a peer at matched error: for each tolerance of the peer, ours at the loosest ``solver.rtol``
that is as accurate, both timed.

Errors are max |x - reference| (m) on a scene's grid, the reference being
:func:`stickslip.reference.simulate_reference` at rtol 1e-13 (:attr:`.scenes.Scene.reference`).
:func:`fmpy_family`: the msl-pendulum scene (0.01 s over 5 s) through ``fmpy.simulate_fmu`` of the extracted
peer over its tolerance sweep (``relative_tolerance``, passed to ``fmi2SetupExperiment``) and of ours over
``solver.rtol``.
"""

import numpy as np

from ..hosts.fmpy_host import ExtractedFMU
from .process_timing import timed_call

PEER_TOLERANCES = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12)
#: our solver.rtol, loosest first
OUR_RTOLS = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13)


def loosest_rtol(error_at, target):
    """``(rtol, error)``: the loosest of :data:`OUR_RTOLS` whose ``error_at(rtol)`` (m) is at most ``target``, or
    the most accurate one tried if none is (its error above the target shows it)."""
    tried = []
    for rtol in OUR_RTOLS:
        tried.append((rtol, error_at(rtol)))
        if tried[-1][1] <= target:
            return tried[-1]
    return min(tried, key=lambda pair: pair[1])


def grid_error(x, scene):
    """Max |x - reference| (m), ``x`` on the scene's whole grid."""
    return float(np.abs(np.asarray(x) - scene.reference.x).max())


def matched(scene, peer_tolerances, run_peer, run_ours, repeats, progress=print, label="peer"):
    """Rows ``{"peer_tolerance", "peer_error", "our_rtol", "our_error", "peer_wall_ms", "peer_cpu_ms",
    "our_wall_ms", "our_cpu_ms", "ratio_wall", "ratio_cpu"}`` (medians of ``repeats`` calls; ratios ours / peer),
    one per peer tolerance. ``run_peer(tolerance)`` and ``run_ours(rtol)`` return x (m) on the scene's grid."""
    scene.reference  # noqa: B018 -- computed outside every timing
    our_errors, our_times, rows = {}, {}, []

    def our_error(rtol):
        if rtol not in our_errors:
            our_errors[rtol] = grid_error(run_ours(rtol), scene)
        return our_errors[rtol]

    for tol in peer_tolerances:
        progress(f"{label} at tolerance {tol:g}, ours at matched error")
        peer_error = grid_error(run_peer(tol), scene)
        rtol, error = loosest_rtol(our_error, peer_error)
        theirs = timed_call(lambda: run_peer(tol), repeats)
        if rtol not in our_times:
            our_times[rtol] = timed_call(lambda: run_ours(rtol), repeats)
        row = {"peer_tolerance": tol, "peer_error": peer_error, "our_rtol": rtol, "our_error": error}
        for clock in ("wall", "cpu"):
            row.update({f"peer_{clock}_ms": 1e3 * theirs.median(clock),
                        f"our_{clock}_ms": 1e3 * our_times[rtol].median(clock),
                        f"ratio_{clock}": our_times[rtol].median(clock) / theirs.median(clock)})
        rows.append(row)
    return rows


def fmpy_family(peer_fmu, peer, ours_fmu, scene, repeats, progress=print):
    """:func:`matched` rows of the peer (``peer``: its :class:`~.c_hosts.Subject`, output and offset) and ours,
    both extracted once, through ``fmpy.simulate_fmu`` on ``scene`` over :data:`PEER_TOLERANCES`."""
    T, h = scene.stop_time, scene.grid_step
    with ExtractedFMU(peer_fmu) as theirs, ExtractedFMU(ours_fmu) as ours:
        return matched(
            scene, PEER_TOLERANCES,
            lambda tol: theirs.simulate({}, T, h, [peer.output], relative_tolerance=tol)[peer.output] - peer.offset,
            lambda rtol: ours.simulate(scene.start_values(rtol), T, h, ["x"])["x"],
            repeats, progress, "FMPy: the peer")
