"""The FMU under FMPy in another CPython than the build's (pyenv's 3.13, else 3.12, in a venv with FMPy made once
as ``.venv-py3.X`` in the checkout): the runtime compiled for that version where the FMU carries it (the build found
it compiled: ``scripts/other_pythons.py compile``), else its Python sources. Every scenario of the suite against the
reference integrator within the scenario's tolerances, with the numbers the build's Python gives, digit for
digit; and the same with the sources forced (``STICKSLIP_PURE_PYTHON``), as every version without compiled files
runs them."""

import importlib.util
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

from stickslip.fmu import build, staging
from stickslip.fmu.compile_runtime import COMPLETE, RUNTIME_PREFIX, runtime_tag
from stickslip.fmu.bundle.floors import DEPENDENCIES_FILE
from stickslip.hosts.fmpy_host import run_fmu
from stickslip.suite.compare import compare
from stickslip.suite.runner import OUTPUTS, reference_on
from stickslip.suite.scenario import load_scenario

REPO = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("other_pythons", REPO / "scripts" / "other_pythons.py")
other_pythons = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(other_pythons)
#: the Pythons tried, first found first
CANDIDATES = ("3.13", "3.12")
SCENARIOS = sorted((REPO / "scenarios").glob("*.toml"))


@pytest.fixture(scope="module")
def other_python():
    """``(version, venv interpreter)`` of the first of :data:`CANDIDATES` pyenv has; skips where none is."""
    pythons = other_pythons.pyenv_pythons()
    build = f"{sys.version_info[0]}.{sys.version_info[1]}"
    version = next((v for v in CANDIDATES if v in pythons and v != build), None)
    if version is None:
        pytest.skip(f"pyenv has none of CPython {', '.join(CANDIDATES)} under {other_pythons.PYENV_VERSIONS}")
    try:
        return version, other_pythons.fmpy_venv(pythons[version], REPO / f".venv-py{version}")
    except (RuntimeError, OSError, subprocess.TimeoutExpired) as exc:
        pytest.skip(f"no venv of CPython {version} with FMPy: {exc}")


@pytest.fixture(scope="module")
def builds_results(fmu_path):
    """{scenario name: the FMU's result in this (the build's) Python, as the suite runs it}."""
    scenarios = [load_scenario(path) for path in SCENARIOS]
    return {s.name: run_fmu(fmu_path, s.start_values(), s.stop_time, s.output_interval,
                            input_signal=s.input_table(), outputs=list(OUTPUTS)) for s in scenarios}


def request_of(scenario):
    """What the child runs for ``scenario``: the suite's co-simulation run (:func:`stickslip.suite.runner.simulate`)."""
    table = scenario.input_table()
    return {"name": scenario.name, "start_values": {k: _plain(v) for k, v in scenario.start_values().items()},
            "stop_time": scenario.stop_time, "output_interval": scenario.output_interval, "outputs": list(OUTPUTS),
            "input": {"names": list(table.dtype.names), "rows": table.tolist()}}


def _plain(value):
    return value.item() if hasattr(value, "item") else value


@pytest.mark.parametrize("sources", [False, True], ids=["as-built", "sources"])
def test_every_scenario_runs_under_another_python_as_under_the_builds(other_python, fmu_path, tmp_path, sources,
                                                                     builds_results):
    """``sources``: the runtime's sources run although the FMU may carry it compiled for that version (as in the
    versions it carries no compiled files for)."""
    version, venv = other_python
    scenarios = [load_scenario(path) for path in SCENARIOS]
    with zipfile.ZipFile(fmu_path) as archive:
        tag = f".cpython-{version.replace('.', '')}-"
        compiled = any(tag in name for name in archive.namelist()) and not sources
    runtime = "compiled" if compiled else "pure"
    results, seconds = other_pythons.run_in(venv, fmu_path, [request_of(s) for s in scenarios], tmp_path,
                                            {other_pythons.PURE_VARIABLE: "1"} if sources else {})
    print(f"CPython {version} ({runtime} runtime): {len(scenarios)} scenarios in {seconds:.1f} s")
    for scenario in scenarios:
        run = results[scenario.name]
        assert run["python"].startswith(f"{version}.") and run["runtime"] == runtime, run
        fmu = run["result"]
        comparison = compare(fmu, reference_on(scenario, fmu["time"]), scenario)
        assert comparison.passed, (scenario.name, comparison.failures)
        here = builds_results[scenario.name]
        assert fmu.dtype.names == here.dtype.names and fmu.tobytes() == here.tobytes(), scenario.name


def test_the_build_carries_the_runtime_compiled_for_every_python_it_finds(tmp_path, monkeypatch):
    """A runtime compiled for another CPython (here a made-up 3.99, its files copies of a real ELF library) in the
    folder ``scripts/other_pythons.py compile`` fills goes into the FMU beside the build's own, and the FMU's
    external dependencies name both versions."""
    package = RUNTIME_PREFIX + runtime_tag()
    other = tmp_path / "others" / f"{package}-cpython-399-{sysconfig.get_platform()}"
    elf = Path(sys.executable).resolve().read_bytes()
    names = ["ab12__mypyc.cpython-399-x86_64-linux-gnu.so", f"{package}/laws.cpython-399-x86_64-linux-gnu.so"]
    for name in names:
        (other / name).parent.mkdir(parents=True, exist_ok=True)
        (other / name).write_bytes(elf)
    (other / COMPLETE).write_text("")
    monkeypatch.setattr(staging, "OTHER_PYTHONS", tmp_path / "others")
    with zipfile.ZipFile(build(tmp_path / "SpringBlockFriction.fmu")) as archive:
        assert all(archive.read(f"resources/{name}") == elf for name in names)
        text = archive.read(DEPENDENCIES_FILE).decode()
    assert f"compiled for CPython {sys.version_info[0]}.{sys.version_info[1]}, 3.99;" in text
