"""The stick-slip map of aging static friction (SPEC section 3; Elmer 1997, section 5).

With an aging ``F_S(t_stick)`` the stick-slip dynamics reduce to a map of the
breakaway position (the position just before each slip):

    x_{n+1} = T(x_n):  slip from (x_n, v_drive) until the block sticks at x_n^s
                       (overshoots included), stay stuck for the smallest t > 0
                       with |kappa (x_n^s + v_drive t) - F_ext| = F_S(t), then
                       x_{n+1} = x_n^s + v_drive t.

(for ``F_ext = 0``: ``F_S(t)/kappa = x_n^s + v_drive t`` and ``T = F_S(t)/kappa``).
The slips are integrated in batches (:func:`.stickslip_cycle.slips_to_stick`), the
stick by the core's exact breakaway search (:func:`stickslip.core.stuck.breakaway_delay`).
``T`` is undefined (NaN) where a slip never sticks again.

Fixed points are stick-slip cycles, stable iff ``|T'| < 1`` (``T'`` by central
differences). A non-convex ``F_S`` (sigmoid) lets two fixed points collide in a
saddle-node: located where the local extremum of ``g = T(x) - x`` touches 0
(a smooth function of ``v_drive``, refined by the secant method). Overshooting
slips make ``T`` non-monotonic: period doubling and chaos, seen in the orbit
diagram (iterates against ``v_drive``) and the Lyapunov exponent ``lim (1/N) sum
ln|T'(x_n)|`` (> 0: chaos).
"""

import math
from dataclasses import dataclass

import numpy as np

from ..core.stuck import breakaway_delay
from .roots import refine, sign_changes
from .stickslip_cycle import slips_to_stick

_FD = 1e-6


@dataclass(frozen=True)
class FixedPoint:
    """A fixed point of the stick-slip map: a stick-slip cycle.

    ``x`` (m): breakaway position; ``slope``: ``T'(x)``; ``stable`` iff
    ``|slope| < 1``; ``period`` (s), ``stick_time`` (s), ``x_stick`` (m);
    ``overshoots``: overshooting returns in its slip.
    """

    v_drive: float
    x: float
    slope: float
    stable: bool
    period: float
    stick_time: float
    x_stick: float
    overshoots: int
    x_max: float = math.nan
    x_min: float = math.nan


def map_values(params, x, v_drive, F_ext=0.0, rtol=1e-11):
    """``T`` at breakaway positions ``x`` (batched, ``v_drive`` per member or shared).

    Returns a dict of arrays: ``T`` (m), ``x_stick`` (m), ``slip_time``,
    ``stick_time`` (s), ``overshoots``, ``x_max, x_min`` (m, the range of the
    slip and the stick); NaN where the slip never sticks again or the stick never ends.
    """
    x, vd = np.broadcast_arrays(np.asarray(x, float), np.asarray(v_drive, float))
    x, vd = x.ravel(), vd.ravel()
    n = x.size
    out = {k: np.full(n, np.nan) for k in ("T", "x_stick", "slip_time", "stick_time", "overshoots", "x_max",
                                           "x_min")}
    ok = np.flatnonzero(np.isfinite(x))
    if ok.size == 0:
        return out
    slips = slips_to_stick(params, x[ok], vd[ok], F_ext, rtol)
    period0 = 2.0 * math.pi * math.sqrt(params.M / params.kappa)
    for i, c in zip(ok, slips):
        if not c.exists:
            continue
        horizon = 1e3 * (params.static.force(0.0) + abs(F_ext)) / (params.kappa * abs(vd[i])) + 1e3 * period0
        t = _breakaway(c.x_stick, vd[i], F_ext, params, horizon)
        if t is None:
            continue
        out["T"][i] = c.x_stick + vd[i] * t
        out["x_stick"][i] = c.x_stick
        out["slip_time"][i] = c.slip_time
        out["stick_time"][i] = t
        out["overshoots"][i] = c.overshoots
        out["x_max"][i] = max(c.x_max, out["T"][i])
        out["x_min"][i] = c.x_min
    return out


