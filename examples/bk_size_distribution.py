"""The size and moment distributions of Carlson and Langer's velocity-weakening Burridge-Knopoff chain.

A chain of 100 like blocks with kinetic law 5 (Carlson and Langer, Phys. Rev. A 40 (1989) 6470) in their units
(M = kappa = F0 = 1, docs/chains.md): coupling kc = l^2 = 100, sigma = 0.01, alpha = 2.5, plate velocity nu =
v_drive = 0.01, constant static friction F0 = 1, the blocks starting stuck at random offsets. The chain engine
(`stickslip.chain.engine.run_chain`, numba-compiled) runs it with its block events streamed to disk, the catalogue
(`stickslip.chain.catalogue`) groups them into slip events, the statistics (`stickslip.chain.statistics`) fit
power laws to the sizes and moments of the events that do not span the chain, after the first two loading cycles
(2 F0/(kappa v_drive) = 200 s, the start's transient). The figure: the distribution of sizes (number of blocks
that slipped), the log-binned density of moments (their summed slip, m, in units of D0 = F0/kappa), each with
the fitted exponent of the power law (not the friction's alpha), and the rate of events at or above a moment
(Gutenberg-Richter's frequency-magnitude relation). The same as a command, with
its own figures: `stickslip chain`.

    python examples/bk_size_distribution.py [--quick] [--stop-time S] [--out DIR]

writes DIR/bk_size_distribution.png and the run's block events and slip events (CSV) into
DIR/bk_size_distribution/ (default DIR: results/examples). --stop-time: the simulated time (default 20000 s, 200
loading cycles; longer runs sharpen the distributions). --quick: 30 blocks over 1000 s (10 loading cycles).
"""

import argparse
import sys
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from stickslip.chain.catalogue import SLIP_EVENTS_FILE, read_slip_events
from stickslip.chain.folder_run import run_into_folder
from stickslip.chain.statistics import catalogue_statistics, ccdf, log_binned_density
from stickslip.chain.template import chain_system
from stickslip.hosts.progress import TimeProgress

# Carlson and Langer's parameters, in their units (M = kappa = F0 = 1: kc = l^2, alpha and nu as they are)
L_SQUARED, SIGMA, ALPHA, NU = 100.0, 0.01, 2.5, 0.01
LOADING_CYCLE = 1.0 / NU  # s: F0 / (kappa v_drive)

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--quick", action="store_true", help="30 blocks over 1000 s (for the tests)")
parser.add_argument("--stop-time", type=float, default=None, help="simulated time, s (default 20000)")
parser.add_argument("--out", default="results/examples", help="output folder (default results/examples)")
args = parser.parse_args()

n = 30 if args.quick else 100
stop_time = args.stop_time or (10 if args.quick else 200) * LOADING_CYCLE
system = chain_system(n, seed=1, M=1.0, kappa=1.0, kc=L_SQUARED, v_drive=NU,
                      kinetic={"law": 5, "F0": 1.0, "sigma": SIGMA, "alpha": ALPHA}, static={"law": 1, "F0": 1.0},
                      x_start=0.5, offset_spread=0.1, name=f"carlson-langer-{n}")
out = Path(args.out)
try:
    with TimeProgress(f"{n} blocks", stop_time, sys.stderr.isatty()) as step:
        run = run_into_folder(system, out / "bk_size_distribution", stop_time=stop_time, progress=step)
except KeyboardInterrupt:  # the engine closed its files: they hold every chunk it finished
    print(f"interrupted: the events so far are in {out / 'bk_size_distribution'}", file=sys.stderr)
    sys.exit(130)
print(f"{n} blocks over {stop_time:g} s ({stop_time / LOADING_CYCLE:g} loading cycles): {run.summary.events} block "
      f"events, {run.slip_events} slip events in {run.summary.wall_time:.1f} s "
      f"({'numba' if run.summary.compiled else 'plain Python'})")

table = read_slip_events(run.folder / SLIP_EVENTS_FILE)
settled = table["start"] >= 2 * LOADING_CYCLE
table = {column: values[settled] for column, values in table.items()}
statistics = catalogue_statistics(table, n)
for name in ("size", "moment"):
    fit = statistics[f"{name}_fit"]
    print(f"{name}: " + (fit["not_fitted"] if "not_fitted" in fit else
                         f"p ~ x^-{fit['alpha']:.2f} +- {fit['standard_error']:.2f} above {fit['x_min']:.3g} "
                         f"({fit['n_tail']} of {fit['n']} events)"))
print(f"{statistics['events']} events after the transient, {statistics['spanning_events']} spanning the chain")


def draw_distribution(ax, x, density, fitted, fit, colour):
    """The ``density`` at ``x`` (where it is not 0) and, over the ``fitted`` values from the fit's x_min on, a line
    of the fitted slope through the data."""
    x, density = x[density > 0], density[density > 0]
    ax.loglog(x, density, "o", color=colour, label="slip events")
    if "alpha" in fit:
        at = np.interp(np.log(fit["x_min"]), np.log(x), np.log(density))
        x = np.geomspace(fit["x_min"], fitted.max(), 30)
        ax.loglog(x, np.exp(at) * (x / fit["x_min"]) ** -fit["alpha"], "k--",
                  label=f"slope -{fit['alpha']:.2f} +- {fit['standard_error']:.2f} (fit, x >= {fit['x_min']:.3g})")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")


size, moment = table["size"], np.abs(table["moment"])
local = size < n  # the events the fits take
fig = Figure(figsize=(15, 4.8), layout="constrained")
sizes, moments, rates = fig.subplots(1, 3)
sizes_seen, counts = np.unique(size, return_counts=True)
draw_distribution(sizes, sizes_seen, counts / size.size, size[local], statistics["size_fit"], "C0")
sizes.axvline(n, color="grey", lw=0.8)
sizes.set(xlabel="size (blocks that slipped)", ylabel="probability",
          title=f"sizes ({statistics['spanning_events']} events span all {n})")
edges, density = log_binned_density(moment[moment > 0])
draw_distribution(moments, np.sqrt(edges[1:] * edges[:-1]), density, moment[local & (moment > 0)],
                  statistics["moment_fit"], "C1")
moments.set(xlabel="|moment| (m = D0)", ylabel="probability density", title="moments (summed slip)")
x, share = ccdf(moment[moment > 0])
rates.loglog(x, share * x.size / (stop_time - 2 * LOADING_CYCLE), drawstyle="steps-post", color="C2")
rates.set(xlabel="|moment| (m)", ylabel="events per s with a larger moment", title="frequency-moment relation")
rates.grid(True, alpha=0.3)
fig.suptitle(f"Carlson-Langer chain: N = {n}, l^2 = {L_SQUARED:g}, sigma = {SIGMA:g}, alpha = {ALPHA:g}, "
             f"nu = {NU:g}; {statistics['events']} slip events over {stop_time / LOADING_CYCLE - 2:g} loading cycles")
fig.savefig(out / "bk_size_distribution.png", dpi=80)
print(f"written to {out / 'bk_size_distribution.png'}")
