"""The bifurcation diagram over the drive velocity: every branch and every bifurcation point.

Branches (amplitude = largest ``x`` of the state, as in Elmer 1997, fig. 3):

- ``continuous-sliding``: ``x_c = (F_K(v) + F_ext)/kappa``, stable iff ``F_K'(v) > 0``;
- ``oscillatory-sliding``: sliding limit cycles (:mod:`.sliding_limit_cycles`), stable and unstable;
- ``stick-slip``: the stick-slip cycle where it exists (:mod:`.stickslip_cycle`; stable:
  its slips all end on the same stick); with an aging static law, the fixed points of
  the stick-slip map (:mod:`.aging_map`), stable and unstable;
- ``overshoot-sliding``: cycles that pass ``v_rel = 0`` both ways without sticking
  (where the stick-slip cycle's stick has shrunk to nothing);
- ``special-boundary``: the special stick-slip boundary (:mod:`.boundary`).

Bifurcation points (each refined to ``tol`` in ``v_drive``):

- ``hopf``: extrema of ``F_K`` (criticality from ``F_K'''``, :mod:`.steady_sliding`);
- ``fold``: saddle-nodes of sliding cycles (``G = 0 = dG/dsigma``);
- ``grazing``: a sliding cycle's largest velocity reaches ``v_drive``;
- ``stick-slip-boundary``: stick-slip appears or disappears: a root of the existence
  margin; ``mechanism`` ``"graze"`` (the cycle meets the special boundary) or
  ``"zero-stick"`` (its stick shrinks to nothing and it turns into an overshooting
  sliding cycle); with aging ``"saddle-node"`` or ``"domain"`` (see
  :func:`.aging_map.existence_changes`), and the map's saddle-nodes are also
  reported as ``fold`` (``cycles: "stick-slip"``);
- ``boundary-switch``: the special boundary switches between ending on the stick
  line and spiralling into an unstable sliding state (a root of the boundary margin).

The work is cut into independent tasks (chunks of the ``v_drive`` grid for the
stick-slip cycles and the boundary, the continuation of the sliding cycles)
that run on an :class:`~.parallel_scan.Executor`: a local process pool or a Dask cluster.
"""

import math
from dataclasses import dataclass, field

import numpy as np

from .parallel_scan import CHUNK, Executor


@dataclass
class Diagram:
    """Everything behind the bifurcation diagram (see the module)."""

    params: object
    F_ext: float
    v_grid: np.ndarray
    hopf: list
    sliding: list  # sliding_limit_cycles.Branch
    stick_slip: list  # StickSlipCycle per grid point
    overshoot: list  # OvershootCycle or None per grid point
    boundary: list  # BoundaryOrbit per grid point
    points: list = field(default_factory=list)  # dicts: v_drive, kind, x_max, ...
    seconds: float = math.nan
    map_points: list = field(default_factory=list)  # aging: FixedPoint list per grid velocity

    def rows(self):
        """Branch data as rows of dicts (the CSV)."""
        p, rows = self.params, []
        for v in self.v_grid:
            x = (p.kinetic.force(float(v)) + self.F_ext) / p.kappa
            rows.append(dict(branch="continuous-sliding", index=0, v_drive=v, x_max=x, x_min=x, v_min=0.0, v_max=0.0,
                             period=math.nan, stable=p.kinetic.slope(float(v)) > 0.0, detail=""))
        for k, b in enumerate(self.sliding):
            for c in b.points:
                if c.grazes:
                    continue
                rows.append(dict(branch="oscillatory-sliding", index=k, v_drive=c.v_drive, x_max=c.x_max,
                                 x_min=c.x_min, v_min=c.v_min, v_max=c.v_max, period=c.period, stable=c.stable,
                                 detail=f"multiplier={c.multiplier:.6g}"))
        for c in self.stick_slip:
            if c.exists:
                rows.append(dict(branch="stick-slip", index=0, v_drive=c.v_drive, x_max=c.x_max, x_min=c.x_min,
                                 v_min=c.v_min, v_max=c.v_max, period=c.period, stable=True,
                                 detail=f"overshoots={c.overshoots};stick_fraction={c.stick_fraction:.6g}"))
        for fps in self.map_points:
            for f in fps:
                rows.append(dict(branch="stick-slip", index=0, v_drive=f.v_drive, x_max=f.x_max, x_min=f.x_min,
                                 v_min=math.nan, v_max=math.nan, period=f.period, stable=f.stable,
                                 detail=f"map_fixed_point={f.x:.12g};slope={f.slope:.6g};overshoots={f.overshoots}"))
        for o in self.overshoot:
            if o is not None:
                rows.append(dict(branch="overshoot-sliding", index=0, v_drive=o.v_drive, x_max=o.x_max,
                                 x_min=o.x_min, v_min=o.v_min, v_max=o.v_max, period=o.period, stable=o.stable,
                                 detail=f"multiplier={o.multiplier:.6g}"))
        for o in self.boundary:
            rows.append(dict(branch="special-boundary", index=0, v_drive=o.v_drive, x_max=o.x_max, x_min=o.x_min,
                             v_min=math.nan, v_max=math.nan, period=math.nan, stable=False,
                             detail=f"fate={o.fate};x_end={o.x_end:.9g};margin={o.margin:.6g}"))
        return rows


