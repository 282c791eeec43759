"""Command-line front ends of the analysis: ``stickslip bifurcation | vc | map | slow-manifold | chart``.

Every command takes the model from a preset (``--preset elmer-fig3``), a
scenario file (``--scenario FILE``: its ``preset``/``[model]``/``[kinetic]``/
``[static]`` tables and a constant ``[inputs.F_ext]``; other tables are optional)
and/or flags that override single values in the FMU's names::

    --kinetic viscous --set kinetic.F0=0.5 --set kinetic.gamma=0.3 --set M=2 --set F_ext=0.1
"""

import json
import math
import tomllib
from pathlib import Path

from ..core import Parameters
from ..core.errors import ParameterError, StickSlipError
from ..core.laws import kinetic_law, static_law

_DEFAULT_MODEL = {"M": 1.0, "kappa": 1.0}


class AnalysisError(StickSlipError, ValueError):
    """A command-line argument does not describe a valid model or run."""


# ----------------------------------------------------------------------
# the model from --preset / --scenario / --kinetic / --static / --set
# ----------------------------------------------------------------------


def add_model_arguments(p):
    g = p.add_argument_group("model (a preset or scenario file, then single overrides)")
    g.add_argument("--preset", help="named parameter set (stickslip.scenario.PRESETS), e.g. elmer-fig3")
    g.add_argument("--scenario", metavar="FILE", help="TOML file with [model], [kinetic], [static] "
                   "(or a preset) and optionally a constant [inputs.F_ext]")
    g.add_argument("--kinetic", metavar="LAW", help="kinetic law name or code (coulomb, viscous, stribeck, lubricated)")
    g.add_argument("--static", metavar="LAW",
                   help="static law name or code (constant, logarithmic, saturating, sigmoid)")
    g.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="override M, kappa, F_ext, kinetic.<param> or static.<param> (repeatable)")


def model_from_args(args):
    """``(Parameters, F_ext)`` from the parsed model arguments."""
    from ..scenario import PRESETS

    model, kin, sta, F_ext = dict(_DEFAULT_MODEL), {}, {}, 0.0
    if args.preset:
        if args.preset not in PRESETS:
            raise AnalysisError(f"--preset {args.preset!r}: expected one of {sorted(PRESETS)}")
        pre = PRESETS[args.preset]
        model.update(pre.get("model", {}))
        kin, sta = dict(pre.get("kinetic", {})), dict(pre.get("static", {}))
    if args.scenario:
        try:
            with open(args.scenario, "rb") as f:
                data = tomllib.load(f)
        except (OSError, tomllib.TOMLDecodeError) as exc:
            raise AnalysisError(f"{args.scenario}: cannot read a TOML file: {exc}") from exc
        if "preset" in data:
            pre = PRESETS.get(data["preset"])
            if pre is None:
                raise AnalysisError(f"{args.scenario}: key 'preset': expected one of {sorted(PRESETS)}")
            model.update(pre.get("model", {}))
            kin, sta = dict(pre.get("kinetic", {})), dict(pre.get("static", {}))
        model.update(data.get("model", {}))
        if "kinetic" in data:
            kin = dict(data["kinetic"])
        if "static" in data:
            sta = dict(data["static"])
        fe = data.get("inputs", {}).get("F_ext", {})
        if "constant" in fe:
            F_ext = float(fe["constant"])
        elif fe:
            raise AnalysisError(f"{args.scenario}: key 'inputs.F_ext': the analysis needs a constant F_ext")
    if args.kinetic:
        kin = {"law": args.kinetic}
    if args.static:
        sta = {"law": args.static}
    for item in args.set:
        name, sep, value = item.partition("=")
        try:
            number = float(value)
        except ValueError:
            number = None
        if not sep or number is None:
            raise AnalysisError(f"--set {item!r}: expected NAME=NUMBER")
        if name in ("M", "kappa"):
            model[name] = number
        elif name == "F_ext":
            F_ext = number
        elif name.startswith("kinetic."):
            kin[name[8:]] = number
        elif name.startswith("static."):
            sta[name[7:]] = number
        else:
            raise AnalysisError(f"--set {item!r}: NAME must be M, kappa, F_ext, kinetic.<param> or static.<param>")
    if "law" not in kin or "law" not in sta:
        raise AnalysisError("no friction laws: give --preset, --scenario or --kinetic and --static")
    try:
        k = kinetic_law(_code(kin.pop("law")), **kin)
        s = static_law(_code(sta.pop("law")), **sta)
        params = Parameters(model["M"], model["kappa"], k, s)
        params.check()
    except ParameterError as exc:
        raise AnalysisError(str(exc)) from exc
    return params, F_ext


