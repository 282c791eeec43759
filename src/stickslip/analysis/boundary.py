"""The special stick-slip boundary (Elmer 1997): the slip orbit that grazes ``v = v_drive``.

In mode +1 a slip reaches ``v = v_drive`` from below only where the
acceleration is >= 0, i.e. ``kappa x <= F_K(0+) + F_ext``; the point

    x_g = (F_K(0+) + F_ext)/kappa,   v = v_drive - 0

is where an orbit touches the stick line tangentially (``dv/dt = 0`` there,
``d^2v/dt^2 = -kappa v_drive/M < 0``: a maximum of ``v``). Integrating the slip
flow backward in time from it gives the *special stick-slip boundary*; going
backward, it either

- ``"stick-line"``: meets ``v = v_drive`` again at some ``x_b`` (``kappa x_b >=
  F_K(0+) + F_ext``); the orbit from ``x_b`` to the graze point and the stick
  line between them bound a region no slip leaves, so a stick-slip cycle
  (whose slips start at the onset ``x_on``) exists iff ``x_on > x_b``, and where
  ``x_b = x_on`` the cycle meets the boundary: stick-slip appears or disappears
  (the grazing margin of :mod:`.stickslip_cycle` vanishes there);
- ``"spiral-cs"``: spirals (backward) into continuous sliding, which must then
  be unstable (forward);
- ``"spiral-cycle"``: spirals into an unstable (forward) sliding cycle;
- ``"escape"``: runs off to infinity.

Which of these happens is decided after one backward revolution. The maxima
of ``v`` along an orbit of the planar slip flow lie on one transversal section
(the branch of the isocline ``dv/dt = 0`` with ``v > 0``), so along the orbit
they form a monotone sequence; the graze point is one of them, with ``v =
v_drive``. If the next maximum backward (of the smooth flow, continued past the
stick line) lies above ``v_drive``, the sequence rises backward and the orbit
has crossed the stick line on its way there; if it lies below, the sequence
falls for ever and the orbit never reaches the stick line: it spirals. So

    b(v_drive) = (first backward maximum of v) - v_drive

is a continuous **boundary margin**: ``"stick-line"`` iff ``b >= 0``, and the
boundary switches between ending on the stick line and spiralling exactly at
the roots of ``b``, where the backward orbit closes through the graze point:
a sliding cycle that grazes ``v = v_drive`` (every grazing cycle passes through
the graze point). :func:`boundary_switches` refines them as sign changes of
``b``. What a spiral tends to (continuous sliding or an unstable cycle) is
resolved, when asked, from the successive maxima of ``x`` (their amplitude
about ``x_c`` converges geometrically; Aitken's extrapolation gives the limit:
0 for continuous sliding); an unresolved spiral is labelled ``"spiral"``.
"""

import math
from dataclasses import dataclass

import numpy as np

from . import flow
from .roots import refine, sign_changes


@dataclass
class BoundaryOrbit:
    """The backward orbit from the graze point at one drive velocity.

    ``fate`` (see the module), ``x_end`` (m): where it meets the stick line
    (``"stick-line"``), ``x_max, x_min`` (m): the range of ``x`` along it (for a
    spiral, up to its limit), ``duration`` (s, backward), ``limit`` (m): the
    amplitude about continuous sliding it spirals into.
    """

    v_drive: float
    fate: str
    x_end: float = math.nan
    x_max: float = math.nan
    x_min: float = math.nan
    duration: float = math.nan
    limit: float = math.nan
    margin: float = math.nan


def graze_point(params, F_ext=0.0):
    """Position (m) where slips touch ``v = v_drive`` tangentially: ``(F_K(0+) + F_ext)/kappa``."""
    return (params.kinetic.at_rest() + F_ext) / params.kappa


class _Spiral:
    """Policy: watch the amplitudes ``x_max - x_c`` along the backward orbit and stop once their limit is known."""

    def __init__(self, xc, scale, max_revs):
        self.xc, self.scale, self.max_revs = xc, scale, max_revs
        self.seq = {}
        self.result = {}

    def __call__(self, i, rec, ev):
        if ev[0] != "xmax":
            return False
        seq = self.seq.setdefault(i, [])
        seq.append(ev[2] - self.xc[i])
        scale = self.scale
        if len(seq) >= 3:
            d1, d2 = seq[-1] - seq[-2], seq[-2] - seq[-3]
            if abs(d1) <= 1e-10 * scale:
                self.result[i] = seq[-1]
                return True
            if d1 * d2 > 0.0 and abs(d1) < abs(d2):
                r = d1 / d2
                limit = seq[-1] + d1 * r / (1.0 - r)
                if len(seq) >= 5:
                    r_prev = (seq[-2] - seq[-3]) / (seq[-3] - seq[-4]) if seq[-3] != seq[-4] else math.inf
                    steady = abs(r - r_prev) <= 1e-3 * abs(r) + 1e-9
                    if steady and (abs(limit) <= 1e-6 * scale or abs(limit - seq[-1]) <= 1e-7 * scale):
                        self.result[i] = limit
                        return True
        if len(seq) >= self.max_revs:
            return True
        return False


