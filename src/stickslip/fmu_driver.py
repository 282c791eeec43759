"""Host side of the SpringBlockFriction FMU: build it when stale and simulate it with FMPy.

:func:`run_fmu` turns every FMI failure into :class:`FMUError` carrying the
FMU's own log text (for a bad parameter: its name, value and allowed range).
The FMU's loader passes errors at every logging setting; logging is on so that
an FMU built without the loader (no C compiler) passes them too.
"""

import itertools
import shutil
from pathlib import Path

import fmpy
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, fmi2Fatal

from .core.errors import StickSlipError
from .fmi_host import callbacks, log_mark, messages_since, preserved_sys_path
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
    model_description = fmpy.read_model_description(str(fmu_path))
    unzipdir = fmpy.extract(str(fmu_path))
    name = f"run{next(_RUN_NUMBERS)}"
    mark = log_mark()
    fmu = FMU2Slave(guid=model_description.guid, unzipDirectory=unzipdir, instanceName=name,
                    modelIdentifier=model_description.coSimulation.modelIdentifier, fmiCallLogger=fmi_call_logger)
    try:
        with preserved_sys_path():  # PythonFMU puts the FMU's resources on sys.path
            fmu.instantiate(callbacks=callbacks(), loggingOn=True)
            return fmpy.simulate_fmu(
                unzipdir, model_description=model_description, fmu_instance=fmu, start_time=0.0,
                stop_time=stop_time, output_interval=output_interval, start_values=start_values,
                input=input_signal, output=outputs,
            )
    except FMICallException as error:
        if error.status == fmi2Fatal:  # PythonFMU already released the slave: freeing it again corrupts memory
            fmu = None
        raise FMUError("\n".join([str(error), *messages_since(mark, name)])) from None
    finally:
        if fmu is not None:
            fmu.freeInstance()
        shutil.rmtree(unzipdir, ignore_errors=True)


_RUN_NUMBERS = itertools.count(1)  # instance names, so each run reads only its own log messages
