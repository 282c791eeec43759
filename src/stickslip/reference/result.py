"""What :func:`simulate_reference` returns."""

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class ReferenceEvent:
    """A mode change at time ``t`` (s).

    ``kind`` is "stick" (slip -> stuck), "slip" (stuck -> slip), "overshoot"
    (slip -> opposite slip through ``v_rel = 0``) or "input" (caused by an
    input jump at a breakpoint). Modes are +1, 0, -1 (SPEC section 1).
    """

    t: float
    kind: str
    mode_before: int
    mode_after: int


@dataclass
class ReferenceResult:
    """The trajectory on the output grid, state after any event at each grid time.

    ``t`` (s), ``x`` (m), ``v`` (m/s), ``mode`` (int), ``t_stick`` (s, 0 while
    slipping), and the inputs held there: ``v_drive`` (m/s), ``F_ext`` (N).
    ``events`` lists every mode change in time order.
    """

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    mode: np.ndarray
    t_stick: np.ndarray
    v_drive: np.ndarray
    F_ext: np.ndarray
    events: list = field(default_factory=list)