# ----------------------------------------------------------------------
# tasks (module level: they run in worker processes or on Dask)
# ----------------------------------------------------------------------


def _task(kind, params, arg, F_ext):
    from . import boundary, sliding_limit_cycles, stickslip_cycle

    if kind == "stick-slip":
        cyc = stickslip_cycle.stick_slip_cycles(params, arg, F_ext)
        guess = [c.phases[-1][2] if c.fate == "no-stick" else math.nan for c in cyc]
        over = stickslip_cycle.overshoot_cycles(params, arg, guess, F_ext) if any(map(math.isfinite, guess)) \
            else [None] * len(cyc)
        return cyc, over
    if kind == "boundary":
        return boundary.special_boundary(params, arg, F_ext, resolve=False)
    if kind == "map-fixed-points":
        from .aging_map import fixed_points_scan

        return fixed_points_scan(params, arg, F_ext)
    if kind == "map-changes":
        from .aging_map import existence_changes, saddle_nodes

        grid, fps, tol = arg
        saddles = saddle_nodes(params, grid[0], grid[-1], F_ext=F_ext, tol=0.1 * tol, grid=grid, fps=fps)
        return saddles, existence_changes(params, grid, fps, F_ext, tol, saddles=saddles)
    if kind == "cycles":
        v_min, v_max = arg
        return sliding_limit_cycles.sliding_cycles(params, v_min, v_max, F_ext)
    if kind == "ss-changes":
        grid, margin, tol = arg
        return stickslip_cycle.changes_from_samples(params, grid, margin, F_ext, tol)
    if kind == "boundary-switches":
        grid, margin, tol = arg
        return boundary.boundary_switches(params, grid, margin, F_ext, tol)
    raise ValueError(kind)


def bifurcation_diagram(params, v_min, v_max, n=400, F_ext=0.0, tol=1e-7, executor=None):
    """Compute the full diagram on ``n`` drive velocities in ``[v_min, v_max]`` (any static law)."""
    import time

    from .steady_sliding import hopf_points

    start = time.perf_counter()
    ex = executor or Executor(jobs=1)
    grid = np.linspace(v_min, v_max, n)
    chunks = [grid[i:i + CHUNK] for i in range(0, grid.size, CHUNK)]
    aging = not params.static.is_constant()
    ss_kind = "map-fixed-points" if aging else "stick-slip"
    tasks = [("cycles", params, (v_min, v_max), F_ext)]
    tasks += [(ss_kind, params, c, F_ext) for c in chunks]
    tasks += [("boundary", params, c, F_ext) for c in chunks]
    results = ex.map(_task, tasks, desc="bifurcation diagram")
    sliding = results[0]
    bnd = [o for part in results[1 + len(chunks):] for o in part]
    margin_b = np.array([o.margin for o in bnd])
    if aging:
        fps = [f for part in results[1:1 + len(chunks)] for f in part]
        ss, over = [], []
        (saddles, changes), switches = ex.map(_task, [("map-changes", params, (grid, fps, tol), F_ext),
                                                      ("boundary-switches", params, (grid, margin_b, tol), F_ext)],
                                              desc="refining")
    else:
        fps, saddles = [], []
        ss = [c for part in results[1:1 + len(chunks)] for c in part[0]]
        over = [o for part in results[1:1 + len(chunks)] for o in part[1]]
        margin_ss = np.array([c.margin if math.isfinite(c.margin) else math.copysign(1e3, c.margin) for c in ss])
        changes, switches = ex.map(_task, [("ss-changes", params, (grid, margin_ss, tol), F_ext),
                                           ("boundary-switches", params, (grid, margin_b, tol), F_ext)],
                                   desc="refining")
    hopf = hopf_points(params, v_min, v_max, F_ext)
    _label_spirals(bnd, sliding, params)
    d = Diagram(params, F_ext, grid, hopf, sliding, ss, over, bnd, map_points=fps)
    d.points = _points(d, changes, switches, saddles)
    d.seconds = time.perf_counter() - start
    if executor is None:
        ex.close()
    return d


