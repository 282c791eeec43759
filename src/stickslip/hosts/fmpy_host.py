"""Host the SpringBlockFriction FMUs under FMPy: co-simulation and model exchange of FMI 2.0 and FMI 3.0, with one
error type (:class:`FMUError`) and one log.

- :class:`ExtractedFMU`: an FMU file read and extracted once: its model description, its variables by name and
  the start values of its parameters and inputs. :meth:`~ExtractedFMU.new_instance` makes an :class:`Instance`
  that logs into the process log; :meth:`~ExtractedFMU.simulate` runs ``fmpy.simulate_fmu`` on the extracted
  folder. The suite (:func:`run_fmu`), the stress tests (:mod:`stickslip.stress.session`) and the benchmark
  build on it.
- :class:`Instance`: :meth:`~Instance.call` turns a failed FMI call into :class:`FmuCallError` (an FMUError)
  carrying the function, the status and the instance's own log text (for a bad parameter: its name, value and
  allowed range). The FMUs' loader passes errors at every logging setting; logging is on by default so that an
  FMU built without the loader (no C compiler) passes them too.
- The Fatal rule: PythonFMU and pythonfmu3 release the slave themselves when they report ``Fatal``, and FMI
  allows no call after it: an instance that reported ``Fatal`` is never terminated or freed
  (:meth:`Instance.free`); its slave stays allocated until the process ends.
- :func:`run_fmu` simulates an FMU file from t = 0 and raises FMUError on any failure.
- The log: FMPy's native logging proxy forwards the messages of every FMI 2 instance in the process to ONE
  logger, the one registered last, and a logger that is later garbage collected makes the next message crash
  the process. So every instance logs through callbacks that live as long as the process, into one list;
  callers read their instance's messages with :func:`log_mark` and :func:`messages_since`.
- Model exchange runs under FMPy's CVode (BDF, Newton with a dense Jacobian by difference quotients) with the
  relative tolerance ``rtol`` and the absolute tolerance ``rtol`` times the FMU's nominal of each state
  (``F_S(0)/kappa`` for ``x``, ``F_S(0)/sqrt(kappa M)`` for ``v``); FMPy caps CVode's step at 1/50 of the run.
  Inputs for model exchange are best given as steps (:func:`stickslip.suite.inputs.held_input_table`): the
  FMU treats an input change as a jump at the next event update, as a co-simulation step holds its inputs.
"""

import functools
import itertools
import shutil
from ctypes import byref

import fmpy
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Model, FMU2Slave, defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2Fatal
from fmpy.fmi3 import FMU3Model, FMU3Slave, fmi3Fatal, fmi3LogMessageCallback
from fmpy.logging import addLoggerProxy

from ..core.errors import StickSlipError
from ..fmu.python_path import preserved_sys_path
from .interrupts import check as check_interrupts
from .interrupts import interrupted

#: interface: (FMPy's fmi_type, the model description's attribute, FMI 2 class, FMI 3 class)
INTERFACES = {"cs": ("CoSimulation", "coSimulation", FMU2Slave, FMU3Slave),
              "me": ("ModelExchange", "modelExchange", FMU2Model, FMU3Model)}
#: FMI version: the status ``Fatal``
FATAL = {2: fmi2Fatal, 3: fmi3Fatal}
#: the status Warning (FMI 2 and 3): a call that returns more failed
WARNING = 1
#: FMI status code: its name
STATUS_NAMES = ("ok", "warning", "discard", "error", "fatal", "pending")

_MESSAGES = []  # (instance name, status, message) of every message with status >= warning, in order
_KEEP_ALIVE = []  # callbacks handed to FMUs: an instance may call them as long as it lives
_INSTANCE_NUMBERS = itertools.count(1)  # instance names, so each run reads only its own log messages


class FMUError(StickSlipError):
    """An FMI call of the FMU failed; the message contains the FMU's log."""


class FmuCallError(FMUError):
    """An FMI call failed: ``function``, ``status`` (2 discard, 3 error, 4 fatal) and the FMU's log ``messages``."""

    def __init__(self, function, status, messages):
        self.function = function
        self.status = status
        self.messages = tuple(messages)
        label = STATUS_NAMES[status] if 0 <= status < len(STATUS_NAMES) else "illegal"
        super().__init__("\n".join([f"{function} failed with status {status} ({label})", *self.messages]))


def _record(instance_name, status, message):
    if status >= 1:  # warning, discard, error or fatal
        _MESSAGES.append((instance_name, int(status), message.decode(errors="replace") if message else ""))


_FMI2_LOGGER = fmi2CallbackLoggerTYPE(
    lambda _env, instance, status, _category, message:
    _record(instance.decode(errors="replace") if instance else "", status, message))


def fmi2_callbacks():
    """FMI 2 callback functions for a new instance, logging into the process log."""
    functions = fmi2CallbackFunctions()
    functions.logger = _FMI2_LOGGER
    functions.allocateMemory = defaultCallbacks.allocateMemory
    functions.freeMemory = defaultCallbacks.freeMemory
    addLoggerProxy(byref(functions))
    _KEEP_ALIVE.append(functions)
    return functions


