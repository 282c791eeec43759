"""The ``adaptive`` master: FMI 2 co-simulation blocks kept exact in a chain by event landing, step rejection
and a coupling of higher order than holding.

One co-simulation instance of ``SpringBlockFriction.fmu`` per block (FMPy, :mod:`stickslip.hosts.fmpy_host`).
A communication step ``[t, T]`` is cut into cells; every block's FMU state at ``t`` is saved
(``fmi2GetFMUstate``) and the step is iterated (Jacobi waveform relaxation): each block steps its cells with
``F_ext`` taken from the neighbours' positions of the previous sweep (iteration 0: extrapolated), interpolated
by cubic Hermite polynomials through ``x`` and ``v`` at the cell ends (a sweep's forces, their lines and residuals
are one linear map of those, :func:`force_map`); the states are restored
(``fmi2SetFMUstate``) before every new sweep, until the cell-end positions change by less than a hundredth of
the step's tolerance. The first sweep's waveforms are cubic (each slipping block's ``d2v/dt2`` from its output
derivative, stuck blocks moving with the surface), and a block whose forces changed so little since it was last
stepped in the attempt that its cell ends could not move by a tenth of the convergence floor is not stepped (nor
restored) again. A slipping block steps each cell in one ``doStep`` under a straight line of force, ``F_ext``
set at the cell's start with its rate (FMI 2: ``fmi2SetRealInputDerivatives``; FMI 3: the input ``der(F_ext)``),
the line carrying the interpolated force's impulse and first moment over the cell (the block's end state is then
exact to ``omega^2 delta^4`` for a cell of length ``delta``, third order in all). A
block stuck at ``t``, whose motion ``F_ext`` does not change, is stepped over the whole step in one ``doStep`` with
the force at ``t`` held in the first sweep only (its cell ends on the line between its ends); if its FMU had an
event, it is stepped again cell by cell with the force at each cell's start (a block is restored only if it was
stepped). Where such a block's force is steady (every force it would be stepped with within ``STEADY_FORCE`` of its
force scale of the force it holds, as between stuck neighbours), it is stepped ahead instead: one ``doStep`` from
``t`` to ``AHEAD_STEPS`` longest steps on (at least to ``T``), its state at ``t`` kept. While its force stays steady
and its step ahead shows no event before an attempt's end, it is neither stepped nor restored nor saved: its cell
ends, ``F_spring`` and ``z_slip`` are read off the lines between its step's ends (it moves with the surface); an
attempt that ends past its line steps it on in one more ``doStep``; when its force moves, or an event of its step
(its breakaway under the held force: FMI 3's early return, FMI 2's ``n_events``) comes before the attempt's end, it is
brought back: its state restored and stepped to ``t`` under the force it held, then stepped as any block stuck at
``t``. An FMI 2 step ahead that passed the breakaway is redone from the saved state to ``EVENT_TOL`` before the
breakaway's time it showed (``t_last_event``), where FMI 3's early return leaves the block: its line ends there, and
no later step ahead goes on through the slip after the breakaway again.
Each block's ``solver.rtol`` (its own integration tolerance) is lowered to ``BLOCK_RTOL_FACTOR`` times ``rtol``:
a block slipping with a numeric law restarts its integration at every ``doStep``.

Step control: the leading error term of each cell (the force's residual against the line, weighted by
``(T - s)^2``, times ``omega^2 + (dF_friction/dv / M)^2`` from the block's own outputs) summed over the step
must stay below ``rtol`` times the chain's length scale (largest ``F_S/kappa``) per second; else the step is
redone shorter. Events: when a block's ``n_events`` moves within a step, or a block stuck at ``t`` ends it with
its true ``z_slip`` (with the coupling force at the step's end) below zero, the step is redone to end just past
the event, located by the Illinois method on the block's indicator (the true ``z_slip`` stuck, ``mode * z_stick``
slipping; past a block's own event: minus the time since it, scaled by the indicator's rate; a redo that shows
another block's event first brackets that one) until the event lies within ``EVENT_TOL`` s before the step's end
(after ``MAX_REDOS`` tries the last one is kept and counted). A redo after a block's own event ends half
``EVENT_TOL`` past its time; the first two redos of a stuck block's breakaway end just before and just after the
zero of its true ``z_slip`` along the attempt's cubic Hermite waveforms (its FMU's ``z_slip`` taken on the line
between ``t`` and ``T``), and the step after a breakaway landed so ends just past it (the block breaks away at
its start): most events land in one or two redos. A step never ends just before an event: a slipping
block whose ``v_rel`` has crossed zero by less than its FMU's event location would start the next step on the
wrong side (a spurious overshoot). Every communication point of the output grid is one.

With ``fmi=3`` the blocks are instances of the FMI 3 FMU made with ``earlyReturnAllowed``: a block's ``doStep``
that returns early at an event more than ``EVENT_TOL`` before the step's end (after the first sweep) stops the
attempt, which is redone to end on that event. The rest of the scheme is the same for both.
"""

import dataclasses
import functools
import math
import time
from ctypes import byref, c_bool, c_double, c_int, c_uint, c_void_p

import numpy as np

from ..core.rootfind import brent
from ..fmu.variables import RATE_INPUT
from ..hosts.fmpy_host import WARNING, FmuCallError, FMUError, log_mark
from ..hosts.interrupts import check as check_interrupts
from .master import ACCESSORS, SystemResult, block_instances, checked_rtol, read_values, references, step_events

DEFAULT_RTOL = 3e-10  # keeps the 2- and 3-block chains' event times within 1e-8 s (1e-9: 4e-8 s)
EVENT_TOL = 1e-10  # s: an event this close before a step's end has landed on it
CELLS = 4  # cells per communication step while a block slips (1 while all are stuck)
STEPS_PER_PERIOD = 8  # longest step: this fraction of the shortest free period
MAX_SWEEPS = 12
MAX_REDOS = 60
AHEAD_STEPS = 8  # a block stuck under a steady force is stepped ahead by this many longest steps
STEADY_FORCE = 1e-13  # of a block's force scale (kappa times the chain's length scale): a force this close is steady
BLOCK_RTOL_FACTOR = 1e-4  # each block's solver.rtol: at most this times the master's rtol (and >= 1e-14)
_GAUSS_U, _GAUSS_W = (np.array([0.5 - math.sqrt(0.15), 0.5, 0.5 + math.sqrt(0.15)]), np.array([5, 8, 5]) / 18.0)
_GAUSS_W1, _GAUSS_W2 = _GAUSS_W * (1.0 - _GAUSS_U), _GAUSS_W * (1.0 - _GAUSS_U) ** 2  # of the moments about the end
_READ_CELL = ("x", "v", "F_friction", "F_spring")
_READ_END = ("z_slip", "z_stick", "t_last_event")
_READ_INT = ("mode", "n_events")


