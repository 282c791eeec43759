"""Per-scenario figure: x(t) of FMU and reference, their difference, and the phase portrait (x, v).

Uses matplotlib's Agg canvas directly (no pyplot state), so it works headless and in worker processes.
"""

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..fmu.variables import UNITS, axis_label


def initial_stick(mode):
    """Boolean mask of the samples of the stick the run starts in (the initial condition), before any slip."""
    mode = np.asarray(mode)
    mask = np.zeros(mode.size, bool)
    if mode.size and mode[0] == 0:
        first_slip = np.flatnonzero(mode != 0)
        mask[: first_slip[0] if first_slip.size else mode.size] = True
    return mask


def held_levels(v_drive, samples=5):
    """The drive velocities (m/s) held for at least ``samples`` consecutive samples: the constant parts of the
    drive (a ramp passes through its values without holding them)."""
    v_drive = np.asarray(v_drive)
    if v_drive.size == 0:
        return v_drive
    starts = np.flatnonzero(np.r_[True, v_drive[1:] != v_drive[:-1]])
    lengths = np.diff(np.r_[starts, v_drive.size])
    return np.unique(v_drive[starts[lengths >= samples]])


def plot_scenario(png_path, title, fmu, ref, max_abs_dx=None):
    """Write ``png_path``: x(t) of the FMU (structured array) and the reference, ``|x_FMU - x_ref|`` on a log
    scale with the tolerance ``max_abs_dx`` (m), and the phase portrait with the stuck phases marked.
    Returns the figure (its lines hold the plotted arrays)."""
    fig = Figure(figsize=(13, 6.5), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplot_mosaic([["x", "phase"], ["dx", "phase"]], width_ratios=(3, 2), height_ratios=(3, 2))
    ax_t, ax_dx, ax_phase = axes["x"], axes["dx"], axes["phase"]
    t = fmu["time"]
    start = initial_stick(fmu["mode"])
    stuck = (fmu["mode"] == 0) & ~start

    ax_t.plot(t, fmu["x"], lw=1.2, color="C0", label="FMU")
    ax_t.plot(ref.t, ref.x, "--", lw=1.0, color="C1", label="reference")
    ax_t.plot(t[stuck], fmu["x"][stuck], ".", ms=2, color="C3", label="stuck (FMU)")
    ax_t.plot(t[start], fmu["x"][start], ".", ms=2, color="0.6", label="initial stick (the initial condition)")
    ax_t.set(ylabel=axis_label("x"), title=title)
    ax_t.tick_params(labelbottom=False)

    dx = np.abs(fmu["x"] - ref.x)
    shown = dx > 0.0
    if not shown.any():  # the FMU equals the reference at every sample: no data sets the log axis's limits
        top = 10.0 * (max_abs_dx if max_abs_dx is not None else 1.0)
        ax_dx.set_yscale("log")
        ax_dx.set_ylim(1e-9 * top, top)
        ax_dx.text(0.5, 0.5, "x_FMU = x_ref at every sample", transform=ax_dx.transAxes, ha="center", va="center")
    ax_dx.semilogy(t[shown], dx[shown], lw=0.8, color="C4", label="|x_FMU - x_ref| (exact zeros not drawn)")
    if max_abs_dx is not None:
        ax_dx.axhline(max_abs_dx, color="C3", ls="--", lw=1.0, label=f"tolerance max_abs_dx = {max_abs_dx:g} {UNITS['x']}")
    ax_dx.sharex(ax_t)
    ax_dx.set(xlabel="t (s)", ylabel=f"|x_FMU - x_ref| ({UNITS['x']})")
    ax_dx.grid(True, which="major", alpha=0.3)

    ax_phase.plot(fmu["x"], fmu["v"], lw=0.8, color="C0")
    ax_phase.plot(ref.x, ref.v, "--", lw=0.8, color="C1")
    for n, level in enumerate(held_levels(fmu["v_drive"])):
        ax_phase.axhline(level, ls=":", lw=0.9, color="grey", label=None if n else "v_drive (its held values)")
    ax_phase.plot(fmu["x"][start], fmu["v"][start], ".", ms=3, color="0.6")
    ax_phase.plot(fmu["x"][stuck], fmu["v"][stuck], ".", ms=3, color="C3")  # later sticks on top
    ax_phase.set(xlabel=axis_label("x"), ylabel=axis_label("v"), title="phase portrait")

    fig.legend(loc="outside lower center", ncols=4, fontsize="small")
    fig.savefig(png_path, dpi=110)
    return fig
