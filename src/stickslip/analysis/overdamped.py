"""The strongly overdamped limit: slow manifold and relaxation oscillations.

Slipping forward, ``M dv/dt = F_K(v_rel) + F_ext - kappa x`` with ``v_rel =
v_drive - v``. When ``|F_K'| >> sqrt(kappa M)`` (away from the extrema of
``F_K``) the velocity relaxes in the fast time ``M/|F_K'|`` onto the **slow
manifold**

    kappa x = F_K(v_rel) + F_ext,

along which ``x`` then drifts slowly (``dx/dt = v_drive - v_rel``). Its branches
are attracting where ``F_K'(v_rel) > 0`` (the fast equation ``M dv_rel/dt =
kappa x - F_ext - F_K(v_rel)`` is then stable) and repelling where ``F_K' < 0``;
at the extrema of ``F_K`` (folds) the slow drift runs off the manifold and the
block jumps (fast) to the other attracting branch or onto the stick line
``v_rel = 0``: relaxation oscillations. :func:`slow_manifold` gives the curve and
its branches; :func:`relaxation_run` a simulated run (the exact core stepper) to
overlay on it, in the plane ``(v_rel, x)``.
"""

import math
from dataclasses import dataclass

import numpy as np

from . import kinetic as kin


@dataclass(frozen=True)
class SlowManifold:
    """``x = (F_K(u) + F_ext)/kappa`` sampled at sliding speeds ``u`` (m/s); ``stable`` where ``F_K'(u) > 0``.

    ``folds``: ``[(u, x), ...]`` at the extrema of ``F_K``; ``ratio``: ``|F_K'(u)|/sqrt(kappa M)``
    (the overdamping: >> 1 means the relaxation onto the manifold is fast).
    """

    u: np.ndarray
    x: np.ndarray
    stable: np.ndarray
    folds: tuple
    ratio: np.ndarray


def slow_manifold(params, u_max, F_ext=0.0, n=600):
    """The slow manifold for sliding speeds ``0 < u <= u_max`` (m/s)."""
    law = params.kinetic
    force, slope = kin.vectorized(law)
    u = np.concatenate([np.geomspace(1e-6 * u_max, 1e-2 * u_max, n // 6), np.linspace(1e-2 * u_max, u_max, n)])
    u = np.unique(u)
    x = (force(u) + F_ext) / params.kappa
    sl = slope(u)
    folds = tuple((e, (law.force(e) + F_ext) / params.kappa) for e, _ in kin.extrema(law, u_max))
    return SlowManifold(u, x, sl > 0.0, folds, np.abs(sl) / math.sqrt(params.kappa * params.M))


def relaxation_run(params, v_drive, t_end=None, F_ext=0.0, x0=0.0, v0=None, rtol=1e-10):
    """A simulated run from ``(x0, v0)`` (default: stuck at the relaxed spring): ``(t, x, v_rel, mode)``."""
    from .classify import simulate

    period0 = 2.0 * math.pi * math.sqrt(params.M / params.kappa)
    if t_end is None:
        t_end = 10.0 * (params.static.force(0.0) + abs(F_ext)) / (params.kappa * v_drive) + 20.0 * period0
    dt = min(period0 / 200.0, t_end / 4000.0)
    t, x, v, mode, *_ = simulate(params, v_drive, t_end, x0, v0, F_ext, dt=dt, rtol=rtol)
    return t, x, v_drive - v, mode


def distance_to_manifold(params, x, v_rel, F_ext=0.0):
    """Force gap ``kappa x - F_ext - F_K(v_rel)`` (N) of slipping states (``v_rel > 0``) from the slow manifold."""
    force, _ = kin.vectorized(params.kinetic)
    v_rel = np.asarray(v_rel, float)
    return params.kappa * np.asarray(x, float) - F_ext - force(np.maximum(v_rel, 0.0))
