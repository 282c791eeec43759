"""Parallel scans: a local process pool by default, a Dask distributed cluster on request.

A scan cuts its grid into fixed chunks (the cut depends only on the grid, never
on the executor), evaluates every chunk as one batch in a worker, and puts the
results back in grid order. Both back ends run the same chunk functions on the
same chunks, so they give identical results; both show a tqdm progress bar.

    with Executor(jobs=2) as ex:                        # local processes (jobs=1: in this process)
        margins = ex.margins(params, grid)
    with Executor(scheduler="tcp://host:8786") as ex:   # a running Dask scheduler
        chart = stability_chart(params, grid, "M", [10, 20, 40], executor=ex)

Chunk functions are module-level, so they pickle for either back end (a model
with Python-callable laws needs Dask, whose cloudpickle carries closures).
"""

import math
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures import as_completed as futures_completed
from dataclasses import dataclass
from multiprocessing import get_context

import numpy as np
from tqdm import tqdm

#: Grid points per chunk: one batch integration each.
CHUNK = 50


class Executor:
    """Runs chunk functions serially, on a local process pool, or on a Dask scheduler (context manager)."""

    def __init__(self, jobs=2, scheduler=None, progress=True):
        self.jobs = max(1, int(jobs))
        self.scheduler = scheduler
        self.progress = progress
        self._pool = None
        self._client = None
        self._own_client = False

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
        if self._client is not None and self._own_client:
            self._client.close()
        self._client = None

    def _dask(self):
        if self._client is None:
            from distributed import Client

            if isinstance(self.scheduler, str):
                self._client, self._own_client = Client(self.scheduler), True
            else:  # a Client or a cluster object
                self._client = self.scheduler if hasattr(self.scheduler, "submit") else Client(self.scheduler)
                self._own_client = not hasattr(self.scheduler, "submit")
        return self._client

    def map(self, fn, items, desc="scan", unit="chunk"):
        """``[fn(*item) for item in items]``, in order, computed on the chosen back end; the bar counts ``unit``."""
        items = list(items)
        parallel = self.scheduler is None and self.jobs > 1 and len(items) > 1
        if parallel and self._pool is None:  # start the workers before the clock: start-up is not chunk time
            self._pool = ProcessPoolExecutor(max_workers=self.jobs, mp_context=get_context("spawn"))
            list(self._pool.map(_ready, range(self.jobs)))
        # smoothing=0: the estimate uses the average rate since the start, not the latest (uneven) chunks
        bar = tqdm(total=len(items), desc=desc, unit=unit, disable=not self.progress, leave=False, smoothing=0)
        try:
            if self.scheduler is not None:
                from distributed import as_completed

                client = self._dask()
                futures = [client.submit(fn, *item, pure=False) for item in items]
                for _ in as_completed(futures):
                    bar.update()
                return client.gather(futures)
            if not parallel:
                out = []
                for item in items:
                    out.append(fn(*item))
                    bar.update()
                return out
            futures = [self._pool.submit(fn, *item) for item in items]
            for _ in futures_completed(futures):  # count chunks as they finish, in any order
                bar.update()
            return [f.result() for f in futures]
        finally:
            bar.close()

    # ------------------------------------------------------------------
    # the scans of the analysis
    # ------------------------------------------------------------------

    def map_grid(self, fn, params, grid, *extra, desc="scan"):
        """``fn(params, chunk, *extra)`` over fixed chunks of ``grid``; lists concatenated in grid order."""
        grid = np.asarray(grid, float)
        chunks = [grid[i:i + CHUNK] for i in range(0, grid.size, CHUNK)]
        parts = self.map(fn, [(params, c, *extra) for c in chunks], desc=desc)
        return [item for part in parts for item in part]

    def margins(self, params, grid, F_ext=0.0):
        """Existence margins of the stick-slip cycle on ``grid`` (see :mod:`.stickslip_cycle`)."""
        return np.array(self.map_grid(_margin_chunk, params, grid, F_ext, desc="stick-slip margin"))

    def cycles(self, params, grid, F_ext=0.0):
        """:class:`~.stickslip_cycle.StickSlipCycle` at every drive velocity of ``grid``."""
        return self.map_grid(_cycle_chunk, params, grid, F_ext, desc="stick-slip cycles")


