"""The FMU in FMPy with an input table, against the independent reference integrator.

SpringBlockFriction.fmu (FMI 2 co-simulation) runs under FMPy's `simulate_fmu` with a table of the inputs
v_drive (m/s) and F_ext (N): the drive steps from 0.1 to 0.3 m/s at t = 200 s. `stickslip.reference` (which
shares no code with the FMU) integrates the same block with the same inputs; the figure shows x, v and mode of
both and |x_FMU - x_ref|. The FMU is dist/SpringBlockFriction.fmu, built there by the package's builder
(`stickslip.fmu.ensure_fmu`, a minute or two) if it is missing or older than the sources.

    python examples/fmu_fmpy.py [--quick] [--fmu PATH] [--out DIR]

writes DIR/fmu_fmpy.png (default DIR: results/examples). --quick: 250 s instead of 400 s.
"""

import argparse
from pathlib import Path

import numpy as np
from fmpy import simulate_fmu
from matplotlib.figure import Figure

from stickslip.fmu import ensure_fmu
from stickslip.reference import parameters_from_values, simulate_reference

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--quick", action="store_true", help="a shorter run (for the tests)")
parser.add_argument("--fmu", help="the FMI 2 FMU to run (default: dist/SpringBlockFriction.fmu, built if needed)")
parser.add_argument("--out", default="results/examples", help="output folder (default results/examples)")
args = parser.parse_args()

stop_time = 250.0 if args.quick else 400.0
table = np.array([(0.0, 0.1, 0.0), (200.0, 0.1, 0.0), (200.0, 0.3, 0.0), (stop_time, 0.3, 0.0)],
                 dtype=[("time", float), ("v_drive", float), ("F_ext", float)])  # the step at t = 200 s
start = {"M": 40.0, "kappa": 1.0, "x_start": 0.0, "v_start": 0.1,  # Elmer 1997, fig. 3; starts stuck
         "kinetic.law": 4, "kinetic.gamma1": 3.0, "kinetic.gamma2": 0.1, "kinetic.v_tilde": 0.2,
         "kinetic.dv": 0.05, "static.law": 1, "static.F0": 1.0, "solver.rtol": 1e-10}  # law codes: docs/variables.md
fmu = args.fmu or ensure_fmu()
result = simulate_fmu(str(fmu), stop_time=stop_time, output_interval=0.1, start_values=start, input=table,
                      output=["x", "v", "mode", "n_events"])
after = np.append(np.diff(result["time"]) > 0.0, True)  # at the step's repeated time, the row after it
fmu_rows, t = result[after], result["time"][after]
reference = simulate_reference(parameters_from_values(start), 0.0, 0.1, [(0.0, 0.1, 0.0), (200.0, 0.3, 0.0)], t)
dx = np.abs(fmu_rows["x"] - reference.x)
print(f"{fmu}: {result['n_events'][-1]} events; reference: {len(reference.events)}; max |x_FMU - x_ref| = "
      f"{dx.max():.2e} m over {t[-1]:g} s")

fig = Figure(figsize=(11, 9), layout="constrained")
axes = fig.subplots(4, 1, sharex=True)
for ax, name, unit in zip(axes, ("x", "v", "mode"), ("m", "m/s", "")):
    ax.plot(t, fmu_rows[name], lw=1.2, label="FMU (FMPy)")
    ax.plot(t, getattr(reference, name), "--", lw=0.9, label="reference")
    ax.set_ylabel(f"{name} ({unit})" if unit else "mode (0 stuck)")
    ax.axvline(200.0, color="0.6", ls=":", lw=0.8)
axes[0].legend(loc="upper left")
axes[0].set_title("drive 0.1 m/s, stepping to 0.3 m/s at t = 200 s (dotted)")
axes[3].semilogy(t[dx > 0], dx[dx > 0], lw=0.8, color="C2")
axes[3].set(ylabel="|x_FMU - x_ref| (m)", xlabel="t (s)")
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
fig.savefig(out / "fmu_fmpy.png", dpi=80)
print(f"written to {out / 'fmu_fmpy.png'}")