def _breakaway(x0, v, F_ext, params, horizon):
    """Stick duration from ``x0`` (core :func:`breakaway_delay`), split where the holding force changes sign.

    The core decides the slope of ``|kappa x - F_ext|`` at the start of a piece
    from the sign of the holding force there, which rounding can flip when the
    piece starts exactly at its zero (then a breakaway inside that piece can be
    missed). Starting the second piece a rounding step past the zero, on the side
    the force is heading, avoids that.
    """
    kappa = params.kappa
    L0, dL = kappa * x0 - F_ext, kappa * v
    if dL == 0.0 or L0 * dL >= 0.0:
        return breakaway_delay(x0, v, F_ext, 0.0, params, horizon)
    t_zero = -L0 / dL
    if t_zero >= horizon:
        return breakaway_delay(x0, v, F_ext, 0.0, params, horizon)
    first = breakaway_delay(x0, v, F_ext, 0.0, params, t_zero)
    if first is not None:
        return first
    x_zero = F_ext / kappa
    x_zero += math.copysign(8.0 * np.finfo(float).eps * max(abs(x_zero), abs(x0), 1e-300), v)
    rest = breakaway_delay(x_zero, v, F_ext, t_zero, params, horizon - t_zero)
    return None if rest is None else t_zero + rest


class StickSlipMap:
    """``T`` at one drive velocity: ``smap(x)`` (arrays), ``smap.slope(x)``, ``smap.domain()``."""

    def __init__(self, params, v_drive, F_ext=0.0, rtol=1e-11):
        self.params, self.v_drive, self.F_ext, self.rtol = params, float(v_drive), float(F_ext), rtol

    def __call__(self, x):
        return map_values(self.params, x, self.v_drive, self.F_ext, self.rtol)["T"]

    def values(self, x):
        return map_values(self.params, x, self.v_drive, self.F_ext, self.rtol)

    def slope(self, x):
        x = np.atleast_1d(np.asarray(x, float))
        h = _FD * np.maximum(np.abs(x), 1e-3)
        t = self(np.concatenate([x + h, x - h]))
        return (t[:x.size] - t[x.size:]) / (2 * h)

    def domain(self):
        return domain(self.params, self.v_drive, self.F_ext)


def domain(params, v_drive, F_ext=0.0):
    """Breakaway positions worth scanning: from ``F_S(0)`` to ``F_S`` after a long stick (m)."""
    s = params.static
    t_long = 10.0 * (s.force(0.0) + abs(F_ext)) / (params.kappa * abs(v_drive))
    return (s.force(0.0) + F_ext) / params.kappa, (s.force(t_long) + F_ext) / params.kappa


def fixed_points(params, v_drive, F_ext=0.0, n=120, x_range=None, rtol=1e-11, tol=1e-12):
    """Fixed points of ``T`` at one drive velocity, in increasing ``x``: a list of :class:`FixedPoint`."""
    return fixed_points_scan(params, [v_drive], F_ext, n, [x_range] if x_range else None, rtol, tol)[0]


