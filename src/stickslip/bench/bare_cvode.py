"""The hybrid model integrated by FMPy's CVode directly, with no FMU: what model exchange costs the solver alone.

:func:`simulate_bare_cvode` drives ``fmpy.sundials.CVodeSolver`` (BDF, absolute tolerances
``rtol`` times the nominals, maximum step ``T/50``, CVode's default 500 steps per call) the way
``fmpy.simulate_fmu`` drives it for an FMU's model exchange: step to the next output time, and
after every root an event update and a re-initialization. Only the model differs: a plain Python
right-hand side, event indicators and event update written from the reference's laws and rules
(:mod:`stickslip.reference`, SPEC section 1), none of ``stickslip.core`` (a test checks the
imports). So its error against the reference is the solver's own, to set beside the FMU's.

- States ``x`` (m), ``v`` (m/s). Stuck: ``x' = v_drive``, ``v' = 0``; slipping in mode ``m``:
  ``x' = v``, ``v' = (F_ext - kappa x + m F_K(m v_rel))/M`` (:func:`~stickslip.reference.rules.acceleration`).
- Indicators, positive while the mode lasts (:data:`INACTIVE` where they do not apply): ``m v_rel``
  (m/s, the slip reaches ``v_rel = 0``), ``F_S(t_stick) - |kappa x - F_ext|`` (N, breakaway), and
  ``m dv_rel/dt`` (m/s^2, an extremum of ``v_rel``: a dip through 0 inside one step changes its sign).
- Update: a slip at ``m v_rel <= 0`` sticks if ``F_S(0)`` holds the spring, else overshoots, with
  ``v = v_drive``; a stuck block breaks away where ``z_slip < 0`` (or ``= 0`` and falling), in the
  direction of the net force without friction.
"""

import math

import numpy as np

from ..suite.compare import Event, transition_kind
from ..reference.laws import parameters_from_values
from ..reference.rules import STUCK, acceleration, breakaway_mode, hold_or_break, initial_mode, z_slip
from .peers import Run

INACTIVE = 1.0  # an indicator's value in the modes where it does not apply
N_INDICATORS = 3  # stick, breakaway, graze


class BareBlock:
    """The block's discrete state between CVode's calls; its methods are ``CVodeSolver``'s callbacks.

    ``p``: :class:`~stickslip.reference.laws.ReferenceParameters`; constant inputs ``v_drive`` (m/s),
    ``F_ext`` (N). ``events`` collects the transitions as :class:`~stickslip.suite.compare.Event` at their times.
    """

    def __init__(self, p, x0, v0, v_drive, F_ext):
        self.p, self.v_drive, self.F_ext = p, float(v_drive), float(F_ext)
        self.t, self.x, self.v = 0.0, float(x0), float(v0)
        self.mode = initial_mode(p, self.x, self.v, self.v_drive, self.F_ext)
        self.t_stuck = 0.0
        self.events = []

    # ---- callbacks (ctypes double pointers, as FMPy passes them to an FMU) ----

    def set_time(self, t):
        self.t = t

    def get_x(self, out, n):
        out[0], out[1] = self.x, self.v_drive if self.mode == STUCK else self.v

    def set_x(self, values, n):
        self.x, self.v = values[0], values[1]

    def get_nominals(self, out, n):
        """``F_S(0)/kappa`` (m) and ``F_S(0)/sqrt(kappa M)`` (m/s), the FMU's nominals."""
        p = self.p
        force = p.static.force(0.0)
        out[0], out[1] = force / p.kappa, force / math.sqrt(p.kappa * p.M)

    def get_dx(self, out, n):
        if self.mode == STUCK:
            out[0], out[1] = self.v_drive, 0.0
        else:
            out[0], out[1] = self.v, acceleration(self.p, self.mode, self.x, self.v, self.v_drive, self.F_ext)

    def get_z(self, out, n):
        if self.mode == STUCK:
            out[0], out[1], out[2] = INACTIVE, z_slip(self.p, self.x, self.F_ext, self.t - self.t_stuck), INACTIVE
        else:
            m = self.mode
            accel = acceleration(self.p, m, self.x, self.v, self.v_drive, self.F_ext)
            out[0], out[1], out[2] = m * (self.v_drive - self.v), INACTIVE, -m * accel

    # ---- event update ----

    def update(self):
        """The transition due at ``t`` (SPEC section 1), logged in ``events``."""
        p, x, old = self.p, self.x, self.mode
        if old == STUCK:
            t_stick = self.t - self.t_stuck
            margin = z_slip(p, x, self.F_ext, t_stick)
            falling = p.static.rate(t_stick) - math.copysign(p.kappa * self.v_drive, p.kappa * x - self.F_ext) < 0.0
            new = breakaway_mode(p, x, self.F_ext) if margin < 0.0 or (margin == 0.0 and falling) else STUCK
            self.v = self.v_drive
        elif old * (self.v_drive - self.v) <= 0.0:  # the slip reached v_rel = 0: this is the event's point
            new = hold_or_break(p, x, self.F_ext, 0.0)
            self.v = self.v_drive
        else:  # a graze root with v_rel still on the mode's side: nothing happens
            new = old
        if new != old:
            self.events.append(Event(transition_kind(old, new), self.t, self.t))
            self.mode = new
            self.t_stuck = self.t


class _ConstantInputs:
    """The solver's ``input``: the inputs are constant, nothing to apply."""

    def apply(self, t, *args, **kwargs):
        pass


def simulate_bare_cvode(scene, rtol):
    """The scene's hybrid model by FMPy's ``CVodeSolver`` at relative tolerance ``rtol``: a :class:`Run` on
    the scene's grid with the events at their located times."""
    from fmpy.sundials import CVodeSolver

    v_drive, F_ext = scene.inputs
    block = BareBlock(parameters_from_values(scene.scenario.law_values), scene.scenario.x0, scene.scenario.v0,
                      v_drive, F_ext)
    block.update()  # as the FMU's event update at the end of initialization
    grid = scene.grid()
    T, step = float(grid[-1]), float(grid[1] - grid[0])
    solver = CVodeSolver(nx=2, nz=N_INDICATORS, get_x=block.get_x, set_x=block.set_x, get_dx=block.get_dx,
                         get_z=block.get_z, get_nominals=block.get_nominals, set_time=block.set_time,
                         input=_ConstantInputs(), startTime=0.0, maxStep=T / 50.0, relativeTolerance=rtol)
    xs, vs = [], []
    t, n_steps = 0.0, 0
    while True:  # fmpy.simulation.simulateME's loop, with its event branch
        if len(xs) == n_steps and math.isclose(t, n_steps * step):  # each grid point once
            xs.append(block.x)
            vs.append(block.v_drive if block.mode == STUCK else block.v)
        if t > T or math.isclose(t, T):
            break
        target = min((n_steps + 1) * step, T)
        state_event, _, t = solver.step(t, target)
        block.set_time(t)
        if math.isclose(t, (n_steps + 1) * step):
            n_steps += 1
        if state_event:
            block.update()
            solver.reset(t)
    del solver
    return Run(grid, np.array(xs), np.array(vs), block.events)
