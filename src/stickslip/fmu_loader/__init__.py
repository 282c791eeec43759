"""The FMU's linux64 binary that loads anywhere: a small C loader in front of PythonFMU's binary.

``loader.c`` is compiled with the system C compiler when an FMU is built
(:func:`install`); see its header for what it does at run time.
"""

from .build import LIBPYTHON_VARIABLE, SOURCES, install

__all__ = ["LIBPYTHON_VARIABLE", "SOURCES", "install"]