def _code(law):
    if isinstance(law, str) and law.isdigit():
        return int(law)
    return law


def add_scan_arguments(p, v_min=0.01, v_max=1.2, n=400):
    g = p.add_argument_group("drive-velocity scan")
    g.add_argument("--v-min", type=float, default=v_min, help=f"smallest drive velocity in m/s (default {v_min})")
    g.add_argument("--v-max", type=float, default=v_max, help=f"largest drive velocity in m/s (default {v_max})")
    g.add_argument("-n", "--points", type=int, default=n, help=f"drive velocities on the grid (default {n})")
    g.add_argument("--tol", type=float, default=1e-7, help="tolerance of located bifurcations in m/s (default 1e-7)")
    g.add_argument("--jobs", type=int, default=2, help="worker processes of the local pool (default 2; 1: serial)")
    g.add_argument("--scheduler", metavar="ADDRESS", help="run the scan on this Dask distributed scheduler")


def _executor(args):
    from .scan import Executor

    return Executor(jobs=args.jobs, scheduler=args.scheduler)


def _out_dir(args):
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    return out


def _json(obj):
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: _json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_json(v) for v in obj]
    return obj


def write_json(path, obj):
    Path(path).write_text(json.dumps(_json(obj), indent=2) + "\n")


# ----------------------------------------------------------------------
# stickslip vc
# ----------------------------------------------------------------------


def add_vc(subparsers):
    p = subparsers.add_parser("vc", help="critical drive velocities above which stick-slip disappears")
    add_model_arguments(p)
    add_scan_arguments(p, v_min=None, v_max=None, n=200)
    p.add_argument("--out", help="directory for vc.json and margin.png (optional)")
    p.set_defaults(handler=_vc)


def _vc(args):
    from .critical import critical_velocities

    params, F_ext = model_from_args(args)
    if params.static.is_constant():
        with _executor(args) as ex:
            result = critical_velocities(params, args.v_min, args.v_max, args.points, F_ext, tol=args.tol,
                                         scan=lambda p, grid: ex.margins(p, grid, F_ext))
        print(f"stick-slip windows in [{result.v_min:g}, {result.v_max:g}] m/s:")
        for a, b in result.windows:
            print(f"  {a:.7f} .. {b:.7f}")
        print("critical drive velocities (stick-slip disappears above): "
              + (", ".join(f"{v:.7f}" for v in result.critical) or "none in range"))
        if args.out:
            out = _out_dir(args)
            write_json(out / "vc.json", {"windows": result.windows, "critical": result.critical,
                                         "changes": [{"v_drive": v, "change": w, "kind": k}
                                                     for v, w, k in result.changes]})
            from .plots import plot_margin

            plot_margin(out / "margin.png", params, result, F_ext)
        return 0
    from .aging_map import critical_velocity

    vc = critical_velocity(params, args.v_min, args.v_max, args.points, F_ext, tol=args.tol)
    print("critical drive velocities of the stick-slip map (stick-slip disappears above): "
          + (", ".join(f"{v:.7f}" for v in vc) or "none in range"))
    if args.out:
        write_json(_out_dir(args) / "vc.json", {"critical": list(vc)})
    return 0


# ----------------------------------------------------------------------
# stickslip bifurcation
# ----------------------------------------------------------------------


def add_bifurcation(subparsers):
    p = subparsers.add_parser("bifurcation", help="bifurcation diagram over the drive velocity (all branches)")
    add_model_arguments(p)
    add_scan_arguments(p)
    p.add_argument("--out", default="bifurcation", help="output directory (default: bifurcation)")
    p.set_defaults(handler=_bifurcation)


def _bifurcation(args):
    from .bifurcation import bifurcation_diagram, write_outputs

    params, F_ext = model_from_args(args)
    if not 0.0 < args.v_min < args.v_max or args.points < 2:
        raise AnalysisError("need 0 < --v-min < --v-max and at least 2 points")
    with _executor(args) as ex:
        d = bifurcation_diagram(params, args.v_min, args.v_max, args.points, F_ext, tol=args.tol, executor=ex)
    write_outputs(d, args.out)
    for pt in d.points:
        extra = pt.get("criticality") or pt.get("mechanism") or ""
        print(f"{pt['kind']:20s} v_drive = {pt['v_drive']:.9f}  {extra}")
    print(f"{len(d.points)} bifurcation points, {args.points} drive velocities in {d.seconds:.1f} s; "
          f"written to {args.out}/bifurcation.png, branches.csv, bifurcation_points.json")
    return 0


