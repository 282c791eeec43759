"""Independent reference integrator of the spring-block model (SPEC section 1).

Shares no code with the FMU's runtime (``stickslip.core``; a test checks its
imports): its own friction laws and parameter checks written from SPEC section 2
(:mod:`.laws`), its own hybrid rules, stepping, event location and errors.
Stuck phases and affine-law slips are closed forms; other slips use scipy's
DOP853 with a graze-proof scan of its dense output. Usage::

    params = parameters_from_values({"M": 1.0, "kappa": 1.0, "kinetic.law": "coulomb", "kinetic.F0": 0.5,
                                     "static.law": "constant", "static.F0": 1.0})
    res = simulate_reference(params, x0, v0, [(0.0, v_drive, F_ext), ...], t_eval)

A chain of blocks joined by springs (SPEC section 5): :func:`simulate_chain` (:mod:`.chain`).

The two integrators (and with them SciPy) load at their first use: a program that only describes blocks or reads
results (a co-simulation's system file, its events) does not pay for them.
"""

import importlib

from .chain_result import ChainBlock, ChainEvent, ChainResult
from .errors import ReferenceFailure, ReferenceParameterError, ReferenceSolverError
from .laws import CustomKinetic, CustomStatic, ReferenceParameters, law, parameters_from_values
from .result import ReferenceEvent, ReferenceResult

_INTEGRATORS = {"simulate_chain": ".chain", "simulate_reference": ".integrate"}  # name: its module, loaded at first use


def __getattr__(name):
    if name in _INTEGRATORS:
        value = getattr(importlib.import_module(_INTEGRATORS[name], __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

__all__ = ["ChainBlock", "ChainEvent", "ChainResult", "CustomKinetic", "CustomStatic", "ReferenceEvent", "ReferenceFailure", "ReferenceParameterError",
           "ReferenceParameters", "ReferenceResult", "ReferenceSolverError", "law", "parameters_from_values",
           "simulate_chain", "simulate_reference"]
