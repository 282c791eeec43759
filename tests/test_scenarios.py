"""Every scenario file: FMU vs reference within its tolerances, and the expected attractor.

Plus the main job end to end: files written, exit status on success and on a failing scenario.
"""

from pathlib import Path

import pytest

from stickslip.cli import main
from stickslip.suite.runner import run_scenario, run_suite
from stickslip.suite.scenario import load_scenario

SCENARIO_DIR = Path(__file__).resolve().parents[1] / "scenarios"
SCENARIOS = sorted(SCENARIO_DIR.glob("*.toml"))


def test_the_suite_has_the_required_scenarios():
    names = {p.stem for p in SCENARIOS}
    assert {f"elmer-fig3-v{v}" for v in ("0.03", "0.07", "0.1", "0.3", "1.0")} <= names
    assert len(SCENARIOS) >= 19
    # every coded law appears in some scenario, so an error in any law shows in the FMU-vs-reference comparison
    values = [load_scenario(p).law_values for p in SCENARIOS]
    assert {v["kinetic.law"] for v in values} == {"coulomb", "viscous", "stribeck", "lubricated", "carlson-langer"}
    assert {v["static.law"] for v in values} == {"constant", "logarithmic", "saturating", "sigmoid"}


def test_the_suite_exercises_F_ext_the_stick_test_and_a_numeric_graze():
    """Scenarios at the weak spots of issue 12: a constant and a stepped F_ext on non-affine laws, the
    stick test at |kappa x - F_ext| == F_S(0), and a graze inside a numeric (non-affine) slip."""
    constant = load_scenario(SCENARIO_DIR / "stribeck-fext-constant.toml")
    step = load_scenario(SCENARIO_DIR / "elmer-fig3-fext-step.toml")
    for s in (constant, step):
        assert s.params.kinetic.affine() is None
    assert {b[2] for b in constant.breakpoints()} == {-0.4}
    before = [F for t, _, F in step.breakpoints() if t < 130.0]
    after = [F for t, _, F in step.breakpoints() if t >= 130.0]
    assert set(before) == {0.0} and after and all(abs(F - 0.4) < 1e-15 for F in after)
    edge = load_scenario(SCENARIO_DIR / "coulomb-FK-equals-FS.toml").law_values
    assert edge["kinetic.F0"] == edge["static.F0"]
    graze = load_scenario(SCENARIO_DIR / "grazing-stribeck-below.toml")
    assert graze.params.kinetic.affine() is None


@pytest.mark.parametrize("path", SCENARIOS, ids=lambda p: p.stem)
def test_fmu_matches_reference_and_expected_attractor(path, fmu_path):
    scenario = load_scenario(path)
    outcome = run_scenario(scenario, fmu_path)
    assert outcome.passed, outcome.problems
    assert outcome.comparison.attractor_fmu == scenario.expected_attractor


def test_cli_run_writes_csv_png_report_and_exits_0(tmp_path, fmu_path):
    out = tmp_path / "out"
    paths = [str(SCENARIO_DIR / f"{name}.toml") for name in ("coulomb-stick-slip", "viscous-above-critical")]
    code = main(["run", *paths, "--out", str(out), "--jobs", "2", "--fmu", str(fmu_path)])
    assert code == 0
    header = (out / "coulomb-stick-slip.csv").read_text().splitlines()[0]
    assert header.startswith('"time","x","v",')
    assert (out / "viscous-above-critical.png").stat().st_size > 0
    assert "| coulomb-stick-slip " in (out / "report.md").read_text()


def test_a_scenario_that_misses_its_attractor_fails_the_suite(tmp_path, fmu_path):
    text = (SCENARIO_DIR / "viscous-above-critical.toml").read_text()
    wrong = tmp_path / "wrong.toml"
    wrong.write_text(text.replace('expected_attractor = "continuous-sliding"', 'expected_attractor = "stick-slip"'))
    result = run_suite([wrong], tmp_path / "out", jobs=1, fmu_path=fmu_path)
    assert not result.ok
    assert "FMU attractor continuous-sliding" in result.outcomes[0].problems
    assert main(["run", str(wrong), "--out", str(tmp_path / "out"), "--jobs", "1", "--fmu", str(fmu_path)]) == 1


def test_the_comparison_never_calls_the_runtime_laws(monkeypatch, fmu_path):
    """With every law method of ``stickslip.core`` broken after loading, a scenario still runs and passes:
    the reference uses its own laws, and the FMU its own bundled copy of the runtime."""
    from stickslip.core import laws

    scenario = load_scenario(SCENARIO_DIR / "elmer-fig3-fext-step.toml")

    def broken(*args):
        raise AssertionError("the runtime's friction law was called")

    for cls in (*laws.KINETIC_LAWS.values(), *laws.STATIC_LAWS.values()):
        for name in ("force", "slope", "rate", "curvature", "affine", "is_constant", "convexity_breaks"):
            if name in vars(cls):
                monkeypatch.setattr(cls, name, broken)
    outcome = run_scenario(scenario, fmu_path)
    assert outcome.passed, outcome.problems
