"""Independent reference integrator of the spring-block model (SPEC section 1).

Shares no stepping or event code with the FMU's stepper (``core.trajectory``):
only the friction-law objects, ``Parameters`` and the errors are common. Stuck
phases and affine-law slips are closed forms; other slips use scipy's DOP853
with a graze-proof scan of its dense output. Usage::

    res = simulate_reference(params, x0, v0, [(0.0, v_drive, F_ext), ...], t_eval)
"""

from .integrate import simulate_reference
from .result import ReferenceEvent, ReferenceResult

__all__ = ["ReferenceEvent", "ReferenceResult", "simulate_reference"]
