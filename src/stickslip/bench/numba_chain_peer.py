"""The chain benchmark's peer: an event-driven chain integrator written with numba as a physicist would, from
SPEC sections 1, 2 and 5 alone (it imports nothing of the package's engine or runtime).

All ``2N`` states ``[x_1..x_N, v_1..v_N]`` (m, m/s) step together with Dormand-Prince 5(4) and error control
(``atol`` = ``rtol`` times each block's scales ``F_S(0)/kappa`` and ``F_S(0)/sqrt(kappa M)``); a stuck block has
``x' = v_drive``, ``v' = 0``. After each accepted step every block's indicator is scanned on the step's cubic
Hermite interpolant (at the cubic's turning points too, so a graze inside the step is seen): slipping in mode
``m``, ``m (v_drive - v)`` (its zero is a stick or an overshoot); stuck, ``F_S(t_stick) - |kappa x - F_ext|``
(its zero is a breakaway). The earliest zero is refined with true steps (DP5 re-stepped from the step's start,
secant inside a bisection bracket) and the block's mode changes there. While every block sticks the chain moves
with the surface, each ``F_ext`` is constant and the next breakaway is solved directly (a closed form for constant
static friction, a bracketed scalar root for aging). Output on a grid from DP5's own continuous extension.

Kinetic laws 1-5, static laws 1-4 (SPEC section 2) as codes with parameter rows (:func:`chain_arrays`); below
``u = 0`` (a stage past a crossing) ``F_K`` continues along its tangent at 0.
"""

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

#: kinetic law code: its parameters (FMU names, without "kinetic.") in the order of the law's row
KINETIC_PARAMETERS = {1: ("F0",), 2: ("F0", "gamma"), 3: ("F0", "F_stribeck", "v_stribeck", "delta", "gamma"),
                      4: ("gamma1", "gamma2", "v_tilde", "dv"), 5: ("F0", "sigma", "alpha")}
#: static law code: its parameters (without "static.")
STATIC_PARAMETERS = {1: ("F0",), 2: ("F0", "A", "tau"), 3: ("F0", "F_inf", "tau"), 4: ("F0", "F_inf", "tau", "n")}
#: event kinds in :attr:`PeerRun.kind`
KINDS = ("slip", "stick", "overshoot")
STUCK = 0
_EPS = 2.220446049250313e-16
_SAFETY, _MIN_FACTOR, _MAX_FACTOR = 0.9, 0.2, 10.0
_MAX_REFINE = 80
_STATIC_SAMPLES = 64  # samples of a non-concave (sigmoid) F_S in a stick's breakaway search

# Dormand-Prince 5(4) tableau, FSAL, and its 4th-order continuous extension (Hairer, Norsett, Wanner; Shampine)
_C = np.array([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0])
_A = np.array([[0, 0, 0, 0, 0, 0], [1 / 5, 0, 0, 0, 0, 0], [3 / 40, 9 / 40, 0, 0, 0, 0],
               [44 / 45, -56 / 15, 32 / 9, 0, 0, 0],
               [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0, 0],
               [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0],
               [35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84]])
