"""Scenario files: the shipped ones load; each kind of malformed file gives a ScenarioError naming file and key."""

import re
import tomllib
from pathlib import Path

import pytest

from stickslip.core.errors import StickSlipError
from stickslip.suite.scenario import ScenarioError, load_scenario, load_scenarios

from scenario_texts import VALID

SCENARIO_DIR = Path(__file__).resolve().parents[1] / "scenarios"


ME_SECTION = "[model_exchange]\nmax_abs_dx = 1e-5\nmax_abs_dv = 1e-5\nevent_time = 1e-4\n"

# (test id, text to replace in VALID, replacement, key the message must name)
MALFORMED = [
    ("not-toml", "[model]", "[model", None),
    ("name-missing", 'name = "case"', "", "'name'"),
    ("name-not-a-filename", 'name = "case"', 'name = "a/b"', "'name'"),
    ("unknown-top-level-key", "[simulation]", "[simulaton]", "'simulaton'"),
    ("attractor-unknown", '"stick-slip"', '"chaos"', "'expected_attractor'"),
    ("preset-unknown", 'name = "case"', 'name = "case"\npreset = "elmer-fig4"', "'preset'"),
    ("mass-negative", "M = 1.0", "M = -1.0", "'model.M'"),
    ("mass-missing", "M = 1.0", "", "'model.M'"),
    ("stiffness-a-string", "kappa = 1.0", 'kappa = "1"', "'model.kappa'"),
    ("initial-x-boolean", "x = 0.0", "x = true", "'initial.x'"),
    ("kinetic-law-unknown", '"coulomb"', '"dahl"', "'kinetic.law'"),
    ("kinetic-law-code-unknown", 'law = "coulomb"', "law = 7", "'kinetic.law'"),
    ("kinetic-parameter-of-another-law", "law = \"coulomb\"\nF0 = 0.5", "law = \"coulomb\"\nF0 = 0.5\ngamma = 0.1",
     "'kinetic.gamma'"),
    ("kinetic-parameter-misspelt", "law = \"coulomb\"\nF0 = 0.5", "law = \"coulomb\"\nF_0 = 0.5", "'kinetic.F_0'"),
    ("static-parameter-missing", 'law = "constant"\nF0 = 1.0', 'law = "constant"', "'static.F0'"),
    ("static-section-missing", '[static]\nlaw = "constant"\nF0 = 1.0', "", "'static'"),
    ("kinetic-exceeds-static", "F0 = 0.5", "F0 = 1.5", "kinetic.F0"),
    ("static-out-of-range", "F0 = 1.0", "F0 = 0.0", "static.F0"),
    ("drive-missing", "[inputs.v_drive]\nconstant = 0.1", "[inputs.F_ext]\nconstant = 0.0", "'inputs.v_drive'"),
    ("drive-constant-and-points", "constant = 0.1", "constant = 0.1\npoints = [[0.0, 0.1]]", "'inputs.v_drive'"),
    ("drive-unknown-key", "constant = 0.1", "value = 0.1", "'inputs.v_drive.value'"),
    ("unknown-input", "[inputs.v_drive]", "[inputs.F_normal]\nconstant = 1.0\n[inputs.v_drive]", "'inputs.F_normal'"),
    ("points-empty", "constant = 0.1", "points = []", "'inputs.v_drive.points'"),
    ("point-not-a-pair", "constant = 0.1", "points = [[0.0, 0.1, 2.0]]", "'inputs.v_drive.points[0]'"),
    ("points-unsorted", "constant = 0.1", "points = [[0.0, 0.1], [5.0, 0.2], [4.0, 0.3]]",
     "'inputs.v_drive.points[2][0]'"),
    ("point-time-three-times", "constant = 0.1", "points = [[0.0, 0.1], [5.0, 0.2], [5.0, 0.3], [5.0, 0.4]]",
     "'inputs.v_drive.points[3][0]'"),
    ("step-at-start", "constant = 0.1", "points = [[0.0, 0.1], [0.0, 0.2]]", "'inputs.v_drive.points[1][0]'"),
    ("point-time-negative", "constant = 0.1", "points = [[-1.0, 0.1]]", "'inputs.v_drive.points[0][0]'"),
    ("point-value-nan", "constant = 0.1", "points = [[0.0, nan]]", "'inputs.v_drive.points[0][1]'"),
    ("force-value-a-string", "[simulation]", '[inputs.F_ext]\nconstant = "0"\n[simulation]', "'inputs.F_ext.constant'"),
    ("stop-time-zero", "stop_time = 10.0", "stop_time = 0.0", "'simulation.stop_time'"),
    ("interval-beyond-stop", "output_interval = 0.1", "output_interval = 20.0", "'simulation.output_interval'"),
    ("rtol-too-large", "output_interval = 0.1", "output_interval = 0.1\nrtol = 2.0", "'simulation.rtol'"),
    ("tail-beyond-stop", "output_interval = 0.1", "output_interval = 0.1\ntail = 11.0", "'simulation.tail'"),
    ("tolerance-missing", "[tolerance]\nmax_abs_dx = 1e-9\nmax_abs_dv = 1e-9\nevent_time = 1e-9", "", "'tolerance'"),
    ("tolerance-negative", "event_time = 1e-9", "event_time = -1e-9", "'tolerance.event_time'"),
    ("model-exchange-unknown-key", "event_time = 1e-9", "event_time = 1e-9\n" + ME_SECTION + 'solver = "cvode"',
     "'model_exchange.solver'"),
    ("model-exchange-rtol-too-large", "event_time = 1e-9", "event_time = 1e-9\n" + ME_SECTION + "rtol = 0.1",
     "'model_exchange.rtol'"),
    ("model-exchange-tolerance-missing", "event_time = 1e-9",
     "event_time = 1e-9\n" + ME_SECTION.replace("max_abs_dv = 1e-5\n", ""), "'model_exchange.max_abs_dv'"),
]