def fixed_points_scan(params, v_grid, F_ext=0.0, n=120, x_ranges=None, rtol=1e-11, tol=1e-12):
    """Fixed points at every drive velocity of ``v_grid`` (all maps in one batch per step)."""
    v_grid = np.atleast_1d(np.asarray(v_grid, float))
    ranges = x_ranges or [domain(params, v, F_ext) for v in v_grid]
    xs = np.concatenate([np.linspace(a, b, n) for a, b in ranges])
    vs = np.repeat(v_grid, n)
    g = map_values(params, xs, vs, F_ext, rtol)["T"] - xs
    brackets = []
    for k in range(v_grid.size):
        for a, b, fa, fb in sign_changes(xs[k * n:(k + 1) * n], g[k * n:(k + 1) * n]):
            brackets.append((k, a, b, fa, fb))
    roots = _secant(params, [(b[1], b[2], b[3], b[4]) for b in brackets], vs_of=[v_grid[b[0]] for b in brackets],
                    F_ext=F_ext, rtol=rtol, tol=tol)
    out = [[] for _ in v_grid]
    if roots:
        xr = np.array(roots)
        vr = np.array([v_grid[b[0]] for b in brackets])
        h = _FD * np.maximum(np.abs(xr), 1e-3)
        vals = map_values(params, np.concatenate([xr, xr + h, xr - h]), np.concatenate([vr] * 3), F_ext, rtol)
        m = xr.size
        slope = (vals["T"][m:2 * m] - vals["T"][2 * m:]) / (2 * h)
        for j, (k, *_) in enumerate(brackets):
            scale = max(abs(xr[j]), 1e-3)
            if not np.isfinite(vals["T"][j]) or abs(vals["T"][j] - xr[j]) > 1e-7 * scale:
                continue  # a jump of T across the diagonal, not a fixed point
            out[k].append(FixedPoint(float(vr[j]), float(xr[j]), float(slope[j]), bool(abs(slope[j]) < 1.0),
                                     float(vals["slip_time"][j] + vals["stick_time"][j]),
                                     float(vals["stick_time"][j]), float(vals["x_stick"][j]),
                                     int(vals["overshoots"][j]), float(vals["x_max"][j]),
                                     float(vals["x_min"][j])))
    return out


def _secant(params, brackets, vs_of, F_ext, rtol, tol, iterations=60):
    """Roots of ``T(x) - x`` inside brackets ``(a, b, ga, gb)`` (Illinois method, all brackets batched)."""
    if not brackets:
        return []
    a = np.array([b[0] for b in brackets])
    b = np.array([b[1] for b in brackets])
    ga = np.array([b[2] for b in brackets])
    gb = np.array([b[3] for b in brackets])
    vs = np.array(vs_of)
    side = np.zeros(a.size)
    for _ in range(iterations):
        live = np.abs(b - a) > tol * np.maximum(np.abs(a), 1.0)
        if not live.any():
            break
        c = np.where(gb != ga, b - gb * (b - a) / (gb - ga), 0.5 * (a + b))
        c = np.where((c <= np.minimum(a, b)) | (c >= np.maximum(a, b)) | ~np.isfinite(c), 0.5 * (a + b), c)
        i = np.flatnonzero(live)
        gc = np.full(a.size, np.nan)
        gc[i] = map_values(params, c[i], vs[i], F_ext, rtol)["T"] - c[i]
        for j in i:
            if not np.isfinite(gc[j]):
                a[j] = b[j] = c[j]
                continue
            if (gc[j] < 0.0) == (gb[j] < 0.0):
                b[j], gb[j] = c[j], gc[j]
                if side[j] == -1:
                    ga[j] *= 0.5
                side[j] = -1
            else:
                a[j], ga[j] = c[j], gc[j]
                if side[j] == 1:
                    gb[j] *= 0.5
                side[j] = 1
            if gc[j] == 0.0:
                a[j] = b[j] = c[j]
    return list(np.where(np.abs(gb) < np.abs(ga), b, a))


# ----------------------------------------------------------------------
# saddle-nodes and critical velocities
# ----------------------------------------------------------------------


def _extremum(params, v, x_lo, x_hi, F_ext, rtol, kind, rounds=5, k=9):
    """Local extremum (``kind`` "min" or "max") of ``g = T(x) - x`` in ``[x_lo, x_hi]`` for each ``v``.

    Batched over ``v``; each round samples ``k`` points and shrinks the window
    around the best sample, then a parabola through three points gives the value.
    """
    v = np.atleast_1d(np.asarray(v, float))
    lo, hi = np.broadcast_to(x_lo, v.shape).astype(float), np.broadcast_to(x_hi, v.shape).astype(float)
    sign = 1.0 if kind == "min" else -1.0
    best_x, best_g = np.full(v.size, np.nan), np.full(v.size, np.nan)
    for _ in range(rounds):
        xs = np.linspace(lo, hi, k).T  # (n, k)
        g = (map_values(params, xs.ravel(), np.repeat(v, k), F_ext, rtol)["T"] - xs.ravel()).reshape(v.size, k)
        g = np.where(np.isfinite(g), g, sign * np.inf)
        j = np.argmin(sign * g, axis=1)
        j = np.clip(j, 1, k - 2)
        rows = np.arange(v.size)
        x0, x1, x2 = xs[rows, j - 1], xs[rows, j], xs[rows, j + 1]
        g0, g1, g2 = g[rows, j - 1], g[rows, j], g[rows, j + 1]
        denom = g0 - 2 * g1 + g2
        with np.errstate(invalid="ignore", divide="ignore"):
            shift = 0.5 * (g0 - g2) / denom * (x1 - x0)
            value = g1 - 0.25 * (g0 - g2) * shift / (x1 - x0)
        good = np.isfinite(shift) & (np.abs(shift) <= (x1 - x0)) & np.isfinite(value)
        best_x = np.where(good, x1 + shift, x1)
        best_g = np.where(good, value, g1)
        width = (x2 - x0) / 2.0
        lo, hi = best_x - width, best_x + width
    return best_x, best_g


