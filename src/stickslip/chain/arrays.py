"""The arrays the chain engine's kernels share, grouped in named tuples (numba passes them as they are).

- :data:`Chain`: the constants: per block ``M`` (kg), ``kappa`` (N/m), law codes and rows (:mod:`.laws`),
  ``k_left``/``k_right`` (N/m, the coupling springs to the block's left and right neighbours, 0 at the ends),
  ``atol_x`` (m) and ``atol_v`` (m/s); ``v_drive`` (m/s), ``rtol`` and ``h_max`` (s, the longest step).
- :data:`Blocks`: each block's ``mode`` (+1, 0, -1 as SPEC section 1), ``x`` (m) and ``v`` (m/s) (current for a
  slipping block; a stuck block's position is ``x_stuck + v_drive (t - t_stuck)``), ``x_stuck`` (m) and
  ``t_stuck`` (s) where its stick began, ``t_break`` (s: when a stuck block whose neighbours all stick breaks away,
  inf otherwise), ``rising`` (its event indicator leaves 0 upwards).
- :data:`Work`: the lists of slipping (``act``) and watched stuck blocks (``mon``: a slipping neighbour), the
  Runge-Kutta stages ``kx``, ``kv`` (16 x N), stage and end states, the dense output's rows ``fx``, ``fv`` (7 x N),
  each block's indicator and its rate at the step's start (``e0``, ``d0``) and end (``e1``, ``d1``), and the scan's
  samples.
- :data:`Out`: the buffers of grid rows and events handed to the sink after each chunk.
- ``clock`` (floats, indices ``T_*``) and ``count`` (ints, indices ``C_*``): the scalars of a run.
"""

from collections import namedtuple

import numpy as np

Chain = namedtuple("Chain", "M kappa kin_law kin sta_law sta k_left k_right atol_x atol_v v_drive rtol h_max")
Blocks = namedtuple("Blocks", "mode x v x_stuck t_stuck t_break rising")
Work = namedtuple("Work", "act mon kx kv sx sv xn vn fx fv e0 d0 e1 d1 sample_t sample_f sample_d")
Out = namedtuple("Out", "row_t row_x ev_t ev_block ev_kind ev_x")

#: ``clock``: time (s), next step size (s), earliest ``t_break`` (s), stop time (s), grid interval (s, 0: none),
#: time of the last event (s)
T_NOW, T_STEP, T_QUIET, T_STOP, T_GRID, T_EVENT = range(6)
#: ``count``: slipping blocks, watched stuck blocks, the block of ``T_QUIET``, next grid index, rows and events in
#: the buffers, accepted and rejected steps, dense outputs built, events in all, events at ``T_EVENT``, step budget
#: of the chunk, status
(C_ACT, C_MON, C_QUIET, C_GRID, C_ROWS, C_EVENTS, C_STEPS, C_REJECTED, C_DENSE, C_ALL_EVENTS, C_INSTANT, C_BUDGET,
 C_STATUS) = range(13)
#: event kinds (:data:`.output.EVENT_KINDS`)
SLIP, STICK, OVERSHOOT = 0, 1, 2
#: samples per step where the event scan reads the dense output
SAMPLES = 12
STAGES = 16


def work_arrays(n):
    """Fresh :data:`Work` for ``n`` blocks."""
    return Work(np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros((STAGES, n)), np.zeros((STAGES, n)),
                *(np.zeros(n) for _ in range(4)), np.zeros((7, n)), np.zeros((7, n)),
                *(np.zeros(n) for _ in range(4)), *(np.zeros(SAMPLES + 3) for _ in range(3)))


def out_arrays(n, rows, events):
    """Empty :data:`Out` buffers for ``rows`` grid rows of ``n`` blocks and ``events`` events."""
    return Out(np.zeros(rows), np.zeros((rows, n)), np.zeros(events), np.zeros(events, np.int64),
               np.zeros(events, np.int64), np.zeros(events))