def _ready(_):
    """A no-op run in each new worker so that it has started (and imported this module) before a scan."""
    return True


def _margin_chunk(params, chunk, F_ext):
    from .stickslip_cycle import grazing_margin

    return list(grazing_margin(params, chunk, F_ext))


def _cycle_chunk(params, chunk, F_ext):
    from .stickslip_cycle import stick_slip_cycles

    return stick_slip_cycles(params, chunk, F_ext)


# ----------------------------------------------------------------------
# 2-D stability charts
# ----------------------------------------------------------------------

#: Chart codes: bit 1 = continuous sliding stable, bit 2 = stick-slip cycle exists.
CHART_LABELS = {0: "neither (oscillatory sliding)", 1: "continuous sliding", 2: "stick-slip",
                3: "continuous sliding + stick-slip"}


@dataclass(frozen=True)
class Chart:
    """A 2-D stability chart: ``code[i, j]`` at ``(values[i], v_drive[j])`` (see :data:`CHART_LABELS`)."""

    name: str
    values: np.ndarray
    v_drive: np.ndarray
    code: np.ndarray
    margin: np.ndarray


def with_value(params, name, value):
    """A copy of ``params`` with one value changed: ``M``, ``kappa``, ``kinetic.<p>`` or ``static.<p>``."""
    from ..core import Parameters

    kinetic, static = params.kinetic, params.static
    M, kappa = params.M, params.kappa
    if name == "M":
        M = value
    elif name == "kappa":
        kappa = value
    elif name.startswith("kinetic."):
        kinetic = type(kinetic)(**{**kinetic.parameters(), name[8:]: value})
    elif name.startswith("static."):
        static = type(static)(**{**static.parameters(), name[7:]: value})
    else:
        raise ValueError(f"unknown parameter {name!r}: expected M, kappa, kinetic.<p> or static.<p>")
    out = Parameters(M, kappa, kinetic, static)
    out.check()
    return out


def parameter_unit(name):
    """The unit of ``M``, ``kappa``, ``kinetic.<p>`` or ``static.<p>`` (``""`` if dimensionless)."""
    from ..core import KINETIC_LAWS, STATIC_LAWS

    units = {"M": "kg", "kappa": "N/m"}
    for kind, laws in (("kinetic", KINETIC_LAWS), ("static", STATIC_LAWS)):
        for law in laws.values():
            units.update({f"{kind}.{p}": unit for p, (_, _, unit) in law.PARAMETERS.items()})
    unit = units.get(name, "")
    return "" if unit == "1" else unit


def _chart_chunk(params, chunk, F_ext, name):
    """One row piece of a chart: ``chunk`` holds ``(value, v_drive)`` pairs of one value."""
    from .stickslip_cycle import grazing_margin

    value = chunk[0][0]
    p = with_value(params, name, value)
    vd = np.array([c[1] for c in chunk])
    margin = grazing_margin(p, vd, F_ext)
    stable = np.array([p.kinetic.slope(v) > 0.0 for v in vd])
    return [(int(s) + 2 * int(m > 0.0), float(m)) for s, m in zip(stable, margin)]


def stability_chart(params, v_grid, name, values, F_ext=0.0, executor=None):
    """Chart of continuous-sliding stability and stick-slip existence over ``v_drive`` and a parameter."""
    v_grid = np.asarray(v_grid, float)
    values = np.asarray(values, float)
    ex = executor or Executor(jobs=1)
    tasks = []
    for value in values:
        for i in range(0, v_grid.size, CHUNK):
            tasks.append((params, [(value, v) for v in v_grid[i:i + CHUNK]], F_ext, name))
    parts = ex.map(_chart_chunk, tasks, desc=f"chart v_drive x {name}")
    flat = [item for part in parts for item in part]
    code = np.array([c for c, _ in flat], int).reshape(values.size, v_grid.size)
    margin = np.array([m for _, m in flat]).reshape(values.size, v_grid.size)
    if executor is None:
        ex.close()
    return Chart(name, values, v_grid, code, np.where(np.isfinite(margin), margin, math.nan))
