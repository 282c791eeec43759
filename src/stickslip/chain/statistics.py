"""Statistics of a slip-event catalogue: size and moment distributions with a fitted power law, recurrence
intervals, and the summary written as ``statistics.json`` and ``statistics.md``.

The power law ``p(x) ~ x^-alpha`` for ``x >= x_min`` is fitted by maximum likelihood (A. Clauset, C. R. Shalizi,
M. E. J. Newman, SIAM Review 51 (2009) 661): the sizes as a discrete law (``p(s) = s^-alpha / zeta(alpha, s_min)``,
Hurwitz's zeta), the moments' magnitudes ``|moment|`` (m) as a continuous one (``alpha = 1 + n / sum ln(x /
x_min)``). ``x_min``, unless given, is the value above which the fitted law is closest to the data in the
Kolmogorov-Smirnov distance (among the observed values with at least :data:`MIN_TAIL` events at or above them).
The uncertainty comes twice: the standard error of the maximum likelihood (the inverse Fisher information,
``(alpha - 1) / sqrt(n)`` for the continuous law) at that ``x_min``, and the standard deviation of the
exponents refitted to bootstrap resamples of the events (``x_min`` chosen again in each). A finite chain's sizes
end at ``N``: the fit says how steeply they fall below that, not that they follow a power law.
"""

import json
import math
from pathlib import Path

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.special import zeta

STATISTICS_JSON = "statistics.json"
STATISTICS_MD = "statistics.md"
#: the fewest events, and of distinct values, at or above a candidate x_min
MIN_TAIL = 20
MIN_DISTINCT = 3
#: the exponents searched (alpha in (1, ALPHA_MAX])
ALPHA_MAX = 20.0
#: the most candidate x_min values tried (quantiles of the observed values beyond this many)
MAX_CANDIDATES = 200


class StatisticsError(ValueError):
    """Data that cannot be fitted (too few events, values that are not positive)."""


def fit_power_law(values, *, discrete, x_min=None, bootstrap=200, seed=0):
    """The power law fitted to ``values`` (> 0) at and above ``x_min`` (chosen by the KS distance if None):
    ``{"alpha", "standard_error", "bootstrap_error", "x_min", "n_tail", "n", "ks_distance", "discrete"}``;
    ``bootstrap_error``: the spread of the exponents refitted at the same ``x_min`` to ``bootstrap`` resamples
    (None without)."""
    values = _positive(values)
    if x_min is None:
        x_min, alpha, error, distance = _choose_x_min(values, discrete)
        if x_min is None:
            raise StatisticsError(f"{values.size} events: a fit needs at least {MIN_TAIL}, with {MIN_DISTINCT} "
                                  "distinct values")
    else:
        x_min = float(x_min)
        alpha, error, distance = _fit_tail(values, x_min, discrete)
    rng = np.random.default_rng(seed)
    tail = values[values >= x_min]
    fit = _discrete_fit if discrete else _continuous_fit
    # a resample of all events keeps a binomial number of them in the tail
    redraws = [fit(rng.choice(tail, max(2, rng.binomial(values.size, tail.size / values.size))), x_min)[0]
               for _ in range(bootstrap)]
    return {"alpha": alpha, "standard_error": error,
            "bootstrap_error": float(np.std(redraws, ddof=1)) if len(redraws) > 1 else None,
            "x_min": x_min, "n_tail": int(tail.size), "n": int(values.size), "ks_distance": distance,
            "discrete": discrete}


def _positive(values):
    values = np.asarray(values, float)
    if values.size == 0 or not np.all(np.isfinite(values)) or np.any(values <= 0):
        raise StatisticsError(f"a power law needs positive finite values, got {values.size} values "
                              f"with {np.count_nonzero(~(values > 0))} not positive")
    return values


