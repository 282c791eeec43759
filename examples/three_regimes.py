"""Stick-slip, continuous sliding and oscillatory sliding side by side (Elmer 1997, fig. 3 parameters).

The same block (M = 40 kg, kappa = 1 N/m, boundary-lubrication friction, F_S = 1 N) starts stuck at the
relaxed spring and is driven at three velocities: at 0.1 m/s it settles on stick-slip, at 0.07 m/s it spirals
into continuous sliding, at 1.0 m/s onto a large sliding limit cycle (oscillatory sliding). Top row: v(t) with
the stuck phases marked; bottom row: the phase portrait (x, v), the last third of the run dark. The runs are
the FMU's own exact stepper, `stickslip.core.Trajectory`, with every stick and slip event recorded.

    python examples/three_regimes.py [--quick] [--out DIR]

writes DIR/three_regimes.png (default DIR: results/examples) and prints each run's events and attractor.
--quick: 100 s per run instead of 300, 400 and 1000 s (too short to settle: see the titles).
"""

import argparse
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from stickslip.analysis import classify_samples
from stickslip.core import Constant, Lubricated, Parameters, Trajectory

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--quick", action="store_true", help="short runs (for the tests)")
parser.add_argument("--out", default="results/examples", help="output folder (default results/examples)")
args = parser.parse_args()

params = Parameters(M=40.0, kappa=1.0, kinetic=Lubricated(gamma1=3.0, gamma2=0.1, v_tilde=0.2, dv=0.05),
                    static=Constant(F0=1.0))
runs = {0.1: 300.0, 0.07: 400.0, 1.0: 1000.0}  # v_drive (m/s): run time (s)
fig = Figure(figsize=(15, 8), layout="constrained")
axes = fig.subplots(2, 3)
for column, (v_drive, t_end) in enumerate(runs.items()):
    t_end = 100.0 if args.quick else t_end
    trajectory = Trajectory(params, x0=0.0, v0=v_drive, v_drive=v_drive, rtol=1e-10, record_events=True)
    t = np.arange(0.0, t_end, 0.05)
    x, v = map(np.array, trajectory.sample(t))  # x (m), v (m/s) on the grid
    events = np.array(trajectory.events)  # rows (t, mode before, mode after); mode 0: stuck, +-1: slipping
    mode = events[np.searchsorted(events[:, 0], t, side="right") - 1, 2]  # the runs start stuck, events[0] at 1 m
    mode[t < events[0, 0]] = events[0, 1]
    tail = t > 2 * t_end / 3
    found = classify_samples(t, x, v, v_drive, mode, tail=t_end / 3)  # the attractor of the last third
    print(f"v_drive = {v_drive} m/s: {len(events)} events; last third: {found.kind}, x in [{found.x_min:.3f}, "
          f"{found.x_max:.3f}] m, period {found.period:.4g} s")
    top, bottom = axes[:, column]
    top.plot(t, v, lw=0.9)
    top.plot(t[mode == 0], v[mode == 0], ".", ms=2, color="C3", label="stuck")
    top.set(title=f"v_drive = {v_drive} m/s: {found.kind}", xlabel="t (s)", ylabel="v (m/s)")
    top.legend(loc="upper right", fontsize=8)
    bottom.plot(x[~tail], v[~tail], lw=0.6, color="0.7", label="transient")
    bottom.plot(x[tail], v[tail], lw=1.2, color="C0", label="last third")
    bottom.axhline(v_drive, ls=":", color="C3", lw=0.8)
    bottom.set(xlabel="x (m)", ylabel="v (m/s)")
    bottom.legend(loc="upper right", fontsize=8)
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
fig.savefig(out / "three_regimes.png", dpi=80)
print(f"written to {out / 'three_regimes.png'}")