def fmi3_logger(instance_name):
    """FMI 3 log callback for the instance ``instance_name``, logging into the process log."""
    logger = fmi3LogMessageCallback(lambda _env, status, _category, message: _record(instance_name, status, message))
    _KEEP_ALIVE.append(logger)
    return logger


def log_mark():
    """The position in the process log; pass it to :func:`messages_since`."""
    return len(_MESSAGES)


def messages_since(mark, instance_name):
    """Messages (status >= warning) of the instance ``instance_name`` logged after ``mark``."""
    return [message for name, _, message in _MESSAGES[mark:] if name == instance_name]


class Instance:
    """One instance of an :class:`ExtractedFMU` (``extracted``): FMPy's object ``fmu`` (FMU2Slave, FMU2Model,
    FMU3Slave or FMU3Model), logging into the process log under ``name``.

    ``fatal`` is set once a call reported ``Fatal``; :meth:`free` then leaves the instance alone (see the module
    text). Use as a context manager to free it at the end.
    """

    def __init__(self, extracted, fmu, name):
        self.extracted = extracted
        self.fmu = fmu
        self.name = name
        self.fatal = False
        self.freed = False

    def call(self, method, *args, **kwargs):
        """``method(*args, **kwargs)``, a method of :attr:`fmu` (or anything that makes FMI calls on it);
        :class:`FmuCallError` with this instance's new log messages if an FMI call fails; KeyboardInterrupt if a
        SIGINT arrived during it (:mod:`.interrupts`), whatever the call returned."""
        check_interrupts()
        first = log_mark()
        try:
            result = method(*args, **kwargs)
        except Exception as error:
            if isinstance(error, FMICallException):
                raise self.failure(error.function, error.status, first) from None
            if interrupted():  # Ctrl-C, which the FMU's library reported as its own error
                raise KeyboardInterrupt from None
            raise
        check_interrupts()  # Ctrl-C that a callback swallowed (FMPy's solver calls Python)
        return result

    def failure(self, function, status, first):
        """The exception for the FMI call ``function`` (its name) that returned ``status`` (Discard or worse), made
        after the log mark ``first``: KeyboardInterrupt if a SIGINT arrived (the FMU's library reported Ctrl-C as
        its own error), else :class:`FmuCallError` with this instance's new log messages. A host that calls the
        FMU's C functions itself (:meth:`function`) raises it, as :meth:`call` does."""
        if status == FATAL[self.extracted.fmi_version]:
            self.fatal = True  # the library released the slave
        if interrupted():
            return KeyboardInterrupt()
        return FmuCallError(function, status, self.messages(first))

    def function(self, name):
        """The FMU's C function ``name`` (e.g. "fmi3SetTime") with FMPy's argument types, for a host that calls it
        on arrays made once, without FMPy's wrapper: it returns the FMI status; raise :meth:`failure` for one above
        Warning, check :func:`~.interrupts.check` around the calls and take :func:`log_mark` before them."""
        return getattr(self.fmu.dll, name)

    def messages(self, first=0):
        """Log messages (status >= warning) of this instance since ``first`` (a :func:`log_mark`)."""
        return messages_since(first, self.name)

    def free(self, terminate=True):
        """Terminate (if ``terminate``) and free the instance, once; never after ``Fatal``."""
        if self.freed:
            return
        self.freed = True
        if self.fatal:
            return
        if terminate:
            try:
                self.fmu.terminate()
            except FMICallException as error:
                if error.status == FATAL[self.extracted.fmi_version]:
                    return
        self.fmu.freeInstance()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.free()


def read_model_description(fmu_path, needs=()):
    """FMPy's model description of the FMU file ``fmu_path``; FMUError naming the file if it is missing, is not an
    FMU that FMPy reads, or has no variable of one of the names ``needs``."""
    try:
        description = fmpy.read_model_description(str(fmu_path))
    except OSError as exc:
        raise FMUError(f"{fmu_path}: cannot read the FMU: {exc.strerror or exc}") from None
    except Exception as exc:  # FMPy's: a zip error, a missing or malformed modelDescription.xml, ...
        text = str(exc).strip().splitlines()
        raise FMUError(f"{fmu_path}: not an FMU ({type(exc).__name__}: {text[0] if text else ''})") from None
    names = {v.name for v in description.modelVariables}
    missing = [name for name in needs if name not in names]
    if missing:
        raise FMUError(f"{fmu_path}: the FMU {description.modelName} has no variable {missing[0]!r}: it is not "
                       f"a SpringBlockFriction FMU")
    return description


