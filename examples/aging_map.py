"""Aging static friction and the stick-slip map (Elmer 1997, section 5): two coexisting stick-slip cycles.

With a static friction that grows with the time stuck, F_S(t_stick), stick-slip reduces to a map of the
position before each slip, x_(n+1) = T(x_n); its fixed points are the stick-slip cycles, stable where
|T'| < 1. Here Coulomb kinetic friction (F_K = 0.5 N) and sigmoid aging F_S = 0.8 + 0.7 t^4/((5 s)^4 + t^4) N,
M = 1 kg, kappa = 1 N/m (scenarios/aging-sigmoid.toml). Left: the aging law. Middle: the map at
v_drive = 0.26 m/s, where a long-stick and a short-stick cycle coexist, with iterates from either end of its
domain (cobwebs) landing on different cycles. Right: the fixed points against the drive velocity, an S
between two saddle-nodes of the map (hysteresis). All from `stickslip.analysis` (`StickSlipMap`, `map_orbit`,
`aging_map.fixed_points_scan`, `saddle_nodes`); `stickslip map` draws these and the orbit diagram.

    python examples/aging_map.py [--quick] [--out DIR]

writes DIR/aging_map.png (default DIR: results/examples) and prints the fixed points and saddle-nodes.
--quick: saddle-nodes located to 1e-4 m/s instead of 1e-7 m/s.
"""

import argparse
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from stickslip.analysis import StickSlipMap, map_orbit, saddle_nodes
from stickslip.analysis.aging_map import fixed_points_scan
from stickslip.core import Coulomb, Parameters, Sigmoid

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--quick", action="store_true", help="coarser saddle-nodes (for the tests)")
parser.add_argument("--out", default="results/examples", help="output folder (default results/examples)")
args = parser.parse_args()

params = Parameters(M=1.0, kappa=1.0, kinetic=Coulomb(F0=0.5), static=Sigmoid(F0=0.8, F_inf=1.5, tau=5.0, n=4.0))
fig = Figure(figsize=(15, 4.8), layout="constrained")
law, cobweb, branches = fig.subplots(1, 3)
t_stick = np.linspace(0.0, 20.0, 200)
law.plot(t_stick, [params.static.force(t) for t in t_stick])
law.set(xlabel="time stuck t_stick (s)", ylabel="static friction F_S (N)", title="sigmoid aging")

v_drive = 0.26  # m/s
smap = StickSlipMap(params, v_drive)
x = np.linspace(*smap.domain(), 300)
cobweb.plot(x, smap(x), label="T(x)")
cobweb.plot(x, x, color="0.6", lw=0.8, label="diagonal")
for colour, x0 in (("C3", x[0]), ("C2", x[-1])):
    orbit = map_orbit(params, v_drive, x0, n=15)  # (x_n, x_(n+1)) to (x_(n+1), x_(n+1)), and on
    cobweb.plot(np.column_stack([orbit[:-1], orbit[1:]]).ravel(), np.repeat(orbit[1:], 2), "-", color=colour,
                lw=0.8, label=f"iterates from x = {x0:.2f} m")
cobweb.set(xlabel="x_n: position before slip n (m)", ylabel="x_(n+1) (m)", title=f"the map at {v_drive} m/s")
cobweb.legend(fontsize=8)

grid = np.linspace(0.2, 0.32, 40)  # m/s; the saddle-node search starts from these fixed points
scan = fixed_points_scan(params, grid)
for v, points in zip(grid, scan):
    for p in points:
        branches.plot(v, p.x, "o", ms=4, color="C3" if p.stable else "C0", mfc="C3" if p.stable else "white")
    print(f"v_drive = {v:.4f} m/s: " + ", ".join(f"x* = {p.x:.4f} m ({'stable' if p.stable else 'unstable'}, "
                                                  f"period {p.period:.2f} s)" for p in points))
saddles = saddle_nodes(params, grid[0], grid[-1], tol=1e-4 if args.quick else 1e-7, grid=grid, fps=scan)
for v, x_saddle in saddles:
    branches.plot(v, x_saddle, "ks", mfc="none", ms=8)
    print(f"saddle-node of the map at v_drive = {v:.7f} m/s, x* = {x_saddle:.4f} m")
branches.set(xlabel="v_drive (m/s)", ylabel="fixed point x* (m)",
             title="stick-slip cycles: stable (filled), unstable (open), saddle-nodes (squares)")
branches.title.set_fontsize(9)
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
fig.savefig(out / "aging_map.png", dpi=80)
print(f"written to {out / 'aging_map.png'}")
