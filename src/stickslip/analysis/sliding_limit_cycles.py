"""Oscillatory sliding: limit cycles that never stick, by shooting and pseudo-arclength continuation.

A sliding cycle stays in mode +1 (``v < v_drive``) throughout, so it is a limit
cycle of the smooth planar slip flow of :mod:`.flow`. Planar, so a Poincare
section is one-dimensional: the section ``v = 0`` at a maximum of ``x``,
parameterized by the distance ``s = x - x_c > 0`` from continuous sliding
``x_c = (F_K(v_drive) + F_ext)/kappa``. The return map ``P(s; v_drive)`` (one
revolution of the flow, DOP853 at ``rtol`` 1e-11) has the cycles as fixed
points; the analysis works with

    G(sigma, v_drive) = (P(s) - s) / s,      sigma = omega s   (a velocity, like v_drive),

which removes the trivial root ``s = 0`` (continuous sliding): ``G(0+, v)`` is
the multiplier of CS minus one, and Hopf points are the roots of ``G(0, v)``.
A cycle is stable iff ``dG/dsigma < 0`` at its root (``P' < 1``).

:func:`cycle_at` finds a cycle by Newton on ``G`` at fixed ``v_drive``;
:func:`continue_branch` follows a branch ``G = 0`` in the plane ``(sigma,
v_drive)`` by pseudo-arclength continuation (tangent predictor, Newton corrector
on ``G = 0`` plus the arclength condition; derivatives by central differences,
all evaluations of one corrector step in one batch), so it passes through folds
(saddle-node pairs of cycles), where ``v_drive`` turns back; folds are then
refined to ``1e-9`` by fitting parabolas ``v(sigma)`` through exact points. A
branch ends where a cycle's largest velocity reaches ``v_drive`` (it grazes the
stick condition and stops being a sliding cycle: refined by the secant method
on ``v_max - v_drive`` along the branch), where it shrinks into a Hopf point,
or where it leaves the scanned range of ``v_drive``. :func:`sliding_cycles`
puts it together: branches from the Hopf points, and from every cycle a coarse
scan of ``G`` over ``(sigma, v_drive)`` finds that no branch has covered yet.
"""

import math
from dataclasses import dataclass, field

import numpy as np

from . import flow

_FD = 1e-6  # relative central-difference step
_MAX_TURN = 0.2  # largest turn of the tangent (rad) between accepted continuation points


@dataclass
class CyclePoint:
    """One sliding cycle: drive ``v_drive`` (m/s), section point ``x_max = x_c + s`` (m), period (s),
    ``x_min`` (m), ``v_min, v_max`` (m/s), ``stable``, and ``sigma = omega s`` (m/s)."""

    v_drive: float
    sigma: float
    x_max: float
    x_min: float
    v_min: float
    v_max: float
    period: float
    stable: bool
    multiplier: float = math.nan

    @property
    def grazes(self):
        return self.v_max >= self.v_drive


@dataclass
class Branch:
    """A continued branch of sliding cycles, in continuation order, with its ends and folds."""

    points: list = field(default_factory=list)
    folds: list = field(default_factory=list)  # CyclePoint at each fold
    grazings: list = field(default_factory=list)  # CyclePoint where v_max = v_drive
    ends: tuple = ("", "")  # how each end stopped: "hopf", "grazing", "range", "steps", "lost"
    hopf: object = None


