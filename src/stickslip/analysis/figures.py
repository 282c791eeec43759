"""Figures of the analysis (matplotlib's Agg canvas, no pyplot state: headless and worker-safe)."""

import math

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

_BRANCH_STYLE = {
    "continuous-sliding": ("C0", "continuous sliding"),
    "oscillatory-sliding": ("C1", "oscillatory sliding"),
    "stick-slip": ("C3", "stick-slip"),
    "overshoot-sliding": ("C4", "overshooting sliding"),
}
_POINT_STYLE = {
    "hopf": ("o", "k", "H"),
    "fold": ("s", "C1", "F"),
    "grazing": ("^", "C2", "G"),
    "stick-slip-boundary": ("D", "C3", "S"),
    "boundary-switch": ("v", "C2", "B"),
}


def _figure(size):
    fig = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _segments(v, y, stable):
    """Runs of consecutive points with the same stability: ``[(v, y, stable), ...]``."""
    out, start = [], 0
    for i in range(1, len(v) + 1):
        if i == len(v) or stable[i] != stable[start]:
            lo = max(start - 1, 0) if start > 0 else start
            out.append((v[lo:i], y[lo:i], stable[start]))
            start = i
    return out


def _gaps(v, y, spacing):
    """Split a sampled curve where consecutive drive velocities are farther apart than ``spacing``."""
    v, y = np.asarray(v), np.asarray(y)
    if v.size == 0:
        return []
    cut = np.flatnonzero(np.diff(v) > spacing) + 1
    return list(zip(np.split(v, cut), np.split(y, cut)))


def plot_bifurcation(png_path, d):
    """Amplitude (largest ``x``) against ``v_drive`` for every branch, bifurcation points labelled."""
    fig = _figure((14, 7))
    ax, side = fig.subplots(1, 2, width_ratios=(4.2, 1))
    side.axis("off")
    grid = d.v_grid
    spacing = 1.5 * (grid[1] - grid[0]) if grid.size > 1 else math.inf
    _draw_continuous_sliding(ax, d)
    _draw_sliding_cycles(ax, d)
    _draw_stick_slip(ax, d, spacing)
    _draw_overshoot_sliding(ax, d, spacing)
    _draw_boundary(ax, d)
    ax.plot([], [], "k-", label="stable")
    ax.plot([], [], "k:", label="unstable")
    table, labelled = _draw_points(ax, d)
    ax.set_xlim(grid[0], grid[-1])
    ax.autoscale_view()
    for v, y, names, col, offset in _label_groups(ax, labelled):
        ax.annotate(names, (v, y), textcoords="offset points", xytext=offset, fontsize=8, color=col)
    for kind, (marker, col, prefix) in _POINT_STYLE.items():
        ax.plot([], [], marker, color=col, mfc="white", mew=1.6, ls="none", label=f"{prefix}: {kind}")
    p = d.params
    ax.set(xlabel="drive velocity v_drive (m/s)", ylabel="amplitude: largest x (m)",
           title=f"Bifurcation diagram: M = {p.M:g} kg, kappa = {p.kappa:g} N/m, {p.kinetic!r}, {p.static!r}")
    ax.title.set_fontsize(9)
    fig.legend(loc="outside lower center", fontsize=7.5, ncols=4)
    side.text(0.0, 1.0, "bifurcation points\n\n" + "\n".join(table), transform=side.transAxes, ha="left",
              va="top", fontsize=7.5, family="monospace")
    fig.savefig(png_path, dpi=120)


def _draw_continuous_sliding(ax, d):
    """Continuous sliding ``x_c = (F_K(v_drive) + F_ext)/kappa``: solid where stable (``F_K' > 0``)."""
    p, grid = d.params, d.v_grid
    xc = np.array([(p.kinetic.force(float(v)) + d.F_ext) / p.kappa for v in grid])
    stable = np.array([p.kinetic.slope(float(v)) > 0.0 for v in grid])
    color, label = _BRANCH_STYLE["continuous-sliding"]
    for vs, ys, st in _segments(grid, xc, stable):
        ax.plot(vs, ys, "-" if st else ":", color=color, lw=1.6 if st else 1.3)
    ax.plot([], [], "-", color=color, label=label)