def _choose_x_min(values, discrete):
    """``(x_min, alpha, standard error, KS distance)`` at the x_min of the smallest KS distance (Nones if no
    candidate has enough events)."""
    ordered = np.sort(values)
    distinct = np.unique(ordered)
    # each candidate leaves MIN_TAIL events and MIN_DISTINCT values at or above it
    candidates = np.unique(ordered[:max(ordered.size - MIN_TAIL + 1, 0)])
    candidates = candidates[candidates <= (distinct[-MIN_DISTINCT] if distinct.size >= MIN_DISTINCT else -np.inf)]
    if candidates.size > MAX_CANDIDATES:
        candidates = np.unique(np.quantile(candidates, np.linspace(0.0, 1.0, MAX_CANDIDATES), method="lower"))
    best = (None, None, None, math.inf)
    for x_min in candidates.tolist():
        alpha, error, distance = _fit_tail(ordered, x_min, discrete)
        if distance < best[3]:
            best = (x_min, alpha, error, distance)
    return best


def _fit_tail(values, x_min, discrete):
    """``(alpha, standard error, KS distance)`` of the law fitted to the values at or above ``x_min``."""
    tail = np.sort(values[values >= x_min])
    if tail.size < 2:
        raise StatisticsError(f"x_min = {x_min!r}: {tail.size} events at or above it, a fit needs 2 or more")
    fit = _discrete_fit if discrete else _continuous_fit
    alpha, error = fit(tail, x_min)
    return alpha, error, _ks_distance(tail, x_min, alpha, discrete)


def _continuous_fit(tail, x_min):
    logs = np.sum(np.log(tail / x_min))
    if logs <= 0.0:
        return ALPHA_MAX, math.inf
    alpha = min(1.0 + tail.size / float(logs), ALPHA_MAX)
    return alpha, (alpha - 1.0) / math.sqrt(tail.size)


def _discrete_fit(tail, x_min):
    """Maximum likelihood of ``p(s) = s^-alpha / zeta(alpha, x_min)``; the error from the Fisher information
    ``n d^2/d alpha^2 ln zeta(alpha, x_min)``."""
    mean_log = float(np.mean(np.log(tail)))

    def minus_log_likelihood(alpha):
        return math.log(zeta(alpha, x_min)) + alpha * mean_log

    alpha = minimize_scalar(minus_log_likelihood, bounds=(1.0 + 1e-6, ALPHA_MAX), method="bounded",
                            options={"xatol": 1e-10}).x
    h = 1e-4
    curvature = (minus_log_likelihood(alpha + h) - 2.0 * minus_log_likelihood(alpha)
                 + minus_log_likelihood(alpha - h)) / h**2
    return float(alpha), (1.0 / math.sqrt(tail.size * curvature) if curvature > 0.0 else math.inf)


def _ks_distance(tail, x_min, alpha, discrete):
    """Largest distance between the tail's empirical CDF and the fitted law's."""
    if discrete:
        values, counts = np.unique(tail, return_counts=True)
        empirical = np.cumsum(counts) / tail.size
        model = 1.0 - zeta(alpha, values + 1.0) / zeta(alpha, x_min)
        return float(np.max(np.abs(empirical - model)))
    model = 1.0 - (tail / x_min) ** (1.0 - alpha)
    n = tail.size
    return float(max(np.max(np.arange(1, n + 1) / n - model), np.max(model - np.arange(n) / n)))


def log_binned_density(values, bins_per_decade=5):
    """``(edges, density)`` of positive ``values`` in logarithmic bins (density: events per unit of x over the
    number of events)."""
    values = _positive(values)
    low, high = math.log10(values.min()), math.log10(values.max())
    edges = np.logspace(low, high + 1e-9, max(1, math.ceil((high - low) * bins_per_decade)) + 1)
    counts, _ = np.histogram(values, edges)
    return edges, counts / (values.size * np.diff(edges))


def ccdf(values):
    """``(x, P(X >= x))`` at the sorted values."""
    x = np.sort(np.asarray(values, float))
    return x, 1.0 - np.arange(x.size) / x.size


