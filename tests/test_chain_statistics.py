"""Statistics and figures of a slip-event catalogue (:mod:`stickslip.chain.statistics`, :mod:`stickslip.chain.plots`)
on synthetic data: the power-law fits on samples of known laws, the recurrence intervals, the summary files."""

import json

import numpy as np
import pytest
from scipy.special import zeta

from stickslip.chain.catalogue import slip_events_table
from stickslip.chain.plots import plot_slips, plot_statistics
from stickslip.chain.statistics import (StatisticsError, catalogue_statistics, ccdf, fit_power_law,
                                        log_binned_density, recurrence, write_statistics)


def continuous_sample(rng, alpha, x_min, n):
    """Draws of ``p(x) ~ x^-alpha``, ``x >= x_min`` (inverse CDF)."""
    return x_min * (1.0 - rng.random(n)) ** (-1.0 / (alpha - 1.0))


def discrete_sample(rng, alpha, s_min, n, s_max=10**6):
    """Draws of ``p(s) = s^-alpha / zeta(alpha, s_min)``, ``s >= s_min`` (inverse CDF over a table; the mass beyond
    ``s_max`` is below 1e-8 for the exponents used)."""
    s = np.arange(s_min, s_max + 1, dtype=float)
    cdf = np.cumsum(s**-alpha) / zeta(alpha, s_min)
    return s[np.minimum(np.searchsorted(cdf, rng.random(n)), s.size - 1)]


@pytest.mark.parametrize("discrete, alpha", [(False, 2.5), (False, 1.7), (True, 2.2), (True, 1.8)])
def test_the_fit_finds_the_exponent_within_its_errors_and_the_errors_are_right(discrete, alpha):
    rng = np.random.default_rng(1)
    draw = discrete_sample if discrete else continuous_sample
    fits = [fit_power_law(draw(rng, alpha, 1.0, 1500), discrete=discrete, x_min=1.0, bootstrap=100, seed=k)
            for k in range(20)]
    estimates = np.array([f["alpha"] for f in fits])
    errors = np.array([f["standard_error"] for f in fits])
    assert np.all(np.abs(estimates - alpha) < 3.0 * errors)
    # the errors are the estimates' spread: over 20 samples the spread is known to about 16%
    assert 0.6 < estimates.std(ddof=1) / errors.mean() < 1.5
    assert np.all(np.abs(np.array([f["bootstrap_error"] for f in fits]) / errors - 1.0) < 0.3)


@pytest.mark.parametrize("discrete", [False, True])
def test_x_min_is_found_where_the_power_law_begins(discrete):
    """Below x_min = 8 the values are uniform (no power law); above it p ~ x^-2.3."""
    rng = np.random.default_rng(4)
    tail = (discrete_sample if discrete else continuous_sample)(rng, 2.3, 8.0, 3000)
    body = rng.integers(1, 8, 3000).astype(float) if discrete else rng.uniform(1.0, 8.0, 3000)
    fit = fit_power_law(np.concatenate([body, tail]), discrete=discrete, bootstrap=50)
    assert 6.0 <= fit["x_min"] <= 12.0
    assert abs(fit["alpha"] - 2.3) < 3.0 * max(fit["standard_error"], fit["bootstrap_error"])
    assert fit["n"] == 6000 and fit["n_tail"] == np.count_nonzero(np.concatenate([body, tail]) >= fit["x_min"])


def test_a_fit_without_enough_or_with_bad_values_is_refused():
    with pytest.raises(StatisticsError, match="5 events: a fit needs at least 20, with 3 distinct values"):
        fit_power_law([1.0, 2.0, 3.0, 4.0, 5.0], discrete=False)
    with pytest.raises(StatisticsError, match="positive finite values, got 3 values with 1 not positive"):
        fit_power_law([1.0, 0.0, 3.0], discrete=True)


