"""The arrays the chain engine's kernels share, and the column and slot names that index them.

The hot kernels take plain arrays (numba passes an array cheaply; a tuple of arrays costs a reference count per
member at every call); the driver groups them in named tuples:

- :data:`Chain`: ``par`` (N x :data:`PAR_WIDTH` floats: per block ``M`` kg, ``kappa`` N/m, ``k_left``/``k_right``
  N/m (the coupling springs to its left and right neighbours, 0 at the ends), ``atol_x`` m, ``atol_v`` m/s, the
  kinetic parameters from column :data:`KIN` and the static ones from :data:`STA`, :mod:`.laws`) and ``law``
  (N x 2 ints: kinetic and static law codes).
- :data:`Blocks`: ``mode`` (+1, 0, -1 as SPEC section 1), ``x`` (m) and ``v`` (m/s) (current for a slipping block;
  a stuck block's position is its closed form ``x_stuck + v_drive (t - t_stuck)``), and ``blk`` (N x
  :data:`BLK_WIDTH`): ``x_stuck`` (m) and ``t_stuck`` (s) where its stick began, ``t_break`` (s: when a stuck block
  whose neighbours all stick breaks away, inf otherwise), its event indicator and rate at the step's start
  (``e0``, ``d0``) and end (``e1``, ``d1``), and ``rising`` (1: the indicator leaves 0 upwards).
- :data:`Work`: the lists of slipping blocks (``act``) and of stuck blocks with a slipping neighbour (``mon``), the
  Runge-Kutta stages ``kx``, ``kv`` (16 x N), stage and end states ``sx``, ``sv``, ``xn``, ``vn``, the dense
  output's rows ``fx``, ``fv`` (7 x N) and the event scan's samples ``smp`` (3 x ...: times, values, rates).
- :data:`Out`: the buffers of grid rows (time, every block's ``x``, ``v`` and mode) and of events (time, block,
  kind, ``x``, the mode after it) handed to the sink after each chunk.
- ``clock`` (floats, slots ``T_*``) and ``count`` (ints, slots ``C_*``): the scalars of a run.
"""

from collections import namedtuple

import numpy as np

Chain = namedtuple("Chain", "par law")
Blocks = namedtuple("Blocks", "mode x v blk")
Work = namedtuple("Work", "act mon kx kv sx sv xn vn fx fv smp")
Out = namedtuple("Out", "row_t row_x row_v row_mode ev_t ev_block ev_kind ev_x ev_mode")

#: columns of ``par``
M, KAPPA, K_LEFT, K_RIGHT, ATOL_X, ATOL_V = range(6)
KIN, STA, PAR_WIDTH = 6, 11, 15
#: columns of ``blk``
X_STUCK, T_STUCK, T_BREAK, E0, D0, E1, D1, RISING = range(8)
BLK_WIDTH = 8
#: ``clock``: time (s), next step size (s), earliest ``t_break`` (s), stop time (s), grid interval (s, 0: none),
#: time of the last event (s), ``v_drive`` (m/s), ``rtol``, the longest step (s)
T_NOW, T_STEP, T_QUIET, T_STOP, T_GRID, T_EVENT, V_DRIVE, RTOL, H_MAX = range(9)
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
                *(np.zeros(n) for _ in range(4)), np.zeros((7, n)), np.zeros((7, n)), np.zeros((3, SAMPLES + 3)))


def out_arrays(n, rows, events):
    """Empty :data:`Out` buffers for ``rows`` grid rows of ``n`` blocks and ``events`` events."""
    return Out(np.zeros(rows), np.zeros((rows, n)), np.zeros((rows, n)), np.zeros((rows, n), np.int64),
               np.zeros(events), np.zeros(events, np.int64), np.zeros(events, np.int64), np.zeros(events),
               np.zeros(events, np.int64))
