"""stickslip: exact spring-block dry friction, as an FMI 2.0 co-simulation FMU and a Python API.

The runtime's public names (:mod:`stickslip.core`) are this package's too, imported when one is first used, so that
the command line's entry point (:mod:`stickslip.cli`) loads nothing before it takes Ctrl-C.
"""

import importlib

__version__ = "0.1.0"


def __getattr__(name):
    core = importlib.import_module(".core", __name__)
    if name == "__all__" or name in core.__all__:
        return getattr(core, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted({*globals(), *importlib.import_module(".core", __name__).__all__})
