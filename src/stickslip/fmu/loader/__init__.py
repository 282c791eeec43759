"""The FMUs' Linux binary that loads anywhere: a small C loader in front of PythonFMU's or pythonfmu3's binary.

``runtime.c`` with the front of the FMU's FMI version (``fmi2_front.c``, ``fmi3_front.c``) is compiled
with the system C compiler when an FMU is built (:func:`install`); see their headers for what they do at
run time.
"""

from .install import LIBPYTHON_VARIABLE, SOURCES, install

__all__ = ["LIBPYTHON_VARIABLE", "SOURCES", "install"]