def _draw_sliding_cycles(ax, d):
    """Each branch of sliding cycles along its arc, from its Hopf point (if any) to its grazings."""
    from .sliding_limit_cycles import CyclePoint

    color, label = _BRANCH_STYLE["oscillatory-sliding"]
    for b in d.sliding:
        pts = [c for c in b.points if not c.grazes]
        if b.hopf is not None:
            h = b.hopf
            pts = [CyclePoint(h.v_drive, 0.0, h.x, h.x, 0.0, 0.0, h.period, h.cycles_stable)] + pts
        pts += list(b.grazings)
        pts.sort(key=lambda c: _arc_key(b, c))
        if not pts:
            continue
        vs = np.array([c.v_drive for c in pts])
        ys = np.array([c.x_max for c in pts])
        st = np.array([c.stable for c in pts])
        for sv, sy, s in _segments(vs, ys, st):
            ax.plot(sv, sy, "-" if s else ":", color=color, lw=1.6 if s else 1.3)
    ax.plot([], [], "-", color=color, label=label)


def _draw_stick_slip(ax, d, spacing):
    """The stick-slip cycles (a line, cut at gaps wider than ``spacing`` m/s), or the aging map's fixed points."""
    color, label = _BRANCH_STYLE["stick-slip"]
    ss = [(c.v_drive, c.x_max) for c in d.stick_slip if c.exists]
    for vs, ys in _gaps([a for a, _ in ss], [b for _, b in ss], spacing):
        ax.plot(vs, ys, "-", color=color, lw=1.8)
    for fps in d.map_points:
        for f in fps:
            ax.plot(f.v_drive, f.x_max, ".", color=color, ms=3.5 if f.stable else 2.5,
                    mfc=color if f.stable else "white")
    ax.plot([], [], "-", color=color, label=label + (" (aging map: dots, open = unstable)" if d.map_points
                                                     else " (stable)"))


def _draw_overshoot_sliding(ax, d, spacing):
    color, label = _BRANCH_STYLE["overshoot-sliding"]
    ov = [(o.v_drive, o.x_max, o.stable) for o in d.overshoot if o is not None]
    for vs, ys in _gaps([a for a, _, _ in ov], [b for _, b, _ in ov], spacing):
        ax.plot(vs, ys, "-", color=color, lw=1.6)
    if ov:
        ax.plot([], [], "-", color=color, label=label)


def _draw_boundary(ax, d):
    """The special stick-slip boundary: bold where, backward, it reaches the stick line."""
    bv = np.array([o.v_drive for o in d.boundary])
    bx = np.array([o.x_max for o in d.boundary])
    line = np.array([o.fate == "stick-line" for o in d.boundary])
    for vs, ys, st in _segments(bv, bx, line):
        ax.plot(vs, ys, "-.", color="C2", lw=1.2 if st else 0.8, alpha=1.0 if st else 0.5)
    ax.plot([], [], "-.", color="C2", lw=1.2, label="special stick-slip boundary: the slip that grazes v_drive,\n"
            "backward to the stick line (stick-slip exists iff the onset lies beyond it)")
    ax.plot([], [], "-.", color="C2", lw=0.8, alpha=0.5, label="the same orbit where, backward, it spirals into "
            "sliding\ninstead of reaching the stick line (it bounds nothing there)")


