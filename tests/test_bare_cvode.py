"""Bare CVode (FMPy's CVodeSolver on the model written from the reference, no FMU) against the FMU's model exchange."""

import ast
import importlib
from pathlib import Path

import numpy as np
import pytest

from stickslip.bench.bare_cvode import simulate_bare_cvode
from stickslip.bench.scenes import SCENES
from stickslip.suite.compare import reference_events
from stickslip.hosts.fmpy_host import run_fmu

RTOLS = (1e-6, 1e-8, 1e-10)


def relative_error(x, scene):
    """max |x - x_ref| over the scene's grid, relative to the amplitude."""
    return float(np.abs(x - scene.reference.x).max()) / scene.amplitude


@pytest.fixture(scope="module")
def bare_errors():
    """``{(scene name, rtol): max|dx|/A}`` of bare CVode on the 300 s elmer-fig3 scenes."""
    return {(name, rtol): relative_error(simulate_bare_cvode(SCENES[name], rtol).x, SCENES[name])
            for name in ("elmer-fig3-v0.1", "elmer-fig3-v0.3") for rtol in RTOLS}


@pytest.mark.parametrize("name", ["elmer-fig3-v0.1", "elmer-fig3-v0.3"])
def test_bare_cvode_finds_the_reference_events(name):
    """At rtol 1e-8 the events of the reference, in order, each within 1e-3 s of the reference's time."""
    scene = SCENES[name]
    run = simulate_bare_cvode(scene, 1e-8)
    ref = reference_events(scene.reference)
    assert len(ref) >= 13
    assert [e.kind for e in run.events] == [e.kind for e in ref]
    assert max(abs(a.t_lo - b.t_lo) for a, b in zip(run.events, ref)) < 1e-3
    assert run.x.shape == run.t.shape == scene.grid().shape


@pytest.mark.parametrize("rtol", RTOLS)
def test_the_fmu_adds_no_error_to_cvodes_own(rtol, fmu3_path, bare_errors):
    """The FMU's model exchange under FMPy's simulate_fmu and bare CVode at the same rtol have the same error
    against the reference, within a factor 2 (measured: equal to 3 digits, 5e-8 to 2e-4 of the amplitude)."""
    name = "elmer-fig3-v0.1"
    scene = SCENES[name]
    result = run_fmu(fmu3_path, scene.start_values(1e-10), scene.stop_time, scene.grid_step, interface="me",
                      outputs=["x"], rtol=rtol)
    fmu_error, bare_error = relative_error(result["x"], scene), bare_errors[name, rtol]
    assert 0.5 <= fmu_error / bare_error <= 2.0


@pytest.mark.parametrize("name", ["elmer-fig3-v0.1", "elmer-fig3-v0.3"])
def test_bare_cvode_error_falls_with_rtol(name, bare_errors):
    errors = [bare_errors[name, rtol] for rtol in RTOLS]
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 1e-6


def test_bare_cvode_imports_nothing_from_the_runtime():
    """``bench.bare_cvode`` and the package modules it imports import no ``stickslip.core``, and no object in
    their namespaces comes from it: the model under CVode is the reference's, not the FMU's."""
    import stickslip.bench.bare_cvode as bare

    names, checked = ["stickslip.bench.bare_cvode"], set()
    while names:
        name = names.pop()
        if name in checked:
            continue
        checked.add(name)
        module = importlib.import_module(name)
        package = name if Path(module.__file__).stem == "__init__" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(Path(module.__file__).read_text())):
            if isinstance(node, ast.ImportFrom) and node.level:
                base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                target = f"{base}.{node.module}" if node.module else base
            elif isinstance(node, ast.ImportFrom):
                target = node.module
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
                assert not any(t.startswith("stickslip") for t in targets), f"{name} imports {targets}"
                continue
            else:
                continue
            assert not target.startswith("stickslip.core"), f"{name} imports {target}"
            if target.startswith("stickslip"):
                names.append(target)
        for attr, value in vars(module).items():
            origin = getattr(value, "__module__", None) or getattr(value, "__name__", "")
            assert not str(origin).startswith("stickslip.core"), f"{name}: {attr} comes from {origin}"
    assert {"stickslip.reference.rules", "stickslip.reference.laws", "stickslip.suite.compare"} <= checked
    assert bare.simulate_bare_cvode.__module__ == "stickslip.bench.bare_cvode"
