"""A master's run against the chain's reference on the same grid: position errors and events, per block.

Errors are judged as a fraction of the chain's amplitude, or of a floor where the chain hardly moves:
:data:`AMPLITUDE_FLOOR` times its length scale (the largest ``F_S(0) / kappa``). A chain at rest (amplitude 0)
passes when the master's positions are within the tolerance times that floor of the reference's.
"""

import math
from dataclasses import dataclass

import numpy as np

#: the smallest amplitude (m) an error is measured against, as a fraction of the chain's length scale
AMPLITUDE_FLOOR = 1e-6


@dataclass(frozen=True)
class Comparison:
    """``amplitude`` (m): the reference's largest range of any block's ``x``; per block (arrays over blocks):
    ``max_abs_dx`` (m), the master's and the reference's event counts, and ``max_event_dt`` (s, NaN where the
    events cannot be paired: the counts or kinds differ, or the master does not know every event's time);
    ``tolerance``: the largest allowed ``max_rel_dx``, or None: the run is not judged (it passes unless an error is
    not finite); ``floor`` (m): the smallest amplitude an error is measured
    against; ``divergence``: whether the chain's trajectory diverges (:class:`~.chaos.Divergence`, None: not
    measured) and ``statistics``: where it does, the run's :class:`~.chaos.StatisticalCheck`, which then judges it
    instead of the amplitude."""

    amplitude: float
    max_abs_dx: np.ndarray
    master_events: np.ndarray
    reference_events: np.ndarray
    max_event_dt: np.ndarray
    tolerance: float | None
    floor: float = 0.0
    divergence: object = None
    statistics: object = None

    @property
    def scale(self):
        """What errors are a fraction of (m): the amplitude, at least the floor."""
        return max(self.amplitude, self.floor)

    @property
    def max_rel_dx(self):
        """The largest ``max |dx|`` of any block as a fraction of :attr:`scale` (0 where both are 0)."""
        largest = float(np.max(self.max_abs_dx))
        if self.scale > 0.0:
            return largest / self.scale
        return 0.0 if largest == 0.0 else math.inf

    @property
    def judged(self):
        """Whether the error is held against a tolerance (else it is only reported)."""
        return self.tolerance is not None

    @property
    def ok(self):
        if self.statistics is not None:
            return self.statistics.ok
        if not self.judged:
            return math.isfinite(self.max_rel_dx)
        return bool(self.max_rel_dx <= self.tolerance)


def amplitude_floor(system):
    """The floor (m) of the amplitude for :func:`compare`: :data:`AMPLITUDE_FLOOR` times the system's length
    scale."""
    return AMPLITUDE_FLOOR * system.length_scale


def compare(result, reference, tolerance, floor=0.0):
    """Compare a :class:`~.master.SystemResult` with a :class:`~stickslip.reference.ChainResult` on the same grid;
    ``tolerance``: the largest allowed ``max |dx|`` as a fraction of the amplitude, or of ``floor`` (m) if that is
    larger (:func:`amplitude_floor`); None: not judged."""
    if result.x.shape != reference.x.shape or not np.allclose(result.t, reference.t, rtol=1e-12, atol=0.0):
        raise ValueError(f"the master's grid ({result.x.shape}) is not the reference's ({reference.x.shape})")
    n = reference.x.shape[1]
    dx = np.abs(result.x - reference.x)
    max_abs_dx = np.where(np.all(np.isfinite(result.x), axis=0), np.max(dx, axis=0, initial=0.0), math.inf)
    reference_events = np.array([sum(e.block == i for e in reference.events) for i in range(n)])
    dt = np.array([_event_dt(result, reference, i) for i in range(n)])
    return Comparison(reference.amplitude(), max_abs_dx, np.asarray(result.event_counts), reference_events, dt,
                      tolerance, floor)


def _event_dt(result, reference, block):
    """Largest event-time difference (s) of ``block`` when the master's events pair with the reference's, else NaN."""
    mine = [e for e in result.events if e.block == block]
    theirs = [e for e in reference.events if e.block == block]
    if not result.events_complete or len(mine) != len(theirs) or \
            any(a.kind != b.kind for a, b in zip(mine, theirs)):
        return math.nan
    return max((abs(a.t - b.t) for a, b in zip(mine, theirs)), default=0.0)