def _draw_points(ax, d):
    """Mark the bifurcation points; returns the side table's lines and ``[(v_drive, x, name, color), ...]`` of
    the drawn points (named H1, F1, ... by kind)."""
    counters = {}
    table = []
    labelled = []
    for pt in d.points:
        marker, col, prefix = _POINT_STYLE[pt["kind"]]
        counters[prefix] = counters.get(prefix, 0) + 1
        name = f"{prefix}{counters[prefix]}"
        extra = pt.get("criticality") or pt.get("mechanism") or ""
        table.append(f"{name:4s}{pt['v_drive']:.7f}  {pt['kind']}" + (f"\n{'':15s}({extra})" if extra else ""))
        y = pt.get("x_max", math.nan)
        if math.isfinite(y):
            ax.plot(pt["v_drive"], y, marker, color=col, ms=7, mfc="white", mew=1.6, zorder=5)
            labelled.append((pt["v_drive"], y, name, col))
    return table, labelled


def _label_groups(ax, points, same=4.0, clear=14.0):
    """Labels ``(v, y, text, color, offset)`` for the points ``(v, y, name, color)``.

    Points within ``same`` pixels (coincident bifurcation points, e.g. a grazing and a boundary switch)
    share one label ``"G1, B1"``. Each label takes the first of the offsets right-above, right-below,
    left-above, left-below, further above, further below whose text centre lies ``clear`` points from
    every marker and every label placed before, so none is drawn on another.
    """
    to_pixels = ax.transData.transform
    groups = []
    for v, y, name, col in points:
        here = to_pixels((v, y))
        for group in groups:
            if math.dist(here, group["at"]) < same:
                group["names"].append(name)
                break
        else:
            groups.append({"at": here, "v": v, "y": y, "names": [name], "color": col})
    scale = ax.figure.dpi / 72.0  # points to pixels
    markers = [g["at"] for g in groups]
    placed, out = [], []
    for g in groups:
        text = ", ".join(g["names"])
        width = 4.8 * len(text)  # points, at fontsize 8
        offsets = [(5, 6), (5, -14), (-width - 5, 6), (-width - 5, -14), (5, 18), (5, -26)]
        for dx, dy in offsets:
            centre = (g["at"][0] + scale * (dx + width / 2), g["at"][1] + scale * (dy + 3))
            others = [m for m in markers if m is not g["at"]] + placed
            if all(math.dist(centre, m) >= clear * scale for m in others):
                break
        placed.append(centre)
        out.append((g["v"], g["y"], text, g["color"] if len(g["names"]) == 1 else "k", (dx, dy)))
    return out


def _arc_key(branch, c):
    """Order of a point along a branch: index of the nearest continuation point (Hopf first)."""
    if c.sigma == 0.0:
        return -1.0
    best, key = math.inf, 0.0
    for k, q in enumerate(branch.points):
        dist = abs(q.v_drive - c.v_drive) + abs(q.sigma - c.sigma)
        if dist < best:
            best, key = dist, k
    if c in branch.points:
        return float(branch.points.index(c))
    # between the nearest point and its neighbour on the side it lies
    return key + 0.5 if key + 1 < len(branch.points) else key + 0.5


