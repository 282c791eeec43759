"""The FMUs in fmusim, the Modelica Association's C simulator (Reference-FMUs v0.0.39, built by
scripts/build_fmusim.sh): FMI 3 model exchange under fmusim's CVode (tolerances 1e-10 and 1e-6), FMI 2 model exchange
(1e-10), FMI 3 and FMI 2 co-simulation, on scenarios with constant inputs; prints max |x - reference| (m) on the
scenario's output grid.

    python scripts/fmusim_scenarios.py FMUSIM SCENARIO_NAME...   (FMUs: dist/, built by `stickslip build`)
"""
import csv
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from stickslip.fmu import default_fmu_path
from stickslip.suite.runner import simulate
from stickslip.suite.scenario import load_scenario

FMUSIM = sys.argv[1]
FMU2, FMU3 = str(default_fmu_path(2)), str(default_fmu_path(3))
OUT = Path("build/fmusim-runs")
OUT.mkdir(parents=True, exist_ok=True)
for name in sys.argv[2:]:
    sc = load_scenario(Path("scenarios") / f"{name}.toml")
    _, ref, _, _ = simulate(sc, FMU2)
    t_ref, x_ref = np.asarray(ref.t), np.asarray(ref.x)
    for label, fmu, args in (("fmi3-me cvode 1e-10", FMU3, ["--interface-type", "me", "--solver", "cvode", "--tolerance", "1e-10"]),
                             ("fmi3-me cvode 1e-6", FMU3, ["--interface-type", "me", "--solver", "cvode", "--tolerance", "1e-6"]),
                             ("fmi2-me cvode 1e-10", FMU2, ["--interface-type", "me", "--solver", "cvode", "--tolerance", "1e-10"]),
                             ("fmi3-cs", FMU3, ["--interface-type", "cs"]), ("fmi2-cs", FMU2, ["--interface-type", "cs"])):
        points = sc.breakpoints()
        if len({(v, f) for _, v, f in points}) > 1:
            print(f"{name}: inputs change during the run: left out"); break
        sv = []
        for k, v in {**sc.start_values(), "v_drive": points[0][1], "F_ext": points[0][2]}.items():
            sv += ["--start-value", k, repr(v)]
        out = OUT / f"{name}-{label.replace(' ', '_')}.csv"
        t0 = time.perf_counter()
        run = subprocess.run([FMUSIM, *args, "--stop-time", repr(sc.stop_time), "--output-interval", repr(sc.output_interval),
                              *sv, "--output-variable", "x", "--output-file", out, fmu], capture_output=True, text=True, timeout=600)
        wall = time.perf_counter() - t0
        rows = list(csv.reader(open(out)))[1:] if out.exists() else []
        t = np.array([float(r[0]) for r in rows]); x = np.array([float(r[1]) for r in rows])
        # fmusim's ME output also has event rows: compare at the reference's grid times (last row at each time)
        err = max((abs(x[np.where(np.isclose(t, tr, rtol=0, atol=1e-9))[0][-1]] - xr) for tr, xr in zip(t_ref, x_ref)
                   if np.any(np.isclose(t, tr, rtol=0, atol=1e-9))), default=float("nan"))
        print(f"{name:22s} {label:22s} exit {run.returncode} rows {len(rows):6d} max|dx| {err:.2e} m  wall {wall:.2f} s  "
              f"{run.stderr.strip()[-120:] or run.stdout.strip()[-120:]}", flush=True)