class ReturnMap:
    """``G(sigma, v_drive)`` and the cycle measures for one model, evaluated in batches."""

    def __init__(self, params, F_ext=0.0, rtol=1e-11):
        self.params = params
        self.F_ext = float(F_ext)
        self.rtol = rtol
        self.omega = math.sqrt(params.kappa / params.M)
        self.n_evaluations = 0

    def centre(self, v_drive):
        law = self.params.kinetic
        return np.array([(law.force(float(v)) + self.F_ext) / self.params.kappa for v in np.atleast_1d(v_drive)])

    def evaluate(self, sigma, v_drive):
        """Batch of one revolution each: dict of arrays ``G, P, period, x_min, v_min, v_max``; NaN where the
        revolution is lost and where ``sigma <= 0`` (m/s): a revolution starts ``sigma / omega`` m right of the
        centre, an amplitude that must be positive (it also scales the integration's absolute tolerance)."""
        sigma, v_drive = np.broadcast_arrays(np.asarray(sigma, float), np.asarray(v_drive, float))
        sigma, v_drive = sigma.ravel(), v_drive.ravel()
        out = {k: np.full(sigma.size, np.nan) for k in ("G", "P", "period", "x_min", "v_min", "v_max")}
        run = np.flatnonzero(sigma > 0.0)
        if run.size == 0:
            return out
        self.n_evaluations += run.size
        s = sigma[run] / self.omega
        xc = self.centre(v_drive[run])
        recs = flow.run(self.params, xc + s, 0.0, v_drive[run], self.F_ext, 1, rtol=self.rtol, scale=s, x_shift=xc,
                        stop_at_cross=False, policy=lambda i, r, e: e[0] == "xmax",
                        t_max=4.0 * 2.0 * math.pi / self.omega)
        for j, (i, r) in enumerate(zip(run, recs)):
            if r.reason != "policy":
                continue
            P = r.x - xc[j]
            out["P"][i] = P
            out["G"][i] = (P - s[j]) / s[j]
            out["period"][i] = r.t
            out["x_min"][i] = min((x for k, t, x, v in r.events if k == "xmin"), default=np.nan)
            out["v_min"][i] = min((v for k, t, x, v in r.events if k == "vmin"), default=np.nan)
            out["v_max"][i] = max((v for k, t, x, v in r.events if k == "vmax"), default=np.nan)
        return out

    def with_gradient(self, sigma, v_drive):
        """``(values, G_sigma, G_v)`` at each point (central differences; one batch of 5 per point)."""
        sigma, v_drive = np.atleast_1d(np.asarray(sigma, float)), np.atleast_1d(np.asarray(v_drive, float))
        ds = _FD * np.maximum(sigma, 1e-3 * np.abs(v_drive))
        dv = _FD * np.maximum(np.abs(v_drive), 1e-3)
        S = np.concatenate([sigma, sigma + ds, sigma - ds, sigma, sigma])
        V = np.concatenate([v_drive, v_drive, v_drive, v_drive + dv, v_drive - dv])
        ev = self.evaluate(S, V)
        n = sigma.size
        G = ev["G"]
        values = {k: a[:n] for k, a in ev.items()}
        return values, (G[n:2 * n] - G[2 * n:3 * n]) / (2 * ds), (G[3 * n:4 * n] - G[4 * n:]) / (2 * dv)

    def point(self, sigma, v_drive, values, g_sigma):
        return CyclePoint(float(v_drive), float(sigma), float(self.centre(v_drive)[0] + sigma / self.omega),
                          float(values["x_min"]), float(values["v_min"]), float(values["v_max"]),
                          float(values["period"]), bool(g_sigma < 0.0), float(1.0 + sigma * g_sigma))


def cycle_at(rmap, sigma0, v_drive, tol=1e-12, max_iter=30):
    """Newton on ``G(., v_drive)`` from ``sigma0``: the cycle (:class:`CyclePoint`) or None."""
    sigma = float(sigma0)
    for _ in range(max_iter):
        values, gs, _ = rmap.with_gradient([sigma], [v_drive])
        g, gs = values["G"][0], gs[0]
        if not (math.isfinite(g) and math.isfinite(gs)) or gs == 0.0:
            return None
        step = -g / gs
        step = max(min(step, sigma), -0.5 * sigma)
        sigma += step
        if abs(step) <= tol * max(sigma, 1e-12):
            values, gs, _ = rmap.with_gradient([sigma], [v_drive])
            return rmap.point(sigma, v_drive, {k: a[0] for k, a in values.items()}, gs[0])
    return None


# ----------------------------------------------------------------------
# pseudo-arclength continuation (all branches advance together)
# ----------------------------------------------------------------------


