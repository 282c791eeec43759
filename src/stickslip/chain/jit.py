"""The compiler of the chain engine's kernels: numba's ``njit`` (cached on disk), or plain Python where numba
cannot be imported or is switched off (``NUMBA_DISABLE_JIT=1``): the same functions, the same numbers, slower.

:func:`say_if_plain` writes once per process on stderr that the engine runs as plain Python.
"""

import sys

try:
    import numba
except ImportError:  # the engine still runs, as plain Python
    numba = None

#: whether the kernels are compiled
COMPILED = numba is not None and not numba.config.DISABLE_JIT
_told = []


def njit(function):
    """``function`` compiled in nopython mode with its machine code cached beside the module (or in
    ``NUMBA_CACHE_DIR``); ``function`` itself where numba is missing."""
    if numba is None:
        return function
    return numba.njit(cache=True, nogil=True)(function)


def say_if_plain():
    """Once per process: a line on stderr if the kernels run as plain Python, and why."""
    if COMPILED or _told:
        return
    _told.append(True)
    why = "numba cannot be imported" if numba is None else "NUMBA_DISABLE_JIT is set"
    print(f"stickslip chain engine: {why}; the kernels run as plain Python (same numbers, far slower)",
          file=sys.stderr)