class AdaptiveMaster:
    """Tolerance ``rtol`` (default ``DEFAULT_RTOL``): the estimated error per second of simulated time, as a
    fraction of the chain's length scale (largest ``F_S / kappa`` of its blocks). ``fmi``: the FMU it runs, 2
    (default) or 3 (with early return; see the module text)."""

    NAME = "adaptive"
    FMI_VERSION = 2
    OPTIONS = ("rtol", "fmi")

    def __init__(self, rtol=None, fmi=None):
        self.rtol = checked_rtol("adaptive", rtol, default=DEFAULT_RTOL, lowest=1e-14)
        if fmi not in (None, 2, 3):
            raise FMUError(f"adaptive: fmi = {fmi!r}: allowed are 2 and 3")
        self.FMI_VERSION = fmi or AdaptiveMaster.FMI_VERSION  # the FMU this instance runs

    def run(self, system, fmu_path, progress=lambda t: None):
        system = block_tolerances(system, self.rtol)
        early_return = self.FMI_VERSION == 3
        flags = {"early_return_allowed": True} if early_return else {}
        try:
            with block_instances(self, system, fmu_path, **flags) as (fmu, instances):
                return _Run(system, _Blocks(fmu, instances, early_return), self.rtol, progress).run()
        except FmuCallError as exc:
            raise FMUError(f"adaptive: {own_tolerance_advice(str(exc), self.rtol)}") from None


def own_tolerance_advice(message, rtol):
    """A block's error ``message`` with the FMU's advice to lower ``solver.rtol``, a value this master sets (to at
    most ``BLOCK_RTOL_FACTOR`` times its ``rtol``), turned into advice on the master's own ``rtol``."""
    cap = max(1e-14, BLOCK_RTOL_FACTOR * rtol)
    return message.replace("lower solver.rtol", f"the adaptive master sets each block's solver.rtol to at most {cap:g} "
                           f"({BLOCK_RTOL_FACTOR:g} times its rtol, at least 1e-14): lower its rtol (--rtol)")


def block_tolerances(system, rtol):
    """``system`` with each block's ``solver.rtol`` (its FMU's own integration tolerance) at most
    ``BLOCK_RTOL_FACTOR * rtol``: a block slipping with a numeric law is cut into many short ``doStep`` calls,
    each starting its Runge-Kutta integration anew, and its errors at the FMU's default 1e-10 add up to more
    than the coupling's."""
    cap = max(1e-14, BLOCK_RTOL_FACTOR * rtol)
    blocks = tuple({**b, "solver.rtol": min(b["solver.rtol"], cap)} for b in system.blocks)
    return dataclasses.replace(system, blocks=blocks)


def cell_times(t, T, cells):
    """The ends of ``cells`` equal cells from ``t`` to ``T`` (s), as ``np.linspace(t, T, cells + 1)`` gives them
    (``t + k (T - t) / cells``, the last ``T``), as floats."""
    step = (T - t) / cells
    return [t + k * step for k in range(cells)] + [T]


def hermite_basis(u):
    """The cubic Hermite basis at ``u`` in [0, 1]: the weights of ``x0``, ``delta v0``, ``x1`` and ``delta v1``."""
    u2, u3 = u * u, u * u * u
    return 2 * u3 - 3 * u2 + 1, u3 - 2 * u2 + u, 3 * u2 - 2 * u3, u3 - u2


# the weights, at a cell's Gauss points, of the force F there in the line that carries F's impulse and first moment
# about the cell's end: its value at the cell's start and end, its rate times the cell's length, and the residual
# int (F - line) (T_cell - s)^2 ds over the cell's length cubed (the Gauss rule of the cubic (T_cell - s)^2 F minus
# the line's, exact for the line: no cancellation)
_LINE_START, _LINE_END = 6.0 * _GAUSS_W1 - 2.0 * _GAUSS_W, 4.0 * _GAUSS_W - 6.0 * _GAUSS_W1
_LINE_RATE, _LINE_RESIDUAL = 6.0 * _GAUSS_W - 12.0 * _GAUSS_W1, _GAUSS_W * (_GAUSS_U ** 2 - _GAUSS_U + 1.0 / 6.0)


@functools.lru_cache(maxsize=None)
def force_map(cells):
    """``P`` with ``F = K [X | delta V] P`` (``X``, ``V``: the positions and velocities at the ``cells + 1`` cell ends
    of ``cells`` equal cells of length ``delta``, one row per block) the forces of a sweep, before scaling by
    ``delta`` (:func:`force_columns`): the columns of ``F`` are the groups (``cells`` columns each, one per cell, but
    for the single columns) the line's start (N), its end, the force at ``T`` (one column); a stuck block's force at
    each cell's start twice, at ``T`` (one); the line's rate times ``delta`` (N), the residual over ``delta^3``. The
    positions inside a cell are its cubic Hermite interpolant through ``x`` and ``v`` at its ends."""
    c = cells
    P = np.zeros((2 * (c + 1), 6 * c + 2))
    basis = np.array(hermite_basis(_GAUSS_U))  # (4, Gauss points)
    for first, weights in ((0, _LINE_START), (c, _LINE_END), (4 * c + 2, _LINE_RATE), (5 * c + 2, _LINE_RESIDUAL)):
        h00, h10, h01, h11 = basis @ weights
        for k in range(c):
            P[(k, c + 1 + k, k + 1, c + 2 + k), first + k] = h00, h10, h01, h11
    for k in range(c):
        P[k, (2 * c + 1 + k, 3 * c + 1 + k)] = 1.0
    P[c, (2 * c, 4 * c + 1)] = 1.0
    P.flags.writeable = False
    return P


@functools.lru_cache(maxsize=None)
def _scale_kinds(cells):
    """Which scale of :func:`force_columns` each row (0: ``x``, 1: ``v``) and column (0: 1, 1: ``1 / delta``, 2:
    ``delta^3``) of :func:`force_map` takes."""
    return np.repeat([0, 1], cells + 1), np.repeat([0, 1, 2], [4 * cells + 2, cells, cells])


def force_columns(cells, delta):
    """``(P, rows)``: :func:`force_map` scaled for cells of length ``delta`` (s), ``F = K [X | V] P``, and the scale
    of each row (1 for ``x``, ``delta`` for ``v``: ``[X | V] * rows`` is in m)."""
    row_kinds, column_kinds = _scale_kinds(cells)
    rows = np.array([1.0, delta])[row_kinds]
    return force_map(cells) * rows[:, None] * np.array([1.0, 1.0 / delta, delta ** 3])[column_kinds], rows


def true_margin(z_slip, kx, held, force):
    """A stuck block's ``z_slip`` (N) with the coupling force ``force`` (N) in place of the force ``held`` (N) its FMU
    computed it with, ``kx`` (N) its spring's force ``kappa x``: the static margin's ``|kx - F_ext|`` taken anew
    (scalars or arrays alike)."""
    return z_slip + abs(kx - held) - abs(kx - force)


def coupling_matrix(system):
    """``K`` (N/m) with ``F_ext = K x`` (SPEC section 5)."""
    n = system.n
    K = np.zeros((n, n))
    for i, kc in enumerate(system.coupling):
        K[i, i] -= kc
        K[i + 1, i + 1] -= kc
        K[i, i + 1] += kc
        K[i + 1, i] += kc
    return K


