"""Command-line front ends of the analysis: ``stickslip bifurcation | vc | map | slow-manifold | chart``.

Every command takes the model from a preset (``--preset elmer-fig3``), a
scenario file (``--scenario FILE``: its ``preset``/``[model]``/``[kinetic]``/
``[static]`` tables and a constant ``[inputs.F_ext]``; other tables are optional)
and/or flags that override single values in the FMU's names::

    --kinetic viscous --set kinetic.F0=0.5 --set kinetic.gamma=0.3 --set M=2 --set F_ext=0.1
"""

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from ..core import Parameters
from ..core.errors import ParameterError, StickSlipError
from ..core.laws import KINETIC_LAWS, STATIC_LAWS
from ..analysis.json_output import write_json

_DEFAULT_MODEL = {"M": (1.0, "kg"), "kappa": (1.0, "N/m")}  # name -> (default, unit)


class AnalysisError(StickSlipError, ValueError):
    """A command-line argument does not describe a valid model or run."""


# ----------------------------------------------------------------------
# the model from --preset / --scenario / --kinetic / --static / --set
# ----------------------------------------------------------------------


def _law_list(laws):
    """``"coulomb 1, viscous 2, ..."``: the law names with their FMU codes."""
    return ", ".join(f"{laws[code].NAME} {code}" for code in sorted(laws))


def add_model_arguments(p):
    g = p.add_argument_group("model (a preset or scenario file, then single overrides)")
    g.add_argument("--preset", help="named parameter set (stickslip.suite.scenario.PRESETS), e.g. elmer-fig3")
    g.add_argument("--scenario", metavar="FILE", help="TOML file with [model], [kinetic], [static] "
                   "(or a preset) and optionally a constant [inputs.F_ext]")
    g.add_argument("--kinetic", metavar="LAW", help=f"kinetic law name or code ({_law_list(KINETIC_LAWS)})")
    g.add_argument("--static", metavar="LAW", help=f"static law name or code ({_law_list(STATIC_LAWS)})")
    g.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="override M, kappa, F_ext, kinetic.<param> or static.<param> (repeatable); "
                        "parameters not given take the law's defaults, which are printed")


def _law_class(option, laws, value):
    """The law class named by ``value`` (name or code, also as a digit string), or AnalysisError listing them."""
    code = int(value) if isinstance(value, str) and value.isdigit() else value
    for law in laws.values():
        if code in (law.CODE, law.NAME) and not isinstance(code, bool):
            return law
    raise AnalysisError(f"{option} {value!r}: unknown law; the known laws are {_law_list(laws)}")


def _value_text(name, value, unit):
    return f"{name} = {value:g}" + ("" if unit in ("", "1") else f" {unit}")


def model_from_args(args, report=print):
    """``(Parameters, F_ext)`` from the parsed model arguments.

    Values nobody gave (``M``, ``kappa`` and law parameters left to their defaults)
    are passed to ``report`` as one line, so a run says which numbers it used.
    """
    spec = _ModelSpec()
    if args.preset:
        spec.take_preset(args.preset, f"--preset {args.preset!r}")
    if args.scenario:
        spec.read_scenario(args.scenario)
    if args.kinetic:
        spec.kinetic = {"law": args.kinetic}
    if args.static:
        spec.static = {"law": args.static}
    for item in args.set:
        spec.override(item)
    return spec.parameters(report)


