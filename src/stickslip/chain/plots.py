"""The figures of a chain's catalogue: the size and moment distributions with their fitted power laws and the
recurrence intervals (:func:`plot_statistics`), and the space-time picture of the slips (:func:`plot_slips`).
matplotlib's Agg canvas directly (no pyplot state), so it works headless."""

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure
from scipy.special import zeta

from .catalogue import SlipGrouper, read_block_events
from .statistics import ccdf, log_binned_density

#: the slip intervals per block the space-time picture draws by default (the first of the run: some loading
#: cycles), and the most it draws
SLIPS_PER_BLOCK = 30
MAX_SLIPS = 20000


def plot_statistics(png_path, title, table, statistics):
    """Write ``png_path``: the log-binned densities of sizes and |moments| with the fitted laws, their
    complementary CDFs, and the recurrence intervals of all events and of those spanning the chain."""
    fig = Figure(figsize=(12, 9), layout="constrained")
    FigureCanvasAgg(fig)
    (density, tails), (recurrences, durations) = fig.subplots(2, 2)
    moment = np.abs(table["moment"])
    for values, key, label, colour in ((table["size"], "size_fit", "size (blocks)", "C0"),
                                       (moment[moment > 0], "moment_fit", "|moment| (m)", "C1")):
        if values.size == 0:
            continue
        edges, rho = log_binned_density(values)
        centres = np.sqrt(edges[1:] * edges[:-1])
        density.loglog(centres[rho > 0], rho[rho > 0], "o", color=colour, label=label)
        x, p = ccdf(values)
        tails.loglog(x, p, drawstyle="steps-post", color=colour, label=label)
        fit = statistics[key]
        if "alpha" in fit:
            _draw_fit(density, tails, values, fit, colour)
    density.set(xlabel="size (blocks) or |moment| (m)", ylabel="probability density", title=f"{title}: distributions")
    tails.set(xlabel="size (blocks) or |moment| (m)", ylabel="P(X >= x)", title="complementary CDF")
    _plot_recurrence(recurrences, table, statistics["blocks"])
    durations.loglog(table["size"], table["duration"], ".", ms=3, alpha=0.5, color="C2")
    durations.set(xlabel="size (blocks)", ylabel="duration (s)", title="duration against size")
    for ax in (density, tails, recurrences, durations):
        ax.grid(True, which="major", alpha=0.3)
    density.legend(fontsize="small")
    tails.legend(fontsize="small")
    fig.savefig(png_path, dpi=100)


def _draw_fit(density, tails, values, fit, colour):
    """The fitted law above its x_min, scaled to the fraction of the drawn ``values`` it describes."""
    alpha, x_min, share = fit["alpha"], fit["x_min"], fit["n_tail"] / values.size
    x = np.geomspace(x_min, values.max(), 50)
    if fit["discrete"]:
        rho, tail = x**-alpha / zeta(alpha, x_min), zeta(alpha, np.ceil(x)) / zeta(alpha, x_min)
    else:
        rho, tail = (alpha - 1.0) / x_min * (x / x_min) ** -alpha, (x / x_min) ** (1.0 - alpha)
    label = f"alpha = {alpha:.2f} +- {fit['standard_error']:.2f} (x >= {x_min:.3g})"
    density.loglog(x, share * rho, "--", color=colour, label=label)
    tails.loglog(x, share * tail, "--", color=colour, label=label)


def _plot_recurrence(ax, table, n_blocks):
    spanning = table["size"] == n_blocks
    for times, label, colour in ((table["start"], "all events", "C0"),
                                 (table["start"][spanning], "spanning the chain", "C3")):
        intervals = np.diff(times)
        intervals = intervals[intervals > 0]
        if intervals.size:
            edges = np.geomspace(intervals.min(), intervals.max() * (1 + 1e-9), 30)
            ax.hist(intervals, edges, histtype="step", color=colour, label=f"{label} ({intervals.size})")
    ax.set_xscale("log")
    ax.set(xlabel="time between slip events (s)", ylabel="count", title="recurrence intervals")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize="small")


def plot_slips(png_path, title, block_events, n_blocks, v_drive, *, slipping_at_start=None, max_slips=None):
    """Write ``png_path``: block against time, a bar over each slip interval coloured by the block's slip relative
    to the surface (|m|, log scale), read from the ``block_events.csv`` file in chunks; the first ``max_slips``
    intervals of the run (default :data:`SLIPS_PER_BLOCK` per block, at most :data:`MAX_SLIPS`; the title says
    where it stops). Returns the number drawn."""
    max_slips = max_slips or min(SLIPS_PER_BLOCK * n_blocks, MAX_SLIPS)
    slips = []
    grouper = SlipGrouper(v_drive, slipping_at_start,
                          on_interval=lambda block, t0, t1, slip: slips.append((block, t0, t1, abs(slip))))
    for chunk in read_block_events(block_events):
        grouper.feed(*chunk)
        if len(slips) >= max_slips:
            break
    slips = slips[:max_slips]
    fig = Figure(figsize=(12, 3.0 + min(6.0, 0.06 * n_blocks + 1.0)), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    block, t0, t1, size = (np.array(c) for c in zip(*slips)) if slips else (np.zeros(0),) * 4
    shown = size > 0
    if shown.any():
        lines = LineCollection(np.stack([np.column_stack([t0, block]), np.column_stack([t1, block])], axis=1)[shown],
                               array=size[shown], cmap="viridis", linewidths=max(1.0, min(14.0, 200.0 / n_blocks)),
                               norm=LogNorm(vmin=size[shown].min(), vmax=size[shown].max()), capstyle="butt")
        ax.add_collection(lines)
        fig.colorbar(lines, ax=ax, label="|slip relative to the surface| (m)")
        ax.set_xlim(0.0, t1.max())
    span = "" if len(slips) < max_slips else f" (the first {max_slips} slips, up to t = {t1.max():.4g} s)"
    ax.set(xlabel="t (s)", ylabel="block", ylim=(0.5, n_blocks + 0.5), title=f"{title}: slips{span}")
    fig.savefig(png_path, dpi=100)
    return len(slips)