_E = np.array([71 / 57600, 0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40])
_P = np.array([[1.0, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
               [0.0, 0.0, 0.0, 0.0],
               [0.0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
               [0.0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
               [0.0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632],
               [0.0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
               [0.0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423]])


@dataclass(frozen=True)
class PeerChain:
    """A chain as flat arrays (block ``i`` 0-based): ``M`` (kg), ``kappa`` (N/m), ``kinetic_law`` / ``static_law``
    (codes), ``kinetic`` (N, 5) / ``static`` (N, 4) parameter rows (:data:`KINETIC_PARAMETERS`,
    :data:`STATIC_PARAMETERS`), ``x0`` (m), ``v0`` (m/s), ``coupling`` (N - 1, N/m), ``v_drive`` (m/s)."""

    M: np.ndarray
    kappa: np.ndarray
    kinetic_law: np.ndarray
    kinetic: np.ndarray
    static_law: np.ndarray
    static: np.ndarray
    x0: np.ndarray
    v0: np.ndarray
    coupling: np.ndarray
    v_drive: float


@dataclass(frozen=True)
class PeerRun:
    """One peer run: ``x`` (m, shape ``(len(t), N)``) on the grid ``t`` (s); the block events in time order
    (``event_t`` s, ``event_block`` 0-based, ``event_kind`` an index of :data:`KINDS`); accepted and rejected DP5
    steps and the true steps spent refining events."""

    t: np.ndarray
    x: np.ndarray
    event_t: np.ndarray
    event_block: np.ndarray
    event_kind: np.ndarray
    steps: int
    rejected: int
    refine_steps: int


def chain_arrays(blocks, coupling, v_drive):
    """A :class:`PeerChain` from block dictionaries by FMU names (``M``, ``kappa``, ``"kinetic.law"``,
    ``"kinetic.F0"``, ..., ``x_start``, ``v_start``), e.g. a system file's ``System.blocks``; a law's parameters
    missing from a block are an error naming the block."""
    n = len(blocks)
    kinetic, static = np.zeros((n, 5)), np.zeros((n, 4))
    for i, b in enumerate(blocks):
        for row, kind, table in ((kinetic, "kinetic", KINETIC_PARAMETERS), (static, "static", STATIC_PARAMETERS)):
            code = int(b[f"{kind}.law"])
            if code not in table:
                raise ValueError(f"block b{i + 1}: {kind}.law = {code}; the peer knows the codes {sorted(table)}")
            for j, name in enumerate(table[code]):
                if f"{kind}.{name}" not in b:
                    raise ValueError(f"block b{i + 1}: {kind}.{name} is missing ({kind} law {code})")
                row[i, j] = float(b[f"{kind}.{name}"])

    def column(name, kind=float):
        return np.array([b[name] for b in blocks], kind)

    return PeerChain(column("M"), column("kappa"), column("kinetic.law", np.int64), kinetic,
                     column("static.law", np.int64), static, column("x_start"), column("v_start"),
                     np.asarray(coupling, float).reshape(-1), float(v_drive))


def run_peer(chain, t_out, rtol):
    """Integrate ``chain`` (:class:`PeerChain`) from ``t_out[0]`` to ``t_out[-1]`` (s) at ``rtol``; a
    :class:`PeerRun` with the positions on ``t_out``."""
    t_out = np.ascontiguousarray(t_out, float)
    if not (rtol > 0.0 and rtol < 1.0):
        raise ValueError(f"rtol = {rtol!r}: allowed is 0 < rtol < 1")
    if chain.coupling.size != chain.M.size - 1:
        raise ValueError(f"coupling: {chain.coupling.size} springs for {chain.M.size} blocks; allowed is N - 1")
    x = np.empty((t_out.size, chain.M.size))
    events, counts = _integrate(chain.M, chain.kappa, chain.kinetic_law, chain.kinetic, chain.static_law,
                                chain.static, chain.coupling, chain.v_drive, chain.x0, chain.v0, t_out, rtol, x)
    n = counts[0]
    return PeerRun(t_out, x, events[0][:n], events[1][:n].astype(np.int64), events[2][:n].astype(np.int64),
                   int(counts[1]), int(counts[2]), int(counts[3]))


# ----------------------------------------------------------------- laws (SPEC section 2)


@njit(cache=True)
def _kinetic_at(law, p, u):
    """``F_K(u)`` (N) of law ``law`` with parameters ``p`` for ``u >= 0``."""
    if law == 1:
        return p[0]
    if law == 2:
        return p[0] + p[1] * u
    if law == 3:
        return p[0] + p[1] * math.exp(-((u / p[2]) ** p[3])) + p[4] * u
    if law == 4:
        d = u - p[2]
        return 0.5 * u * (p[0] + p[1] + (p[1] - p[0]) * d / math.sqrt(p[3] * p[3] + d * d))
    return p[0] * (1.0 - p[1]) / (1.0 + 2.0 * p[2] * u / (1.0 - p[1]))


@njit(cache=True)
def _kinetic_slope0(law, p):
    """``dF_K/du`` (N s/m) at ``u = 0+``."""
    if law == 2:
        return p[1]
    if law == 3:
        return p[4] - (p[1] / p[2] if p[3] == 1.0 else 0.0)
    if law == 4:
        return 0.5 * (p[0] + p[1] - (p[1] - p[0]) * p[2] / math.sqrt(p[3] * p[3] + p[2] * p[2]))
    if law == 5:
        return -2.0 * p[0] * p[2]
    return 0.0


@njit(cache=True)
def _kinetic(law, p, u):
    """``F_K(u)`` (N), continued along its tangent at 0 for ``u < 0``."""
    if u >= 0.0:
        return _kinetic_at(law, p, u)
    return _kinetic_at(law, p, 0.0) + _kinetic_slope0(law, p) * u


@njit(cache=True)
def _static(law, q, t):
    """``F_S(t)`` (N) after sticking ``t >= 0`` s."""
    if law == 1:
        return q[0]
    if law == 2:
        return q[0] + q[1] * math.log1p(t / q[2])
    if law == 3:
        return q[0] + (q[1] - q[0]) * (1.0 - math.exp(-t / q[2]))
    s = (t / q[2]) ** q[3]
    return q[0] + (q[1] - q[0]) * s / (1.0 + s)


# ----------------------------------------------------------------- right-hand side and one DP5 step


@njit(cache=True)
def _forces(x, kc, out):
    """Coupling forces ``F_ext`` (N) at the positions ``x`` (m) into ``out``; with velocities, their rates."""
    out[:] = 0.0
    for i in range(kc.size):
        pull = kc[i] * (x[i + 1] - x[i])
        out[i] += pull
        out[i + 1] -= pull


@njit(cache=True)
def _rhs(y, modes, ch, force, out):
    """``dy/dt`` of ``y = [x, v]`` into ``out``; ``ch``: the chain's arrays ``(M, kappa, kinetic_law, kinetic,
    static_law, static, coupling, v_drive)``; ``force``: workspace of N."""
    M, kappa, klaw, kp, kc, vd = ch[0], ch[1], ch[2], ch[3], ch[6], ch[7]
    n = M.size
    _forces(y[:n], kc, force)
    for i in range(n):
        m = modes[i]
        if m == STUCK:
            out[i], out[n + i] = vd, 0.0
        else:
            out[i] = y[n + i]
            out[n + i] = (force[i] - kappa[i] * y[i] + m * _kinetic(klaw[i], kp[i], m * (vd - y[n + i]))) / M[i]


@njit(cache=True)
def _step(y, f0, h, modes, ch, K, stage, force, y1):
    """One DP5 step of ``h`` s from ``y`` (with ``f0 = dy/dt``): the 5th-order state into ``y1``, stages into
    ``K`` (``K[6]`` = ``dy/dt`` at ``y1``)."""
    K[0, :] = f0
    for s in range(1, 7):
        stage[:] = y
        for j in range(s):
            if _A[s, j] != 0.0:
                stage += (h * _A[s, j]) * K[j]
        _rhs(stage, modes, ch, force, K[s])
    y1[:] = stage


@njit(cache=True)
def _error_norm(y, y1, K, h, rtol, atol):
    """The largest over all states of the embedded error estimate over its tolerance
    ``atol + rtol max(|y|, |y1|)`` (the largest, not the RMS: one slipping block among many stuck ones is held to
    its tolerance whatever N is)."""
    worst = 0.0
    for k in range(y.size):
        e = 0.0
        for s in range(7):
            e += _E[s] * K[s, k]
        scale = atol[k] + rtol * max(abs(y[k]), abs(y1[k]))
        worst = max(worst, abs(h * e) / scale)
    return worst


@njit(cache=True)
def _dense(y, K, h, theta, out, count):
    """The first ``count`` states at ``theta`` in [0, 1] of the step (DP5's continuous extension) into ``out``."""
    b = np.zeros(7)
    for s in range(7):
        b[s] = theta * (_P[s, 0] + theta * (_P[s, 1] + theta * (_P[s, 2] + theta * _P[s, 3])))
    for k in range(count):
        acc = 0.0
        for s in range(7):
            acc += b[s] * K[s, k]
        out[k] = y[k] + h * acc


# ----------------------------------------------------------------- indicators on the step's cubic Hermite


@njit(cache=True)
def _cubic(y0, y1, d0, d1, h, c):
    """Power coefficients in ``theta`` of the Hermite cubic through ``y0, y1`` with slopes ``d0, d1`` (per s)."""
    c[0], c[1] = y0, h * d0
    c[2] = 3.0 * (y1 - y0) - 2.0 * h * d0 - h * d1
    c[3] = 2.0 * (y0 - y1) + h * d0 + h * d1


@njit(cache=True)
def _poly(c, theta):
    return c[0] + theta * (c[1] + theta * (c[2] + theta * c[3]))


@njit(cache=True)
def _samples(c, extra, out):
    """Sorted sample points in (0, 1] of a cubic ``c``: its turning points inside, ``extra`` uniform points, 1;
    returns their count."""
    count = 0
    a, b, cc = 3.0 * c[3], 2.0 * c[2], c[1]
    if a != 0.0:
        disc = b * b - 4.0 * a * cc
        if disc >= 0.0:
            r = math.sqrt(disc)
            for root in ((-b - r) / (2.0 * a), (-b + r) / (2.0 * a)):
                if 0.0 < root < 1.0:
                    out[count] = root
                    count += 1
    elif b != 0.0 and 0.0 < -cc / b < 1.0:
        out[count] = -cc / b
        count += 1
    for k in range(1, extra + 1):
        out[count] = k / (extra + 1.0)
        count += 1
    out[count] = 1.0
    count += 1
    out[:count].sort()
    return count


@njit(cache=True)
def _indicator_cubic(i, modes, y0, y1, f0, f1, h, kappa, kc, vd, c, work):
    """Block ``i``'s indicator on the step as a cubic in ``theta`` (into ``c``; ``work``: workspace (2, 4)):
    ``m (v_drive - v)`` (m/s) slipping in mode ``m``; stuck, its holding force
    ``kappa x_i - F_ext_i = (kappa + kc_(i-1) + kc_i) x_i - kc_(i-1) x_(i-1) - kc_i x_(i+1)`` (N)."""
    n = kappa.size
    if modes[i] != STUCK:
        m = modes[i]
        _cubic(m * (vd - y0[n + i]), m * (vd - y1[n + i]), -m * f0[n + i], -m * f1[n + i], h, c)
        return
    own, other = work[0], work[1]
    _cubic(y0[i], y1[i], f0[i], f1[i], h, own)
    for a in range(4):
        c[a] = kappa[i] * own[a]
    for j, k in ((i - 1, i - 1), (i + 1, i)):
        if 0 <= j < n:
            _cubic(y0[j], y1[j], f0[j], f1[j], h, other)
            for a in range(4):
                c[a] += kc[k] * (own[a] - other[a])


@njit(cache=True)
def _on_cubic(stuck, c, slaw, q, tau, h, theta):
    """The indicator at ``theta`` from its cubic ``c``: itself slipping; stuck, ``F_S(tau + theta h) - |c|``."""
    value = _poly(c, theta)
    return _static(slaw, q, tau + theta * h) - abs(value) if stuck else value


@njit(cache=True)
def _hermite_zero(i, modes, t_stuck, t0, y0, y1, f0, f1, h, ch, c, work, points):
    """The first ``theta`` in (0, 1] where block ``i``'s indicator falls to 0 or below on the step's cubic Hermite
    (bisection on the cubic between the samples that bracket it), or -1 if it stays above."""
    kappa, slaw, sp, kc, vd = ch[1], ch[4], ch[5], ch[6], ch[7]
    _indicator_cubic(i, modes, y0, y1, f0, f1, h, kappa, kc, vd, c, work)
    stuck = modes[i] == STUCK
    tau = t0 - t_stuck[i] if stuck else 0.0
    extra = 0 if not stuck or slaw[i] == 1 else (_STATIC_SAMPLES // 8 if slaw[i] == 4 else 4)
    count = _samples(c, extra, points)
    lo = 0.0
    for k in range(count):
        hi = points[k]
        if _on_cubic(stuck, c, slaw[i], sp[i], tau, h, hi) <= 0.0:
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                if mid <= lo or mid >= hi:
                    break
                if _on_cubic(stuck, c, slaw[i], sp[i], tau, h, mid) <= 0.0:
                    hi = mid
                else:
                    lo = mid
            return hi
        lo = hi
    return -1.0


@njit(cache=True)
def _true_indicator(i, modes, t_stuck, t, y, ch):
    """Block ``i``'s indicator at time ``t`` (s) from the state ``y``: ``m (v_drive - v)`` slipping, stuck
    ``F_S(t - t_stuck) - |kappa x - F_ext|``."""
    kappa, slaw, sp, kc, vd = ch[1], ch[4], ch[5], ch[6], ch[7]
    if modes[i] != STUCK:
        return modes[i] * (vd - y[kappa.size + i])
    return _static(slaw[i], sp[i], t - t_stuck[i]) - abs(_hold(i, y, kappa, kc))


@njit(cache=True)
def _hold(i, y, kappa, kc):
    """The force (N) needed to hold block ``i`` at the state ``y``: ``kappa x_i - F_ext_i``."""
    n = kappa.size
    hold = kappa[i] * y[i]
    if i > 0:
        hold += kc[i - 1] * (y[i] - y[i - 1])
    if i < n - 1:
        hold += kc[i] * (y[i] - y[i + 1])
    return hold


# ----------------------------------------------------------------- events: refined with true steps


@njit(cache=True)
def _refine(i, theta, modes, t_stuck, t0, y0, f0, y1, h, ch, ws, y_event):
    """The event of block ``i`` near ``theta`` (its zero on the cubic) located with true DP5 steps from the step's
    start (secant inside a bisection bracket, Illinois): the fraction of the step at the event (its state into
    ``y_event``; the indicator at or below 0 there), or -1 where the true indicator stays above 0 (a dip of the
    cubic alone); also the true steps spent."""
    K2, stage, force, trial = ws
    lo, g_lo, hi, g_hi = 0.0, _true_indicator(i, modes, t_stuck, t0, y0, ch), 1.0, 0.0
    _step(y0, f0, theta * h, modes, ch, K2, stage, force, trial)
    g = _true_indicator(i, modes, t_stuck, t0 + theta * h, trial, ch)
    spent = 1
    if g <= 0.0:
        hi, g_hi = theta, g
        y_event[:] = trial
    else:
        lo, g_lo = theta, g
        g_hi = _true_indicator(i, modes, t_stuck, t0 + h, y1, ch)
        if g_hi > 0.0:
            return -1.0, spent
        y_event[:] = y1
    side = 0
    while (hi - lo) * h > 2.0 * _EPS * (abs(t0) + h) and g_hi < 0.0 and spent < _MAX_REFINE:
        mid = 0.5 * (lo + hi)
        theta = lo + g_lo * (hi - lo) / (g_lo - g_hi) if g_lo > 0.0 else mid
        if not lo < theta < hi:
            theta = mid
        _step(y0, f0, theta * h, modes, ch, K2, stage, force, trial)
        g = _true_indicator(i, modes, t_stuck, t0 + theta * h, trial, ch)
        spent += 1
        if g <= 0.0:
            hi, g_hi = theta, g
            y_event[:] = trial
            g_lo = g_lo * 0.5 if side == -1 else g_lo
            side = -1
        else:
            lo, g_lo = theta, g
            g_hi = g_hi * 0.5 if side == 1 else g_hi
            side = 1
    return hi, spent


@njit(cache=True)
def _first_event(t0, y0, f0, y1, K, h, modes, t_stuck, ch, ws, scan, y_event, counts):
    """``(block, theta)`` of the step's first event (its state into ``y_event``), or ``(-1, 1.0)``: each block's
    zero on the cubic Hermite, the earliest refined with true steps (the next one where that was a dip of the cubic
    alone)."""
    c, work, points, found = scan
    n = ch[0].size
    for i in range(n):
        found[i] = _hermite_zero(i, modes, t_stuck, t0, y0, y1, f0, K[6], h, ch, c, work, points)
    while True:
        block, best = -1, 2.0
        for i in range(n):
            if 0.0 <= found[i] < best:
                block, best = i, found[i]
        if block < 0:
            return -1, 1.0
        theta, spent = _refine(block, best, modes, t_stuck, t0, y0, f0, y1, h, ch, ws, y_event)
        counts[3] += spent
        if theta >= 0.0:
            return block, theta
        found[block] = -1.0


@njit(cache=True)
def _apply_event(i, t, y, modes, t_stuck, ch):
    """Block ``i``'s mode change at time ``t`` (s) with ``v_rel = 0``: the index of its kind in :data:`KINDS`."""
    kappa, slaw, sp, kc, vd = ch[1], ch[4], ch[5], ch[6], ch[7]
    hold = _hold(i, y, kappa, kc)
    y[kappa.size + i] = vd
    if modes[i] == STUCK:
        modes[i] = 1 if hold > 0.0 else -1
        t_stuck[i] = math.nan
        return 0
    if abs(hold) <= _static(slaw[i], sp[i], 0.0):
        modes[i], t_stuck[i] = STUCK, t
        return 1
    modes[i] = -modes[i]
    return 2


# ----------------------------------------------------------------- every block stuck: the next breakaway directly


@njit(cache=True)
def _break_time(law, q, tau, hold, rate, s_max):
    """Time (s) until ``|hold + rate s|`` exceeds ``F_S(tau + s)`` (N, N/s, s); inf beyond ``s_max``. Constant
    ``F_S``: the closed form; aging: ``F_S - |hold + rate s|`` is concave for laws 2 and 3 (one sign change in
    ``[0, s_max]``), sampled for the sigmoid; the zero by bisection to rounding."""
    if law == 1:
        if rate == 0.0:
            return math.inf
        s = ((q[0] if rate > 0.0 else -q[0]) - hold) / rate
        return max(s, 0.0) if s <= s_max else math.inf
    count = 1 if law != 4 else _STATIC_SAMPLES
    lo = 0.0
    for k in range(1, count + 1):
        hi = s_max * k / count
        if _static(law, q, tau + hi) - abs(hold + rate * hi) <= 0.0:
            if _static(law, q, tau) - abs(hold) <= 0.0:
                return 0.0
            for _ in range(200):
                mid = 0.5 * (lo + hi)
                if mid <= lo or mid >= hi:
                    break
                if _static(law, q, tau + mid) - abs(hold + rate * mid) <= 0.0:
                    hi = mid
                else:
                    lo = mid
            return hi
        lo = hi
    return math.inf


@njit(cache=True)
def _next_breakaway(t, y, t_stuck, ch, s_max):
    """``(s, block)``: the first breakaway of a chain whose blocks all stick, ``s`` s after ``t`` (inf, -1: none
    before ``t + s_max``). The chain moves with the surface, so every ``F_ext`` stays as it is."""
    kappa, slaw, sp, kc, vd = ch[1], ch[4], ch[5], ch[6], ch[7]
    best, block = math.inf, -1
    for i in range(kappa.size):
        s = _break_time(slaw[i], sp[i], t - t_stuck[i], _hold(i, y, kappa, kc), kappa[i] * vd, s_max)
        if s < best:
            best, block = s, i
    return best, block


# ----------------------------------------------------------------- the run


@njit(cache=True)
def _start(ch, x0, v0, rtol):
    """``(y, modes, t_stuck, atol, h_max)`` at the start (time 0 of ``t_stuck``): a block is stuck where
    ``v0 = v_drive`` and ``F_S(0)`` holds it; ``h_max`` an eighth of the shortest free period (Gershgorin)."""
    M, kappa, slaw, sp, kc, vd = ch[0], ch[1], ch[4], ch[5], ch[6], ch[7]
    n = M.size
    y = np.concatenate((x0, v0))
    modes, t_stuck, atol = np.empty(n, np.int64), np.full(n, math.nan), np.empty(2 * n)
    w2 = 0.0
    for i in range(n):
        hold = _hold(i, y, kappa, kc)
        if v0[i] != vd:
            modes[i] = 1 if v0[i] < vd else -1
        elif abs(hold) <= _static(slaw[i], sp[i], 0.0):
            modes[i], t_stuck[i] = STUCK, 0.0
        else:
            modes[i] = 1 if hold > 0.0 else -1
        length = sp[i, 0] / kappa[i]
        atol[i], atol[n + i] = rtol * length, rtol * length * math.sqrt(kappa[i] / M[i])
        side = (kc[i - 1] if i > 0 else 0.0) + (kc[i] if i < n - 1 else 0.0)
        w2 = max(w2, (kappa[i] + 2.0 * side) / M[i])
    return y, modes, t_stuck, atol, 2.0 * math.pi / math.sqrt(w2) / 8.0


@njit(cache=True)
def _write_linear(t_out, k, t0, t1, y, vd, xout):
    """Grid rows ``t0 < t_out[k..] <= t1`` of a chain moving with the surface from ``y`` at ``t0``; next ``k``."""
    n = xout.shape[1]
    while k < t_out.size and t_out[k] <= t1:
        for i in range(n):
            xout[k, i] = y[i] + vd * (t_out[k] - t0)
        k += 1
    return k


@njit(cache=True)
def _write_dense(t_out, k, t0, t1, y, K, h, xout):
    """Grid rows ``t0 < t_out[k..] <= t1`` from the step of ``h`` s from ``y`` at ``t0`` (stages ``K``); next
    ``k``."""
    while k < t_out.size and t_out[k] <= t1:
        _dense(y, K, h, (t_out[k] - t0) / h, xout[k], xout.shape[1])
        k += 1
    return k


@njit(cache=True)
def _record(events, count, t, block, kind):
    """Append an event row ``(t, block, kind)``, doubling the array when full; the array."""
    if count == events.shape[0]:
        bigger = np.empty((2 * count, 3))
        bigger[:count] = events
        events = bigger
    events[count, 0], events[count, 1], events[count, 2] = t, block, kind
    return events


@njit(cache=True)
def _stuck_phase(t, t_end, y, t_stuck, ch, t_out, k, xout):
    """Every block stuck: move with the surface to the first breakaway (or ``t_end``); ``(t, k, block)``, block
    -1 where none came."""
    s, block = _next_breakaway(t, y, t_stuck, ch, t_end - t)
    t1 = t_end if block < 0 else t + s
    k = _write_linear(t_out, k, t, t1, y, ch[7], xout)
    for i in range(ch[0].size):
        y[i] += ch[7] * (t1 - t)
    return t1, k, block


@njit(cache=True)
def _integrate(M, kappa, klaw, kp, slaw, sp, kc, vd, x0, v0, t_out, rtol, xout):
    """The run from ``t_out[0]`` to ``t_out[-1]``: positions into ``xout``; ``(events (n, 3), counts)`` with
    ``counts`` = events, accepted steps, rejected steps, refining steps."""
    ch = (M, kappa, klaw, kp, slaw, sp, kc, vd)
    n = M.size
    y, modes, t_stuck, atol, h_max = _start(ch, x0 - 0.0, v0 - 0.0, rtol)
    t_stuck += t_out[0]
    K, y1, f0, y_event = np.empty((7, 2 * n)), np.empty(2 * n), np.empty(2 * n), np.empty(2 * n)
    ws = (np.empty((7, 2 * n)), np.empty(2 * n), np.empty(n), np.empty(2 * n))
    scan = (np.empty(4), np.empty((2, 4)), np.empty(_STATIC_SAMPLES // 8 + 4), np.empty(n))
    events, counts = np.empty((64, 3)), np.zeros(4, np.int64)
    t, t_end, k, h, fresh, rejected = t_out[0], t_out[-1], 1, h_max / 8.0, True, False
    xout[0, :] = x0
    while t < t_end:
        block, t_event = -1, t
        if np.all(modes == STUCK):
            t, k, block = _stuck_phase(t, t_end, y, t_stuck, ch, t_out, k, xout)
        else:
            if fresh:
                _rhs(y, modes, ch, ws[2], f0)
            last = h >= t_end - t
            h = t_end - t if last else h
            _step(y, f0, h, modes, ch, K, ws[1], ws[2], y1)
            err = _error_norm(y, y1, K, h, rtol, atol)
            factor = _MAX_FACTOR if err == 0.0 else min(_MAX_FACTOR, max(_MIN_FACTOR, _SAFETY * err ** -0.2))
            if err > 1.0:
                h *= min(factor, 1.0)
                counts[2] += 1
                fresh, rejected = False, True
                continue
            factor = min(factor, 1.0) if rejected else factor
            counts[1] += 1
            block, theta = _first_event(t, y, f0, y1, K, h, modes, t_stuck, ch, ws, scan, y_event, counts)
            t1 = t_end if last and block < 0 else t + theta * h
            k = _write_dense(t_out, k, t, t1, y, K, h, xout)
            y[:] = y_event if block >= 0 else y1
            f0[:] = K[6]
            t, h, fresh, rejected = t1, min(h * factor, h_max), block >= 0, False
        if block >= 0:
            events = _record(events, counts[0], t, block, _apply_event(block, t, y, modes, t_stuck, ch))
            counts[0] += 1
            fresh = True
    return (events[:counts[0], 0].copy(), events[:counts[0], 1].copy(), events[:counts[0], 2].copy()), counts
