"""The bifurcation diagram of Elmer's boundary-lubrication law (F.-J. Elmer, J. Phys. A 30 (1997) 6057, fig. 3).

Every branch over the drive velocity: continuous sliding, oscillatory sliding (sliding limit cycles),
stick-slip and overshooting sliding, stable and unstable, with the special stick-slip boundary and the
bifurcation points (Hopf, folds, grazings, where stick-slip appears or disappears), printed as a table.
The computation is `stickslip.analysis.bifurcation_diagram`, the figure `stickslip.analysis.figures`
(the same as `stickslip bifurcation --preset elmer-fig3`).

    python examples/bifurcation_fig3.py [--quick] [--out DIR]

writes DIR/bifurcation_fig3.png (default DIR: results/examples). --quick: 12 drive velocities in
[0.01, 0.12] m/s instead of 400 in [0.01, 1.2] m/s, bifurcations located to 1e-5 m/s instead of 1e-7 m/s
(the window without stick-slip around 0.07 m/s, in seconds; the whole diagram takes minutes).
"""

import argparse
from pathlib import Path

from stickslip.analysis import Executor, bifurcation_diagram
from stickslip.analysis.figures import plot_bifurcation
from stickslip.core import Constant, Lubricated, Parameters

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--quick", action="store_true", help="a coarse diagram (for the tests)")
parser.add_argument("--out", default="results/examples", help="output folder (default results/examples)")


def main(args):
    # Elmer's fig. 3: M = 40 kg, kappa = 1 N/m, F_S = 1 N; F_K(u) rises to 0.393 N at u = 0.163 m/s, falls to
    # 0.057 N at 0.417 m/s and rises again (gamma1, gamma2 in N s/m; v_tilde, dv in m/s)
    params = Parameters(M=40.0, kappa=1.0, kinetic=Lubricated(gamma1=3.0, gamma2=0.1, v_tilde=0.2, dv=0.05),
                        static=Constant(F0=1.0))
    v_max, points, tol = (0.12, 12, 1e-5) if args.quick else (1.2, 400, 1e-7)  # m/s, -, m/s
    with Executor(jobs=2) as executor:  # two worker processes
        diagram = bifurcation_diagram(params, v_min=0.01, v_max=v_max, n=points, tol=tol, executor=executor)
    print(f"{'kind':20s} {'v_drive (m/s)':>14s} {'largest x (m)':>14s}  detail")
    for point in diagram.points:
        detail = point.get("criticality") or point.get("mechanism") or point.get("change") or ""
        print(f"{point['kind']:20s} {point['v_drive']:14.7f} {point['x_max']:14.5f}  {detail}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    plot_bifurcation(out / "bifurcation_fig3.png", diagram)
    print(f"{len(diagram.points)} bifurcation points in {diagram.seconds:.1f} s")
    print(f"written to {out / 'bifurcation_fig3.png'}")


if __name__ == "__main__":  # the worker processes import this file: only the main process runs it
    main(parser.parse_args())