@dataclass
class _ModelSpec:
    """The model as the arguments give it, in the FMU's names: ``model`` (``M`` kg, ``kappa`` N/m), the kinetic
    and static law (``law`` and parameters), and a constant ``F_ext`` (N); later sources override earlier."""

    model: dict = field(default_factory=dict)
    kinetic: dict = field(default_factory=dict)
    static: dict = field(default_factory=dict)
    F_ext: float = 0.0

    def take_preset(self, name, where):
        """The preset ``name`` (``where``: what named it, for the error) replaces the laws and sets the model."""
        from ..suite.scenario import PRESETS

        preset = PRESETS.get(name)
        if preset is None:
            raise AnalysisError(f"{where}: expected one of {sorted(PRESETS)}")
        self.model.update(preset.get("model", {}))
        self.kinetic, self.static = dict(preset.get("kinetic", {})), dict(preset.get("static", {}))

    def read_scenario(self, path):
        """A scenario file's ``preset``, ``[model]``, ``[kinetic]``, ``[static]`` and constant ``[inputs.F_ext]``."""
        try:
            with open(path, "rb") as f:
                data = tomllib.load(f)
        except (OSError, tomllib.TOMLDecodeError) as exc:
            raise AnalysisError(f"{path}: cannot read a TOML file: {exc}") from exc
        if "preset" in data:
            self.take_preset(data["preset"], f"{path}: key 'preset'")
        self.model.update(data.get("model", {}))
        if "kinetic" in data:
            self.kinetic = dict(data["kinetic"])
        if "static" in data:
            self.static = dict(data["static"])
        fe = data.get("inputs", {}).get("F_ext", {})
        if "constant" in fe:
            self.F_ext = float(fe["constant"])
        elif fe:
            raise AnalysisError(f"{path}: key 'inputs.F_ext': the analysis needs a constant F_ext")

    def override(self, item):
        """One ``--set NAME=VALUE``."""
        name, sep, value = item.partition("=")
        try:
            number = float(value)
        except ValueError:
            number = None
        if not sep or number is None:
            raise AnalysisError(f"--set {item!r}: expected NAME=NUMBER")
        if name in ("M", "kappa"):
            self.model[name] = number
        elif name == "F_ext":
            self.F_ext = number
        elif name.startswith("kinetic."):
            self.kinetic[name[8:]] = number
        elif name.startswith("static."):
            self.static[name[7:]] = number
        else:
            raise AnalysisError(f"--set {item!r}: NAME must be M, kappa, F_ext, kinetic.<param> or static.<param>")

    def parameters(self, report):
        """``(Parameters, F_ext)``, checked; the defaults used go to ``report`` as one line."""
        kin, sta = dict(self.kinetic), dict(self.static)
        kinetic_cls = _law_class("--kinetic", KINETIC_LAWS, kin.pop("law")) if "law" in kin else None
        static_cls = _law_class("--static", STATIC_LAWS, sta.pop("law")) if "law" in sta else None
        if kinetic_cls is None or static_cls is None:
            raise AnalysisError("no friction laws: give --preset, --scenario, or --kinetic LAW and --static LAW "
                                f"(kinetic: {_law_list(KINETIC_LAWS)}; static: {_law_list(STATIC_LAWS)})")
        defaults = [_value_text(name, value, unit) for name, (value, unit) in _DEFAULT_MODEL.items()
                    if name not in self.model]
        for prefix, cls, given in (("kinetic", kinetic_cls, kin), ("static", static_cls, sta)):
            defaults += [_value_text(f"{prefix}.{name}", value, unit) for name, (value, _, unit)
                         in cls.PARAMETERS.items() if name not in given]
        model = {name: self.model.get(name, value) for name, (value, _) in _DEFAULT_MODEL.items()}
        try:
            params = Parameters(model["M"], model["kappa"], kinetic_cls(**kin), static_cls(**sta))
            params.check()
        except ParameterError as exc:
            raise AnalysisError(str(exc)) from exc
        if defaults:
            report(f"defaults used ({kinetic_cls.NAME} kinetic, {static_cls.NAME} static law): " + ", ".join(defaults))
        return params, self.F_ext


def add_scan_arguments(p, v_min=0.01, v_max=1.2, n=400):
    g = p.add_argument_group("drive-velocity scan")
    g.add_argument("--v-min", type=float, default=v_min, help=f"smallest drive velocity in m/s (default {v_min})")
    g.add_argument("--v-max", type=float, default=v_max, help=f"largest drive velocity in m/s (default {v_max})")
    g.add_argument("-n", "--points", type=int, default=n, help=f"drive velocities on the grid (default {n})")
    g.add_argument("--tol", type=float, default=1e-7, help="tolerance of located bifurcations in m/s (default 1e-7)")
    g.add_argument("--jobs", type=int, default=2, help="worker processes of the local pool (default 2; 1: serial)")
    g.add_argument("--scheduler", metavar="ADDRESS", help="run the scan on this Dask distributed scheduler")