def _v_drive(args):
    """``--v-drive``, else a constant ``[inputs.v_drive]`` of the scenario file, else None."""
    if getattr(args, "v_drive", None) is not None:
        return args.v_drive
    if args.scenario:
        with open(args.scenario, "rb") as f:
            vd = tomllib.load(f).get("inputs", {}).get("v_drive", {})
        if "constant" in vd:
            return float(vd["constant"])
    return None


# ----------------------------------------------------------------------
# stickslip map
# ----------------------------------------------------------------------


def add_map(subparsers):
    p = subparsers.add_parser("map", help="stick-slip map of aging static friction: fixed points, saddle-nodes, "
                              "critical velocity, orbit diagram and Lyapunov exponent")
    add_model_arguments(p)
    add_scan_arguments(p, v_min=None, v_max=None, n=60)
    p.add_argument("--v-drive", type=float, help="drive velocity of the map plot (default: the scenario's, "
                   "else the middle of the scan)")
    p.add_argument("--orbit", action="store_true", help="always draw the orbit diagram and Lyapunov exponent "
                   "(by default only where overshooting makes the map non-monotonic)")
    p.add_argument("--transient", type=int, default=100, help="map iterations discarded (default 100)")
    p.add_argument("--keep", type=int, default=60, help="map iterations kept per drive velocity (default 60)")
    p.add_argument("--out", default="map", help="output directory (default: map)")
    p.set_defaults(handler=_map)


def _map(args):
    import numpy as np

    from . import aging_map as am
    from .plots import plot_fixed_points, plot_map, plot_orbit_diagram

    params, F_ext = model_from_args(args)
    natural = (params.static.force(0.0) + abs(F_ext)) / math.sqrt(params.kappa * params.M)
    v_min = args.v_min if args.v_min is not None else 0.02 * natural
    v_max = args.v_max if args.v_max is not None else 2.0 * natural
    if not 0.0 < v_min < v_max:
        raise AnalysisError("need 0 < --v-min < --v-max")
    v_drive = _v_drive(args) or 0.5 * (v_min + v_max)
    out = _out_dir(args)
    smap = am.StickSlipMap(params, v_drive, F_ext)
    lo, hi = smap.domain()
    xs = np.linspace(lo, hi, 300)
    ts = smap(xs)
    fps = am.fixed_points(params, v_drive, F_ext)
    plot_map(out / "map.png", smap, xs, ts, fps)
    grid = np.linspace(v_min, v_max, args.points)
    scan = am.fixed_points_scan(params, grid, F_ext)
    saddles = am.saddle_nodes(params, v_min, v_max, args.points, F_ext, tol=args.tol)
    critical = am.critical_velocity(params, v_min, v_max, args.points, F_ext, tol=args.tol)
    plot_fixed_points(out / "fixed_points.png", grid, scan, saddles, critical)
    monotone = bool(np.all(np.diff(ts[np.isfinite(ts)]) >= -1e-12))
    summary = {
        "v_drive": v_drive,
        "fixed_points": [dict(x=f.x, slope=f.slope, stable=f.stable, period=f.period, stick_time=f.stick_time,
                              overshoots=f.overshoots) for f in fps],
        "saddle_nodes": [dict(v_drive=v, x=x) for v, x in saddles],
        "critical_velocities": list(critical),
        "monotone_at_v_drive": monotone,
    }
    if args.orbit or not monotone or any(p.slope < 0.0 for f in scan for p in f):
        with _executor(args) as ex:
            parts = ex.map(_orbit_chunk, [(params, grid[i:i + 10], F_ext, args.transient, args.keep)
                                          for i in range(0, grid.size, 10)], desc="orbit diagram")
        iterates = np.concatenate([p[0] for p in parts])
        exponents = np.concatenate([p[1] for p in parts])
        plot_orbit_diagram(out / "orbit_diagram.png", grid, iterates, exponents)
        summary["lyapunov"] = [dict(v_drive=float(v), exponent=float(e)) for v, e in zip(grid, exponents)]
        chaotic = [float(v) for v, e in zip(grid, exponents) if e > 0.0]
        summary["chaotic_v_drive"] = chaotic
        print(f"orbit diagram: Lyapunov exponent > 0 (chaos) at {len(chaotic)} of {grid.size} drive velocities")
    write_json(out / "map.json", summary)
    print(f"v_drive = {v_drive:g} m/s: fixed points " + ", ".join(
        f"x* = {f.x:.9f} ({'stable' if f.stable else 'unstable'}, T' = {f.slope:.4g}, period {f.period:.6g} s)"
        for f in fps))
    for v, x in saddles:
        print(f"saddle-node of the map at v_drive = {v:.9f} m/s (x* = {x:.6f} m)")
    print("critical drive velocities: " + (", ".join(f"{v:.9f}" for v in critical) or "none in range"))
    print(f"written to {out}/")
    return 0


