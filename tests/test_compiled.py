"""The compiled runtime (mypyc, from the same sources) and its pure-Python fallback: same numbers, either way."""

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import fmpy
import numpy as np
import pytest

import stickslip.core as compiled
from stickslip.core._implementation import COMPILED_MODULES, import_pure_copy
from stickslip.fmu import build, source_tag
from stickslip.suite.scenario import load_scenario

CORE = Path(compiled.__file__).parent
pure = import_pure_copy(str(CORE), "stickslip_pure_core")
SCENARIOS = sorted((Path(__file__).resolve().parents[1] / "scenarios").glob("*.toml"))
HAS_COMPILED = all(list(CORE.glob(f"{name}.*.so")) for name in COMPILED_MODULES)


def test_the_python_api_runs_the_compiled_modules_when_they_are_built():
    if not HAS_COMPILED:
        pytest.skip("this install has no compiled modules (no C compiler at install time)")
    assert compiled.IMPLEMENTATION == "compiled (mypyc)"
    assert compiled.trajectory.__file__.endswith(".so") and pure.trajectory.__file__.endswith(".py")


def _run(core, scenario):
    """Every output at every output time, and the events, of ``scenario`` run by ``core``'s Trajectory."""
    p = scenario.params
    params = core.Parameters(p.M, p.kappa, core.kinetic_law(p.kinetic.CODE, **p.kinetic.parameters()),
                             core.static_law(p.static.CODE, **p.static.parameters()))
    breaks = scenario.breakpoints()
    _, v_drive, F_ext = breaks[0]
    traj = core.Trajectory(params, scenario.x0, scenario.v0, v_drive, F_ext, 0.0, scenario.rtol, record_events=True)
    rows, pending = [], list(breaks[1:])
    n = round(scenario.stop_time / scenario.output_interval)
    for k in range(n + 1):
        t = k * scenario.output_interval
        while pending and pending[0][0] <= t:
            t_input, v_drive, F_ext = pending.pop(0)
            traj.advance_to(t_input)
            traj.set_inputs(v_drive, F_ext)
        traj.advance_to(t)
        rows.append(traj.outputs())
    return rows, traj.events


@pytest.mark.parametrize("path", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_compiled_and_pure_agree_bit_for_bit_on_every_scenario(path):
    scenario = load_scenario(path)
    rows, events = _run(compiled, scenario)
    pure_rows, pure_events = _run(pure, scenario)
    assert len(rows) > 100 and events
    assert rows == pure_rows  # every output, exactly
    assert events == pure_events


def _probe(extra_env, code, cwd):
    env = {**os.environ, **extra_env}
    run = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, env=env,
                         stdin=subprocess.DEVNULL, cwd=cwd)
    assert run.returncode == 0, run.stderr
    return run.stdout.strip()


def test_the_sources_run_when_asked_to_or_when_they_changed_since_compiling(tmp_path):
    if not HAS_COMPILED:
        pytest.skip("this install has no compiled modules")
    code = """
        import stickslip.core as c
        print(c.IMPLEMENTATION, c.trajectory.__file__.endswith('.py'))
    """
    assert _probe({"STICKSLIP_PURE_PYTHON": "1"}, code, tmp_path) == \
        "pure Python (STICKSLIP_PURE_PYTHON is set) True"
    copy = tmp_path / "copy" / "stickslip_edited"
    shutil.copytree(CORE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    with open(copy / "poly.py", "a") as source:
        source.write("\n# edited after compiling\n")
    edited = """
        import stickslip_edited as c
        print(c.IMPLEMENTATION, c.poly.__file__.endswith('.py'))
    """
    assert _probe({"PYTHONPATH": str(copy.parent)}, edited, tmp_path) == \
        "pure Python (the sources changed since they were compiled) True"


def _fmu_run(folder, cwd):
    """``(implementation of the FMU's runtime, x at every output time as hex)`` of a stick-slip run of the
    extracted FMU ``folder``, in a fresh process (a process imports an FMU's runtime once).

    The process ends without interpreter teardown: under pytest, some of these processes (pure and compiled
    FMUs alike) abort at exit with glibc's "corrupted double-linked list", after their results are out.
    """
    code = f"""
        import sys, fmpy
        result = fmpy.simulate_fmu({str(folder)!r}, stop_time=60.0, output_interval=0.5, output=["x", "n_events"],
            start_values={{"kinetic.law": 3, "kinetic.F0": 0.4, "kinetic.F_stribeck": 0.3,
                          "kinetic.v_stribeck": 0.05, "static.F0": 1.0}})
        runtime = next(m for name, m in sys.modules.items() if name.startswith("sbf_runtime_") and "." not in name)
        assert result["n_events"][-1] >= 3
        print(runtime.IMPLEMENTATION.split(":")[0])
        print(" ".join(float(x).hex() for x in result["x"]), flush=True)
        import os; os._exit(0)  # no teardown: see the docstring
    """
    implementation, xs = _probe({}, code, cwd).splitlines()
    return implementation, xs


def test_the_fmu_falls_back_to_its_sources_when_its_compiled_modules_cannot_load(fmu_path, tmp_path):
    folder = Path(fmpy.extract(str(fmu_path), unzipdir=str(tmp_path / "fmu")))
    groups = list((folder / "resources").glob("*__mypyc.*.so"))
    if not groups:
        pytest.skip("this FMU has no compiled modules (no C compiler at build time)")
    implementation, xs = _fmu_run(folder, tmp_path)
    for group in groups:
        group.unlink()  # as on a host that cannot load the compiled modules
    fallback, fallback_xs = _fmu_run(folder, tmp_path)
    assert implementation == "compiled (mypyc)"
    assert fallback == "pure Python (the compiled modules do not load"
    assert fallback_xs == xs  # bit for bit


def test_a_build_without_a_c_compiler_gives_a_working_pure_fmu_and_says_so(tmp_path):
    code = f"""
        from pathlib import Path
        import stickslip.fmu.staging as staging
        staging.CACHE = Path({str(tmp_path / "cache")!r})  # nothing compiled earlier to reuse,
        staging.PREBUILT = Path({str(tmp_path / "prebuilt")!r})  # nor compiled when the package was installed
        from stickslip.fmu import build
        print(build(Path({str(tmp_path / "SpringBlockFriction.fmu")!r})))
    """
    run = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                         env={**os.environ, "CC": str(tmp_path / "no-such-compiler")}, cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert "the FMUs' runtime stays pure Python" in run.stderr
    pure_fmu = fmpy.extract(run.stdout.strip().splitlines()[-1], unzipdir=str(tmp_path / "pure_fmu"))
    implementation, xs = _fmu_run(pure_fmu, tmp_path)
    assert implementation == "pure Python (no compiled modules for this Python)"
    params = compiled.Parameters(1.0, 1.0, compiled.kinetic_law(3, F0=0.4, F_stribeck=0.3, v_stribeck=0.05),
                                 compiled.static_law(1, F0=1.0))
    traj = compiled.Trajectory(params, 0.0, 0.0, v_drive=0.1)  # the FMU's defaults otherwise
    expected = [0.0] + [traj.x for t in np.arange(1, 121) * 0.5 if traj.advance_to(float(t)) is None]
    assert xs.split() == [x.hex() for x in expected]  # the pure FMU gives the compiled stepper's numbers
