"""A Burridge-Knopoff chain of 10 blocks through the model-exchange master, with its space-time picture.

systems/bk10-velocity-weakening.toml: ten blocks with velocity-weakening friction, each held by its own spring
and joined to its neighbours by stiffer ones, loaded slowly (0.01 m/s). The `me` master runs one FMI 3 FMU
instance per block in model exchange, all in one solver with the coupling exact (`stickslip.systems`);
`stickslip.reference.simulate_chain` integrates the same chain independently. The space-time picture (block
against time, colour = slip speed, white = stuck) shows slips running along the chain and smaller events that
stop part way; below it, the largest |x_me - x_ref| over the blocks. The same run with the report and the mode picture:
`stickslip system run systems/bk10-velocity-weakening.toml --master me`.

    python examples/chain_spacetime.py [--quick] [--fmu PATH] [--out DIR]

writes DIR/chain_spacetime.png (default DIR: results/examples). --quick: 80 s (the first run of slips along
the chain) instead of the file's 300 s.
--fmu: the FMI 3 FMU (default: dist/SpringBlockFriction-fmi3.fmu, built there if missing or stale).
"""

import argparse
import dataclasses
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure

from stickslip.fmu import ensure_fmu
from stickslip.reference import simulate_chain
from stickslip.systems import load_system, make_master

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--quick", action="store_true", help="a shorter run (for the tests)")
parser.add_argument("--fmu", help="the FMI 3 FMU (default: dist/SpringBlockFriction-fmi3.fmu, built if needed)")
parser.add_argument("--out", default="results/examples", help="output folder (default results/examples)")
args = parser.parse_args()

system = load_system(Path(__file__).resolve().parents[1] / "systems" / "bk10-velocity-weakening.toml")
if args.quick:
    system = dataclasses.replace(system, stop_time=80.0)  # the first slips start at 68 s
result = make_master("me").run(system, args.fmu or ensure_fmu(fmi_version=3))
reference = simulate_chain(system.chain_blocks(), system.coupling, system.v_drive, system.times())
error = np.abs(result.x - reference.x).max(axis=1)
slips = [sum(1 for e in reference.events if e.block == i and e.kind == "slip") for i in range(system.n)]
print(f"{system.n} blocks over {system.stop_time:g} s: me master {result.wall_time:.1f} s; slips per block "
      f"(reference): {slips}; max |x_me - x_ref| = {error.max():.2e} m")

fig = Figure(figsize=(11, 6.5), layout="constrained")
top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=(3, 1))
edges = np.append(result.t, result.t[-1] + system.output_interval)
slip_speed = np.abs(system.v_drive - result.v.T)  # |v_rel| (m/s): 0 while stuck
image = top.pcolormesh(edges, np.arange(system.n + 1) + 0.5, slip_speed, cmap=colormaps["viridis"].with_extremes(
    under="white"), norm=LogNorm(vmin=1e-4, vmax=slip_speed.max()))
fig.colorbar(image, ax=top, label="slip speed |v_drive - v| (m/s); white: stuck")
top.set(ylabel="block", yticks=range(1, system.n + 1), title=f"{system.name}: me master, space-time")
bottom.semilogy(result.t[error > 0], error[error > 0], lw=0.8)
bottom.set(xlabel="t (s)", ylabel="max |x - x_ref| (m)")
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
fig.savefig(out / "chain_spacetime.png", dpi=80)
print(f"written to {out / 'chain_spacetime.png'}")
