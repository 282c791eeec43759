"""Direct FMI access to the SpringBlockFriction FMU for the stress tests (FMPy's ``FMU2Slave``).

The stress matrix and the property tests need what ``fmpy.simulate_fmu`` hides:
the exact communication points, inputs that change at any step, the FMU's own
log text and status code, FMU states, and timing per ``doStep``. A
:class:`FmuSession` extracts the FMU once and makes :class:`Instance` objects.

PythonFMU reports every Python exception as ``fmi2Fatal`` (this FMU's Linux
loader, :mod:`stickslip.fmu.loader`, reports it as ``fmi2Error``) and releases the
slave itself. This FMU balances that release so that an importer may still
free the instance, but other builds and other PythonFMU FMUs do not, and FMI
allows no call after ``fmi2Fatal``: an instance that returned ``fmi2Fatal`` is
never terminated or freed here (its slave stays allocated until the process
ends). Instances log through the process-wide logger of :mod:`stickslip.hosts.fmpy_host`.
"""

import shutil
import time

import fmpy
import numpy as np
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2Error,
    fmi2Fatal,
    fmi2LastSuccessfulTime,
)

from ..hosts.fmpy_host import FMUError, fmi2_callbacks, log_mark, messages_since

REAL_OUTPUTS = ("x", "v", "v_rel", "F_friction", "F_spring", "t_stick", "z_slip", "z_stick", "t_last_event")
INTEGER_OUTPUTS = ("mode", "n_events", "n_stick_events", "n_slip_events", "n_overshoots", "n_steps")
INPUTS = ("v_drive", "F_ext")
#: every column a sample holds (besides ``time``)
COLUMNS = REAL_OUTPUTS + INPUTS + INTEGER_OUTPUTS
STATUS_NAMES = ("ok", "warning", "discard", "error", "fatal", "pending")

class FmuCallError(FMUError):
    """An FMI call failed: ``function``, ``status`` (2 discard, 3 error, 4 fatal) and the FMU's log ``messages``."""

    def __init__(self, function, status, messages):
        self.function = function
        self.status = status
        self.messages = tuple(messages)
        label = STATUS_NAMES[status] if 0 <= status < len(STATUS_NAMES) else "illegal"
        super().__init__("\n".join([f"{function} failed with status {status} ({label})", *self.messages]))