class _Walker:
    """One branch direction under continuation: the point ``z = (sigma, v_drive)`` (m/s), the unit tangent
    ``t``, the arclength step ``h`` (m/s), the index of its start, how it ended (``done``, "" while it runs), its
    accepted steps and its last accepted ``(z, values, G_sigma, G_v)``."""

    def __init__(self, z, t, h, branch):
        self.z, self.t, self.h = np.array(z, float), np.array(t, float), h
        self.branch = branch
        self.done = ""
        self.steps = 0
        self.last = None


@dataclass
class _Continuation:
    """One pseudo-arclength continuation: the return map, the velocity scale (m/s), the largest step and the
    smallest ``sigma`` (m/s), the range of ``v_drive`` (m/s) and the number of steps a walker may take."""

    rmap: ReturnMap
    scale: float
    h_max: float
    sigma_min: float
    v_min: float
    v_max: float
    max_steps: int

    def correct(self, live, preds):
        """Newton corrector of every walker at once from its predicted point; for each, ``(values, G_sigma,
        G_v, z)`` at its last evaluated point (within 1e-9 of the branch), or None if it did not converge."""
        zs = [p.copy() for p in preds]
        converged = [False] * len(live)
        failed = [False] * len(live)
        info = [None] * len(live)
        for _ in range(8):
            idx = [i for i in range(len(live)) if not converged[i] and not failed[i]]
            if not idx:
                break
            vals, gs, gv = self.rmap.with_gradient([zs[i][0] for i in idx], [zs[i][1] for i in idx])
            for n, i in enumerate(idx):
                w = live[i]
                g, a, b = vals["G"][n], gs[n], gv[n]
                if not (np.isfinite(g) and np.isfinite(a) and np.isfinite(b)) or zs[i][0] <= 0.0:
                    failed[i] = True
                    continue
                J = np.array([[a, b], [w.t[0], w.t[1]]])
                r = np.array([g, w.t @ (zs[i] - preds[i])])
                try:
                    d = -np.linalg.solve(J, r)
                except np.linalg.LinAlgError:
                    failed[i] = True
                    continue
                info[i] = ({k: arr[n] for k, arr in vals.items()}, a, b, zs[i].copy())
                zs[i] = zs[i] + d
                if np.hypot(*d) <= 1e-9 * self.scale:
                    converged[i] = True
                elif np.hypot(*d) > 0.5 * w.h + 1e-12:
                    failed[i] = True
        return [found if ok else None for found, ok in zip(info, converged)]

    def advance(self, w, found):
        """Accept the corrected point ``found`` of walker ``w`` (True), or shorten its step (False); mark the
        walker done where its branch grazes, shrinks into a Hopf point, leaves the range or runs out of steps."""
        if found is None or not np.isfinite(found[0]["G"]):
            w.h *= 0.5
            if w.h < 1e-7 * self.scale:
                w.done = "lost"
            return False
        values, a, b, z = found
        t_new = np.array([-b, a])
        t_new /= np.linalg.norm(t_new)
        if t_new @ w.t < 0.0:
            t_new = -t_new
        if t_new @ w.t < math.cos(_MAX_TURN) and w.h > 1e-4 * self.scale:
            w.h *= 0.5  # the branch bends: take a shorter step
            return False
        w.z, w.t = z, t_new
        w.last = (z.copy(), values, a, b)
        w.steps += 1
        w.h = min(w.h * 1.4, self.h_max)
        if values["v_max"] >= z[1]:
            w.done = "grazing"
        elif z[0] < self.sigma_min:
            w.done = "hopf"
        elif not self.v_min <= z[1] <= self.v_max:
            w.done = "range"
        elif w.steps >= self.max_steps:
            w.done = "steps"
        return True


