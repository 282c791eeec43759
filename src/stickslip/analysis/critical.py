"""Critical drive velocities: where stick-slip disappears as ``v_drive`` grows (any kinetic law).

For a constant static law the stick-slip cycle exists exactly where the
existence margin of :mod:`.stickslip_cycle` is positive. Scanning it over
``v_drive`` gives the windows of stick-slip; each window's upper end is a
critical velocity ``v_c`` (stick-slip disappears above it, maybe to reappear
in a later window). Every end is a sign change of the margin refined to
``tol``. For an aging static law the critical velocity comes from the
stick-slip map instead (:func:`stickslip.analysis.aging_map.critical_velocity`).
"""

import math
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


@dataclass(frozen=True)
class ScanRange:
    """A drive-velocity range ``[v_min, v_max]`` (m/s) and, in words, why these ends."""

    v_min: float
    v_max: float
    reason: str


def default_scan_range(params, F_ext=0.0):
    """The range in which a constant static law's stick-slip can appear or disappear, from the law.

    With ``w = (F_S(0) + |F_ext|)/sqrt(kappa M)`` (the natural velocity) the slip
    from the onset makes ``v_rel`` oscillate about ``v_drive`` with an amplitude
    of about ``sqrt(v_drive^2 + w^2)``, so it samples ``F_K`` on ``[0, ~2 v_drive]``.
    The range ends at the largest of: ``3 w``; twice the largest sliding speed
    ``u_s`` where ``F_K'`` changes sign (every change of damping lies inside);
    and 3 times the speed ``w / sqrt(4 pi zeta)`` above which the damping ratio
    ``zeta = F_K'(inf)/(2 sqrt(kappa M))`` left at large sliding speeds takes more
    from one oscillation than the slip has to spare, so it can no longer return
    to ``v_rel = 0`` (no such bound if ``F_K'(inf) = 0``). It starts at ``1e-3 w``.
    """
    impedance = math.sqrt(params.kappa * params.M)
    natural = (params.static.force(0.0) + abs(F_ext)) / impedance
    speeds = natural * np.logspace(-4.0, 3.0, 1401)
    slopes = np.array([params.kinetic.slope(float(u)) for u in speeds])
    flips = np.flatnonzero(np.sign(slopes[1:]) * np.sign(slopes[:-1]) < 0)
    u_s = float(speeds[flips[-1] + 1]) if flips.size else 0.0
    zeta = max(float(slopes[-1]), 0.0) / (2.0 * impedance)
    damped = natural / math.sqrt(4.0 * math.pi * zeta) if zeta > 0.0 else 0.0
    v_max = max(3.0 * natural, 2.0 * u_s, 3.0 * damped)
    why = [f"3 x the natural velocity w = {natural:.4g} m/s"]
    if u_s:
        why.append(f"2 x the last sign change of F_K' at {u_s:.4g} m/s")
    why.append(f"3 x the damping bound {damped:.4g} m/s" if damped else
               "no damping bound: F_K' = 0 at large sliding speeds, stick-slip may persist above")
    return ScanRange(1e-3 * natural, v_max, "largest of " + "; ".join(why))


def critical_velocities(params, v_min=None, v_max=None, n=200, F_ext=0.0, tol=1e-7, rtol=1e-11, scan=None):
    """Scan ``[v_min, v_max]`` on ``n`` points and return the stick-slip windows and critical velocities.

    Ends not given come from :func:`default_scan_range`. ``scan``: an optional
    function ``(params, grid) -> margins`` (a parallel scan, :mod:`.parallel_scan`); by
    default the margins are computed here in one batch.
    """
    default = default_scan_range(params, F_ext)
    v_min = default.v_min if v_min is None else float(v_min)
    v_max = default.v_max if v_max is None else float(v_max)
    grid = np.linspace(v_min, v_max, n)
    margin = grazing_margin(params, grid, F_ext, rtol) if scan is None else np.asarray(scan(params, grid))
    return from_changes(v_min, v_max, margin[0] > 0.0, changes_from_samples(params, grid, margin, F_ext, tol, rtol))


def from_changes(v_min, v_max, exists_at_v_min, changes):
    """:class:`CriticalVelocities` of ``[v_min, v_max]`` from whether stick-slip exists at ``v_min`` and the
    ordered changes ``[(v_drive, "appears"/"disappears", kind), ...]``."""
    windows, start = [], (v_min if exists_at_v_min else None)
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