def saddle_nodes(params, v_min, v_max, n=60, F_ext=0.0, tol=1e-8, n_x=120, rtol=1e-11, grid=None, fps=None):
    """Saddle-nodes of the map's fixed points in ``[v_min, v_max]``: ``[(v_drive, x), ...]``.

    Where the number of fixed points changes by two between neighbouring grid
    velocities, the pair is born at the extremum of ``g = T(x) - x`` that lies
    between them; that extremum's value is a smooth function of ``v_drive``
    whose root is the saddle-node (:func:`_saddle_node`). ``grid`` and ``fps``
    (from :func:`fixed_points_scan`) may be given instead of being computed.
    """
    if grid is None:
        grid = np.linspace(v_min, v_max, n)
    if fps is None:
        fps = fixed_points_scan(params, grid, F_ext, n_x, rtol=rtol)
    out = []
    for k in range(len(grid) - 1):
        if abs(len(fps[k]) - len(fps[k + 1])) == 2:
            out.extend(_saddle_node(params, (grid[k], fps[k]), (grid[k + 1], fps[k + 1]), F_ext, tol, n_x, rtol))
    return out


def _fold_extremum(params, a, b, F_ext, rtol):
    """``(e, window, kind)`` for the fixed-point pair that exists at one of the drive velocities ``a`` and ``b``
    (each ``(v_drive, fixed points)``) and not at the other: ``e(v)`` is the extremum of ``g = T(x) - x`` over
    ``window`` (m), signed so that it is negative where the pair exists; None if no such pair is found. The
    window lies between the pair's neighbouring fixed points at both velocities, so that it holds the
    extremum the pair is born from and no other fixed point's zero of ``g``."""
    many, few = (a[1], b[1]) if len(a[1]) > len(b[1]) else (b[1], a[1])
    # the colliding pair: neighbours with slopes on both sides of 1, farthest from the survivors
    pair, best = None, -1.0
    for p0, p1 in zip(many, many[1:]):
        if (p0.slope - 1.0) * (p1.slope - 1.0) < 0.0:
            dist = min((abs(0.5 * (p0.x + p1.x) - q.x) for q in few), default=math.inf)
            if dist > best:
                pair, best = (p0, p1), dist
    if pair is None:
        return None
    kind = "max" if pair[0].slope > 1.0 else "min"  # g rises then falls: a maximum between them
    width = 2.0 * (pair[1].x - pair[0].x) + 1e-6
    others = [q.x for q in few] + [q.x for q in many if q not in pair]
    below = max((x for x in others if x < pair[0].x), default=-math.inf)
    above = min((x for x in others if x > pair[1].x), default=math.inf)
    window = (max(pair[0].x - width, 0.5 * (below + pair[0].x)), min(pair[1].x + width, 0.5 * (above + pair[1].x)))

    def e(v):
        _, g = _extremum(params, v, window[0], window[1], F_ext, rtol, kind)
        return g if kind == "max" else -g

    return e, window, kind


