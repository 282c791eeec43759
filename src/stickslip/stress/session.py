"""Step-by-step FMI 2 access to the SpringBlockFriction FMU for the stress tests, on the FMPy host.

The stress matrix and the property tests need what ``fmpy.simulate_fmu`` hides:
the exact communication points, inputs that change at any step, the FMU's own
log text and status code, FMU states, and timing per ``doStep``. A
:class:`FmuSession` is an :class:`~stickslip.hosts.fmpy_host.ExtractedFMU` (extracted
once) whose :meth:`~FmuSession.instantiate` makes :class:`Instance` objects in step mode.

Failed calls raise :class:`~stickslip.hosts.fmpy_host.FmuCallError`; instances log
into the host's process log and follow its Fatal rule. PythonFMU reports every
Python exception as ``fmi2Fatal`` (this FMU's Linux loader, :mod:`stickslip.fmu.loader`,
reports it as ``fmi2Error``) and releases the slave itself. This FMU balances that
release so that an importer may still free the instance, but other builds and other
PythonFMU FMUs do not, and FMI allows no call after ``fmi2Fatal``: an instance that
returned ``fmi2Fatal`` is never terminated or freed here (its slave stays allocated
until the process ends).
"""

import time

import numpy as np
from fmpy.fmi2 import fmi2Error, fmi2Fatal, fmi2LastSuccessfulTime

from ..fmu.variables import INPUTS, INTEGER_OUTPUTS, REAL_OUTPUTS
from ..hosts import fmpy_host
from ..hosts.fmpy_host import FmuCallError

#: every column a sample holds (besides ``time``)
COLUMNS = REAL_OUTPUTS + INPUTS + INTEGER_OUTPUTS


class Instance(fmpy_host.Instance):
    """One FMU instance of a :class:`FmuSession`. ``time`` is the end of the last successful step (s)."""

    def __init__(self, extracted, fmu, name):
        super().__init__(extracted, fmu, name)
        self.time = 0.0
        self.step_seconds = []  # wall time of every doStep (s)

    # ---- initialization ------------------------------------------------------

    def enter_initialization(self, start_time):
        """``fmi2SetupExperiment`` at ``start_time`` (s), then ``fmi2EnterInitializationMode``."""
        self.call(self.fmu.setupExperiment, startTime=start_time)
        self.call(self.fmu.enterInitializationMode)
        self.time = float(start_time)

    def exit_initialization(self):
        self.call(self.fmu.exitInitializationMode)

    # ---- values ---------------------------------------------------------------

    def set_value(self, name, value):
        variable = self.extracted.variables[name]
        if variable.type in ("Integer", "Enumeration"):  # the law selectors are Enumerations
            self.call(self.fmu.setInteger, [variable.valueReference], [int(value)])
        else:
            self.call(self.fmu.setReal, [variable.valueReference], [float(value)])

    def set_values(self, values):
        """:meth:`set_value` of every ``{name: value}`` in ``values``, in its order."""
        for name, value in values.items():
            self.set_value(name, value)

    def set_inputs(self, v_drive, F_ext):
        refs = [self.extracted.variables[n].valueReference for n in INPUTS]
        self.call(self.fmu.setReal, refs, [float(v_drive), float(F_ext)])

    def real_value(self, name):
        """The Real variable ``name`` now."""
        return self.call(self.fmu.getReal, [self.extracted.variables[name].valueReference])[0]

    def read(self):
        """Every output and input now, as ``{name: value}`` (``time`` included)."""
        variables = self.extracted.variables
        reals = self.call(self.fmu.getReal, [variables[n].valueReference for n in REAL_OUTPUTS + INPUTS])
        integers = self.call(self.fmu.getInteger, [variables[n].valueReference for n in INTEGER_OUTPUTS])
        row = dict(zip(REAL_OUTPUTS + INPUTS, reals))
        row.update(zip(INTEGER_OUTPUTS, integers))
        row["time"] = self.time
        return row

    # ---- steps ----------------------------------------------------------------

    def do_step(self, h):
        """``doStep(time, h)``; the new time is ``time + h`` exactly as the FMU computes it."""
        start = time.perf_counter()
        self.call(self.fmu.doStep, self.time, h)
        self.step_seconds.append(time.perf_counter() - start)
        self.time = self.time + h

    def step_to(self, t):
        """One ``doStep`` from ``time`` with ``h = t - time``; ``time`` becomes ``time + h`` (may differ from ``t``
        in the last bit: that sum is what the FMU is asked for)."""
        self.do_step(t - self.time)

    def last_successful_time(self):
        return self.call(self.fmu.getRealStatus, fmi2LastSuccessfulTime)

    # ---- FMU state ------------------------------------------------------------

    def get_state(self):
        return self.call(self.fmu.getFMUstate)

    def set_state(self, state, t):
        self.call(self.fmu.setFMUstate, state)
        self.time = t

    def free_state(self, state):
        self.call(self.fmu.freeFMUstate, state)


class FmuSession(fmpy_host.ExtractedFMU):
    """The FMU extracted once; :meth:`instantiate` makes initialized instances. Use as a context manager."""

    instance_type = Instance

    def __init__(self, fmu_path):
        super().__init__(fmu_path)
        self._count = 0

    def instantiate(self, start_values, name=None, start_time=0.0, logging_on=True):
        """An instance in step mode: instantiated, initialization entered, start values set, initialization done.

        Raises :class:`FmuCallError` (with the FMU's log) if a call fails; the
        instance is then cleaned up (never freed after ``fmi2Fatal``).
        """
        self._count += 1
        instance = self.new_instance(name or f"stress{self._count}", logging_on=logging_on)
        try:
            instance.enter_initialization(start_time)
            instance.set_values(start_values)
            instance.exit_initialization()
        except FmuCallError:
            instance.free()
            raise
        return instance


def as_columns(rows):
    """Samples (list of dicts from :meth:`Instance.read`) as ``{column: numpy array}``."""
    names = ("time",) + COLUMNS
    return {n: np.array([r[n] for r in rows], dtype=int if n in INTEGER_OUTPUTS else float) for n in names}


__all__ = ["COLUMNS", "FmuCallError", "FmuSession", "Instance", "as_columns", "fmi2Error", "fmi2Fatal"]
