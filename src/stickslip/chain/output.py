"""Where the chain engine streams its output: sinks that take batches and keep memory flat.

A sink has ``positions(t, x)``: grid rows, ``t`` the times (s, shape ``(k,)``) and ``x`` every block's position
(m, shape ``(k, N)``, the state after any event at that time); ``events(t, block, kind, x)``: a batch of block events
in time order, ``t`` (s), ``block`` (0-based ints), ``kind`` (codes of :data:`EVENT_KINDS`), ``x`` the block's
position (m); and ``close()``. The engine calls them between its compiled chunks and closes the sink at the end of
the run (also when it stops early).
"""

from pathlib import Path

import numpy as np

#: event kind code: its name (SPEC section 1): slip (stuck -> slipping), stick (slipping -> stuck), overshoot (the
#: slip direction reverses)
EVENT_KINDS = ("slip", "stick", "overshoot")
POSITIONS_FILE = "positions.csv"
EVENTS_FILE = "block_events.csv"


class CsvSink:
    """Writes ``<folder>/positions.csv`` (``time,x_b1,...,x_bN``; only if positions come) and
    ``<folder>/block_events.csv`` (``time,block,kind,x``, ``block`` 1-based, ``kind`` by name); every batch is
    flushed, so the files are complete up to the last batch if the run stops."""

    def __init__(self, folder):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self._positions = None
        self._events = open(self.folder / EVENTS_FILE, "w")
        self._events.write("time,block,kind,x\n")
        self._events.flush()

    @property
    def files(self):
        """The files written (paths)."""
        return [self.folder / name for name, f in ((POSITIONS_FILE, self._positions), (EVENTS_FILE, self._events))
                if f is not None]

    def positions(self, t, x):
        if self._positions is None:
            self._positions = open(self.folder / POSITIONS_FILE, "w")
            self._positions.write(",".join(["time", *(f"x_b{i + 1}" for i in range(x.shape[1]))]) + "\n")
        np.savetxt(self._positions, np.column_stack([t, x]), fmt="%.17g", delimiter=",")
        self._positions.flush()

    def events(self, t, block, kind, x):
        names = np.array(EVENT_KINDS)[kind]
        lines = (f"{ti!r},{b + 1},{k},{xi!r}\n" for ti, b, k, xi in zip(t.tolist(), block.tolist(), names, x.tolist()))
        self._events.writelines(lines)
        self._events.flush()

    def close(self):
        for f in (self._positions, self._events):
            if f is not None and not f.closed:
                f.close()


class MemorySink:
    """Keeps everything in arrays (tests, short runs): ``t`` and ``x`` of the grid rows, ``event_t``,
    ``event_block`` (0-based), ``event_kind`` (codes of :data:`EVENT_KINDS`) and ``event_x`` once closed (or after
    :meth:`arrays`)."""

    def __init__(self):
        self._rows, self._events = [], []

    def positions(self, t, x):
        self._rows.append((np.array(t), np.array(x)))

    def events(self, t, block, kind, x):
        self._events.append((np.array(t), np.array(block), np.array(kind), np.array(x)))

    def close(self):
        self.arrays()

    def arrays(self):
        """Join the batches into the attributes."""
        rows = self._rows or [(np.zeros(0), np.zeros((0, 0)))]
        self.t = np.concatenate([r[0] for r in rows])
        self.x = np.concatenate([r[1] for r in rows]) if self._rows else np.zeros((0, 0))
        parts = list(zip(*self._events)) or [[np.zeros(0)], [np.zeros(0, int)], [np.zeros(0, int)], [np.zeros(0)]]
        self.event_t, self.event_block, self.event_kind, self.event_x = (np.concatenate(p) for p in parts)
        return self

    def kinds(self):
        """The event kinds by name."""
        return [EVENT_KINDS[k] for k in self.event_kind]
