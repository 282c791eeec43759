"""A chain run into a folder: the engine's output streamed to disk with its catalogue, then the statistics and
figures (what ``stickslip chain`` writes, docs/chains.md).

:func:`run_into_folder` writes ``positions.csv`` (with an output interval), ``block_events.csv`` and
``slip_events.csv`` as the engine goes (flushed every chunk: a run stopped by Ctrl-C keeps them);
:func:`summarise_folder` then writes ``statistics.json``, ``statistics.md``, ``statistics.png`` (distributions,
recurrence intervals) and ``slips.png`` (the space-time picture of the slips).
"""

from dataclasses import dataclass
from pathlib import Path

from ..reference.rules import initial_mode
from .catalogue import BLOCK_EVENTS_FILE, SLIP_EVENTS_FILE, CatalogueSink, read_slip_events
from .engine import run_chain
from .output import POSITIONS_FILE, CsvSink
from .plots import plot_slips, plot_statistics
from .spec import ChainSpec
from .reference_check import REFERENCE_JSON
from .statistics import STATISTICS_JSON, STATISTICS_MD, catalogue_statistics, write_statistics

STATISTICS_PNG = "statistics.png"
SLIPS_PNG = "slips.png"


@dataclass
class FolderRun:
    """A run's folder, the engine's :class:`~.engine.ChainRunSummary`, the catalogue's grouper at the end (its
    ``open_event`` and counts) and the number of slip events written."""

    folder: Path
    summary: object
    grouper: object
    slip_events: int

    @property
    def files(self):
        """The files the run wrote, in the order a reader looks at them."""
        names = (SLIP_EVENTS_FILE, BLOCK_EVENTS_FILE, POSITIONS_FILE)
        return [self.folder / name for name in names if (self.folder / name).exists()]


def slipping_at_start(system):
    """``{block (1-based): x_start}`` of the blocks of ``system`` that slip from time 0 (their start values break
    them loose: no ``slip`` event marks it), by the reference's rule."""
    forces = system.forces([b["x_start"] for b in system.blocks])
    return {i: block.x0 for i, (block, force) in enumerate(zip(system.chain_blocks(), forces), start=1)
            if initial_mode(block.params, block.x0, block.v0, system.v_drive, force) != 0}


def run_into_folder(system, folder, *, stop_time, output_interval=None, rtol=1e-10, progress=None):
    """Run the chain of ``system`` (:class:`stickslip.systems.system_file.System`) from 0 to ``stop_time`` (s) with
    the engine at ``rtol``, positions every ``output_interval`` s (None: none), into ``folder`` (made if missing);
    return a :class:`FolderRun`. The files of an earlier run there are replaced or removed (a run that stops leaves
    no statistics of another)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for name in (POSITIONS_FILE, STATISTICS_JSON, STATISTICS_MD, STATISTICS_PNG, SLIPS_PNG, REFERENCE_JSON):
        (folder / name).unlink(missing_ok=True)
    spec = ChainSpec.from_system(system)
    sink = CatalogueSink(CsvSink(folder), folder, system.v_drive, slipping_at_start(system))
    summary = run_chain(spec, stop_time, rtol=rtol, output_interval=output_interval, sink=sink, progress=progress)
    return FolderRun(folder, summary, sink.grouper, sink.writer.rows)


def summarise_folder(folder, system, title, extra=None, bootstrap=200):
    """Write the statistics of the catalogue in ``folder`` (``extra``: more entries for ``statistics.json``, e.g.
    the run's settings) and its figures; return the paths written."""
    folder = Path(folder)
    table = read_slip_events(folder / SLIP_EVENTS_FILE)
    statistics = catalogue_statistics(table, system.n, bootstrap=bootstrap)
    files = list(write_statistics(folder, statistics, extra))
    plot_statistics(folder / STATISTICS_PNG, title, table, statistics)
    plot_slips(folder / SLIPS_PNG, title, folder / BLOCK_EVENTS_FILE, system.n, system.v_drive,
               slipping_at_start=slipping_at_start(system))
    return files + [folder / STATISTICS_PNG, folder / SLIPS_PNG]
