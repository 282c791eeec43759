"""Parallel scans: serial, local process pool and a Dask LocalCluster give identical results."""

import numpy as np
import pytest

from stickslip.core import Constant, Lubricated, Parameters
from stickslip.analysis import parallel_scan


def elmer():
    return Parameters(40.0, 1.0, Lubricated(gamma1=3.0, gamma2=0.1, v_tilde=0.2, dv=0.05), Constant(F0=1.0))


@pytest.fixture(scope="module")
def dask_cluster():
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                       dashboard_address=None)
    yield cluster
    cluster.close()


def test_pool_and_dask_give_identical_margins(dask_cluster):
    p = elmer()
    grid = np.linspace(0.03, 1.1, 70)  # two chunks
    with parallel_scan.Executor(jobs=1, progress=False) as ex:
        serial = ex.margins(p, grid)
    with parallel_scan.Executor(jobs=2, progress=False) as ex:
        pool = ex.margins(p, grid)
    with parallel_scan.Executor(scheduler=dask_cluster.scheduler_address, progress=False) as ex:
        dask = ex.margins(p, grid)
    assert np.array_equal(serial, pool) and np.array_equal(serial, dask)
    assert np.any(serial > 0.0) and np.any(serial < 0.0)


def test_stability_chart_on_dask(dask_cluster):
    p = elmer()
    grid = np.linspace(0.05, 0.5, 12)
    with parallel_scan.Executor(scheduler=dask_cluster, progress=False) as ex:
        chart = parallel_scan.stability_chart(p, grid, "M", [20.0, 40.0], executor=ex)
    serial = parallel_scan.stability_chart(p, grid, "M", [20.0, 40.0])
    assert np.array_equal(chart.code, serial.code) and np.array_equal(chart.margin, serial.margin)
    # continuous sliding is stable exactly where F_K' > 0, whatever M
    stable = np.array([p.kinetic.slope(v) > 0.0 for v in grid])
    assert np.array_equal(chart.code[0] & 1, stable.astype(int))
    assert np.array_equal(chart.code[1] & 1, stable.astype(int))
    # the M = 40 row's stick-slip column agrees with the margin scan
    assert np.array_equal(chart.code[1] >> 1, (parallel_scan.Executor(jobs=1, progress=False).margins(p, grid) > 0.0))