def continue_branches(rmap, starts, v_min, v_max, h0=None, h_max=None, max_steps=400, sigma_min=None):
    """Pseudo-arclength continuation from ``starts``: ``[(sigma, v_drive, tangent (ds, dv)), ...]``.

    Each start is followed in the direction of its tangent until the branch
    grazes (``v_max >= v_drive``), shrinks into continuous sliding (``sigma <
    sigma_min``), leaves ``[v_min, v_max]`` or runs out of steps. Returns, for each
    start, the list of accepted ``(sigma, v_drive, values, G_sigma, G_v)``.
    """
    scale = max(abs(v_max), abs(v_min), 1e-6)
    h0 = 0.01 * scale if h0 is None else h0
    cont = _Continuation(rmap, scale, 0.08 * scale if h_max is None else h_max,
                         1e-4 * scale if sigma_min is None else sigma_min, v_min, v_max, max_steps)
    walkers = []
    for k, (s, v, t) in enumerate(starts):
        t = np.array(t, float)
        walkers.append(_Walker((s, v), t / np.linalg.norm(t), h0, k))
    paths = [[] for _ in starts]
    # the starting points themselves
    vals, gs, gv = rmap.with_gradient([w.z[0] for w in walkers], [w.z[1] for w in walkers])
    for i, w in enumerate(walkers):
        w.last = (w.z.copy(), {k: a[i] for k, a in vals.items()}, gs[i], gv[i])
        paths[w.branch].append(w.last)
    while True:
        live = [w for w in walkers if not w.done]
        if not live:
            break
        for w, found in zip(live, cont.correct(live, [w.z + w.h * w.t for w in live])):
            if cont.advance(w, found):
                paths[w.branch].append(w.last)
    return paths, [w.done for w in walkers]


def _points(rmap, path):
    return [rmap.point(z[0], z[1], values, a) for z, values, a, b in path]


def _stencil(rmap, sigma, v_drive, rel=1e-4):
    """Values and derivatives from a 3x3 stencil at each point (one batch for all points).

    Returns a dict of arrays: ``G, Gs, Gv, Gss, Gsv`` and ``w, ws, wv`` for the
    grazing function ``w = v_max - v_drive``, plus the raw ``values`` at the centres.
    """
    sigma, v_drive = np.atleast_1d(np.asarray(sigma, float)), np.atleast_1d(np.asarray(v_drive, float))
    n = sigma.size
    ds = rel * np.maximum(sigma, 1e-3 * np.abs(v_drive))
    dv = rel * np.maximum(np.abs(v_drive), 1e-3)
    offsets = [(i, j) for i in (-1, 0, 1) for j in (-1, 0, 1)]
    S = np.concatenate([sigma + i * ds for i, j in offsets])
    V = np.concatenate([v_drive + j * dv for i, j in offsets])
    ev = rmap.evaluate(S, V)
    G = {o: ev["G"][k * n:(k + 1) * n] for k, o in enumerate(offsets)}
    W = {o: ev["v_max"][k * n:(k + 1) * n] - V[k * n:(k + 1) * n] for k, o in enumerate(offsets)}
    c = offsets.index((0, 0))
    return {
        "G": G[0, 0], "Gs": (G[1, 0] - G[-1, 0]) / (2 * ds), "Gv": (G[0, 1] - G[0, -1]) / (2 * dv),
        "Gss": (G[1, 0] - 2 * G[0, 0] + G[-1, 0]) / ds**2,
        "Gsv": (G[1, 1] - G[1, -1] - G[-1, 1] + G[-1, -1]) / (4 * ds * dv),
        "w": W[0, 0], "ws": (W[1, 0] - W[-1, 0]) / (2 * ds), "wv": (W[0, 1] - W[0, -1]) / (2 * dv),
        "values": {k: a[c * n:(c + 1) * n] for k, a in ev.items()},
    }


