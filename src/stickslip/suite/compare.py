"""FMU vs reference on the FMU's output grid: state errors, event times, attractor.

Events are mode changes of three kinds named by the transition: "stick"
(slip -> stuck), "slip" (stuck -> slip) and "overshoot" (slip -> opposite slip).
The FMU reports them as counters and ``t_last_event`` at its communication
points: a communication step with exactly one new event, and ``t_last_event``
inside it, gives that event's time; otherwise only the step is known.
"""

from dataclasses import dataclass

import numpy as np

KINDS = ("stick", "slip", "overshoot")
FMU_COUNTERS = {"stick": "n_stick_events", "slip": "n_slip_events", "overshoot": "n_overshoots"}

#: Sliding oscillations whose velocity range shrinks by more than this factor
#: from the first to the second half of the tail are decaying onto continuous sliding.
DECAY_RATIO = 0.9


@dataclass(frozen=True)
class Event:
    """A mode change of ``kind`` known to lie in ``[t_lo, t_hi]`` (s); timed when ``t_lo == t_hi``."""

    kind: str
    t_lo: float
    t_hi: float

    @property
    def timed(self):
        return self.t_lo == self.t_hi


@dataclass(frozen=True)
class EventMatch:
    """Events paired by kind and order: max |t_fmu - t_ref| (s) over timed pairs, and counts."""

    max_time_error: float
    n_matched: int
    n_unmatched: int


@dataclass(frozen=True)
class Comparison:
    """Errors FMU - reference (m, m/s), event match, attractors, and what missed the tolerance."""

    max_abs_dx: float
    max_abs_dv: float
    final_abs_dx: float
    final_abs_dv: float
    events: EventMatch
    attractor_fmu: str
    attractor_ref: str
    failures: tuple

    @property
    def passed(self):
        return not self.failures


def transition_kind(mode_before, mode_after):
    """Kind of the mode change ``mode_before -> mode_after`` (None if the mode did not change)."""
    if mode_before == mode_after:
        return None
    if mode_after == 0:
        return "stick"
    return "slip" if mode_before == 0 else "overshoot"


def fmu_events(result):
    """Events recovered from the FMU's counters and ``t_last_event`` at its communication points."""
    t = result["time"]
    counts = {kind: np.diff(result[name], prepend=0) for kind, name in FMU_COUNTERS.items()}
    events = []
    for i in np.flatnonzero(sum(counts.values())):
        t_lo = t[max(i - 1, 0)]
        t_last = result["t_last_event"][i]
        timed = sum(c[i] for c in counts.values()) == 1 and t_lo <= t_last <= t[i]
        for kind in KINDS:
            events += [Event(kind, t_last, t_last) if timed else Event(kind, t_lo, t[i])] * int(counts[kind][i])
    return events


def reference_events(ref):
    """Timed events of a reference result (its input events count by their mode change)."""
    events = []
    for e in ref.events:
        kind = transition_kind(e.mode_before, e.mode_after)
        if kind is not None:
            events.append(Event(kind, e.t, e.t))
    return events


def match_events(fmu, ref, window):
    """Pair FMU and reference events of each kind in time order, within ``window`` s of each other."""
    errors, n_matched, n_unmatched = [], 0, 0
    for kind in KINDS:
        times = sorted(e.t_lo for e in ref if e.kind == kind)
        j = 0
        for e in sorted((e for e in fmu if e.kind == kind), key=lambda e: e.t_hi):
            while j < len(times) and times[j] < e.t_lo - window:
                n_unmatched, j = n_unmatched + 1, j + 1
            if j < len(times) and times[j] <= e.t_hi + window:
                if e.timed:
                    errors.append(abs(e.t_lo - times[j]))
                n_matched, j = n_matched + 1, j + 1
            else:
                n_unmatched += 1
        n_unmatched += len(times) - j
    return EventMatch(max(errors, default=0.0), n_matched, n_unmatched)


def stick_counts(events, t):
    """Cumulative number of "stick" events at each time of ``t``."""
    return np.searchsorted(sorted(e.t_hi for e in events if e.kind == "stick"), t, side="right")


def classify_attractor(t, v, v_drive, n_sticks, tail):
    """Attractor of a run from its last ``tail`` s.

    ``n_sticks`` is the cumulative number of sticks at each time. Returns "rest"
    (surface and block still), "stick-slip" (at least two sticks in the tail),
    "continuous-sliding" (no stick; the velocity oscillation has died out or
    shrinks), "oscillatory-sliding" (no stick; it does not shrink) or
    "undetermined" (one stick, or no stick and no sliding: the tail is too short).
    """
    in_tail = t >= t[-1] - tail
    late = t >= t[-1] - tail / 2
    early = in_tail & ~late
    speed = max(np.abs(v_drive[in_tail]).max(), np.abs(v[in_tail]).max())
    still = 1e-9 + 1e-6 * speed  # m/s
    if abs(v_drive[-1]) <= still and np.abs(v[late]).max() <= still:
        return "rest"
    sticks = n_sticks[-1] - n_sticks[in_tail][0]
    if sticks >= 2:
        return "stick-slip"
    if sticks == 1 or abs(v[late].mean()) > 0.5 * abs(v_drive[-1]):
        return "undetermined"
    spread_early, spread_late = np.ptp(v[early]), np.ptp(v[late])
    if spread_late <= still or spread_late < DECAY_RATIO * spread_early:
        return "continuous-sliding"
    return "oscillatory-sliding"


def compare(fmu, ref, scenario):
    """Compare an FMU result (structured array) with a reference result for ``scenario``.

    At an input breakpoint FMPy records the FMU before it applies the new inputs
    (left limit) while the reference gives the state after them, so a stuck block's
    velocity jump there is not an error: ``v`` is compared at the other grid times.
    """
    t = fmu["time"]
    dx = np.abs(fmu["x"] - ref.x)
    dv = np.abs(fmu["v"] - ref.v)[~np.isin(t, [b[0] for b in scenario.breakpoints()[1:]])]
    events_f, events_r = fmu_events(fmu), reference_events(ref)
    events = match_events(events_f, events_r, scenario.output_interval)
    attractor_fmu = classify_attractor(t, fmu["v"], fmu["v_drive"], fmu["n_stick_events"], scenario.tail)
    attractor_ref = classify_attractor(t, ref.v, ref.v_drive, stick_counts(events_r, t), scenario.tail)
    tol = scenario.tolerance
    checks = [
        (dx.max() <= tol.max_abs_dx, f"max |dx| {dx.max():.3g} m > {tol.max_abs_dx:g} m"),
        (dv.max() <= tol.max_abs_dv, f"max |dv| {dv.max():.3g} m/s > {tol.max_abs_dv:g} m/s"),
        (events.max_time_error <= tol.event_time,
         f"event-time error {events.max_time_error:.3g} s > {tol.event_time:g} s"),
        (events.n_unmatched == 0, f"{events.n_unmatched} unmatched events"),
        (attractor_fmu == scenario.expected_attractor, f"FMU attractor {attractor_fmu}"),
        (attractor_ref == scenario.expected_attractor, f"reference attractor {attractor_ref}"),
    ]
    return Comparison(
        max_abs_dx=float(dx.max()),
        max_abs_dv=float(dv.max()),
        final_abs_dx=float(dx[-1]),
        final_abs_dv=float(dv[-1]),
        events=events,
        attractor_fmu=attractor_fmu,
        attractor_ref=attractor_ref,
        failures=tuple(message for ok, message in checks if not ok),
    )
