"""Critical drive velocities: where stick-slip disappears as ``v_drive`` grows (any kinetic law).

For a constant static law the stick-slip cycle exists exactly where the
existence margin of :mod:`.stickslip_cycle` is positive. Scanning it over
``v_drive`` gives the windows of stick-slip; each window's upper end is a
critical velocity ``v_c`` (stick-slip disappears above it, maybe to reappear
in a later window). Every end is a sign change of the margin refined to
``tol``. For an aging static law the critical velocity comes from the
stick-slip map instead (:func:`stickslip.analysis.aging_map.critical_velocity`).
"""

from dataclasses import dataclass

import numpy as np

from .stickslip_cycle import changes_from_samples, grazing_margin


@dataclass(frozen=True)
class CriticalVelocities:
    """Stick-slip windows ``[(v_from, v_to), ...]`` (m/s) in the scanned range and the critical velocities.

    ``critical`` lists the upper ends where stick-slip disappears (the ``v_c``);
    ``changes`` every refined change ``(v_drive, "appears"/"disappears", kind)``;
    a window reaching a scan end has that end as its bound.
    """

    v_min: float
    v_max: float
    windows: tuple
    critical: tuple
    changes: tuple


def critical_velocities(params, v_min=None, v_max=None, n=200, F_ext=0.0, tol=1e-7, rtol=1e-11, scan=None):
    """Scan ``[v_min, v_max]`` on ``n`` points and return the stick-slip windows and critical velocities.

    Defaults: ``v_min`` = 1e-3 and ``v_max`` = 3 of the natural velocity
    ``(F_S(0) + |F_ext|)/sqrt(kappa M)`` (the speed a stick-slip's slip reaches).
    ``scan``: an optional function ``(params, grid) -> margins`` (a parallel
    scan, :mod:`.scan`); by default the margins are computed here in one batch.
    """
    natural = (params.static.force(0.0) + abs(F_ext)) / np.sqrt(params.kappa * params.M)
    v_min = 1e-3 * natural if v_min is None else float(v_min)
    v_max = 3.0 * natural if v_max is None else float(v_max)
    grid = np.linspace(v_min, v_max, n)
    margin = grazing_margin(params, grid, F_ext, rtol) if scan is None else np.asarray(scan(params, grid))
    changes = changes_from_samples(params, grid, margin, F_ext, tol, rtol)
    windows, start = [], (v_min if margin[0] > 0.0 else None)
    for v, what, _ in changes:
        if what == "appears":
            start = v
        elif start is not None or not windows:
            windows.append((v_min if start is None else start, v))
            start = None
    if start is not None:
        windows.append((start, v_max))
    critical = tuple(v for v, what, _ in changes if what == "disappears")
    return CriticalVelocities(v_min, v_max, tuple(windows), critical, tuple(changes))