def test_log_bins_and_the_complementary_cdf():
    values = continuous_sample(np.random.default_rng(2), 2.0, 0.01, 5000)
    edges, density = log_binned_density(values)
    assert np.sum(density * np.diff(edges)) == pytest.approx(1.0)
    assert np.allclose(np.diff(np.log10(edges)), 0.2, rtol=0.2)
    x, p = ccdf([3.0, 1.0, 2.0, 2.0])
    assert x.tolist() == [1.0, 2.0, 2.0, 3.0] and p.tolist() == [1.0, 0.75, 0.5, 0.25]


def test_recurrence_intervals_of_periodic_and_poisson_events():
    periodic = recurrence(np.arange(100) * 7.0)
    assert periodic["count"] == 99 and periodic["mean"] == pytest.approx(7.0) and periodic["cv"] == pytest.approx(0)
    poisson = recurrence(np.cumsum(np.random.default_rng(3).exponential(2.0, 20000)))
    assert poisson["mean"] == pytest.approx(2.0, rel=0.03) and poisson["cv"] == pytest.approx(1.0, abs=0.03)
    assert recurrence([1.0, 2.0])["mean"] is None


def synthetic_catalogue(rng, n_blocks=20, n=800):
    """Slip events with power-law sizes (cut at the chain's length), moments growing with size, Poisson starts."""
    size = np.minimum(discrete_sample(rng, 2.0, 1, n), n_blocks).astype(int)
    start = np.cumsum(rng.exponential(5.0, n))
    duration = 0.5 * size ** 0.5
    moment = -size * 0.3 * np.exp(rng.normal(0.0, 0.1, n))
    rows = zip(start, duration, size, moment, rng.integers(1, n_blocks + 1, n), start + duration, size, 2 * size)
    return slip_events_table(list(rows))


def test_catalogue_statistics_and_their_files(tmp_path):
    table = synthetic_catalogue(np.random.default_rng(5))
    stats = catalogue_statistics(table, 20, bootstrap=50)
    spanning = table["start"][table["size"] == 20]
    assert stats["events"] == 800 and stats["spanning_events"] == spanning.size > 10
    assert stats["spanning_recurrence"]["mean"] == pytest.approx(np.mean(np.diff(spanning)))
    assert stats["largest_moment"] == pytest.approx(np.max(np.abs(table["moment"])))
    assert stats["size_fit"]["discrete"] and not stats["moment_fit"]["discrete"]
    json_path, md_path = write_statistics(tmp_path, stats, {"open_event": None, "stop_time": 1.0})
    assert json.loads(json_path.read_text())["size_fit"]["alpha"] == stats["size_fit"]["alpha"]
    text = md_path.read_text()
    assert "800 slip events of a chain of 20 blocks" in text and f"alpha = {stats['size_fit']['alpha']:.3f}" in text
    few = catalogue_statistics(slip_events_table(list(zip(*(c[:3] for c in table.values())))), 20, bootstrap=0)
    assert "not_fitted" in few["size_fit"] and "3 events: a fit needs at least 20, with 3 distinct values" in few["size_fit"]["not_fitted"]


def test_the_figures_are_written(tmp_path):
    table = synthetic_catalogue(np.random.default_rng(6))
    plot_statistics(tmp_path / "statistics.png", "synthetic", table, catalogue_statistics(table, 20, bootstrap=0))
    events = tmp_path / "block_events.csv"
    events.write_text("time,block,kind,x\n1.0,2,slip,0.5\n1.2,3,slip,0.4\n1.5,2,stick,0.1\n1.6,3,stick,0.2\n"
                      "3.0,1,slip,0.3\n")
    assert plot_slips(tmp_path / "slips.png", "synthetic", events, 3, 0.01) == 2
    assert plot_slips(tmp_path / "one.png", "synthetic", events, 3, 0.01, max_slips=1) == 1
    for name in ("statistics.png", "slips.png", "one.png"):
        assert (tmp_path / name).read_bytes()[:4] == b"\x89PNG"
