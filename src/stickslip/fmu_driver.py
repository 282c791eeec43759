"""Host side of the SpringBlockFriction FMU: build it when stale and simulate it with FMPy.

:func:`run_fmu` turns every FMI failure into :class:`FMUError` carrying the
FMU's own log text (for a bad parameter: its name, value and allowed range).
PythonFMU passes that text only when debug logging is on, so it always is.
"""

import shutil
import sys
from ctypes import byref
from pathlib import Path

import fmpy
from fmpy.fmi1 import FMICallException, printLogMessage
from fmpy.fmi2 import fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2Fatal
from fmpy.logging import addLoggerProxy

from .core.errors import StickSlipError
from .fmu_build import REPO, MODEL_NAME, build, built_tag, source_tag


class FMUError(StickSlipError):
    """An FMI call of the FMU failed; the message contains the FMU's log."""


def default_fmu_path():
    """Path of the FMU that ``python build_fmu.py`` writes: ``<repo>/dist/SpringBlockFriction.fmu``."""
    return REPO / "dist" / f"{MODEL_NAME}.fmu"


def ensure_fmu(fmu_path=None):
    """Build the FMU at ``fmu_path`` (default: :func:`default_fmu_path`) unless it matches the sources; return its path.

    An FMU matches when the source tag in its name-mangled runtime is that of the current sources.
    """
    fmu_path = Path(fmu_path or default_fmu_path())
    if not fmu_path.is_file() or built_tag(fmu_path) != source_tag():
        build(fmu_path)
    return fmu_path


def run_fmu(fmu_path, start_values, stop_time, output_interval, input_signal=None, outputs=None, fmi_call_logger=None):
    """Simulate the FMU from t = 0 to ``stop_time`` s with communication step ``output_interval`` s.

    ``start_values``: {FMU variable name: value}. ``input_signal``: a numpy structured array with
    fields ``time`` and any of ``v_drive``, ``F_ext`` (interpolated linearly, applied at the start of
    each step and held during it). ``outputs``: names to record (default: all outputs).
    Returns FMPy's structured result array (field ``time`` plus the outputs).
    """
    messages = []

    def collect(_env, _instance, status, _category, message):
        if status >= 1:  # warning, discard, error or fatal
            messages.append(message.decode())

    model_description = fmpy.read_model_description(str(fmu_path))
    unzipdir = fmpy.extract(str(fmu_path))
    path_before = list(sys.path)
    fmu = None
    try:
        fmu = fmpy.instantiate_fmu(
            unzipdir, model_description, "CoSimulation", debug_logging=True, logger=collect,
            fmi_call_logger=fmi_call_logger,
        )
        return fmpy.simulate_fmu(
            unzipdir, model_description=model_description, fmu_instance=fmu, start_time=0.0, stop_time=stop_time,
            output_interval=output_interval, start_values=start_values, input=input_signal, output=outputs,
        )
    except FMICallException as error:
        if error.status == fmi2Fatal:  # PythonFMU already released the slave: freeing it again corrupts memory
            fmu = None
        raise FMUError("\n".join([str(error), *messages])) from None
    finally:
        if fmu is not None:
            fmu.freeInstance()
        sys.path[:] = path_before  # PythonFMU put the FMU's resources on sys.path
        shutil.rmtree(unzipdir, ignore_errors=True)
        _restore_fmpy_logger()


_PRINTING_LOGGER = fmi2CallbackLoggerTYPE(printLogMessage)  # lives as long as the process


def _restore_fmpy_logger():
    """Make FMPy's default printing logger the process-wide one again.

    FMPy's native logging proxy forwards every FMU's messages to ONE process-wide
    logger, the last one registered: after a run it would point to that run's
    freed callback, and the next instance that logs would crash the process.
    """
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = _PRINTING_LOGGER
    addLoggerProxy(byref(callbacks))
