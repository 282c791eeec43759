"""Per-scenario figure: x(t) of FMU and reference, and the phase portrait (x, v) with stuck phases marked.

Uses matplotlib's Agg canvas directly (no pyplot state), so it works headless and in worker processes.
"""

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


def plot_scenario(png_path, title, fmu, ref):
    """Write ``png_path``: FMU result (structured array) and reference result over time and in phase space."""
    fig = Figure(figsize=(12, 4.5), layout="constrained")
    FigureCanvasAgg(fig)
    ax_t, ax_phase = fig.subplots(1, 2, width_ratios=(3, 2))
    stuck = fmu["mode"] == 0

    ax_t.plot(fmu["time"], fmu["x"], lw=1.2, label="FMU")
    ax_t.plot(ref.t, ref.x, "--", lw=1.0, label="reference")
    ax_t.plot(fmu["time"][stuck], fmu["x"][stuck], ".", ms=2, color="C3", label="stuck (FMU)")
    ax_t.set(xlabel="t (s)", ylabel="x (m)", title=title)
    ax_t.legend(loc="best", fontsize="small")

    ax_phase.plot(fmu["x"], fmu["v"], lw=0.8, label="FMU")
    ax_phase.plot(ref.x, ref.v, "--", lw=0.8, label="reference")
    ax_phase.plot(fmu["x"], fmu["v_drive"], ":", lw=0.8, color="grey", label="v_drive")
    ax_phase.plot(fmu["x"][stuck], fmu["v"][stuck], ".", ms=3, color="C3", label="stuck (FMU)")
    ax_phase.set(xlabel="x (m)", ylabel="v (m/s)", title="phase portrait")
    ax_phase.legend(loc="best", fontsize="small")

    fig.savefig(png_path, dpi=110)