def plot_margin(png_path, params, result, F_ext=0.0):
    """The stick-slip existence margin over the scanned drive velocities, with the critical velocities.

    The margin is continuous where stick-slip appears or disappears; it jumps where the slip's number of
    overshoots changes (the return that decides whether the slip sticks is then another one), which is
    drawn as a break with a dotted line.
    """
    from .stickslip_cycle import stick_slip_cycles

    fig = _figure((9, 5))
    ax = fig.subplots()
    grid = np.linspace(result.v_min, result.v_max, 400)
    cycles = stick_slip_cycles(params, grid, F_ext)
    margin = np.array([c.margin if math.isfinite(c.margin) else math.copysign(1e3, c.margin) for c in cycles])
    shots = np.array([c.overshoots if c.exists else -1 for c in cycles])
    jumps = [k for k in range(1, grid.size) if shots[k] != shots[k - 1] and min(shots[k], shots[k - 1]) >= 0]
    for part, (lo, hi) in enumerate(zip([0, *jumps], [*jumps, grid.size])):
        ax.plot(grid[lo:hi], margin[lo:hi], "-", color="C3", label="existence margin E" if part == 0 else None)
    for n, k in enumerate(jumps):
        ax.axvline(0.5 * (grid[k - 1] + grid[k]), color="0.4", ls=":", lw=1.0,
                   label=None if n else "the slip's overshoot count changes: another return decides, E jumps "
                                         "(stick-slip exists on both sides)")
        ax.annotate(f"{shots[k - 1]}\u2192{shots[k]} overshoots", (grid[k], 1.0), xycoords=("data", "axes fraction"),
                    textcoords="offset points", xytext=(3, -12), fontsize=7, color="0.3")
    ax.axhline(0.0, color="0.5", lw=0.8)
    for v in result.critical:
        ax.axvline(v, color="C0", ls="--", lw=0.9)
        ax.annotate(f"v_c = {v:.6f}", (v, 0.0), textcoords="offset points", xytext=(3, -14), fontsize=8, color="C0")
    for n, (a, b) in enumerate(result.windows):
        ax.axvspan(a, b, color="C3", alpha=0.08, label=None if n else "stick-slip exists")
    ax.plot([], [], "--", color="C0", lw=0.9, label="critical velocity v_c (stick-slip disappears above)")
    ax.set(xlabel="v_drive (m/s)", ylabel="margin (m/s)", title="stick-slip exists where the margin E is > 0")
    fig.legend(loc="outside lower center", ncols=2, fontsize=8)
    fig.savefig(png_path, dpi=110)


def plot_chart(png_path, chart):
    """A 2-D stability chart: continuous-sliding stability and stick-slip existence."""
    from matplotlib.colors import ListedColormap

    from .parallel_scan import CHART_LABELS, parameter_unit

    fig = _figure((9, 5.5))
    ax = fig.subplots()
    cmap = ListedColormap(["#f4e3c1", "#9ecae1", "#fb9a99", "#b39ddb"])
    v, y = chart.v_drive, chart.values
    ax.pcolormesh(v, y, chart.code, cmap=cmap, vmin=-0.5, vmax=3.5, shading="nearest")
    for code, label in CHART_LABELS.items():
        ax.plot([], [], "s", color=cmap(code), ms=10, label=label)
    unit = parameter_unit(chart.name)
    ax.set(xlabel="v_drive (m/s)", ylabel=chart.name + (f" ({unit})" if unit else " (dimensionless)"),
           title=f"stability chart: v_drive x {chart.name}")
    fig.legend(loc="outside right upper", fontsize=8)
    fig.savefig(png_path, dpi=110)


def plot_slow_manifold(png_path, params, manifold, run=None, F_ext=0.0, v_drive=None):
    """The slow manifold ``kappa x = F_K(v_rel) + F_ext`` (stable solid, unstable dashed) with a simulated run."""
    fig = _figure((10, 6))
    ax = fig.subplots()
    u, x, st = manifold.u, manifold.x, manifold.stable
    for vs, ys, s in _segments(u, x, st):
        ax.plot(vs, ys, "-" if s else "--", color="C0", lw=2.2 if s else 1.5)
    ax.plot([], [], "-", color="C0", lw=2.2, label="slow manifold, attracting (F_K' > 0)")
    ax.plot([], [], "--", color="C0", lw=1.5, label="slow manifold, repelling (F_K' < 0)")
    for uf, xf in manifold.folds:
        ax.plot(uf, xf, "o", color="k", mfc="white", ms=6)
    if manifold.folds:
        ax.plot([], [], "o", color="k", mfc="white", label="folds (extrema of F_K)")
    fs0 = params.static.force(0.0)
    ax.plot([0.0, 0.0], [(F_ext - fs0) / params.kappa, (F_ext + fs0) / params.kappa], "-", color="C3", lw=4,
            alpha=0.5, label="stick line (v_rel = 0, contact holds)")
    if run is not None:
        t, xr, vr, mode = run
        ax.plot(vr, xr, "-", color="C1", lw=0.9, alpha=0.9, label="simulated run")
        stuck = mode == 0
        ax.plot(vr[stuck], xr[stuck], ".", color="C3", ms=2)
    ax.set(xlabel="v_rel = v_drive - v (m/s)", ylabel="x (m)",
           title="strongly overdamped limit: slow manifold and relaxation oscillations"
           + (f" (v_drive = {v_drive:g} m/s)" if v_drive is not None else ""))
    ax.set_xlim(min(-0.05 * u[-1], float(np.min(run[2])) if run is not None else 0.0), u[-1])
    fig.legend(loc="outside lower center", ncols=2, fontsize=8)
    fig.savefig(png_path, dpi=110)