class _CellCalls:
    """One instance's C functions of a cell (FMI 2 or, ``fmi3``, 3), called without FMPy's wrappers:
    ``set_reals``, ``set_rates`` (FMI 2's input derivatives), ``do_step``, ``get_reals``, ``get_ints``,
    ``get_derivatives`` (of outputs); and of its saved state: :meth:`get_state`, :meth:`set_state`,
    :meth:`free_state`."""

    NAMES = {False: ("fmi2SetReal", "fmi2SetRealInputDerivatives", "fmi2DoStep", "fmi2GetReal", "fmi2GetInteger",
                     "fmi2GetRealOutputDerivatives"),
             True: ("fmi3SetFloat64", None, "fmi3DoStep", "fmi3GetFloat64", "fmi3GetInt32",
                    "fmi3GetOutputDerivatives")}
    STATE_NAMES = {False: ("fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate"),
                   True: ("fmi3GetFMUState", "fmi3SetFMUState", "fmi3FreeFMUState")}

    def __init__(self, instance, fmi3):
        self.instance, self.component = instance, instance.fmu.component
        self.set_reals, self.set_rates, self.do_step, self.get_reals, self.get_ints, self.get_derivatives = (
            name and instance.function(name) for name in self.NAMES[fmi3])
        self.state_names = self.STATE_NAMES[fmi3]
        self._get_state, self._set_state, self._free_state = (instance.function(n) for n in self.state_names)

    def get_state(self):
        """The FMU's state now (a new FMU state: free it with :meth:`free_state`)."""
        state, first = c_void_p(), log_mark()
        self.check(self._get_state(self.component, byref(state)), self.state_names[0], first)
        return state

    def set_state(self, state):
        """The FMU back to ``state`` (from :meth:`get_state`)."""
        first = log_mark()
        self.check(self._set_state(self.component, state), self.state_names[1], first)

    def free_state(self, state):
        """Free ``state`` (from :meth:`get_state`)."""
        first = log_mark()
        self.check(self._free_state(self.component, byref(state)), self.state_names[2], first)

    def check(self, status, function, first):
        """Raise the instance's :meth:`~stickslip.hosts.fmpy_host.Instance.failure` if the call ``function`` (its
        name), made after the log mark ``first``, returned ``status`` above Warning."""
        if status > WARNING:
            raise self.instance.failure(function, status, first)


class _Blocks:
    """The instances: their saved states, inputs, steps and outputs. A block is restored only if it was stepped
    since its state was saved or last restored. ``early_return``: FMI 3 instances made with ``earlyReturnAllowed``
    (their ``doStep`` stops at the first event inside it)."""

    def __init__(self, fmu, instances, early_return=False):
        self.instances, self.early_return = instances, early_return
        self.get_real = ACCESSORS[fmu.fmi_version][0]
        self.cell_refs, self.end_refs = references(fmu, _READ_CELL), references(fmu, _READ_END)
        self.int_refs = references(fmu, _READ_INT)
        if fmu.fmi_version == 3 and RATE_INPUT not in fmu.variables:
            raise FMUError(f"adaptive: the FMI 3 FMU {fmu.path} has no input {RATE_INPUT}: it was built by an "
                           f"older stickslip; rebuild it (stickslip build)")
        self.fmi3 = fmu.fmi_version == 3
        # the arrays of the calls in a cell (set the force and its rate, doStep, read the cell's end), made once
        forces = ("F_ext", RATE_INPUT) if self.fmi3 else ("F_ext",)
        self._force_refs = (c_uint * len(forces))(*references(fmu, forces))
        self._forces, self._rate, self._order = (c_double * 2)(), (c_double * 1)(), (c_int * 1)(1)
        reals = self.cell_refs + self.end_refs
        self._real_refs, self._reals = (c_uint * len(reals))(*reals), (c_double * len(reals))()
        self._int_refs, self._ints = (c_uint * 2)(*self.int_refs), (c_int * 2)()
        self._early, self._last_time = c_bool(), c_double()  # fmi3DoStep's earlyReturn, lastSuccessfulTime
        self._step_answers = (byref(c_bool()), byref(c_bool()), byref(self._early), byref(self._last_time))
        self._calls = [_CellCalls(instance, self.fmi3) for instance in instances]
        self._v_ref = (c_uint * 1)(*references(fmu, ("v",)))
        self._order2, self._jerk = (c_int * 1)(2), (c_double * 1)()  # jerk(): v's second derivative
        self.ends = [None] * len(instances)  # each block's end outputs (see end()) where its last step ended
        self.states = [None] * len(instances)
        self.moved = [False] * len(instances)  # stepped since the save or the last restore
        self.do_steps = self.restores = self.early_returns = 0
        self.stepped = None  # (x, v, F_friction, F_spring) where the last step ended

    def save(self, skip):
        """Save the FMU state of each block that ``skip`` (a bool per block) does not mark (the previous state freed)."""
        check_interrupts()
        for i in (~skip).nonzero()[0].tolist():
            self.save_block(i)
        check_interrupts()

    def save_block(self, i):
        """Save block ``i``'s FMU state (the previous one freed): it is now where it is restored to."""
        calls = self._calls[i]
        if self.states[i] is not None:
            calls.free_state(self.states[i])
        self.states[i] = calls.get_state()
        self.moved[i] = False

    def restore(self, i):
        """Block ``i`` back to its saved state (no call if it is there)."""
        if self.moved[i]:
            check_interrupts()
            self._calls[i].set_state(self.states[i])
            check_interrupts()
            self.moved[i] = False
            self.restores += 1

    def free(self):
        for calls, state in zip(self._calls, self.states):
            if state is not None:
                calls.free_state(state)
        self.states = [None] * len(self.instances)

    def step(self, i, t, h, force=None, rate=0.0, last=True):
        """Block ``i`` from ``t`` over ``h`` s with ``F_ext = force + rate (s - t)`` (N, N/s; ``force`` None: the
        force goes on as it was set): None, or the time (s) of the event inside the step where it returned early
        (its state there the event's left limit; the next step starts there). :attr:`stepped` is then
        ``(x, v, F_friction, F_spring)`` where the step ended; the outputs of :meth:`end` are read only if ``last``
        (the block's last step in the attempt, as planned). A Ctrl-C is looked for after the calls (as after every
        FMI call: none can have come unseen before them)."""
        early = self._set_step_read(self._calls[i], t, h, force, rate, last)
        check_interrupts()
        self.moved[i] = True
        self.do_steps += 1
        self.stepped = self._reals[:len(_READ_CELL)]
        self.ends[i] = (*self._reals[len(_READ_CELL):], *self._ints) if last else None
        if early:
            self.early_returns += 1
            return self._last_time.value
        return None

    def _set_step_read(self, calls, t, h, force, rate, last):
        """The FMI calls of :meth:`step` on the FMU's C functions (``calls``, a :class:`_CellCalls`) and arrays made
        once: the force and its rate set (FMI 2: setting ``F_ext`` sets its rate to 0; FMI 3: the input
        ``der(F_ext)``), ``doStep``, the outputs of the cell's end and, if ``last``, of :meth:`end` read. True if the
        step returned early (FMI 3 with early return)."""
        c, n, first, check = calls.component, len(self._reals) if last else len(_READ_CELL), log_mark(), calls.check
        if force is not None:
            self._forces[0], self._forces[1] = force, rate
            if self.fmi3:
                check(calls.set_reals(c, self._force_refs, 2, self._forces, 2), "fmi3SetFloat64", first)
            else:
                check(calls.set_reals(c, self._force_refs, 1, self._forces), "fmi2SetReal", first)
                if rate != 0.0:
                    self._rate[0] = rate
                    check(calls.set_rates(c, self._force_refs, 1, self._order, self._rate),
                          "fmi2SetRealInputDerivatives", first)
        if self.fmi3:
            check(calls.do_step(c, t, h, False, *self._step_answers), "fmi3DoStep", first)
            check(calls.get_reals(c, self._real_refs, n, self._reals, n), "fmi3GetFloat64", first)
            if last:
                check(calls.get_ints(c, self._int_refs, 2, self._ints, 2), "fmi3GetInt32", first)
            return self.early_return and self._early.value
        check(calls.do_step(c, t, h, False), "fmi2DoStep", first)
        check(calls.get_reals(c, self._real_refs, n, self._reals), "fmi2GetReal", first)
        if last:
            check(calls.get_ints(c, self._int_refs, 2, self._ints), "fmi2GetInteger", first)
        return False

    def cell(self, i):
        """``(x, v, F_friction, F_spring)`` of block ``i``."""
        b = self.instances[i]
        return b.call(getattr(b.fmu, self.get_real), self.cell_refs)

    def jerk(self, i):
        """Block ``i``'s ``d2v/dt2`` (m/s^3) now, with its force going on as set (``fmi2GetRealOutputDerivatives``,
        ``fmi3GetOutputDerivatives``)."""
        calls, first = self._calls[i], log_mark()
        check_interrupts()
        if self.fmi3:
            status = calls.get_derivatives(calls.component, self._v_ref, 1, self._order2, self._jerk, 1)
        else:
            status = calls.get_derivatives(calls.component, self._v_ref, 1, self._order2, self._jerk)
        calls.check(status, calls.NAMES[self.fmi3][5], first)
        check_interrupts()
        return self._jerk[0]

    def n_events(self, i):
        """Block ``i``'s ``n_events`` where its last step ended."""
        return self.ends[i][4]

    def end(self):
        """``(z_slip, z_stick, t_last_event, mode, n_events)`` of every block, each an array over blocks: read where
        each block's last step ended (a block is restored only to be stepped again), or now before any step or where
        a block's last step was not planned as its last (an attempt stopped at an event)."""
        if None in self.ends:
            return [np.array(column) for column in read_values(self.instances, self.end_refs, self.int_refs)]
        reals, ints = len(_READ_END), len(_READ_INT)
        return [*np.array([end[:reals] for end in self.ends]).T, *np.array([end[reals:] for end in self.ends]).T]


