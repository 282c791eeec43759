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
"""

from .chain import ChainBlock, simulate_chain
from .chain_result import ChainEvent, ChainResult
from .errors import ReferenceFailure, ReferenceParameterError, ReferenceSolverError
from .integrate import simulate_reference
from .laws import CustomKinetic, CustomStatic, ReferenceParameters, law, parameters_from_values
from .result import ReferenceEvent, ReferenceResult

__all__ = ["ChainBlock", "ChainEvent", "ChainResult", "CustomKinetic", "CustomStatic", "ReferenceEvent", "ReferenceFailure", "ReferenceParameterError",
           "ReferenceParameters", "ReferenceResult", "ReferenceSolverError", "law", "parameters_from_values",
           "simulate_chain", "simulate_reference"]