def _newton2(rmap, z0, system, iters=12, tol=1e-11):
    """Batched 2-D Newton on ``system(stencil) -> (F1, F2, J)`` from the points ``z0`` (list of (sigma, v)).

    Returns a list of CyclePoint (None where Newton failed).
    """
    z = np.array(z0, float).reshape(-1, 2)
    done = np.zeros(len(z), bool)
    ok = np.ones(len(z), bool)
    for _ in range(iters):
        act = np.flatnonzero(~done & ok)
        if act.size == 0:
            break
        st = _stencil(rmap, z[act, 0], z[act, 1])
        F1, F2, J = system(st)
        for n, i in enumerate(act):
            Jn = np.array([[J[0][0][n], J[0][1][n]], [J[1][0][n], J[1][1][n]]])
            r = np.array([F1[n], F2[n]])
            if not (np.all(np.isfinite(Jn)) and np.all(np.isfinite(r))):
                ok[i] = False
                continue
            try:
                d = -np.linalg.solve(Jn, r)
            except np.linalg.LinAlgError:
                ok[i] = False
                continue
            limit = 0.5 * max(z[i, 0], 1e-9)
            if abs(d[0]) > limit:
                d *= limit / abs(d[0])
            z[i] += d
            if abs(d[0]) <= tol * max(z[i, 0], 1e-9) and abs(d[1]) <= tol * max(abs(z[i, 1]), 1e-9):
                done[i] = True
    good = np.flatnonzero(done & ok)
    out = [None] * len(z)
    if good.size:
        vals, gs, _ = rmap.with_gradient(z[good, 0], z[good, 1])
        for n, i in enumerate(good):
            out[i] = rmap.point(z[i, 0], z[i, 1], {k: a[n] for k, a in vals.items()}, gs[n])
    return out


def refine_folds(rmap, guesses):
    """Folds (saddle-nodes of cycles) near ``guesses`` ``[(sigma, v), ...]``: ``G = 0, dG/dsigma = 0``."""
    return _newton2(rmap, guesses, lambda st: (st["G"], st["Gs"], ((st["Gs"], st["Gv"]), (st["Gss"], st["Gsv"]))))


def refine_grazings(rmap, guesses):
    """Grazing cycles near ``guesses``: ``G = 0`` and ``v_max = v_drive``."""
    return _newton2(rmap, guesses, lambda st: (st["G"], st["w"], ((st["Gs"], st["Gv"]), (st["ws"], st["wv"]))))


def scan_cycles(rmap, v_grid, n_sigma=28, sigma_max=1.2):
    """Coarse detection: roots of ``G`` along ``sigma`` at each ``v_drive`` of ``v_grid``.

    ``sigma`` runs geometrically from 1e-3 to ``sigma_max`` times ``v_drive``
    (a sliding cycle's velocity amplitude is below ``v_drive``). Returns
    ``[(sigma, v_drive, stable), ...]`` (bracket midpoints, interpolated).
    """
    v_grid = np.asarray(v_grid, float)
    frac = np.geomspace(1e-3, sigma_max, n_sigma)
    S = (frac[None, :] * v_grid[:, None]).ravel()
    V = np.repeat(v_grid, n_sigma)
    G = rmap.evaluate(S, V)["G"].reshape(v_grid.size, n_sigma)
    found = []
    for j, v in enumerate(v_grid):
        g = G[j]
        for i in range(n_sigma - 1):
            if np.isfinite(g[i]) and np.isfinite(g[i + 1]) and (g[i] < 0.0) != (g[i + 1] < 0.0):
                s0, s1 = frac[i] * v, frac[i + 1] * v
                s = s0 - g[i] * (s1 - s0) / (g[i + 1] - g[i])
                found.append((s, v, g[i] > 0.0))
    return found, G


def sliding_cycles(params, v_min, v_max, F_ext=0.0, hopf=None, n_scan=40, rtol=1e-11, max_steps=300):
    """Every branch of sliding cycles met in ``[v_min, v_max]``: a list of :class:`Branch`.

    Branches start at the Hopf points (``hopf``: from :func:`.steady_sliding.hopf_points`
    by default; the first point from the normal form's amplitude) and at cycles
    of a coarse scan that no branch has covered. Affine laws have none.
    """
    from .steady_sliding import hopf_points

    if params.kinetic.affine() is not None:
        return []  # a linear slip flow (damped, undamped or anti-damped) has no isolated limit cycles
    rmap = ReturnMap(params, F_ext, rtol)
    if hopf is None:
        hopf = hopf_points(params, v_min, v_max, F_ext)
    starts, origins = _hopf_starts(rmap, hopf)
    branches = []  # (Branch, path)
    if starts:
        paths, ends = continue_branches(rmap, starts, v_min, v_max, max_steps=max_steps)
        for path, end, h in zip(paths, ends, origins):
            b = Branch(_points(rmap, path), ends=("hopf", end), hopf=h)
            branches.append((b, path))
    _add_unreached_branches(rmap, branches, v_min, v_max, n_scan, max_steps)
    _refine_folds_and_grazings(rmap, branches)
    return [b for b, _ in branches]