class _Attempt:
    """One communication step ``[t, T]`` tried: the cell times, each block's ``x``, ``v`` (arrays ``(N, cells + 1)``,
    views of ``XV``, both side by side) and ``F_friction`` at the cell ends, the end outputs, the error estimate (m)
    and the sweeps it took."""

    def __init__(self, times, X, V, cuttable):
        self.times, self.cells = times, times.size - 1
        self.XV = np.concatenate([X, V], axis=1)
        self.X, self.V = self.XV[:, :self.cells + 1], self.XV[:, self.cells + 1:]
        self.T = float(times[-1])
        self.cell_times = times.tolist()  # s, as floats for the calls
        self.delta = self.cell_times[1] - self.cell_times[0]  # s: each cell's length
        # the sweep's forces (_Run._forces), and the scale of a sweep's change of x and v (to m)
        self.force_columns, self.change_scale = force_columns(self.cells, self.delta)
        self.hold_share = (times[1:] - times[0]) / (self.T - times[0])  # each cell end's share of the step
        self.cuttable = cuttable  # an early return more than EVENT_TOL before T (after the first sweep) stops it
        self.friction = np.zeros_like(X)
        # N: F_spring at T; each block's F_ext at the end of its last cell (N) and its rate there (N/s); the z_slip
        # at T of the blocks stepped ahead (their FMUs' line)
        self.spring, self.held, self.held_rate, self.ahead_z_slip = np.zeros((4, X.shape[0]))
        self.error, self.sweeps, self.converged = 0.0, 0, False
        self.end = None
        self.margin = None  # N: the true z_slip at T (_Run._held_margin), once the end outputs are read
        self.cut = None  # (t_e, block): the first event a block's early return showed inside the step
        # N: the forces each block was last stepped with in this attempt (NaN: not stepped)
        self.forces = np.full((X.shape[0], 2 * (times.size - 1)), np.nan)


class _Ahead:
    """The blocks stepped ahead, arrays over all blocks (``on``: those stepped ahead). Such a block, stuck at ``t0``,
    was stepped to ``t1`` (s) under ``force`` (N) held, without an event before ``until`` (s): its FMU is left at
    ``t1``, its state saved at ``t0`` kept. ``lines`` (``(blocks, 3, 2)``): its ``x``, ``F_spring`` and ``z_slip``
    (m, N, N) at ``t0`` and at ``t1``; ``v`` (m/s) and ``friction`` (N) at ``t1``; ``end``: :meth:`_Blocks.end`'s
    outputs at ``t0`` (a column each; they keep their values while it sticks without an event). In between it moves
    on the line between its ends (with the surface)."""

    def __init__(self, n):
        self.on = np.zeros(n, bool)
        self.t0, self.t1, self.until, self.force, self.v, self.friction = (np.zeros(n) for _ in range(6))
        self.lines = np.zeros((n, 3, 2))
        self.end = np.zeros((n, len(_READ_END) + len(_READ_INT)))

    def begin(self, i, t0, force, start, end):
        """Block ``i`` stepped ahead from ``t0`` (s) under ``force`` (N), ``start`` its ``(x, F_spring, z_slip)`` and
        ``end`` its :meth:`_Blocks.end` outputs at ``t0`` (its line's end is set next)."""
        self.on[i], self.t0[i], self.force[i], self.lines[i, :, 0], self.end[i] = True, t0, force, start, end


