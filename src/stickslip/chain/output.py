"""Where the chain engine streams its output: sinks that take batches and keep memory flat.

A sink has ``positions(t, x)``: grid rows, ``t`` the times (s, shape ``(k,)``) and ``x`` every block's position
(m, shape ``(k, N)``, the state after any event at that time); ``events(t, block, kind, x)``: a batch of block events
in time order, ``t`` (s), ``block`` (0-based ints), ``kind`` (codes of :data:`EVENT_KINDS`), ``x`` the block's
position (m); and ``close()``. The engine calls them between its compiled chunks and closes the sink at the end of
the run (also when it stops early). A sink that also wants velocities and modes defines ``states(t, x, v, mode)``
(called instead of ``positions``: ``v`` m/s and ``mode`` -1/0/+1, shape ``(k, N)``), and one that wants each event's
new mode defines ``transitions(t, block, kind, x, mode)`` (called instead of ``events``).
"""

from pathlib import Path

import numpy as np

#: event kind code: its name (SPEC section 1): slip (stuck -> slipping), stick (slipping -> stuck), overshoot (the
#: slip direction reverses)
EVENT_KINDS = ("slip", "stick", "overshoot")
POSITIONS_FILE = "positions.csv"
EVENTS_FILE = "block_events.csv"


EVENTS_HEADER = "time,block,kind,x\n"


def event_lines(t, block, kind, x):
    """The lines of ``block_events.csv`` for a batch of events (``block`` 0-based, written 1-based)."""
    names = np.array(EVENT_KINDS)[kind]
    return [f"{ti!r},{b + 1},{k},{xi!r}\n" for ti, b, k, xi in zip(t.tolist(), block.tolist(), names, x.tolist())]


def write_block_events(path, t, block, kind, x):
    """``path``: the block events (arrays as :meth:`CsvSink.events` takes them) as ``block_events.csv`` is written."""
    with open(path, "w") as f:
        f.write(EVENTS_HEADER)
        f.writelines(event_lines(np.asarray(t), np.asarray(block), np.asarray(kind), np.asarray(x)))


class CsvSink:
    """Writes ``<folder>/<prefix>positions.csv`` (``time,x_b1,...,x_bN``; only if positions come) and
    ``<folder>/<prefix>block_events.csv`` (``time,block,kind,x``, ``block`` 1-based, ``kind`` by name); every batch is
    flushed, so the files are complete up to the last batch if the run stops."""

    def __init__(self, folder, prefix=""):
        self.folder, self.prefix = Path(folder), prefix
        self.folder.mkdir(parents=True, exist_ok=True)
        self._positions = None
        self._events = open(self.folder / (prefix + EVENTS_FILE), "w")
        self._events.write(EVENTS_HEADER)
        self._events.flush()

    @property
    def files(self):
        """The files written (paths)."""
        return [self.folder / (self.prefix + name) for name, f in ((POSITIONS_FILE, self._positions),
                                                                   (EVENTS_FILE, self._events)) if f is not None]

    def positions(self, t, x):
        if self._positions is None:
            self._positions = open(self.folder / (self.prefix + POSITIONS_FILE), "w")
            self._positions.write(",".join(["time", *(f"x_b{i + 1}" for i in range(x.shape[1]))]) + "\n")
        np.savetxt(self._positions, np.column_stack([t, x]), fmt="%.17g", delimiter=",")
        self._positions.flush()

    def events(self, t, block, kind, x):
        self._events.writelines(event_lines(t, block, kind, x))
        self._events.flush()

    def close(self):
        for f in (self._positions, self._events):
            if f is not None and not f.closed:
                f.close()


class MemorySink:
    """Keeps everything in arrays (tests, short runs): ``t``, ``x``, ``v`` and ``mode`` of the grid rows,
    ``event_t``, ``event_block`` (0-based), ``event_kind`` (codes of :data:`EVENT_KINDS`), ``event_x`` and
    ``event_mode`` (the mode after it; -2 where events came without) once closed (or after :meth:`arrays`)."""

    def __init__(self):
        self._rows, self._events = [], []

    def positions(self, t, x):
        x = np.array(x)
        self.states(t, x, np.full(x.shape, np.nan), np.full(x.shape, -2))

    def states(self, t, x, v, mode):
        self._rows.append((np.array(t), np.array(x), np.array(v), np.array(mode)))

    def events(self, t, block, kind, x):
        self.transitions(t, block, kind, x, np.full(len(t), -2))

    def transitions(self, t, block, kind, x, mode):
        self._events.append((np.array(t), np.array(block), np.array(kind), np.array(x), np.array(mode)))

    def close(self):
        self.arrays()

    def arrays(self):
        """Join the batches into the attributes."""
        rows = list(zip(*self._rows)) or [[np.zeros(0)], [np.zeros((0, 0))], [np.zeros((0, 0))],
                                          [np.zeros((0, 0), int)]]
        self.t, self.x, self.v, self.mode = (np.concatenate(p) for p in rows)
        events = list(zip(*self._events)) or [[np.zeros(0)], [np.zeros(0, int)], [np.zeros(0, int)], [np.zeros(0)],
                                              [np.zeros(0, int)]]
        self.event_t, self.event_block, self.event_kind, self.event_x, self.event_mode = (
            np.concatenate(p) for p in events)
        return self

    def kinds(self):
        """The event kinds by name."""
        return [EVENT_KINDS[k] for k in self.event_kind]