def write(tmp_path, text, name="case.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_the_valid_base_loads(tmp_path):
    scenario = load_scenario(write(tmp_path, VALID))
    assert scenario.name == "case"
    assert scenario.start_values()["kinetic.law"] == 1
    assert scenario.tail == pytest.approx(10.0 / 3.0)
    assert scenario.breakpoints() == [(0.0, 0.1, 0.0)]


@pytest.mark.parametrize("old, new, key", [case[1:] for case in MALFORMED], ids=[case[0] for case in MALFORMED])
def test_malformed_file_names_file_and_key(tmp_path, old, new, key):
    assert old in VALID
    path = write(tmp_path, VALID.replace(old, new, 1))
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert isinstance(info.value, StickSlipError)
    assert str(path) in str(info.value)
    if key is not None:
        assert key in str(info.value)


def test_missing_file_is_a_scenario_error(tmp_path):
    with pytest.raises(ScenarioError, match="nothing.toml"):
        load_scenario(tmp_path / "nothing.toml")


def test_duplicate_names_in_a_suite(tmp_path):
    write(tmp_path, VALID, "a.toml")
    second = write(tmp_path, VALID, "b.toml")
    with pytest.raises(ScenarioError, match="'name'") as info:
        load_scenarios([tmp_path])
    assert str(second) in str(info.value)


def test_preset_fills_model_and_laws_and_a_file_section_replaces_the_preset_one(tmp_path):
    text = (VALID.replace('name = "case"', 'name = "case"\npreset = "elmer-fig3"')
            .replace("[model]\nM = 1.0\nkappa = 1.0\n", "")
            .replace('[kinetic]\nlaw = "coulomb"\nF0 = 0.5\n', "")
            .replace('law = "constant"\nF0 = 1.0', 'law = "constant"\nF0 = 2.0'))
    p = load_scenario(write(tmp_path, text)).params
    assert (p.M, p.kappa, p.kinetic.NAME, p.kinetic.gamma1, p.static.F0) == (40.0, 1.0, "lubricated", 3.0, 2.0)


@pytest.mark.parametrize("path", sorted(SCENARIO_DIR.glob("*.toml")), ids=lambda p: p.stem)
def test_shipped_scenario_loads_and_is_named_after_its_file(path):
    assert load_scenario(path).name == path.stem


def test_model_exchange_section_is_optional_and_its_rtol_has_a_default(tmp_path):
    assert load_scenario(write(tmp_path, VALID)).model_exchange is None
    scenario = load_scenario(write(tmp_path, VALID + ME_SECTION))
    assert scenario.model_exchange.rtol == 1e-8
    assert (scenario.model_exchange.tolerance.max_abs_dx, scenario.model_exchange.tolerance.event_time) == (1e-5, 1e-4)


def test_law_values_are_the_files_numbers_and_build_the_reference(tmp_path):
    """The reference's laws come from the file's numbers (``law_values``), not from the runtime's objects."""
    from stickslip.reference import parameters_from_values
    from stickslip.reference.laws import Stribeck

    s = load_scenario(SCENARIO_DIR / "stribeck-fext-constant.toml")
    assert s.law_values == {"M": 1.0, "kappa": 1.0, "kinetic.law": "stribeck", "kinetic.F0": 0.4,
                            "kinetic.F_stribeck": 0.3, "kinetic.v_stribeck": 0.1, "kinetic.delta": 2.0,
                            "kinetic.gamma": 0.05, "static.law": "constant", "static.F0": 1.0}
    assert isinstance(parameters_from_values(s.law_values).kinetic, Stribeck)
    assert s.start_values()["kinetic.law"] == 3 and s.start_values()["kinetic.gamma"] == 0.05


def test_grazing_scenario_drive_is_a_relative_1e_7_below_the_critical_velocity():
    """Recompute v_c (scipy DOP853 at rtol 1e-13 and brentq, independent of FMU and reference)."""
    from stickslip.reference import parameters_from_values
    from stickslip.stress.cases import graze_velocity_numeric

    s = load_scenario(SCENARIO_DIR / "grazing-stribeck-below.toml")
    v_c = graze_velocity_numeric(parameters_from_values(s.law_values), 0.05, 1.0)
    v_drive = float(s.signals["v_drive"].value[0])
    assert v_drive == pytest.approx(v_c * (1 - 1e-7), rel=1e-13)
    assert s.v0 == v_drive


@pytest.mark.parametrize("path", sorted(SCENARIO_DIR.glob("*.toml")), ids=lambda p: p.stem)
def test_every_scenario_runs_under_model_exchange_too(path):
    """`stickslip run --interface me scenarios/` needs a [model_exchange] section in every file."""
    assert load_scenario(path).model_exchange is not None


#: "period 39.9 s", "period about 44 s": the stick-slip period a scenario's description states
STATED_PERIOD = re.compile(r"period (about )?(\d+(?:\.\d+)?) s\b")


def _constant_inputs(path):
    """``(v_drive, F_ext)`` of a scenario file whose inputs are constants (m/s, N), else None."""
    inputs = tomllib.loads(path.read_text()).get("inputs", {})
    constant = {name: table.get("constant") for name, table in inputs.items()}
    if set(constant) - {"v_drive", "F_ext"} or None in constant.values():
        return None
    return constant.get("v_drive"), constant.get("F_ext", 0.0)


def test_stated_stick_slip_periods_hold():
    """Where a stick-slip scenario with constant inputs and a constant static law states its cycle's period, the
    stick-slip cycle has that period (to 1%, or to the last digit given)."""
    from stickslip.analysis import stick_slip_cycles

    checked = []
    for path in sorted(SCENARIO_DIR.glob("*.toml")):
        scenario, inputs = load_scenario(path), _constant_inputs(path)
        stated = STATED_PERIOD.search(" ".join(scenario.description.split()))
        if scenario.expected_attractor != "stick-slip" or not inputs or not scenario.params.static.is_constant() \
                or stated is None:
            continue
        cycle = stick_slip_cycles(scenario.params, [inputs[0]], inputs[1])[0]
        text = stated.group(2)
        digit = 10.0 ** -len(text.partition(".")[2])
        assert cycle.exists and abs(cycle.period - float(text)) <= max(0.01 * cycle.period, digit), \
            f"{path.name}: states period {text} s, the stick-slip cycle's is {cycle.period:.4g} s"
        checked.append(path.stem)
    assert {"elmer-fig3-v0.03", "elmer-fig3-v0.1", "elmer-fig3-v0.3"} <= set(checked)