class ExtractedFMU:
    """The FMU at ``fmu_path`` read (``model_description``, FMPy's; FMUError as :func:`read_model_description`, which
    checks that it has the variables ``needs``) and extracted to a temporary ``folder`` once; ``variables``: its
    model variables by name. Use as a context manager (the folder is removed at the end)."""

    #: the class :meth:`new_instance` makes
    instance_type = Instance

    def __init__(self, fmu_path, needs=()):
        self.path = str(fmu_path)
        self.model_description = read_model_description(self.path, needs)
        self.folder = fmpy.extract(self.path)
        self.variables = {v.name: v for v in self.model_description.modelVariables}
        self.fmi_version = int(self.model_description.fmiVersion[0])

    @functools.cached_property
    def defaults(self):
        """{parameter or input: its start value in the model description}, an int for an integer variable."""
        return {name: (int(v.start) if v.type.startswith(("Int", "UInt")) else float(v.start))
                for name, v in self.variables.items() if v.causality in ("parameter", "input")}

    def start_values(self, overrides):
        """Every parameter and input with its start value, ``overrides`` (FMU names) applied."""
        unknown = set(overrides) - set(self.defaults)
        if unknown:
            raise KeyError(f"not parameters or inputs of the FMU: {sorted(unknown)}")
        return {**self.defaults, **overrides}

    def new_instance(self, name=None, interface="cs", logging_on=True, fmi_call_logger=None, event_mode_used=False,
                     early_return_allowed=False):
        """A new instance (``fmi2Instantiate`` with fmuType fmi2CoSimulation or fmi2ModelExchange,
        ``fmi3InstantiateCoSimulation`` or ``fmi3InstantiateModelExchange``, for ``interface`` "cs" or "me") named
        ``name`` (default: a new name), logging into the process log; FMUError if the FMU has no such interface.
        ``event_mode_used``, ``early_return_allowed``: fmi3InstantiateCoSimulation's eventModeUsed and
        earlyReturnAllowed (FMI 3 co-simulation only)."""
        _, attribute, *classes = INTERFACES[interface]
        cls = classes[self.fmi_version - 2]
        if getattr(self.model_description, attribute) is None:
            raise FMUError(f"the FMI {self.fmi_version} FMU {self.model_description.modelName} has no "
                           f"{'model exchange' if interface == 'me' else 'co-simulation'}")
        name = name or f"run{next(_INSTANCE_NUMBERS)}"
        fmu = cls(guid=self.model_description.guid, unzipDirectory=self.folder, instanceName=name,
                  modelIdentifier=getattr(self.model_description, attribute).modelIdentifier,
                  fmiCallLogger=fmi_call_logger)
        with preserved_sys_path():  # PythonFMU and pythonfmu3 put the FMU's resources on sys.path
            if self.fmi_version == 2:
                fmu.instantiate(callbacks=fmi2_callbacks(), loggingOn=logging_on)
            else:
                flags = ({"eventModeUsed": event_mode_used, "earlyReturnAllowed": early_return_allowed}
                         if interface == "cs" else {})
                fmu.instantiate(loggingOn=logging_on, logMessage=fmi3_logger(name), **flags)
        check_interrupts()
        return self.instance_type(self, fmu, name)

    def simulate(self, start_values, stop_time, output_interval, outputs=None, **options):
        """FMPy's result array (field ``time`` plus ``outputs``, default: every output) from t = 0 to ``stop_time``
        s with communication step (model exchange: output interval) ``output_interval`` s; ``options``: more
        arguments of ``fmpy.simulate_fmu`` (without ``fmu_instance``, FMPy makes its own instance)."""
        with preserved_sys_path():  # PythonFMU and pythonfmu3 put the FMU's resources on sys.path
            return fmpy.simulate_fmu(
                self.folder, model_description=self.model_description, start_time=0.0, stop_time=stop_time,
                output_interval=output_interval, start_values=start_values,
                output=None if outputs is None else list(outputs), **options,
            )

    def close(self):
        """Remove the extracted folder."""
        shutil.rmtree(self.folder, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def run_fmu(fmu_path, start_values, stop_time, output_interval, interface=None, input_signal=None, outputs=None,
            rtol=1e-8, fmi_call_logger=None):
    """Simulate the FMU at ``fmu_path`` from t = 0 to ``stop_time`` s, sampled every ``output_interval`` s.

    ``interface``: "cs" (co-simulation: the FMU's own exact stepper, communication step ``output_interval``;
    the default) or "me" (model exchange, FMI 2 or 3, under FMPy's CVode at relative tolerance ``rtol``, outputs at
    the grid points only). ``start_values``: {FMU variable name: value}. ``input_signal``: a numpy structured
    array with fields ``time`` and any of ``v_drive``, ``F_ext`` (interpolated linearly, applied at the start
    of each step and held during it). ``outputs``: names to record (default: all outputs).
    Returns FMPy's structured result array (field ``time`` plus the outputs); FMUError (a failed FMI call:
    :class:`FmuCallError`) on any failure.
    """
    interface = interface or "cs"
    options = {"relative_tolerance": rtol, "record_events": False} if interface == "me" else {}
    with ExtractedFMU(fmu_path) as fmu:
        instance = fmu.new_instance(interface=interface, fmi_call_logger=fmi_call_logger)
        try:
            return instance.call(fmu.simulate, start_values, stop_time, output_interval, outputs,
                                 fmu_instance=instance.fmu, fmi_type=INTERFACES[interface][0], input=input_signal,
                                 **options)
        except RuntimeError as error:  # FMPy's CVode failed
            raise FMUError(f"model exchange: {error}") from None
        finally:
            instance.free(terminate=False)  # fmpy.simulate_fmu terminates the instance it is given