def _orbit_chunk(params, grid, F_ext, transient, keep):
    from .aging_map import orbit_diagram

    return orbit_diagram(params, grid, F_ext, transient, keep)


# ----------------------------------------------------------------------
# stickslip slow-manifold
# ----------------------------------------------------------------------


def add_slow_manifold(subparsers):
    p = subparsers.add_parser("slow-manifold", help="strongly overdamped limit: slow manifold and a simulated "
                              "relaxation oscillation")
    add_model_arguments(p)
    p.add_argument("--v-drive", type=float, help="drive velocity (default: the scenario's)")
    p.add_argument("--t-end", type=float, help="simulated time in s (default: several stick-slip cycles)")
    p.add_argument("--u-max", type=float, help="largest sliding speed drawn in m/s (default: from the run)")
    p.add_argument("--out", default="slow-manifold", help="output directory (default: slow-manifold)")
    p.set_defaults(handler=_slow_manifold)


def _slow_manifold(args):
    import numpy as np

    from .overdamped import relaxation_run, slow_manifold
    from .plots import plot_slow_manifold

    params, F_ext = model_from_args(args)
    v_drive = _v_drive(args)
    if v_drive is None or not v_drive > 0.0:
        raise AnalysisError("give --v-drive > 0 (or a scenario with a constant v_drive)")
    run = relaxation_run(params, v_drive, args.t_end, F_ext)
    u_max = args.u_max or 1.2 * max(float(np.max(run[2])), v_drive)
    m = slow_manifold(params, u_max, F_ext)
    out = _out_dir(args)
    plot_slow_manifold(out / "slow_manifold.png", params, m, run, F_ext, v_drive)
    write_json(out / "slow_manifold.json", {
        "v_drive": v_drive, "folds": [dict(v_rel=u, x=x) for u, x in m.folds],
        "overdamping_ratio_min": float(np.min(m.ratio)), "overdamping_ratio_max": float(np.max(m.ratio))})
    for u, x in m.folds:
        print(f"fold of the slow manifold at v_rel = {u:.6g} m/s, x = {x:.6g} m")
    print(f"|F_K'|/sqrt(kappa M) from {np.min(m.ratio):.3g} to {np.max(m.ratio):.3g}; written to {out}/")
    return 0


# ----------------------------------------------------------------------
# stickslip chart
# ----------------------------------------------------------------------


def add_chart(subparsers):
    p = subparsers.add_parser("chart", help="2-D stability chart over v_drive and a second parameter")
    add_model_arguments(p)
    add_scan_arguments(p, n=100)
    p.add_argument("--param", required=True, help="second parameter: M, kappa, kinetic.<p> or static.<p>")
    p.add_argument("--values", required=True, metavar="FROM:TO:N", help="its values, e.g. 10:80:15")
    p.add_argument("--out", default="chart", help="output directory (default: chart)")
    p.set_defaults(handler=_chart)


def _chart(args):
    import csv

    import numpy as np

    from .plots import plot_chart
    from .scan import stability_chart

    params, F_ext = model_from_args(args)
    try:
        a, b, n = args.values.split(":")
        values = np.linspace(float(a), float(b), int(n))
    except ValueError as exc:
        raise AnalysisError(f"--values {args.values!r}: expected FROM:TO:N") from exc
    grid = np.linspace(args.v_min, args.v_max, args.points)
    with _executor(args) as ex:
        chart = stability_chart(params, grid, args.param, values, F_ext, executor=ex)
    out = _out_dir(args)
    plot_chart(out / "chart.png", chart)
    with open(out / "chart.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow([args.param, "v_drive", "code", "cs_stable", "stick_slip", "margin"])
        for i, value in enumerate(values):
            for j, v in enumerate(grid):
                c = int(chart.code[i, j])
                w.writerow([f"{value:.12g}", f"{v:.12g}", c, c & 1, c >> 1, f"{chart.margin[i, j]:.9g}"])
    print(f"chart of {values.size} x {grid.size} points written to {out}/chart.png and chart.csv")
    return 0
