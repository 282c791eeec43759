"""The ``native`` master: the compiled chain engine (:mod:`stickslip.chain`), no FMU.

Every block of the system in one event-driven integration: DOP853 steps of the slipping blocks at the relative
tolerance ``rtol`` (default 1e-10), stuck blocks in closed form, each block's events located on the steps' dense
output (graze-proof) and landed by true steps (:mod:`stickslip.chain.kernel`). Its grid rows are the system's output
grid; every block event is known with its time (``events_complete``), and written as CSV where
:attr:`NativeMaster.events_path` is set (columns ``time,block,kind,x``, :mod:`stickslip.chain.output`).
"""

import numpy as np

from ..hosts.fmpy_host import FMUError
from .master import SystemResult, checked_rtol, new_event


class NativeMaster:
    """Relative tolerance ``rtol`` of the chain engine (default 1e-10, allowed ``[1e-14, 0.01]``)."""

    NAME = "native"
    FMI_VERSION = None  # runs no FMU
    OPTIONS = ("rtol",)

    def __init__(self, rtol=None):
        self.rtol = checked_rtol("native", rtol, default=1e-10, lowest=1e-14)
        self.events_path = None

    def run(self, system, fmu_path=None, progress=lambda t: None):
        """Simulate ``system`` (``fmu_path`` is not used); a :class:`~.master.SystemResult` on its grid."""
        # here: the chain package loads numba, which the other masters' commands do not need
        from ..chain.engine import run_chain
        from ..chain.output import MemorySink, write_block_events
        from ..chain.spec import ChainSpec

        sink = MemorySink()
        summary = run_chain(ChainSpec.from_system(system), system.stop_time, rtol=self.rtol,
                            output_interval=system.output_interval, sink=sink, progress=progress)
        grid = system.times()
        if sink.t.shape != grid.shape or not np.allclose(sink.t, grid, rtol=1e-12, atol=0.0):
            raise FMUError(f"native: the engine's {sink.t.size} grid rows are not the system's {grid.size} times")
        if self.events_path is not None:
            write_block_events(self.events_path, sink.event_t, sink.event_block, sink.event_kind, sink.event_x)
        events = _events(system, sink)
        counts = np.bincount(sink.event_block, minlength=system.n)
        stats = {"steps": summary.steps, "rejected steps": summary.rejected_steps,
                 "dense outputs": summary.dense_outputs, "compile time (s)": round(summary.compile_time, 3),
                 "compiled": "yes" if summary.compiled else "no (plain Python)"}
        return SystemResult(self.NAME, grid, sink.x, sink.v, sink.mode, events, True, counts, summary.wall_time,
                            settings={"rtol": self.rtol}, stats=stats)


def _events(system, sink):
    """The sink's events as :class:`~stickslip.reference.ChainEvent`: the mode before each from the block's previous
    event, or its start (stuck if it starts at ``v_drive``, else the sign of ``v_rel``)."""
    from ..chain.output import EVENT_KINDS

    modes = [0 if b["v_start"] == system.v_drive else (1 if system.v_drive > b["v_start"] else -1)
             for b in system.blocks]
    events = []
    for t, block, kind, after in zip(sink.event_t.tolist(), sink.event_block.tolist(), sink.event_kind.tolist(),
                                     sink.event_mode.tolist()):
        before = {"slip": 0, "overshoot": -after}.get(EVENT_KINDS[kind], modes[block])
        events.append(new_event(t, block, before, after))
        modes[block] = after
    return events