def _label_spirals(bnd, sliding, params):
    """Name what each unresolved spiral tends to: an unstable sliding cycle if one exists there, else CS."""
    for o in bnd:
        if o.fate != "spiral":
            continue
        inside = False
        for b in sliding:
            pts = [c for c in b.points if not c.stable and not c.grazes]
            for c0, c1 in zip(pts, pts[1:]):
                if min(c0.v_drive, c1.v_drive) <= o.v_drive <= max(c0.v_drive, c1.v_drive):
                    inside = True
        o.fate = "spiral-cycle" if inside else "spiral-cs"


def _interp_ss(d, v):
    """The stick-slip branch's amplitude at ``v`` (interpolated; aging: the nearest stable fixed point)."""
    if d.map_points:
        near = min((f for fps in d.map_points for f in fps), key=lambda f: abs(f.v_drive - v), default=None)
        return near.x_max if near is not None else math.nan
    pts = [(c.v_drive, c.x_max) for c in d.stick_slip if c.exists]
    if not pts:
        return math.nan
    vs, xs = zip(*pts)
    return float(np.interp(v, vs, xs))


def _points(d, changes, switches, saddles=()):
    pts = []
    for v, x in saddles:
        near = min((f for fps in d.map_points for f in fps), key=lambda f: abs(f.x - x) + abs(f.v_drive - v),
                   default=None)
        pts.append(dict(v_drive=v, kind="fold", x_max=near.x_max if near is not None else math.nan,
                        cycles="stick-slip", map_fixed_point=x))
    for h in d.hopf:
        pts.append(dict(v_drive=h.v_drive, kind="hopf", x_max=h.x, criticality=h.criticality,
                        extremum=h.extremum, F2=h.F2, F3=h.F3, lyapunov=h.lyapunov,
                        cycles="stable" if h.cycles_stable else "unstable",
                        side="above" if h.side > 0 else "below"))
    for k, b in enumerate(d.sliding):
        for f in b.folds:
            pts.append(dict(v_drive=f.v_drive, kind="fold", x_max=f.x_max, branch=k, period=f.period))
        for g in b.grazings:
            pts.append(dict(v_drive=g.v_drive, kind="grazing", x_max=g.x_max, branch=k, period=g.period,
                            stable=g.stable))
    for v, what, mech in changes:
        pts.append(dict(v_drive=v, kind="stick-slip-boundary", x_max=_interp_ss(d, v), change=what,
                        mechanism=mech))
    for v, below, above in switches:
        xb = [o.x_max for o in d.boundary]
        pts.append(dict(v_drive=v, kind="boundary-switch", x_max=float(np.interp(v, d.v_grid, xb)),
                        below=below, above=above))
    pts.sort(key=lambda p: p["v_drive"])
    return pts


def write_outputs(d, out_dir):
    """``bifurcation.png``, ``branches.csv`` and ``bifurcation_points.json`` in ``out_dir``."""
    import csv
    from pathlib import Path

    from .json_output import write_json
    from .figures import plot_bifurcation

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = d.rows()
    with open(out / "branches.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.12g}" if isinstance(v, float) else v) for k, v in r.items()})
    write_json(out / "bifurcation_points.json", d.points)
    plot_bifurcation(out / "bifurcation.png", d)