def _hopf_starts(rmap, hopf):
    """Continuation starts ``(sigma, v_drive, tangent)`` on the cycles next to the Hopf points, and the points."""
    kinetic = rmap.params.kinetic
    starts, origins = [], []
    for h in hopf:
        if h.side == 0:
            continue
        dv = 1e-3 * max(abs(h.v_drive), 1e-3)
        v = h.v_drive + h.side * dv
        amp = h.amplitude(v, slope=kinetic.slope(v))
        if not math.isfinite(amp):
            continue
        c = cycle_at(rmap, amp * h.omega, v)
        if c is None:
            continue
        starts.append((c.sigma, c.v_drive, (c.sigma, 2.0 * (c.v_drive - h.v_drive))))
        origins.append(h)
    return starts, origins


def _add_unreached_branches(rmap, branches, v_min, v_max, n_scan, max_steps):
    """Continue both ways from cycles of a coarse scan that no branch of ``branches`` covers (up to 6 more)."""
    found, _ = scan_cycles(rmap, np.linspace(v_min, v_max, n_scan))
    found = [f for f in found if f[0] < 1.05 * f[1]]  # velocity amplitude above v_drive: grazed long ago
    for _ in range(6):
        seeds = [f for f in found if not _covered(f, branches)]
        if not seeds:
            break
        s, v, _ = seeds[0]
        c = cycle_at(rmap, s, v)
        if c is None or c.grazes or _covered((c.sigma, c.v_drive, None), branches):
            found.remove(seeds[0])
            continue
        vals, gs, gv = rmap.with_gradient([c.sigma], [c.v_drive])
        t = np.array([-gv[0], gs[0]])
        paths, ends = continue_branches(rmap, [(c.sigma, c.v_drive, t), (c.sigma, c.v_drive, -t)], v_min, v_max,
                                        max_steps=max_steps)
        path = paths[1][::-1] + paths[0][1:]
        b = Branch(_points(rmap, path), ends=(ends[1], ends[0]))
        branches.append((b, path))


def _refine_folds_and_grazings(rmap, branches):
    """Locate the folds (``dG/dsigma`` changes sign) and grazings (``v_max - v_drive`` does) along each path."""
    fold_guess, graze_guess = [], []
    for k, (b, path) in enumerate(branches):
        for j in range(1, len(path)):
            (z0, v0, a0, _), (z1, v1, a1, _) = path[j - 1], path[j]
            if a0 * a1 < 0.0:  # dG/dsigma changes sign: the tangent turned back in v_drive
                fold_guess.append((k, 0.5 * (z0 + z1)))
            if (v0["v_max"] - z0[1] < 0.0) != (v1["v_max"] - z1[1] < 0.0):
                graze_guess.append((k, 0.5 * (z0 + z1)))
    for guesses, refine, attr in ((fold_guess, refine_folds, "folds"), (graze_guess, refine_grazings, "grazings")):
        if guesses:
            for (k, _), pt in zip(guesses, refine(rmap, [z for _, z in guesses])):
                if pt is not None:
                    getattr(branches[k][0], attr).append(pt)


def _covered(found, branches, rel=0.05):
    s, v, _ = found
    for b, path in branches:
        for z, *_ in path:
            if abs(z[1] - v) <= 0.03 * max(abs(v), 1e-9) and abs(z[0] - s) <= rel * max(s, 1e-9) + 0.02 * abs(v):
                return True
        pts = np.array([z for z, *_ in path])
        if len(pts) >= 2:
            # between consecutive points of a branch
            for (s0, v0), (s1, v1) in zip(pts[:-1], pts[1:]):
                if min(v0, v1) - 1e-12 <= v <= max(v0, v1) + 1e-12:
                    lam = 0.5 if v1 == v0 else (v - v0) / (v1 - v0)
                    if abs(s0 + lam * (s1 - s0) - s) <= rel * max(s, 1e-9) + 0.02 * abs(v):
                        return True
    return False
