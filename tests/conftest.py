"""Shared fixtures: the FMUs (FMI 2 and FMI 3, and the coupling FMU) built once per test run from the current
sources, a folder of the session's own for the FMUs built at the default path (the main job's ``dist/`` stays as
it is), and the C hosts. Under pytest-xdist (``scripts/test.sh``: one worker process per core) the FMUs and the C
hosts are made by the first worker that needs them, in a folder all workers share, and the others wait for them."""

import fcntl
import os
import shutil
from pathlib import Path

import fmpy
import pytest

from stickslip.fmu import build
from stickslip.fmu.coupling import build_coupling
from stickslip.hosts.c_host import HostBuildError, compile_host

import machine_needs

#: the test files that take longest (minutes on 2 cores: wheels, FMU builds that compile, Wine, long runs), run
#: first, so that pytest-xdist's workers (``scripts/test.sh``) end together, not one of them running these at the end
SLOW_FILES = ("test_package.py", "test_stress.py", "test_windows_compiled_runtime.py", "test_chain_ensemble.py",
              "test_fmu_front.py", "test_other_python.py", "test_systems.py", "test_windows_loader.py")

#: the main job's FMUs (``scripts/setup.sh`` builds them there), which no test may replace
MAIN_DIST = Path(__file__).resolve().parents[1] / "dist"


def _files(folder):
    """``{path: (size in bytes, modification time in ns)}`` of the files below ``folder`` (none if it is missing)."""
    return {path: (path.stat().st_size, path.stat().st_mtime_ns) for path in sorted(folder.rglob("*"))
            if path.is_file()}


def pytest_collection_modifyitems(items):
    """The tests of :data:`SLOW_FILES` first, in that order, then the others as collected."""
    items.sort(key=lambda item: SLOW_FILES.index(item.path.name) if item.path.name in SLOW_FILES else len(SLOW_FILES))


@pytest.fixture(scope="session", autouse=True)
def session_dist(tmp_path_factory):
    """The folder of the FMUs built at the default path during the tests: ``$STICKSLIP_DIST``, which
    ``stickslip.fmu.default_fmu_path`` reads, set for the session. At the end, the main job's ``dist/`` must be
    as it was at the start."""
    before = _files(MAIN_DIST)
    folder = tmp_path_factory.mktemp("dist")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("STICKSLIP_DIST", str(folder))
        yield folder
    assert _files(MAIN_DIST) == before, f"the tests changed the main job's FMUs in {MAIN_DIST}"


def made_once(tmp_path_factory, name, make):
    """The path ``make(folder)`` returns, made once per test run into ``folder``, the folder ``name`` of the run's
    temporary folder: under pytest-xdist the one all its workers share, the first worker that asks makes it while the
    others wait on a lock, then take its path. Where ``make`` skips or fails, nothing is kept: the next that asks
    makes it again."""
    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        base = base.parent  # the run's folder; each worker's own (popen-gw<N>) is below it
    folder, made = base / name, base / f"{name}.path"
    with open(base / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        if not made.is_file():
            shutil.rmtree(folder, ignore_errors=True)  # what a make that failed left
            folder.mkdir()
            made.write_text(str(make(folder)))
        return Path(made.read_text())


@pytest.fixture(scope="session")
def fmu_path(tmp_path_factory):
    """Path of a SpringBlockFriction.fmu freshly built from the working tree (dist/ is left alone)."""
    return made_once(tmp_path_factory, "fmu", lambda folder: build(folder / "SpringBlockFriction.fmu"))


@pytest.fixture(scope="session")
def fmu3_path(tmp_path_factory):
    """Path of a SpringBlockFriction-fmi3.fmu freshly built from the working tree."""
    return made_once(tmp_path_factory, "fmu3",
                     lambda folder: build(fmi_version=3, dest=folder / "SpringBlockFriction-fmi3.fmu"))


@pytest.fixture(scope="session")
def coupling_path(tmp_path_factory):
    """Path of a ChainCoupling.fmu freshly built from the working tree."""
    return made_once(tmp_path_factory, "coupling", lambda folder: build_coupling(folder / "ChainCoupling.fmu"))


def _extracted(path):
    """(extracted folder, model description, {name: variable}) of the FMU at ``path``; removes the folder after."""
    folder = fmpy.extract(str(path))
    description = fmpy.read_model_description(str(path))
    yield folder, description, {v.name: v for v in description.modelVariables}
    shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture(scope="session")
def unzipped(fmu_path):
    """(extracted folder, model description, {name: variable}) of the session's FMU."""
    yield from _extracted(fmu_path)


@pytest.fixture(scope="session")
def unzipped3(fmu3_path):
    """The same for the session's FMI 3 FMU."""
    yield from _extracted(fmu3_path)


@pytest.fixture(scope="session")
def unzipped_coupling(coupling_path):
    """The same for the session's coupling FMU."""
    yield from _extracted(coupling_path)


def _c_host(tmp_path_factory, fmi_version):
    """The C host of ``fmi_version`` (``src/stickslip/hosts/c_host/``), compiled; the tests that use it are skipped
    where the machine cannot build it or start the FMU's Python in it. With a compiler, a host that does not
    compile fails them."""
    what = f"the FMI {fmi_version} C host"
    machine_needs.c_compiler(what)
    machine_needs.libpython(what)
    try:
        return made_once(tmp_path_factory, f"c_host{fmi_version}",
                         lambda folder: compile_host(folder, fmi_version=fmi_version))
    except HostBuildError as exc:
        pytest.fail(f"the C host must build where there is a C compiler: {exc}")


@pytest.fixture(scope="session")
def host(tmp_path_factory):
    return _c_host(tmp_path_factory, 2)


@pytest.fixture(scope="session")
def host3(tmp_path_factory):
    return _c_host(tmp_path_factory, 3)
