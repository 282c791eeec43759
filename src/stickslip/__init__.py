"""stickslip: exact spring-block dry friction, as an FMI 2.0 co-simulation FMU and a Python API."""

from .core import *  # noqa: F401,F403
from .core import __all__

__version__ = "0.1.0"