def _saddle_node(params, a, b, F_ext, tol, n_x, rtol, halvings=12):
    """The saddle-node ``[(v_drive, x)]`` between the drive velocities of ``a`` and ``b`` (each ``(v_drive,
    fixed points)``, their counts two apart), or ``[]``. Where the extremum of :func:`_fold_extremum` does not
    change sign between them (a coarse grid), the interval is halved by fixed-point counts until it does."""
    for _ in range(halvings + 1):
        found = _fold_extremum(params, a, b, F_ext, rtol)
        if found is None:
            return []
        e, window, kind = found
        (lo, hi) = sorted((a[0], b[0]))
        ends = e(np.array([lo, hi]))
        if ends[0] * ends[1] < 0.0:
            root = refine(e, [(lo, hi, *ends)], tol=tol)[0][0]
            x, _ = _extremum(params, root, window[0], window[1], F_ext, rtol, kind)
            return [(float(root), float(x[0]))]
        middle = 0.5 * (a[0] + b[0])
        fps = fixed_points_scan(params, [middle], F_ext, n_x, rtol=rtol)[0]
        if len(fps) == len(a[1]):
            a = (middle, fps)
        elif len(fps) == len(b[1]):
            b = (middle, fps)
        else:
            return []  # a count neither side has: other bifurcations inside
    return []


def _track(params, x0, vs, F_ext, rtol, iterations=30):
    """Newton on ``T(x) = x`` from ``x0`` at each drive velocity of ``vs`` (batched): True where it converges
    to a fixed point with ``T' < 1`` (the stick-slip cycle followed from a neighbouring velocity)."""
    x = np.full(vs.size, float(x0))
    ok = np.zeros(vs.size, bool)
    live = np.ones(vs.size, bool)
    for _ in range(iterations):
        i = np.flatnonzero(live)
        if i.size == 0:
            break
        h = _FD * np.maximum(np.abs(x[i]), 1e-3)
        t = map_values(params, np.concatenate([x[i], x[i] + h, x[i] - h]), np.concatenate([vs[i]] * 3), F_ext,
                       rtol)["T"]
        m = i.size
        g = t[:m] - x[i]
        slope = (t[m:2 * m] - t[2 * m:]) / (2 * h)
        step = -g / (slope - 1.0)
        bad = ~np.isfinite(step) | (slope >= 1.0)
        live[i[bad]] = False
        good = i[~bad]
        x[good] += np.clip(step[~bad], -0.2 * np.abs(x[good]) - 1e-3, 0.2 * np.abs(x[good]) + 1e-3)
        done = np.abs(step[~bad]) <= 1e-11 * np.maximum(np.abs(x[good]), 1.0)
        ok[good[done]] = True
        live[good[done]] = False
    return ok


def has_cycle(fps):
    """Stick-slip persists: some fixed point does not repel monotonically (``T' < 1``)."""
    return any(p.slope < 1.0 for p in fps)


def critical_velocity(params, v_min=None, v_max=None, n=60, F_ext=0.0, tol=1e-7, n_x=120, rtol=1e-11):
    """Drive velocities where stick-slip (a fixed point of ``T`` with ``T' < 1``) disappears as ``v_drive`` grows.

    A disappearance through a saddle-node is refined on the extremum of ``T(x) - x``;
    one where the cycle's slip stops returning to stick is refined by k-section.
    """
    s = params.static
    natural = (s.force(0.0) + abs(F_ext)) / math.sqrt(params.kappa * params.M)
    v_min = 1e-3 * natural if v_min is None else v_min
    v_max = 3.0 * natural if v_max is None else v_max
    grid = np.linspace(v_min, v_max, n)
    fps = fixed_points_scan(params, grid, F_ext, n_x, rtol=rtol)
    return [v for v, what, _ in existence_changes(params, grid, fps, F_ext, tol, n_x, rtol) if what == "disappears"]