class _Run:
    """One co-simulation: the blocks, the current communication point, the samples and the events."""

    def __init__(self, system, blocks, rtol, progress):
        self.system, self.blocks, self.progress = system, blocks, progress
        self.K = coupling_matrix(system)
        self.M = np.array([b["M"] for b in system.blocks])
        self.kappa = np.array([b["kappa"] for b in system.blocks])
        self.omega2 = self.kappa / self.M
        self.tol = rtol * system.length_scale  # m per s
        self.h_slip = system.shortest_period() / STEPS_PER_PERIOD
        self.grid = system.times()
        self.t_end = float(self.grid[-1])
        self.ahead_length = AHEAD_STEPS * self.h_slip
        # N, per block: how far a stuck block's force may move from the one it holds and still be steady (its margin
        # moves by as much)
        self.steady_force = STEADY_FORCE * self.omega2 * self.M * system.length_scale
        self.ahead = _Ahead(system.n)
        self.t = 0.0
        first = np.array([blocks.cell(i) for i in range(system.n)])
        self.x, self.v, self.spring = first[:, 0], first[:, 1], first[:, 3]
        self.a = (first[:, 3] + first[:, 2] + self.K @ self.x) / self.M
        self.end = blocks.end()
        self.jerk = self._jerk(np.zeros(system.n))
        self.margin = self.end[0]  # N: each block's true z_slip at t (F_ext set from the positions there)
        self.rows = [(self.x.copy(), self.v.copy(), self.end[3].copy())]
        self.events, self.complete = [], True
        self.h = self.h_slip / 4.0
        self.breaking = None  # the block whose breakaway the last step was landed on (its margin's zero)
        self.stats = {"communication steps": 0, "rejected steps": 0, "event redos": 0, "events not landed": 0,
                      "sweeps": 0, "sweeps of a block skipped": 0, "stuck blocks stepped ahead": 0,
                      "holds of a block stepped ahead": 0, "blocks brought back from ahead": 0}

    def run(self):
        start = time.perf_counter()
        try:
            while self.t < self.t_end:
                self._advance()
        finally:
            self.blocks.free()
        xs, vs, modes = (np.array(column) for column in zip(*self.rows))
        self.stats["doStep calls"] = self.blocks.do_steps
        self.stats["state restores"] = self.blocks.restores
        if self.blocks.early_return:
            self.stats["early returns"] = self.blocks.early_returns
        return SystemResult(AdaptiveMaster.NAME, self.grid[:len(xs)].copy(), xs, vs, modes, self.events,
                            self.complete, np.array(self.end[4]), time.perf_counter() - start,
                            {"rtol": self.tol / self.system.length_scale,
                             "event tolerance (s)": EVENT_TOL}, self.stats)

    def _advance(self):
        """One accepted communication step from ``t`` (redone shorter, and on an event, as needed)."""
        self.blocks.save(skip=self.ahead.on)
        next_grid = self.grid[np.searchsorted(self.grid, self.t, side="right")]
        slipping = bool((self.end[3] != 0).any())
        # a block whose breakaway the last step landed on breaks away at once: the step ends just past it (a longer
        # one would be redone to end there)
        breaking, self.breaking, first = self.breaking, None, self.t + 0.5 * EVENT_TOL
        if breaking is None or self.end[3][breaking] != 0 or first <= self.t:  # (or floats space times wider there)
            first = None
        for _ in range(MAX_REDOS):
            h = min(self.h, self.h_slip) if slipping else math.inf
            T = min(self.t + h if first is None else first, float(next_grid))
            clipped = T < self.t + h
            attempt = self._attempt(T, CELLS if slipping else 1)
            if attempt.cut is not None or (attempt.converged and attempt.error <= 2.0 * self.tol * (T - self.t)):
                break
            first = None
            self.stats["rejected steps"] += 1
            self.h = (T - self.t) * (0.5 if not attempt.converged else self._factor(attempt))
        else:
            raise FMUError(f"adaptive: no step from t = {self.t!r} s meets the tolerance")
        crossing = self._crossing(attempt)
        if crossing is not None:
            attempt = self._land(attempt, crossing)
        if attempt.error > 0.0 and not clipped and attempt.T == T:
            self.h = (T - self.t) * self._factor(attempt)
        self._accept(attempt)
        if self.t == float(next_grid):
            self.rows.append((self.x.copy(), self.v.copy(), self.end[3].copy()))
            self.progress(self.t)

    def _factor(self, attempt):
        """The step's growth factor from its error estimate (local error order 4 per cell: 3 per second)."""
        ratio = self.tol * (attempt.T - self.t) / max(attempt.error, 1e-300)
        return min(2.0, max(0.2, 0.8 * ratio ** (1.0 / 3.0)))

    def _attempt(self, T, cells, cuttable=True):
        """The step ``[t, T]`` in ``cells`` cells, swept until the waveforms converge (or ``MAX_SWEEPS``); with early
        return (FMI 3) and ``cuttable``, stopped at the first event a block's early return shows inside it."""
        times = cell_times(self.t, T, cells)
        if not all(s0 < s1 for s0, s1 in zip(times, times[1:])):  # a step of a few ulp (an event landed just
            times = [self.t, T]  # before a grid point)
        times = np.array(times)
        tau = times - self.t
        a, j = self._predicted_acceleration()[:, None], self.jerk[:, None]
        attempt = _Attempt(times, self.x[:, None] + self.v[:, None] * tau + a * tau ** 2 / 2 + j * tau ** 3 / 6,
                           self.v[:, None] + a * tau + j * tau ** 2 / 2, cuttable and self.blocks.early_return)
        slipping = self.end[3] != 0
        floor = max(0.01 * self.tol * (T - self.t), 1e-14 * (1.0 + float(np.abs(self.x).max())))
        settled = np.zeros(self.system.n, bool)  # stuck at t and still stuck, without an event, after a sweep
        self._ahead_rows(attempt, settled)
        while attempt.sweeps < MAX_SWEEPS and not attempt.converged:
            before = attempt.XV.copy()
            residual = self._sweep(attempt, slipping, settled, floor)
            if attempt.cut is not None:
                break  # redone to end at the event (_land)
            change = float((np.abs(attempt.XV - before) * attempt.change_scale).max())
            attempt.sweeps += 1
            # a hold that had an event is swept before the attempt converges (the cubic predictor
            # can make the first sweep's change tiny on a short step)
            unswept = attempt.sweeps == 1 and (~slipping & ~settled).any()
            attempt.converged = change <= floor and not unswept
            # the error estimate after the first sweep (an attempt far off is rejected there) and the last (those
            # between would be overwritten)
            if attempt.sweeps == 1 or attempt.converged or attempt.sweeps == MAX_SWEEPS:
                attempt.error = self._estimate(attempt, residual, slipping)
                if attempt.error > 4.0 * self.tol * (T - self.t):
                    break  # rejected whatever the sweeps give
        self.stats["sweeps"] += attempt.sweeps
        attempt.end = self.blocks.end()
        ahead = self.ahead.on.nonzero()[0]
        if ahead.size:  # where the blocks ahead are at T (their FMUs are further)
            attempt.end[0][ahead] = attempt.ahead_z_slip[ahead]
            for k in range(1, len(attempt.end)):
                attempt.end[k][ahead] = self.ahead.end[ahead, k]
        return attempt

    def _sweep(self, attempt, slipping, settled, floor):
        """Step every block not ``settled`` (updated: True for a block stuck at ``t`` that stayed stuck without an
        event) once over ``attempt``; return the force residuals (:meth:`_forces`) of the waveforms before it.
        Jacobi: every block's forces from the waveforms before the sweep. A block whose forces did not change is not
        stepped again (:meth:`_unchanged`)."""
        lines, rate, residual = self._forces(attempt, slipping)
        used, held_force = lines[:, :-1], lines[:, 0]  # the force at each cell's start and end; a stuck block's at t
        # a stuck block's force is steady where it stays within steady_force of the one it holds
        holds = np.where(self.ahead.on, self.ahead.force, held_force)
        steady = np.abs(lines - holds[:, None]).max(axis=1) <= self.steady_force
        for i in (self.ahead.on & ~steady).nonzero()[0].tolist():
            self._bring_back(i, attempt)
            settled[i] = False
        if attempt.sweeps == 0:  # no block was stepped in the attempt yet
            # a block stuck at t: its motion does not depend on the force (stepped again only after an event)
            held = (~settled & ~slipping).nonzero()[0]
            if held.size:
                self._hold_blocks(held, attempt, held_force, settled, steady)
            stepped = ~settled & slipping
        else:
            swept = ~settled
            stepped = swept & ~self._unchanged(attempt, used, floor)
            self.stats["sweeps of a block skipped"] += int(np.count_nonzero(swept)) - int(np.count_nonzero(stepped))
        starts, rates = lines[:, :attempt.cells].tolist(), rate.tolist()
        for i in stepped.nonzero()[0].tolist():
            self.blocks.restore(i)
            self._sweep_block(i, attempt, starts[i], rates[i])
            attempt.forces[i] = used[i]
        return residual

    def _predicted_acceleration(self):
        """Each block's acceleration (m/s^2) at ``t`` for the first sweep's waveforms: 0 for a stuck block (it moves
        with the surface, as its first sweep gives it: a slipping neighbour's forces are then unchanged in the second
        sweep and it is not stepped again)."""
        return np.where(self.end[3] == 0, 0.0, self.a)

    def _hold_blocks(self, blocks, attempt, forces, settled, steady):
        """Step each of ``blocks`` (an index array of blocks stuck at ``t``) over the whole of ``attempt`` in one
        ``doStep`` with ``F_ext`` its entry of ``forces`` (N, per block); ``settled`` (updated) True for those that
        stayed stuck without an event: their cell ends are then on the line from their start to their end (they move
        with the surface). A block whose force is ``steady`` (per block) over the attempt is stepped ahead instead
        (:meth:`_step_ahead`) where that shows no event before ``T``."""
        ends, stepped = [], []
        for i in blocks.tolist():
            if steady[i] and self._step_ahead(i, attempt, forces[i]):
                settled[i] = True
                continue
            self.blocks.restore(i)
            self._step(i, self.t, attempt.T, forces[i], 0.0, attempt, may_cut=False)
            ends.append((*self.blocks.stepped, self.blocks.n_events(i)))
            stepped.append(i)
        if not stepped:
            return
        blocks = np.array(stepped)
        x, v, friction, spring, n_events = (np.array(column) for column in zip(*ends))
        x0 = self.x[blocks]
        attempt.X[blocks, 1:] = x0[:, None] + attempt.hold_share * (x - x0)[:, None]
        attempt.V[blocks, 1:], attempt.friction[blocks, 1:] = v[:, None], friction[:, None]
        attempt.spring[blocks], attempt.held[blocks], attempt.held_rate[blocks] = spring, forces[blocks], 0.0
        settled[blocks] = n_events == self.end[4][blocks]

    def _step_ahead(self, i, attempt, force):
        """Step block ``i``, stuck at ``t`` under the steady ``force`` (N), ahead in one ``doStep`` beyond ``T``, by
        ``ahead_length`` (to the run's end at most; with early return, to its first event): True if that shows no
        event before ``T``, the block then stepped ahead (:class:`_Ahead`; its rows of ``attempt`` filled), else
        False (its FMU moved)."""
        self.blocks.restore(i)
        t1 = min(max(attempt.T, self.t + self.ahead_length), self.t_end)
        if not self._extend_line(i, self.t, t1, force, self.end[4][i], self.t, force):
            return False
        self.ahead.begin(i, self.t, force, (self.x[i], self.spring[i], self.margin[i]),
                         [column[i] for column in self.end])
        if self.ahead.until[i] < attempt.T:
            self.ahead.on[i] = False
            return False
        self._fill_ahead(np.array([i]), attempt)
        return True

    def _ahead_rows(self, attempt, settled):
        """The rows of ``attempt`` of the blocks stepped ahead, those blocks ``settled``; one stepped ahead to before
        ``T`` is stepped further first (:meth:`_step_further`) or, where that shows an event before ``T``, brought
        back to ``t`` (:meth:`_bring_back`)."""
        for i in (self.ahead.on & (self.ahead.until < attempt.T)).nonzero()[0].tolist():
            if not self._step_further(i, attempt):
                self._bring_back(i, attempt)
        blocks = self.ahead.on.nonzero()[0]
        if blocks.size:
            self._fill_ahead(blocks, attempt)
            settled[blocks] = True
            self.stats["holds of a block stepped ahead"] += blocks.size

    def _step_further(self, i, attempt):
        """Block ``i``, stepped ahead to before ``T`` without an event, stepped on from its ``t1`` beyond ``T`` by
        ``ahead_length`` under the force it holds (its line then ends further): True if that shows no event before
        ``T``."""
        ahead = self.ahead
        t1 = float(ahead.t1[i])
        if ahead.until[i] < t1 or t1 >= self.t_end:
            return False  # its line ends at an event, or at the run's end
        t2 = min(max(attempt.T, t1 + self.ahead_length), self.t_end)
        return (self._extend_line(i, t1, t2, None, ahead.end[i, 4], float(ahead.t0[i]), float(ahead.force[i]))
                and ahead.until[i] >= attempt.T)

    def _extend_line(self, i, t0, t1, force, n_events, saved_at, held):
        """Step block ``i`` from ``t0`` to ``t1`` (s) in one ``doStep`` under ``force`` held (N; None: the force it
        holds, ``held``), ``n_events`` its event count at ``t0`` and at ``saved_at``, where its FMU state was saved:
        True, its line ending where the step ended (:meth:`_end_line`), or at its breakaway where the step passed it
        without returning early (:meth:`_before_breakaway`); False if that fails (its FMU beyond the event)."""
        t_e = self.blocks.step(i, t0, t1 - t0, force, 0.0)
        if t_e is None and self.blocks.n_events(i) != n_events:
            t_e = self._before_breakaway(i, t0, n_events, saved_at, held)
            if t_e is None:
                return False
        self._end_line(i, t1 if t_e is None else t_e, t_e)
        self.stats["stuck blocks stepped ahead"] += 1
        return True

    def _before_breakaway(self, i, t0, n_events, saved_at, held):
        """Block ``i``, whose step from ``t0`` (s) passed its breakaway (FMI 2: no early return; its event count was
        ``n_events``), back at its state saved at ``saved_at`` and stepped under ``held`` (N) to ``EVENT_TOL`` before
        the breakaway's time its step showed, as FMI 3's early return would leave it (the slip after the breakaway not
        integrated again at every attempt until it): that time, or None where the step showed more than the one event
        or that time is not after ``t0`` (its FMU then beyond the event)."""
        t_b = self.blocks.ends[i][2] - EVENT_TOL  # its t_last_event
        if self.blocks.n_events(i) != n_events + 1 or t_b <= t0:
            return None
        self.blocks.restore(i)
        self.blocks.step(i, saved_at, t_b - saved_at, held, 0.0)
        return t_b if self.blocks.n_events(i) == n_events else None

    def _end_line(self, i, t1, t_e):
        """Block ``i``'s line (stepped ahead) ends at ``t1`` (s), where its last step ended (at ``t_e``: returned early
        at its breakaway, where ``z_slip`` is 0, ``until`` then just before it; its outputs there are those after
        it)."""
        x, v, friction, spring = self.blocks.stepped
        ahead = self.ahead
        ahead.t1[i], ahead.until[i] = t1, (t1 if t_e is None else t_e - EVENT_TOL)
        ahead.lines[i, :, 1] = x, spring, (self.blocks.ends[i][0] if t_e is None else 0.0)
        ahead.v[i], ahead.friction[i] = v, friction

    def _fill_ahead(self, blocks, attempt):
        """The rows of ``attempt`` of ``blocks`` (an index array of blocks stepped ahead) on their lines."""
        ahead = self.ahead
        t0, lines = ahead.t0[blocks], ahead.lines[blocks]
        share = (attempt.times[1:] - t0[:, None]) / (ahead.t1[blocks] - t0)[:, None]
        start = lines[:, :, :1]
        on_line = start + share[:, None, :] * (lines[:, :, 1:] - start)  # (blocks, x spring z_slip, cell ends)
        attempt.X[blocks, 1:] = on_line[:, 0]
        attempt.V[blocks, 1:], attempt.friction[blocks, 1:] = ahead.v[blocks, None], ahead.friction[blocks, None]
        attempt.spring[blocks], attempt.ahead_z_slip[blocks] = on_line[:, 1, -1], on_line[:, 2, -1]
        attempt.held[blocks], attempt.held_rate[blocks] = ahead.force[blocks], 0.0

    def _bring_back(self, i, attempt):
        """Block ``i``, stepped ahead, back at ``t``: its state at its ``t0`` restored, stepped to ``t`` under the
        force it held, its state saved there (the step's) and its margin at ``t`` read."""
        ahead = self.ahead
        ahead.on[i] = False
        self.blocks.restore(i)
        if self.t > ahead.t0[i]:
            self._step(i, float(ahead.t0[i]), self.t, float(ahead.force[i]), 0.0, attempt, may_cut=False)
            self.blocks.save_block(i)
            self.margin[i] = self.blocks.ends[i][0]
        self.stats["blocks brought back from ahead"] += 1

    def _sweep_block(self, i, attempt, start, rate):
        """Step block ``i`` over every cell ``k`` of ``attempt`` in one ``doStep`` with ``F_ext`` from ``start[k]``
        (N) at the cell's start, growing at ``rate[k]`` (N/s); read the cell ends."""
        times, may_cut = attempt.cell_times, attempt.sweeps > 0 and attempt.cuttable
        cells, blocks, ends = len(times) - 1, self.blocks, []
        for k in range(cells):
            t0, t1 = times[k], times[k + 1]
            if self._step(i, t0, t1, start[k], rate[k], attempt, may_cut, last=k == cells - 1):
                break
            ends.append(blocks.stepped)
        if ends:  # the cells stepped (all, but for a step stopped at an event), written at once
            x, v, friction, spring = zip(*ends)
            k = len(ends) - 1  # the last one
            attempt.X[i, 1:k + 2], attempt.V[i, 1:k + 2], attempt.friction[i, 1:k + 2] = x, v, friction
            attempt.spring[i], attempt.held[i] = spring[k], start[k] + rate[k] * (times[k + 1] - times[k])
            attempt.held_rate[i] = rate[k]

    def _step(self, i, t0, t1, force, rate, attempt, may_cut, last=True):
        """Block ``i`` from ``t0`` to ``t1`` (s) with ``F_ext = force + rate (s - t0)`` (N); True if it returned early
        at an event more than ``EVENT_TOL`` before the attempt's end and ``may_cut``: the event is then
        ``attempt.cut`` (the earliest of such) and the block stays there. Any other early return is stepped on from
        (the event applied, the force going on along its line). ``last``: the block's last step in the attempt
        (:meth:`_Blocks.step`)."""
        t_e = self.blocks.step(i, t0, t1 - t0, force, rate, last)
        while t_e is not None:
            if may_cut and attempt.T - t_e > EVENT_TOL:
                attempt.cut = min(attempt.cut or (math.inf, -1), (t_e, int(i)))
                return True
            t_e = self.blocks.step(i, t_e, t1 - t_e, last=last)
        return False

    def _unchanged(self, attempt, forces, floor):
        """Per block, True if it need not be stepped again: when the ``forces`` (N, one row per block) it would be
        stepped with differ from those it was last stepped with in ``attempt`` by so little that its cell ends
        could move by at most a tenth of the convergence ``floor`` (m): ``|dF| (T - t)^2 / M``; False for a block
        not stepped in ``attempt`` yet."""
        change = np.abs(forces - attempt.forces).max(axis=1)
        return change * (attempt.T - self.t) ** 2 / self.M <= 0.1 * floor

    def _forces(self, attempt, slipping):
        """``(lines, rate, residual)``, arrays ``(N, cells)`` but for ``lines``: per block, ``F_ext`` at each cell's
        start, at each cell's end and at ``T`` (N; ``2 cells + 1`` columns): a ``slipping`` block's on the line
        ``F_ext = start + rate (s - t_cell)`` (N, N/s) that carries the interpolated coupling force's impulse and first
        moment about the cell's end, a stuck block's held from the cell's start (its ``rate`` 0); and the residual
        ``int (F - line) (T_cell - s)^2 ds`` (N s^3) of the line (:func:`force_map`)."""
        c = attempt.cells
        F = (self.K @ attempt.XV) @ attempt.force_columns
        lines = np.where(slipping[:, None], F[:, :2 * c + 1], F[:, 2 * c + 1:4 * c + 2])
        return lines, np.where(slipping[:, None], F[:, 4 * c + 2:5 * c + 2], 0.0), F[:, 5 * c + 2:]

    def _estimate(self, attempt, residual, slipping):
        """The step's error estimate (m): per slipping block, the velocity error of its cells' force residuals
        (``lambda^2 / 2M`` times the residual, ``lambda^2 = omega^2 + (dF_friction/dv / M)^2``) over ``lambda``,
        summed over the cells; the largest of any block (0 if none slips)."""
        if not slipping.any():
            return 0.0
        dv = np.abs(attempt.V[:, 1:] - attempt.V[:, :-1])
        dF = attempt.friction[:, 1:] - attempt.friction[:, :-1]
        gamma = np.where(dv > 1e-12, np.abs(dF) / np.maximum(dv, 1e-12), 0.0)
        lam2 = self.omega2[:, None] + (gamma / self.M[:, None]) ** 2
        per_cell = np.sqrt(lam2) / (2.0 * self.M[:, None]) * np.abs(residual)
        return float(np.where(slipping, per_cell.sum(axis=1), 0.0).max())

    def _accept(self, attempt):
        """Make ``attempt`` the new communication point; record its events."""
        before, end = self.end, attempt.end
        events, complete = step_events(*(column.tolist() for column in (end[2], before[3], end[3], before[4], end[4])))
        self.events += events
        self.complete = self.complete and complete
        self.t, self.end, self.margin = attempt.T, end, self._held_margin(attempt)
        self.x, self.v, self.spring = attempt.X[:, -1].copy(), attempt.V[:, -1].copy(), attempt.spring.copy()
        self.a = (attempt.spring + attempt.friction[:, -1] + self.K @ self.x) / self.M
        self.jerk = self._jerk(attempt.held_rate)
        self.stats["communication steps"] += 1

    def _jerk(self, rate):
        """Each block's ``d2v/dt2`` (m/s^3) at ``t`` for the first sweep's waveforms: a slipping block's from its
        output derivative, with the coupling force's rate ``K v`` in place of the ``rate`` (N/s) its force was last
        set with; 0 while stuck."""
        jerk = np.zeros(self.system.n)
        for i in (self.end[3] != 0).nonzero()[0].tolist():
            jerk[i] = self.blocks.jerk(i) + (self.K[i] @ self.v - rate[i]) / self.M[i]
        return jerk

    def _held_margin(self, attempt):
        """Each block's ``z_slip`` (N) at the step's end with the true coupling force there (the FMU's is with the
        force it held over the last cell); meaningful for the blocks stuck at ``t``. Worked out once per attempt."""
        if attempt.margin is None:
            attempt.margin = true_margin(attempt.end[0], -attempt.spring, attempt.held, self.K @ attempt.X[:, -1])
        return attempt.margin

    def _crossing(self, attempt):
        """``(block, t_e)`` of the first event in ``attempt``, None if none: a block's own (``n_events`` moved; ``t_e``
        its time, or the step's middle for two or more; or where its early return stopped the attempt) or a block
        stuck at ``t`` whose true margin at the end is negative (``t_e`` None; its time, for the order, on the line
        between its margins at ``t`` and the end)."""
        if attempt.cut is not None:
            return attempt.cut[1], attempt.cut[0]
        moved = attempt.end[4] != self.end[4]
        found = [(attempt.end[2][i] if attempt.end[4][i] == self.end[4][i] + 1 else 0.5 * (self.t + attempt.T),
                  int(i), True) for i in moved.nonzero()[0].tolist()]
        margin = self._held_margin(attempt)
        for i in ((self.end[3] == 0) & ~moved & (margin < 0.0)).nonzero()[0].tolist():
            share = self.margin[i] / max(self.margin[i] - margin[i], 1e-300)
            found.append((self.t + min(max(share, 0.0), 1.0) * (attempt.T - self.t), int(i), False))
        if not found:
            return None
        t_e, block, own = min(found)
        return block, (float(t_e) if own else None)

    def _indicator(self, attempt, block):
        """Block ``block``'s indicator at the end of ``attempt`` (None: at ``t``), positive while its mode at ``t``
        lasts: the true ``z_slip`` (with the coupling force at that point) while stuck, ``mode * v_rel`` while
        slipping."""
        mode = self.end[3][block]
        if mode != 0:
            return float(mode * (self.end if attempt is None else attempt.end)[1][block])
        return float(self.margin[block] if attempt is None else self._held_margin(attempt)[block])

    def _margin_zero(self, attempt, block):
        """Where the true margin of ``block`` (stuck at ``t``) first falls below zero in ``attempt`` (s): its FMU's
        ``z_slip`` (under the force it held) on the line between its values at ``t`` and ``T``, corrected as in
        :meth:`_held_margin` with ``kappa x`` and the coupling force of the positions' cubic Hermite waveforms;
        located by Brent's method, to a tenth of ``EVENT_TOL``, in the first cell whose end has it negative. None if
        no cell end has it negative before ``T``'s or at ``T``."""
        held, margin_t, z_end = attempt.held[block], self.margin[block], attempt.end[0][block]
        X, V, delta = attempt.X, attempt.V, attempt.delta

        def margin(k, u):  # at the share u of cell k
            h00, h10, h01, h11 = hermite_basis(u)
            x = h00 * X[:, k] + h10 * delta * V[:, k] + h01 * X[:, k + 1] + h11 * delta * V[:, k + 1]
            share = (k + u) / attempt.cells
            return true_margin(margin_t + share * (z_end - margin_t), self.kappa[block] * x[block], held,
                               float(self.K[block] @ x))

        for k in range(attempt.cells):
            m_start, m_end = margin(k, 0.0), margin(k, 1.0)
            if m_end < 0.0 <= m_start:
                break
        else:
            return None
        u = brent(lambda u: margin(k, u), 0.0, 1.0, m_start, m_end, xtol=0.1 * EVENT_TOL / delta)
        return attempt.cell_times[k] + u * delta

    def _bracket(self, lo_attempt, attempt, crossing):
        """``(psi_lo, psi_hi, rate)``: the indicator of the crossing's block at the end of ``lo_attempt`` (None:
        ``t``) and of ``attempt``; past a block's own event at ``t_e`` the latter is ``-(T - t_e) * rate``, with the
        indicator's mean rate from ``lo`` to ``t_e`` (its value there is of the new mode)."""
        block, t_e = crossing
        lo = self.t if lo_attempt is None else lo_attempt.T
        psi_lo = max(self._indicator(lo_attempt, block), 1e-300)
        if t_e is None:
            return psi_lo, min(self._indicator(attempt, block), -1e-300), None
        rate = psi_lo / max(t_e - lo, EVENT_TOL)
        return psi_lo, -(attempt.T - t_e) * rate, rate

    def _land(self, attempt, crossing):
        """The step redone to end on its first event, just past it: Illinois on the indicator of the block whose
        event comes first (:meth:`_bracket`; a redo that shows another block's event first brackets that one)."""
        lo_attempt, lo, hi, side = None, self.t, attempt.T, 0
        psi_lo, psi_hi, rate = self._bracket(None, attempt, crossing)
        zero = self._margin_zero(attempt, crossing[0]) if crossing[1] is None else None
        # a breakaway's first two redos: just before and just after where the attempt's waveforms put it
        guesses = [] if zero is None else [zero - 0.4 * EVENT_TOL, zero + 0.4 * EVENT_TOL]
        for _ in range(MAX_REDOS):
            own = crossing[1]
            if attempt.T == hi and hi - (lo if own is None else own) <= EVENT_TOL:
                self.breaking = crossing[0] if own is None else None
                return attempt
            if hi - lo <= EVENT_TOL:  # the event's far side (a step before it would end on a stale mode)
                T = hi if hi > lo else lo + 0.5 * EVENT_TOL
            elif own is not None and own >= lo:  # half the tolerance past the block's own event, where it lands
                T = min(max(own + 0.5 * EVENT_TOL, lo + 0.25 * EVENT_TOL), hi - 0.25 * EVENT_TOL)
            elif guesses and lo < guesses[0] < hi:
                T = guesses.pop(0)
            else:
                T = min(max((lo * psi_hi - hi * psi_lo) / (psi_hi - psi_lo), lo + 0.25 * EVENT_TOL),
                        hi - 0.25 * EVENT_TOL)
            attempt = self._attempt(T, CELLS if np.any(self.end[3] != 0) else 1)
            self.stats["event redos"] += 1
            found = self._crossing(attempt)
            if found is not None:  # the zero is before T: the guess after it is no use
                guesses.clear()
            if found is None:
                lo_attempt, lo, psi_lo = attempt, T, max(self._indicator(attempt, crossing[0]), 1e-300)
                psi_hi, side = (psi_hi * 0.5 if side == -1 else psi_hi), -1
            elif found[0] != crossing[0] or (found[1] is None) != (own is None):
                crossing, hi, side = found, T, 0
                psi_lo, psi_hi, rate = self._bracket(lo_attempt, attempt, crossing)
            else:
                crossing, hi = found, T
                psi_hi = -(T - found[1]) * rate if found[1] is not None else min(self._indicator(attempt, found[0]),
                                                                                 -1e-300)
                psi_lo, side = (psi_lo * 0.5 if side == 1 else psi_lo), 1
        self.stats["events not landed"] += 1  # events that keep moving (triggering each other): the last try
        if attempt.cut is not None:  # the last try stopped at its event: redone to its end, through the event
            attempt = self._attempt(attempt.T, CELLS if np.any(self.end[3] != 0) else 1, cuttable=False)
        return attempt
