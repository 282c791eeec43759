"""The earthquake catalogue of a chain: its block events grouped into slip events, streaming.

A block event (``block_events.csv``: ``time,block,kind,x``; ``block`` 1-based, ``kind`` ``slip`` stuck ->
slipping, ``stick`` slipping -> stuck, ``overshoot`` the slip reverses, ``x`` the block's position in m) changes
one block's mode. A *slip event* begins with a ``slip`` while every block is stuck and ends when every block is
stuck again (at a ``stick``). Its columns in ``slip_events.csv``:

- ``start``, ``end`` (s) and ``duration = end - start`` (s);
- ``size``: the number of distinct blocks that slipped (a block slipping twice counts once);
- ``moment`` (m): the blocks' summed slip relative to the surface, over every slip interval of every block
  ``sum (x_stick - x_slip - v_drive (t_stick - t_slip))``; negative where the blocks fall back against the
  surface's motion (as a chain driven at ``v_drive > 0`` does);
- ``first_block``: the block whose ``slip`` began it (1-based);
- ``n_slips`` (slip intervals: ``size`` plus the repeated slips) and ``n_block_events`` (its block events,
  overshoots included).

Blocks that slip at time 0 (their start values make them slip: no ``slip`` event) are given to the grouper with
their start positions: they open an event at 0 whose ``first_block`` is the lowest of them. An event still open
when the run ends has no end, duration or final moment: it is left out of ``slip_events.csv``, and
:attr:`SlipGrouper.open_event` says what is known of it (the statistics report it). Events are fed in batches in
time order (:meth:`SlipGrouper.feed`); memory holds one open event, whatever the length of the run.
"""

import csv
import itertools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .output import EVENT_KINDS, EVENTS_FILE

#: the catalogue's input, written by :class:`stickslip.chain.output.CsvSink`
BLOCK_EVENTS_FILE = EVENTS_FILE
SLIP_EVENTS_FILE = "slip_events.csv"
BLOCK_EVENT_COLUMNS = ("time", "block", "kind", "x")
SLIP_EVENT_COLUMNS = ("start", "duration", "size", "moment", "first_block", "end", "n_slips", "n_block_events")
#: block events read at a time from a file
CHUNK_ROWS = 65536


class CatalogueError(ValueError):
    """Block events that cannot be grouped (a file's wrong columns, a block sticking that does not slip, time
    running back); the message names the file or the event."""


@dataclass
class OpenEvent:
    """A slip event not ended yet: ``start`` (s), ``first_block``, the blocks that slipped, the slip intervals and
    block events so far, and the summed relative slip of the intervals already ended (m)."""

    start: float
    first_block: int
    blocks: set = field(default_factory=set)
    n_slips: int = 0
    n_block_events: int = 0
    moment: float = 0.0

    def summary(self):
        """The event as a dict (for the statistics' summary)."""
        return {"start": self.start, "first_block": self.first_block, "blocks_so_far": len(self.blocks),
                "n_block_events": self.n_block_events}


class SlipGrouper:
    """Groups block events, fed in batches in time order, into slip events (module docstring).

    ``v_drive``: the surface's speed (m/s); ``slipping_at_start``: ``{block (1-based): x at time 0 (m)}`` of the
    blocks slipping from the start (default none); ``on_interval(block, t_slip, t_stick, slip)``, if given, is
    called at the end of each block's slip interval (``slip`` relative to the surface, m)."""

    def __init__(self, v_drive, slipping_at_start=None, on_interval=None):
        self.v_drive = float(v_drive)
        self.on_interval = on_interval
        self.slipping = {}  # block: (t_slip, x_slip) of each block slipping now
        self.open_event = None
        self.n_block_events = 0
        self._t = -np.inf
        for block in sorted(slipping_at_start or {}):
            self._slip(0.0, int(block), float(slipping_at_start[block]))

    def feed(self, t, block, kind, x):
        """Take a batch of block events (arrays or lists: times in s, 1-based blocks, kinds, positions in m) and
        return the slip events they end, as rows in the order of :data:`SLIP_EVENT_COLUMNS`."""
        rows = []
        for ti, bi, ki, xi in zip(np.asarray(t, float).tolist(), np.asarray(block).tolist(), _kinds(kind),
                                  np.asarray(x, float).tolist()):
            if ti < self._t:
                raise CatalogueError(f"block event at t = {ti!r} s (block {bi}, {ki}) comes after t = {self._t!r} s: "
                                     "the events must be in time order")
            self._t = ti
            self.n_block_events += 1
            row = self._apply(ti, bi, ki, xi)
            if row is not None:
                rows.append(row)
        return rows

    def _apply(self, t, block, kind, x):
        """One block event; the finished slip event's row if it ends one."""
        if kind == "slip":
            if block in self.slipping:
                raise CatalogueError(f"block {block} slips at t = {t!r} s while it is slipping already")
            self._slip(t, block, x)
            return None
        if block not in self.slipping:
            raise CatalogueError(f"block {block} has a '{kind}' at t = {t!r} s while it is stuck (no slip before)")
        event = self.open_event
        event.n_block_events += 1
        if kind == "overshoot":
            return None
        t_slip, x_slip = self.slipping.pop(block)
        slip = x - x_slip - self.v_drive * (t - t_slip)
        event.moment += slip
        if self.on_interval is not None:
            self.on_interval(block, t_slip, t, slip)
        if self.slipping:
            return None
        self.open_event = None
        return (event.start, t - event.start, len(event.blocks), event.moment, event.first_block, t,
                event.n_slips, event.n_block_events)

    def _slip(self, t, block, x):
        if self.open_event is None:
            self.open_event = OpenEvent(t, block)
        event = self.open_event
        event.blocks.add(block)
        event.n_slips += 1
        event.n_block_events += 1
        self.slipping[block] = (t, x)