def existence_changes(params, grid, fps, F_ext=0.0, tol=1e-7, n_x=120, rtol=1e-11, saddles=None):
    """Where stick-slip (a fixed point with ``T' < 1``) appears or disappears between grid velocities.

    ``fps``: :func:`fixed_points_scan` on ``grid``. Returns ``[(v_drive, "appears" or
    "disappears", "saddle-node" or "domain"), ...]``: a saddle-node of the map, or
    the cycle leaving the map's domain (its slip stops sticking), refined by k-section.
    """
    from .roots import refine_labels

    if saddles is None:
        saddles = saddle_nodes(params, grid[0], grid[-1], F_ext=F_ext, tol=0.1 * tol, n_x=n_x, rtol=rtol,
                               grid=grid, fps=fps)
    labels = [has_cycle(f) for f in fps]
    out = []
    for k in range(len(grid) - 1):
        if labels[k] == labels[k + 1]:
            continue
        what = "disappears" if labels[k] else "appears"
        near = [v for v, _ in saddles if grid[k] <= v <= grid[k + 1]]
        if near:
            out.append((near[0], what, "saddle-node"))
            continue

        good = k if labels[k] else k + 1
        seeds = [f.x for f in fps[good] if f.slope < 1.0]

        def label(vv, seeds=seeds):
            vv = np.atleast_1d(vv)
            alive = np.zeros(vv.size, bool)
            for x0 in seeds:
                alive |= _track(params, x0, vv, F_ext, rtol)
            return list(alive)

        (root, *_), = refine_labels(label, [(grid[k], grid[k + 1], labels[k], labels[k + 1])], tol=tol)
        out.append((root, what, "domain"))
    return out


# ----------------------------------------------------------------------
# iterates: orbit diagram and Lyapunov exponent
# ----------------------------------------------------------------------


def map_orbit(params, v_drive, x0, n, F_ext=0.0, rtol=1e-11):
    """``[x0, T(x0), T(T(x0)), ...]`` (``n + 1`` values; NaN once the slips stop sticking)."""
    xs = [float(x0)]
    for _ in range(n):
        xs.append(float(map_values(params, [xs[-1]], v_drive, F_ext, rtol)["T"][0]))
    return np.array(xs)


def orbit_diagram(params, v_grid, F_ext=0.0, n_transient=100, n_keep=60, x0=None, rtol=1e-10, lyapunov=True):
    """Iterates of ``T`` against ``v_drive`` (all velocities iterated together) and Lyapunov exponents.

    Returns ``(iterates, exponents)``: ``iterates[i]`` holds the ``n_keep`` values
    after ``n_transient`` (NaN if the orbit left the map's domain), ``exponents[i]``
    the mean of ``ln|T'|`` over the kept iterates (NaN without ``lyapunov``).
    The orbits start at the breakaway after a first stick from the relaxed spring.
    """
    v = np.atleast_1d(np.asarray(v_grid, float))
    x = np.array([domain(params, vv, F_ext)[0] for vv in v]) if x0 is None else np.broadcast_to(x0, v.shape) * 1.0
    kept = np.full((v.size, n_keep), np.nan)
    log_sum = np.zeros(v.size)
    for it in range(n_transient + n_keep):
        measure = lyapunov and it >= n_transient
        if measure:
            h = _FD * np.maximum(np.abs(x), 1e-3)
            vals = map_values(params, np.concatenate([x, x + h, x - h]), np.concatenate([v] * 3), F_ext, rtol)["T"]
            nxt = vals[:v.size]
            slope = (vals[v.size:2 * v.size] - vals[2 * v.size:]) / (2 * h)
            log_sum += np.log(np.abs(slope) + 1e-300)
        else:
            nxt = map_values(params, x, v, F_ext, rtol)["T"]
        x = nxt
        if it >= n_transient:
            kept[:, it - n_transient] = x
    exponents = log_sum / n_keep if lyapunov else np.full(v.size, np.nan)
    exponents = np.where(np.all(np.isfinite(kept), axis=1), exponents, np.nan)
    return kept, exponents


def lyapunov_exponent(params, v_drive, F_ext=0.0, n_transient=100, n_iter=200, rtol=1e-10):
    """The map's Lyapunov exponent at ``v_drive`` (> 0: chaotic stick-slip; NaN if the orbit escapes)."""
    _, exps = orbit_diagram(params, [v_drive], F_ext, n_transient, n_iter, rtol=rtol)
    return float(exps[0])
