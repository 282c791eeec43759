"""A system run's figures: each block's ``x(t)`` (master against reference, with the error), and the space-time
picture of which block slips when (block index against time, colour = mode). matplotlib's Agg canvas directly
(no pyplot state), so it works headless; fixed margins (:func:`fixed_margins`) rather than a layout engine, which
measured every text of a figure and took about half of its drawing time."""

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Patch

#: mode -1, 0, +1: colour and legend label
MODE_COLOURS = {-1: ("#2166ac", "slipping, v > v_drive (-1)"), 0: ("#f0f0f0", "stuck (0)"),
                1: ("#b2182b", "slipping, v < v_drive (+1)")}


def plot_positions(png_path, title, result, reference):
    """Write ``png_path``: one panel per block with ``x_i(t)`` of the master and the reference, and a last panel
    with every block's ``|dx_i|`` on a log scale (reference None: the master's ``x_i(t)`` alone)."""
    n = result.x.shape[1]
    panels = n + (reference is not None)
    fig = Figure(figsize=(12, 1.4 * n + 3.0))
    FigureCanvasAgg(fig)
    axes = fig.subplots(panels, 1, sharex=True, height_ratios=[1.0] * n + [1.6] * (panels - n), squeeze=False,
                        gridspec_kw=fixed_margins(fig, left=0.85, right=0.15, top=0.35, bottom=0.55, gap=0.15,
                                                  rows=panels))[:, 0]
    for i, ax in enumerate(axes[:n]):
        ax.plot(result.t, result.x[:, i], lw=1.1, color="C0", label=f"{result.master}")
        if reference is not None:
            ax.plot(reference.t, reference.x[:, i], "--", lw=0.9, color="C1", label="reference")
        ax.set_ylabel(f"b{i + 1}.x (m)")
        ax.grid(True, alpha=0.3)
    axes[0].set_title(title)
    axes[0].legend(loc="upper left", fontsize="small", ncols=2)
    if reference is None:
        axes[-1].set_xlabel("t (s)")
        fig.savefig(png_path, dpi=100)
        return
    ax = axes[-1]
    for i in range(n):
        dx = np.abs(result.x[:, i] - reference.x[:, i])
        shown = dx > 0.0
        ax.semilogy(result.t[shown], dx[shown], lw=0.8, label=f"b{i + 1}")
    ax.set(xlabel="t (s)", ylabel="|x - x_ref| (m)")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(loc="lower right", fontsize="small", ncols=min(n, 10))
    fig.savefig(png_path, dpi=100)


def plot_space_time(png_path, title, result, reference):
    """Write ``png_path``: block index against time coloured by mode, the master above the reference (if any)."""
    n = result.x.shape[1]
    runs = [(result, result.master)] + ([] if reference is None else [(reference, "reference")])
    fig = Figure(figsize=(12, (0.25 * n + 1.75) * len(runs)))
    FigureCanvasAgg(fig)
    # the right margin holds the legend of the modes
    axes = fig.subplots(len(runs), 1, sharex=True, squeeze=False,
                        gridspec_kw=fixed_margins(fig, left=0.6, right=2.15, top=0.35, bottom=0.55, gap=0.4,
                                                  rows=len(runs)))[:, 0]
    colours = ListedColormap([MODE_COLOURS[m][0] for m in (-1, 0, 1)])
    for ax, (run, label) in zip(axes, runs):
        t = run.t
        edges = np.concatenate([t, [t[-1] + (t[-1] - t[-2] if t.size > 1 else 1.0)]])
        ax.pcolormesh(edges, np.arange(n + 1) + 0.5, run.mode.T, cmap=colours, vmin=-1.5, vmax=1.5)
        ax.set(ylabel="block", title=f"{title}: {label}", ylim=(0.5, n + 0.5))
        ax.set_yticks(range(1, n + 1), [f"b{i}" for i in range(1, n + 1)] if n <= 12 else None)
    axes[-1].set_xlabel("t (s)")
    handles = [Patch(color=c, label=text) for c, text in MODE_COLOURS.values()]
    axes[0].legend(handles=handles, loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize="small")
    fig.savefig(png_path, dpi=100)


def fixed_margins(fig, left, right, top, bottom, gap, rows):
    """The grid's margins of ``fig`` for ``rows`` panels one above the other: ``left``, ``right``, ``top``,
    ``bottom`` and the ``gap`` between panels in inches (room for the labels, titles and legends outside the panels),
    as ``fig.subplots``' ``gridspec_kw``."""
    width, height = fig.get_size_inches()
    panel = (height - top - bottom - gap * (rows - 1)) / rows  # in: the panels' mean height
    return {"left": left / width, "right": 1.0 - right / width, "top": 1.0 - top / height, "bottom": bottom / height,
            "hspace": gap / panel}
