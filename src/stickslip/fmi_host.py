"""What a host process must do around PythonFMU FMUs under FMPy, in one place.

- PythonFMU puts an FMU's resources (or a build folder) on ``sys.path`` and
  leaves it there: :func:`preserved_sys_path` puts the old path back.
- FMPy's native logging proxy forwards the messages of every FMU in the
  process to ONE logger, the one registered last; a logger that is later
  garbage collected makes the next message crash the process. So every
  instance we create logs through :data:`_LOGGER`, which lives as long as the
  process and appends to :data:`_MESSAGES`; callers read their instance's
  messages with :func:`log_mark` and :func:`messages_since`.
"""

import sys
from contextlib import contextmanager
from ctypes import byref

from fmpy.fmi2 import defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.logging import addLoggerProxy

_MESSAGES = []  # (instance name, status, message) of every message with status >= warning, in order
_KEEP_ALIVE = []  # callback structs handed to FMUs: an FMU may keep the pointer for its whole life


@contextmanager
def preserved_sys_path():
    """Restore ``sys.path`` after the block, whatever PythonFMU added to it."""
    before = list(sys.path)
    try:
        yield
    finally:
        sys.path[:] = before


def _collect(_env, instance, status, _category, message):
    if status >= 1:  # warning, discard, error or fatal
        _MESSAGES.append((instance.decode(errors="replace") if instance else "", int(status),
                          message.decode(errors="replace") if message else ""))


_LOGGER = fmi2CallbackLoggerTYPE(_collect)


def callbacks():
    """FMI 2 callback functions for a new instance; makes :data:`_LOGGER` the proxy's target."""
    functions = fmi2CallbackFunctions()
    functions.logger = _LOGGER
    functions.allocateMemory = defaultCallbacks.allocateMemory
    functions.freeMemory = defaultCallbacks.freeMemory
    addLoggerProxy(byref(functions))
    _KEEP_ALIVE.append(functions)
    return functions


def log_mark():
    """The position in the process log; pass it to :func:`messages_since`."""
    return len(_MESSAGES)


def messages_since(mark, instance_name):
    """Messages (status >= warning) of the instance ``instance_name`` logged after ``mark``."""
    return [message for name, _, message in _MESSAGES[mark:] if name == instance_name]