def _first_revolution(params, vd, F_ext, rtol, scale, xc):
    xg = graze_point(params, F_ext)
    period0 = 2.0 * math.pi * math.sqrt(params.M / params.kappa)
    return flow.run(params, xg, vd, vd, F_ext, 1, backward=True, rtol=rtol, scale=scale, x_shift=xc,
                    stop_at_cross=False, policy=lambda i, r, e: e[0] == "vmax", t_max=20.0 * period0)


def _centres(params, vd, F_ext):
    law = params.kinetic
    return np.array([(law.force(float(v)) + F_ext) / params.kappa for v in vd])


def boundary_margin(params, v_drives, F_ext=0.0, rtol=1e-11):
    """The boundary margin ``b`` (m/s) at each drive velocity: >= 0 iff the boundary ends on the stick line."""
    vd = np.atleast_1d(np.asarray(v_drives, float))
    scale = (params.static.force(0.0) + abs(F_ext)) / params.kappa
    recs = _first_revolution(params, vd, F_ext, rtol, scale, _centres(params, vd, F_ext))
    return np.array([r.v - v if r.reason == "policy" else (math.inf if r.reason == "escape" else math.nan)
                     for v, r in zip(vd, recs)])


def special_boundary(params, v_drives, F_ext=0.0, rtol=1e-11, resolve=True, max_revs=150):
    """Classify the special stick-slip boundary at each drive velocity (> 0): a list of :class:`BoundaryOrbit`.

    ``resolve``: follow each spiral (up to ``max_revs`` revolutions) to tell
    ``"spiral-cs"`` from ``"spiral-cycle"``; otherwise spirals are ``"spiral"``.
    """
    vd = np.atleast_1d(np.asarray(v_drives, float))
    law = params.kinetic
    xg = graze_point(params, F_ext)
    xc = _centres(params, vd, F_ext)
    scale = (params.static.force(0.0) + abs(F_ext)) / params.kappa
    recs = _first_revolution(params, vd, F_ext, rtol, scale, xc)
    out = []
    spirals = []
    for i, (v, r) in enumerate(zip(vd, recs)):
        o = BoundaryOrbit(float(v), "")
        if r.reason == "escape":
            o.fate, o.margin = "escape", math.inf
        elif r.reason != "policy":
            o.fate = "undecided"
        else:
            o.margin = r.v - v
            cross = [e for e in r.events if e[0] == "cross"]
            if o.margin >= 0.0 and cross:
                _, t_b, x_b, _ = cross[0]
                xs = [x for k, t, x, _ in r.events if k in ("xmax", "xmin") and t >= t_b] + [xg, x_b]
                o.fate, o.x_end, o.duration = "stick-line", x_b, -t_b
                o.x_max, o.x_min = max(xs), min(xs)
            else:
                xs = [x for k, t, x, _ in r.events if k in ("xmax", "xmin")] + [xg]
                o.x_max, o.x_min = max(xs), min(xs)
                o.fate = "spiral-cycle" if law.slope(float(v)) > 0.0 else "spiral"
                if o.fate == "spiral":
                    spirals.append(i)
        out.append(o)
    if resolve and spirals:
        sel = np.array(spirals)
        policy = _Spiral(xc[sel], scale, max_revs)
        period0 = 2.0 * math.pi * math.sqrt(params.M / params.kappa)
        recs = flow.run(params, xg, vd[sel], vd[sel], F_ext, 1, backward=True, rtol=rtol, scale=scale,
                        x_shift=xc[sel], stop_at_cross=True, policy=policy, t_max=(max_revs + 5) * period0 * 4)
        for j, i in enumerate(spirals):
            if j in policy.result:
                limit = policy.result[j]
                out[i].limit = limit
                out[i].fate = "spiral-cs" if abs(limit) <= 1e-5 * scale else "spiral-cycle"
    return out


def boundary_switches(params, v_grid, margins=None, F_ext=0.0, tol=1e-7, rtol=1e-11):
    """Drive velocities where the boundary switches between the stick line and a spiral.

    Returns ``[(v_drive, "stick-line" or "spiral" below, ... above), ...]``, each a
    sign change of :func:`boundary_margin` on ``v_grid`` refined to ``tol``.
    """
    v_grid = np.asarray(v_grid, float)
    if margins is None:
        margins = boundary_margin(params, v_grid, F_ext, rtol)
    brackets = sign_changes(v_grid, margins)
    found = refine(lambda v: boundary_margin(params, v, F_ext, rtol), brackets, tol=tol)
    name = {True: "stick-line", False: "spiral"}
    return [(root, name[fa >= 0.0], name[fb >= 0.0]) for root, a, b, fa, fb in found]