def plot_map(png_path, smap, xs, ts, fps):
    """The stick-slip map ``T`` at one drive velocity with the diagonal and its fixed points."""
    fig = _figure((7, 6.5))
    ax = fig.subplots()
    ax.plot(xs, ts, "-", color="C0", lw=1.5, label="T(x)")
    ax.plot(xs, xs, "-", color="0.6", lw=0.8, label="diagonal")
    for f in fps:
        ax.plot(f.x, f.x, "o", color="C3", mfc="C3" if f.stable else "white", ms=7)
    ax.plot([], [], "o", color="C3", label="stable fixed point (stick-slip cycle)")
    ax.plot([], [], "o", color="C3", mfc="white", label="unstable fixed point")
    ax.set(xlabel="$x_n$: position before slip $n$ (m)", ylabel="$x_{n+1} = T(x_n)$ (m)",
           title=f"stick-slip map at v_drive = {smap.v_drive:g} m/s")
    fig.legend(loc="outside lower center", ncols=2, fontsize=8)
    fig.savefig(png_path, dpi=110)


def plot_fixed_points(png_path, v_grid, fps, saddles, critical):
    """Fixed points of the map against ``v_drive`` (stable filled, unstable open), saddle-nodes marked."""
    fig = _figure((9, 5.5))
    ax = fig.subplots()
    for v, f in zip(v_grid, fps):
        for p in f:
            ax.plot(v, p.x, ".", color="C3" if p.stable else "C0", ms=4 if p.stable else 3)
    ax.plot([], [], ".", color="C3", label="stable fixed point")
    ax.plot([], [], ".", color="C0", label="unstable fixed point")
    for v, x in saddles:
        ax.plot(v, x, "s", color="k", mfc="white", ms=7)
        ax.annotate(f"SN {v:.6f}", (v, x), textcoords="offset points", xytext=(5, 5), fontsize=8)
    if saddles:
        ax.plot([], [], "s", color="k", mfc="white", label="saddle-node")
    for v in critical:
        ax.axvline(v, color="C3", ls="--", lw=0.9)
    ax.set(xlabel="v_drive (m/s)", ylabel="fixed point x* (m)", title="stick-slip cycles of the aging map")
    fig.legend(loc="outside lower center", ncols=2, fontsize=8)
    fig.savefig(png_path, dpi=110)


def plot_orbit_diagram(png_path, v_grid, iterates, exponents):
    """Iterates of the map against ``v_drive`` and the Lyapunov exponent (chaos where > 0)."""
    fig = _figure((10, 7))
    ax, ax2 = fig.subplots(2, 1, sharex=True, height_ratios=(2, 1))
    for v, its in zip(v_grid, iterates):
        ax.plot(np.full(its.size, v), its, ".", color="k", ms=1.5, alpha=0.7)
    ax.set(ylabel="$x_n$ (m)", title="orbit diagram of the stick-slip map")
    ax2.plot(v_grid, exponents, "-", color="C0", lw=1)
    ax2.axhline(0.0, color="0.5", lw=0.8)
    ax2.fill_between(v_grid, 0, np.where(exponents > 0, exponents, 0), color="C3", alpha=0.3, label="chaos")
    ax2.set(xlabel="v_drive (m/s)", ylabel="Lyapunov exponent\n(per map iteration)")
    fig.legend(loc="outside lower center", ncols=2, fontsize=8)
    fig.savefig(png_path, dpi=110)