def _executor(args):
    from ..analysis.parallel_scan import Executor

    return Executor(jobs=args.jobs, scheduler=args.scheduler)


def _out_dir(args):
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    return out


# ----------------------------------------------------------------------
# stickslip vc
# ----------------------------------------------------------------------


def add_vc(subparsers):
    p = subparsers.add_parser("vc", help="drive velocities where stick-slip appears and disappears")
    add_model_arguments(p)
    add_scan_arguments(p, v_min=None, v_max=None, n=200)
    p.add_argument("--out", default="vc", help="directory for vc.json and margin.png (default: vc)")
    p.set_defaults(handler=_vc)


def _vc(args):
    import numpy as np

    from ..analysis.critical import critical_velocities, default_scan_range, from_changes

    params, F_ext = model_from_args(args)
    default = default_scan_range(params, F_ext)
    v_min = default.v_min if args.v_min is None else args.v_min
    v_max = default.v_max if args.v_max is None else args.v_max
    if not 0.0 < v_min < v_max:
        raise AnalysisError("need 0 < --v-min < --v-max")
    chosen = "given" if args.v_max is not None and args.v_min is not None else f"default from the law: {default.reason}"
    print(f"scanning v_drive in [{v_min:.6g}, {v_max:.6g}] m/s on {args.points} points ({chosen})")
    if params.static.is_constant():
        with _executor(args) as ex:
            result = critical_velocities(params, v_min, v_max, args.points, F_ext, tol=args.tol,
                                         scan=lambda p, grid: ex.margins(p, grid, F_ext))
    else:  # aging: stick-slip is a fixed point of the stick-slip map
        from ..analysis import aging_map as am

        grid = np.linspace(v_min, v_max, args.points)
        fps = am.fixed_points_scan(params, grid, F_ext)
        result = from_changes(v_min, v_max, am.has_cycle(fps[0]),
                              am.existence_changes(params, grid, fps, F_ext, args.tol))
    print("stick-slip windows (m/s):" + ("" if result.windows else " none in range"))
    for lo, hi in result.windows:
        print(f"  {lo:.7f} .. {hi:.7f}")
    print("as v_drive grows, stick-slip" + ("" if result.changes else " neither appears nor disappears in range"))
    for v, change, kind in result.changes:
        print(f"  {change:10s} at {v:.7f} m/s ({_CHANGE_KINDS.get(kind, kind)})")
    print("critical drive velocities (stick-slip disappears above): "
          + (", ".join(f"{v:.7f}" for v in result.critical) or "none in range"))
    out = _out_dir(args)
    write_json(out / "vc.json", {"v_min": v_min, "v_max": v_max, "range": chosen, "windows": result.windows,
                                 "critical": result.critical,
                                 "changes": [{"v_drive": v, "change": w, "kind": k} for v, w, k in result.changes]})
    written = [out / "vc.json"]
    if params.static.is_constant():
        from ..analysis.figures import plot_margin

        plot_margin(out / "margin.png", params, result, F_ext)
        written.append(out / "margin.png")
    print("written to " + " and ".join(map(str, written)))
    return 0


#: how a stick-slip birth or death happens (the vanishing term of the existence margin)
_CHANGE_KINDS = {"graze": "the slip grazes v = v_drive", "zero-stick": "the stick shrinks to nothing",
                 "saddle-node": "saddle-node of the stick-slip map", "domain": "the cycle's slip stops sticking"}


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
    from ..analysis.bifurcation import bifurcation_diagram, write_outputs

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

    from ..analysis import aging_map as am
    from ..analysis.figures import plot_fixed_points, plot_map, plot_orbit_diagram

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
    from ..analysis.aging_map import orbit_diagram

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

    from ..analysis.overdamped import relaxation_run, slow_manifold
    from ..analysis.figures import plot_slow_manifold

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

    from ..analysis.figures import plot_chart
    from ..analysis.parallel_scan import stability_chart

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