class FmuSession:
    """The FMU extracted once; :meth:`instantiate` makes initialized instances. Use as a context manager."""

    def __init__(self, fmu_path):
        self.path = str(fmu_path)
        self.description = fmpy.read_model_description(self.path)
        self.folder = fmpy.extract(self.path)
        self.variables = {v.name: v for v in self.description.modelVariables}
        self.defaults = {
            name: (int(v.start) if v.type == "Integer" else float(v.start))
            for name, v in self.variables.items() if v.causality in ("parameter", "input")
        }
        self._count = 0

    def close(self):
        shutil.rmtree(self.folder, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def start_values(self, overrides):
        """Every parameter and input with its start value, ``overrides`` (FMU names) applied."""
        unknown = set(overrides) - set(self.defaults)
        if unknown:
            raise KeyError(f"not parameters or inputs of the FMU: {sorted(unknown)}")
        return {**self.defaults, **overrides}

    def instantiate(self, start_values, name=None, start_time=0.0, logging_on=True):
        """An instance in step mode: instantiated, start values set, initialization done.

        Raises :class:`FmuCallError` (with the FMU's log) if a call fails; the
        instance is then cleaned up (never freed after ``fmi2Fatal``).
        """
        self._count += 1
        name = name or f"stress{self._count}"
        fmu = FMU2Slave(guid=self.description.guid, unzipDirectory=self.folder,
                        modelIdentifier=self.description.coSimulation.modelIdentifier, instanceName=name)
        fmu.instantiate(callbacks=fmi2_callbacks(), loggingOn=logging_on)
        instance = Instance(self, fmu, name)
        try:
            instance.call("fmi2SetupExperiment", fmu.setupExperiment, startTime=start_time)
            instance.call("fmi2EnterInitializationMode", fmu.enterInitializationMode)
            for key, value in start_values.items():
                instance.set_value(key, value)
            instance.call("fmi2ExitInitializationMode", fmu.exitInitializationMode)
        except FmuCallError:
            instance.free()
            raise
        instance.time = float(start_time)
        return instance


class Instance:
    """One FMU instance in step mode. ``time`` is the end of the last successful step (s)."""

    def __init__(self, session, fmu, name):
        self.session = session
        self.fmu = fmu
        self.name = name
        self.time = 0.0
        self.fatal = False
        self.freed = False
        self.step_seconds = []  # wall time of every doStep (s)

    # ---- calls --------------------------------------------------------------

    def call(self, function, method, *args, **kwargs):
        """Call an FMPy method; raise FmuCallError with this instance's new log messages on failure."""
        first = log_mark()
        try:
            return method(*args, **kwargs)
        except FMICallException as exc:
            if exc.status == fmi2Fatal:
                self.fatal = True
            raise FmuCallError(function, exc.status, self.messages(first)) from None

    def messages(self, first=0):
        """Log messages (status >= warning) of this instance since ``first`` (a :func:`log_mark`)."""
        return messages_since(first, self.name)

    def set_value(self, name, value):
        variable = self.session.variables[name]
        if variable.type == "Integer":
            self.call("fmi2SetInteger", self.fmu.setInteger, [variable.valueReference], [int(value)])
        else:
            self.call("fmi2SetReal", self.fmu.setReal, [variable.valueReference], [float(value)])

    def set_inputs(self, v_drive, F_ext):
        refs = [self.session.variables[n].valueReference for n in INPUTS]
        self.call("fmi2SetReal", self.fmu.setReal, refs, [float(v_drive), float(F_ext)])

    def do_step(self, h):
        """``doStep(time, h)``; the new time is ``time + h`` exactly as the FMU computes it."""
        start = time.perf_counter()
        self.call("fmi2DoStep", self.fmu.doStep, self.time, h)
        self.step_seconds.append(time.perf_counter() - start)
        self.time = self.time + h

    def step_to(self, t):
        """One ``doStep`` from ``time`` with ``h = t - time``; ``time`` becomes ``time + h`` (may differ from ``t``
        in the last bit: that sum is what the FMU is asked for)."""
        self.do_step(t - self.time)

    def last_successful_time(self):
        return self.call("fmi2GetRealStatus", self.fmu.getRealStatus, fmi2LastSuccessfulTime)

    def read(self):
        """Every output and input now, as ``{name: value}`` (``time`` included)."""
        variables = self.session.variables
        reals = self.call("fmi2GetReal", self.fmu.getReal,
                          [variables[n].valueReference for n in REAL_OUTPUTS + INPUTS])
        integers = self.call("fmi2GetInteger", self.fmu.getInteger,
                             [variables[n].valueReference for n in INTEGER_OUTPUTS])
        row = dict(zip(REAL_OUTPUTS + INPUTS, reals))
        row.update(zip(INTEGER_OUTPUTS, integers))
        row["time"] = self.time
        return row

    # ---- FMU state ----------------------------------------------------------

    def get_state(self):
        return self.call("fmi2GetFMUstate", self.fmu.getFMUstate)

    def set_state(self, state, t):
        self.call("fmi2SetFMUstate", self.fmu.setFMUstate, state)
        self.time = t

    def free_state(self, state):
        self.call("fmi2FreeFMUstate", self.fmu.freeFMUstate, state)

    # ---- end ----------------------------------------------------------------

    def free(self):
        """Terminate and free, unless the FMU returned fmi2Fatal (see the module text)."""
        if self.freed:
            return
        self.freed = True
        if self.fatal:
            return
        try:
            self.fmu.terminate()
        except FMICallException as exc:
            if exc.status == fmi2Fatal:
                return
        self.fmu.freeInstance()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.free()


def as_columns(rows):
    """Samples (list of dicts from :meth:`Instance.read`) as ``{column: numpy array}``."""
    names = ("time",) + COLUMNS
    return {n: np.array([r[n] for r in rows], dtype=int if n in INTEGER_OUTPUTS else float) for n in names}


__all__ = ["COLUMNS", "FmuCallError", "FmuSession", "INPUTS", "INTEGER_OUTPUTS", "Instance", "REAL_OUTPUTS",
           "STATUS_NAMES", "as_columns", "fmi2Error", "fmi2Fatal"]