def _kinds(kind):
    """The kinds as strings (names, or the codes of :data:`stickslip.chain.output.EVENT_KINDS`); every one must be
    one of those."""
    kind = np.asarray(kind)
    if kind.dtype.kind in "iu" and (kind.size == 0 or 0 <= kind.min() <= kind.max() < len(EVENT_KINDS)):
        return np.array(EVENT_KINDS)[kind].tolist()
    names = [str(k) for k in kind.tolist()]
    bad = set(names) - set(EVENT_KINDS)
    if bad:
        raise CatalogueError(f"block event kind {sorted(bad)[0]!r}: allowed is one of {list(EVENT_KINDS)}")
    return names


def slip_events_table(rows):
    """Slip-event rows as ``{column: array}`` (:data:`SLIP_EVENT_COLUMNS`)."""
    columns = list(zip(*rows)) if rows else [()] * len(SLIP_EVENT_COLUMNS)
    return {name: np.array(values, dtype=int if name in ("size", "first_block", "n_slips", "n_block_events")
                           else float)
            for name, values in zip(SLIP_EVENT_COLUMNS, columns)}


def group_slip_events(t, block, kind, x, *, v_drive, slipping_at_start=None):
    """The slip events of block events held in memory: ``({column: array}, open event or None)``."""
    grouper = SlipGrouper(v_drive, slipping_at_start)
    return slip_events_table(grouper.feed(t, block, kind, x)), grouper.open_event


class SlipEventWriter:
    """``slip_events.csv`` written as rows come (flushed after each batch, so that what is written stays on
    Ctrl-C); floats with every digit (``repr``)."""

    def __init__(self, path):
        self.path = Path(path)
        self._file = self.path.open("w", newline="")
        self._csv = csv.writer(self._file, lineterminator="\n")
        self._csv.writerow(SLIP_EVENT_COLUMNS)
        self._file.flush()
        self.rows = 0

    def write(self, rows):
        self._csv.writerows(rows)
        self._file.flush()
        self.rows += len(rows)

    def close(self):
        self._file.close()


class CatalogueSink:
    """A sink of the chain engine (:mod:`stickslip.chain.output`) that passes everything on to ``inner`` and groups
    the block events into ``<folder>/slip_events.csv`` as they come (``v_drive``, ``slipping_at_start``: as for
    :class:`SlipGrouper`); ``grouper`` holds the open event and the counts at the end."""

    def __init__(self, inner, folder, v_drive, slipping_at_start=None):
        self.inner = inner
        self.grouper = SlipGrouper(v_drive, slipping_at_start)
        self.writer = SlipEventWriter(Path(folder) / SLIP_EVENTS_FILE)

    def positions(self, t, x):
        self.inner.positions(t, x)

    def events(self, t, block, kind, x):
        """A batch of block events, ``block`` 0-based as the engine gives them."""
        self.inner.events(t, block, kind, x)
        self.writer.write(self.grouper.feed(t, np.asarray(block) + 1, kind, x))

    def close(self):
        self.inner.close()
        self.writer.close()


def read_block_events(path, chunk_rows=CHUNK_ROWS):
    """The block events of a ``block_events.csv`` in chunks: yields ``(t, block, kind, x)`` arrays of at most
    ``chunk_rows`` events each (memory: one chunk)."""
    path = Path(path)
    with path.open(newline="") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if header is None or tuple(header[:4]) != BLOCK_EVENT_COLUMNS:
            raise CatalogueError(f"{path}: the first line must be the columns {','.join(BLOCK_EVENT_COLUMNS)}, "
                                 f"got {header!r}")
        while chunk := list(itertools.islice(reader, chunk_rows)):
            try:
                t, block, kind, x = zip(*(row[:4] for row in chunk))
                arrays = np.array(t, float), np.array(block, int), kind, np.array(x, float)
            except ValueError as exc:
                raise CatalogueError(f"{path}: a row of block events that is not time,block,kind,x: {exc}") from None
            yield arrays


def catalogue_file(block_events, slip_events, *, v_drive, slipping_at_start=None, chunk_rows=CHUNK_ROWS):
    """Group the block events of the CSV file ``block_events`` into ``slip_events`` (CSV), chunk by chunk; return
    the :class:`SlipGrouper` at the end (its ``open_event``, ``n_block_events``) and the number of slip events
    written."""
    grouper = SlipGrouper(v_drive, slipping_at_start)
    writer = SlipEventWriter(slip_events)
    try:
        for chunk in read_block_events(block_events, chunk_rows):
            writer.write(grouper.feed(*chunk))
    finally:
        writer.close()
    return grouper, writer.rows


def read_slip_events(path):
    """The slip events of a ``slip_events.csv`` as ``{column: array}`` (the columns of
    :data:`SLIP_EVENT_COLUMNS`)."""
    path = Path(path)
    with path.open(newline="") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if header is None or tuple(header[:len(SLIP_EVENT_COLUMNS)]) != SLIP_EVENT_COLUMNS:
            raise CatalogueError(f"{path}: the first line must be the columns {','.join(SLIP_EVENT_COLUMNS)}, "
                                 f"got {header!r}")
        rows = [tuple(float(v) for v in row[:len(SLIP_EVENT_COLUMNS)]) for row in reader]
    return slip_events_table(rows)
