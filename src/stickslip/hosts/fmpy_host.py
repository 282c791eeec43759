"""Host the SpringBlockFriction FMUs under FMPy: FMI 2.0 co-simulation, FMI 3.0 co-simulation and model exchange,
with one error type (:class:`FMUError`) and one log.

- :func:`instantiate` makes an instance of an extracted FMU that logs into the process log; :func:`run_fmu`
  simulates an FMU file with ``fmpy.simulate_fmu`` and turns every FMI failure into :class:`FMUError` carrying
  the FMU's own log text (for a bad parameter: its name, value and allowed range). The FMUs' loader passes
  errors at every logging setting; logging is on so that an FMU built without the loader (no C compiler)
  passes them too.
- The log: FMPy's native logging proxy forwards the messages of every FMI 2 instance in the process to ONE
  logger, the one registered last, and a logger that is later garbage collected makes the next message crash
  the process. So every instance logs through callbacks that live as long as the process, into one list;
  callers read their instance's messages with :func:`log_mark` and :func:`messages_since`.
- Model exchange runs under FMPy's CVode (BDF, Newton with a dense Jacobian by difference quotients) with the
  relative tolerance ``rtol`` and the absolute tolerance ``rtol`` times the FMU's nominal of each state
  (``F_S(0)/kappa`` for ``x``, ``F_S(0)/sqrt(kappa M)`` for ``v``); FMPy caps CVode's step at 1/50 of the run.
  Inputs for model exchange are best given as steps (:func:`stickslip.suite.inputs.held_input_table`): the
  FMU treats an input change as a jump at the next event update, as a co-simulation step holds its inputs.
- PythonFMU and pythonfmu3 release the slave themselves when they report ``Fatal``: such an instance is never
  freed again.
"""

import itertools
import shutil
from ctypes import byref

import fmpy
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2Fatal
from fmpy.fmi3 import FMU3Model, FMU3Slave, fmi3Fatal, fmi3LogMessageCallback
from fmpy.logging import addLoggerProxy

from ..core.errors import StickSlipError
from ..fmu.python_path import preserved_sys_path

#: interface: (FMPy's fmi_type, the model description's attribute, FMI 2 class, FMI 3 class)
INTERFACES = {"cs": ("CoSimulation", "coSimulation", FMU2Slave, FMU3Slave),
              "me": ("ModelExchange", "modelExchange", None, FMU3Model)}
FATAL = {2: fmi2Fatal, 3: fmi3Fatal}

_MESSAGES = []  # (instance name, status, message) of every message with status >= warning, in order
_KEEP_ALIVE = []  # callbacks handed to FMUs: an instance may call them as long as it lives
_INSTANCE_NUMBERS = itertools.count(1)  # instance names, so each run reads only its own log messages


class FMUError(StickSlipError):
    """An FMI call of the FMU failed; the message contains the FMU's log."""


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


def fmi_version(model_description):
    """2 or 3, the FMI version of a model description read by FMPy."""
    return int(model_description.fmiVersion[0])


def instantiate(model_description, unzipdir, interface="cs", name=None, logging_on=True, fmi_call_logger=None):
    """An instantiated FMPy instance of the FMU extracted to ``unzipdir`` (``interface`` "cs" or "me"), logging
    into the process log under ``name`` (default: a new name); FMUError if the FMU has no such interface."""
    _, attribute, *classes = INTERFACES[interface]
    version = fmi_version(model_description)
    cls = classes[version - 2]
    if cls is None or getattr(model_description, attribute) is None:
        raise FMUError(f"the FMI {version} FMU {model_description.modelName} has no "
                       f"{'model exchange' if interface == 'me' else 'co-simulation'}")
    name = name or f"run{next(_INSTANCE_NUMBERS)}"
    fmu = cls(guid=model_description.guid, unzipDirectory=unzipdir, instanceName=name,
              modelIdentifier=getattr(model_description, attribute).modelIdentifier, fmiCallLogger=fmi_call_logger)
    with preserved_sys_path():  # PythonFMU and pythonfmu3 put the FMU's resources on sys.path
        if version == 2:
            fmu.instantiate(callbacks=fmi2_callbacks(), loggingOn=logging_on)
        else:
            fmu.instantiate(loggingOn=logging_on, logMessage=fmi3_logger(name))
    return fmu


def run_fmu(fmu_path, start_values, stop_time, output_interval, interface=None, input_signal=None, outputs=None,
            rtol=1e-8, fmi_call_logger=None):
    """Simulate the FMU at ``fmu_path`` from t = 0 to ``stop_time`` s, sampled every ``output_interval`` s.

    ``interface``: "cs" (co-simulation: the FMU's own exact stepper, communication step ``output_interval``;
    the default) or "me" (FMI 3 model exchange under FMPy's CVode at relative tolerance ``rtol``, outputs at
    the grid points only). ``start_values``: {FMU variable name: value}. ``input_signal``: a numpy structured
    array with fields ``time`` and any of ``v_drive``, ``F_ext`` (interpolated linearly, applied at the start
    of each step and held during it). ``outputs``: names to record (default: all outputs).
    Returns FMPy's structured result array (field ``time`` plus the outputs); FMUError on any FMI failure.
    """
    interface = interface or "cs"
    model_description = fmpy.read_model_description(str(fmu_path))
    unzipdir = fmpy.extract(str(fmu_path))
    mark, name = log_mark(), f"run{next(_INSTANCE_NUMBERS)}"
    fmu = None
    try:
        fmu = instantiate(model_description, unzipdir, interface, name, fmi_call_logger=fmi_call_logger)
        options = {"relative_tolerance": rtol, "record_events": False} if interface == "me" else {}
        with preserved_sys_path():
            return fmpy.simulate_fmu(
                unzipdir, model_description=model_description, fmu_instance=fmu, fmi_type=INTERFACES[interface][0],
                start_time=0.0, stop_time=stop_time, output_interval=output_interval, start_values=start_values,
                input=input_signal, output=outputs, **options,
            )
    except FMICallException as error:
        if error.status == FATAL[fmi_version(model_description)]:  # the library released the slave: never free it
            fmu = None
        raise FMUError("\n".join([str(error), *messages_since(mark, name)])) from None
    except RuntimeError as error:  # FMPy's CVode failed
        raise FMUError(f"model exchange: {error}") from None
    finally:
        if fmu is not None:
            fmu.freeInstance()
        shutil.rmtree(unzipdir, ignore_errors=True)
