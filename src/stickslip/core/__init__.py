"""The FMU runtime: friction laws, hybrid model and exact stepper.

Pure Python and ``math`` only (no numpy/scipy), and only relative imports, so
``build_fmu.py`` can bundle this folder into the FMU under a name that only the
FMU uses. The hot modules may also be compiled from these same sources (mypyc);
:data:`IMPLEMENTATION` says which runs (see :mod:`._implementation`).
"""

import os as _os

# an FMU's copy: its modules packed into one file beside this one (see ._implementation), after the compiled ones
__path__.append(_os.path.join(__path__[0], "sources.zip"))

from ._implementation import select as _select

IMPLEMENTATION = _select(__name__, _os.path.dirname(__file__))

from . import saved_state
from .errors import ParameterError, SolverError, StateError, StickSlipError
from .exchange import INDICATORS, ExchangeBlock
from .laws import (
    KINETIC_LAWS,
    STATIC_LAWS,
    CallableKinetic,
    CallableStatic,
    CarlsonLanger,
    Constant,
    Coulomb,
    Logarithmic,
    Lubricated,
    Saturating,
    Sigmoid,
    Stribeck,
    Viscous,
    kinetic_law,
    static_law,
)
from .model import BACKWARD, FORWARD, STUCK, Parameters, check_input, check_rate_scale
from .ranges import ANY_FINITE, NON_NEGATIVE, POSITIVE, check
from .state_bytes import BlockStateFormat
from .trajectory import OUTPUT_NAMES, RTOL_RANGE, Trajectory, state_snapshot

__all__ = [
    "ANY_FINITE", "BACKWARD", "BlockStateFormat", "FORWARD",
    "IMPLEMENTATION", "INDICATORS", "ExchangeBlock", "NON_NEGATIVE", "POSITIVE", "STUCK", "KINETIC_LAWS",
    "OUTPUT_NAMES", "STATIC_LAWS",
    "CallableKinetic", "CallableStatic", "CarlsonLanger", "Constant", "Coulomb", "Logarithmic", "Lubricated",
    "Parameters", "ParameterError", "RTOL_RANGE", "Saturating", "Sigmoid", "SolverError", "StateError",
    "StickSlipError", "Stribeck", "Trajectory", "Viscous", "check", "check_input", "check_rate_scale", "kinetic_law",
    "saved_state", "state_snapshot", "static_law",
]