def recurrence(times):
    """``{"count", "mean", "std", "cv", "median"}`` of the intervals (s) between successive ``times`` (Nones below
    two intervals); ``cv``: std over mean (1 for a Poisson process, below 1 for a periodic one)."""
    intervals = np.diff(np.asarray(times, float))
    if intervals.size < 2:
        return {"count": int(intervals.size), "mean": None, "std": None, "cv": None, "median": None}
    mean, std = float(intervals.mean()), float(intervals.std(ddof=1))
    return {"count": int(intervals.size), "mean": mean, "std": std, "cv": std / mean if mean > 0 else None,
            "median": float(np.median(intervals))}


def catalogue_statistics(table, n_blocks, *, bootstrap=200, seed=0):
    """The statistics of a slip-event table (``{column: array}``, :mod:`.catalogue`) of a chain of ``n_blocks``:
    counts, the size and moment fits (``{"not_fitted": why}`` where too few events), the recurrence intervals of all
    events and of those spanning the chain (``size == n_blocks``). The fits take the events that do not span the
    chain: those that do pile up at its length (and at their moments), apart from the law of the others."""
    size, moment, start = table["size"], np.abs(table["moment"]), table["start"]
    fits = {}
    local = size < n_blocks
    for name, values, discrete in (("size", size[local], True), ("moment", moment[local & (moment > 0)], False)):
        try:
            fits[name] = fit_power_law(values, discrete=discrete, bootstrap=bootstrap, seed=seed)
        except StatisticsError as exc:
            fits[name] = {"not_fitted": str(exc)}
    return {"events": int(size.size), "blocks": int(n_blocks),
            "spanning_events": int(np.count_nonzero(size == n_blocks)),
            "largest_size": int(size.max()) if size.size else None,
            "largest_moment": float(moment.max()) if size.size else None,
            "duration": {"mean": float(table["duration"].mean()) if size.size else None,
                         "max": float(table["duration"].max()) if size.size else None},
            "size_fit": fits["size"], "moment_fit": fits["moment"],
            "recurrence": recurrence(start), "spanning_recurrence": recurrence(start[size == n_blocks])}


def write_statistics(folder, statistics, extra=None):
    """Write ``statistics.json`` (the dict, with ``extra`` entries: run settings, the open event) and
    ``statistics.md`` (the same for a reader) into ``folder``; return their paths."""
    folder = Path(folder)
    data = {**(extra or {}), **statistics}
    json_path, md_path = folder / STATISTICS_JSON, folder / STATISTICS_MD
    json_path.write_text(json.dumps(data, indent=2) + "\n")
    md_path.write_text(statistics_markdown(data))
    return json_path, md_path


def statistics_markdown(data):
    """The statistics as a short markdown report."""
    lines = ["# Slip-event statistics", "",
             f"{data['events']} slip events of a chain of {data['blocks']} blocks; {data['spanning_events']} span "
             f"the chain (size {data['blocks']}); largest size {data['largest_size']}, largest |moment| "
             f"{_number(data['largest_moment'])} m.", ""]
    for name, unit in (("size", "blocks"), ("moment", "m, of |moment|")):
        fit = data[f"{name}_fit"]
        if "not_fitted" in fit:
            lines.append(f"- {name}: no power law fitted ({fit['not_fitted']})")
            continue
        lines.append(f"- {name} ({unit}, of the events not spanning the chain): p ~ x^-alpha with alpha = {fit['alpha']:.3f} +- "
                     f"{fit['standard_error']:.3f} (maximum likelihood), +- {_number(fit['bootstrap_error'])} "
                     f"(bootstrap), above x_min = {fit['x_min']:.4g} ({fit['n_tail']} of {fit['n']} events, "
                     f"KS distance {fit['ks_distance']:.3f})")
    for key, label in (("recurrence", "all events"), ("spanning_recurrence", "events spanning the chain")):
        r = data[key]
        lines.append(f"- recurrence intervals of {label}: {r['count']} intervals, mean {_number(r['mean'])} s, "
                     f"std {_number(r['std'])} s, cv {_number(r['cv'])}")
    if data.get("open_event"):
        lines.append(f"- an event still open at the end of the run is left out: {data['open_event']}")
    return "\n".join(lines) + "\n"


def _number(value):
    return "n/a" if value is None else f"{value:.4g}"
