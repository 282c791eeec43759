"""PythonFMU and pythonfmu3 put an FMU's resources (or a build folder) on ``sys.path`` and leave them there:
:func:`preserved_sys_path` puts the old path back, for the builders and the hosts alike."""

import sys
from contextlib import contextmanager


@contextmanager
def preserved_sys_path():
    """Restore ``sys.path`` after the block, whatever was added to it."""
    before = list(sys.path)
    try:
        yield
    finally:
        sys.path[:] = before
