"""The FMU under FMPy in another CPython than the build's (pyenv's 3.13, else 3.12, in a venv with FMPy made once
as ``.venv-py3.X`` in the checkout): the runtime compiled for that version where the FMU carries it (the build found
it compiled: ``scripts/other_pythons.py compile``), else its Python sources. Every scenario of the suite against the
reference integrator within the scenario's tolerances, with the numbers the build's Python gives, digit for
digit."""

import importlib.util
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

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


def request_of(scenario):
    """What the child runs for ``scenario``: the suite's co-simulation run (:func:`stickslip.suite.runner.simulate`)."""
    table = scenario.input_table()
    return {"name": scenario.name, "start_values": {k: _plain(v) for k, v in scenario.start_values().items()},
            "stop_time": scenario.stop_time, "output_interval": scenario.output_interval, "outputs": list(OUTPUTS),
            "input": {"names": list(table.dtype.names), "rows": table.tolist()}}


def _plain(value):
    return value.item() if hasattr(value, "item") else value


def test_every_scenario_runs_under_another_python_as_under_the_builds(other_python, fmu_path, tmp_path):
    version, venv = other_python
    scenarios = [load_scenario(path) for path in SCENARIOS]
    with zipfile.ZipFile(fmu_path) as archive:
        tag = f".cpython-{version.replace('.', '')}-"
        runtime = "compiled" if any(tag in name for name in archive.namelist()) else "pure"
    results, seconds = other_pythons.run_in(venv, fmu_path, [request_of(s) for s in scenarios], tmp_path)
    print(f"CPython {version} ({runtime} runtime): {len(scenarios)} scenarios in {seconds:.1f} s")
    for scenario in scenarios:
        run = results[scenario.name]
        assert run["python"].startswith(f"{version}.") and run["runtime"] == runtime, run
        fmu = run["result"]
        comparison = compare(fmu, reference_on(scenario, fmu["time"]), scenario)
        assert comparison.passed, (scenario.name, comparison.failures)
        here = run_fmu(fmu_path, scenario.start_values(), scenario.stop_time, scenario.output_interval,
                       input_signal=scenario.input_table(), outputs=list(OUTPUTS))
        assert fmu.dtype.names == here.dtype.names and fmu.tobytes() == here.tobytes(), scenario.name
