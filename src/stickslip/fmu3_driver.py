"""Host side of the FMI 3 FMU: build it when stale and simulate it with FMPy, as co-simulation or model exchange.

Co-simulation is driven exactly as the FMI 2 FMU (:func:`stickslip.fmu_driver.run_fmu`). Model exchange
runs under FMPy's CVode (BDF, Newton with a dense Jacobian by difference quotients) with the relative
tolerance ``rtol`` and the absolute tolerance ``rtol`` times the FMU's nominal of each state
(``F_S(0)/kappa`` for ``x``, ``F_S(0)/sqrt(kappa M)`` for ``v``); FMPy caps CVode's step at 1/50 of the
run. Inputs for model exchange are best given as steps (:func:`held_input_table`): the FMU treats an
input change as a jump at the next event update, as a co-simulation step holds its inputs.
"""

import itertools
import shutil

import fmpy
import numpy as np
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Model, FMU3Slave, fmi3Fatal, fmi3LogMessageCallback

from .fmi_host import preserved_sys_path
from .fmu3_build import build3, default_fmu3_path, is_current
from .fmu_driver import FMUError
from .inputs import INPUT_NAMES

INTERFACES = {"cs": ("CoSimulation", FMU3Slave), "me": ("ModelExchange", FMU3Model)}
_LOGGERS = []  # log callbacks handed to FMU instances: an instance may call its logger as long as it lives
_RUN_NUMBERS = itertools.count(1)


def ensure_fmu3(fmu_path=None):
    """Build the FMI 3 FMU at ``fmu_path`` (default ``dist/SpringBlockFriction-fmi3.fmu``) unless it is
    current; return its path."""
    fmu_path = fmu_path or default_fmu3_path()
    if not is_current(fmu_path):
        build3(fmu_path)
    return fmu_path


def held_input_table(breakpoints, stop_time):
    """FMPy input table that holds each of ``breakpoints`` ``[(t, v_drive, F_ext), ...]`` until the next
    (a step there) and the last until ``stop_time``."""
    rows = [(breakpoints[0][0], *breakpoints[0][1:])]
    for (_, *before), (t, *after) in zip(breakpoints, breakpoints[1:]):
        rows += [(t, *before), (t, *after)]
    rows.append((stop_time, *breakpoints[-1][1:]))
    return np.array(rows, dtype=[("time", np.float64)] + [(name, np.float64) for name in INPUT_NAMES])


def run_fmu3(fmu_path, start_values, stop_time, output_interval, interface="cs", input_signal=None, outputs=None,
             rtol=1e-8):
    """Simulate the FMI 3 FMU from t = 0 to ``stop_time`` s; FMPy's result array, sampled every ``output_interval`` s.

    ``interface``: "cs" (the FMU's own exact stepper, communication step ``output_interval``) or "me"
    (FMPy's CVode at relative tolerance ``rtol``, outputs at the grid points only). Other arguments as
    :func:`stickslip.fmu_driver.run_fmu`. An FMI failure raises :class:`FMUError` with the FMU's log.
    """
    fmi_type, cls = INTERFACES[interface]
    model_description = fmpy.read_model_description(str(fmu_path))
    unzipdir = fmpy.extract(str(fmu_path))
    messages = []
    logger = fmi3LogMessageCallback(lambda _env, status, _category, message: messages.append(
        message.decode(errors="replace")) if status >= 1 else None)
    _LOGGERS.append(logger)
    fmu = cls(guid=model_description.guid, unzipDirectory=unzipdir, instanceName=f"run3_{next(_RUN_NUMBERS)}",
              modelIdentifier=getattr(model_description, "modelExchange" if interface == "me" else "coSimulation")
              .modelIdentifier)
    options = {"relative_tolerance": rtol, "record_events": False} if interface == "me" else {}
    try:
        with preserved_sys_path():  # pythonfmu3 puts the FMU's resources on sys.path
            fmu.instantiate(loggingOn=True, logMessage=logger)
            return fmpy.simulate_fmu(
                unzipdir, model_description=model_description, fmu_instance=fmu, fmi_type=fmi_type,
                start_time=0.0, stop_time=stop_time, output_interval=output_interval, start_values=start_values,
                input=input_signal, output=outputs, **options,
            )
    except FMICallException as error:
        if error.status == fmi3Fatal:  # pythonfmu3 released the slave: never free it again
            fmu = None
        raise FMUError("\n".join([str(error), *messages])) from None
    except RuntimeError as error:  # FMPy's CVode failed
        raise FMUError(f"model exchange: {error}") from None
    finally:
        if fmu is not None:
            fmu.freeInstance()
        shutil.rmtree(unzipdir, ignore_errors=True)
