"""Bad input gets a clear error and loses nothing (issue 5, item 3).

Every invalid parameter or input: an FMI error status from the FMU with a log
message that names the variable and the allowed range; through FMPy
(``run_fmu``) an exception with that message; and the process runs the next
simulation. ``tests/test_fmu.py`` has 22 such cases; this file covers every
other parameter and bound systematically, inputs during the run, misuse of
``fmi2DoStep``, extreme-but-valid parameter combinations, and malformed
scenario files beyond ``tests/test_scenario_files.py``.
"""

import math
import subprocess
import sys

import pytest

from stickslip.core import KINETIC_LAWS, STATIC_LAWS, RTOL_RANGE, StickSlipError
from stickslip.core.ranges import ANY_FINITE, POSITIVE
from stickslip.hosts.fmpy_host import FMUError, run_fmu
from stickslip.suite.scenario import ScenarioError, load_scenario, load_scenarios
from stickslip.stress.session import FmuCallError, FmuSession, fmi2Error, fmi2Fatal

import machine_needs
from fmu_probe import run_probe
from scenario_texts import VALID

STICK_SLIP = {"M": 1.0, "kappa": 1.0, "kinetic.F0": 0.5, "static.F0": 1.0}


@pytest.fixture(scope="module")
def session(fmu_path):
    with FmuSession(fmu_path) as s:
        yield s


def _runs_normally(session):
    """The next simulation in this process: stick-slip with one breakaway in 10 s."""
    inst = session.instantiate(session.start_values(dict(STICK_SLIP, v_start=0.1)))
    try:
        for _ in range(10):
            inst.do_step(1.0)
        row = inst.read()
    finally:
        inst.free()
    return row["n_events"] == 1 and row["mode"] == 1


# ---------------------------------------------------------------------------
# parameters: every one, every kind of bad value
# ---------------------------------------------------------------------------

# (name, value) pairs that tests/test_fmu.py already checks
COVERED = {("M", -1.0), ("M", 0.0), ("M", "nan"), ("kappa", 0.0), ("kappa", math.inf), ("x_start", "nan"),
           ("v_start", -math.inf), ("kinetic.law", 7), ("static.law", 0), ("kinetic.F0", -0.1),
           ("kinetic.v_stribeck", 0.0), ("kinetic.delta", 0.5), ("kinetic.dv", -0.05), ("static.F0", 0.0),
           ("static.tau", -1.0), ("static.F_inf", "nan"), ("static.n", 30.0), ("solver.rtol", 0.0),
           ("v_drive", "nan"), ("F_ext", math.inf)}


def _key(name, value):
    return (name, "nan") if isinstance(value, float) and math.isnan(value) else (name, value)


def _law_owner(kind, laws, parameter):
    """Lowest law code that uses ``parameter``, its allowed Range and unit."""
    for code in sorted(laws):
        if parameter in laws[code].PARAMETERS:
            _, allowed, unit = laws[code].PARAMETERS[parameter]
            return code, allowed, unit
    raise KeyError(parameter)


def _bad_values(allowed):
    """Values outside ``allowed``: non-finite ones and each side of each bound."""
    values = [math.nan, math.inf, -math.inf]
    if allowed.low is not None:
        values.append(allowed.low if allowed.low_open else -1e-300 if allowed.low == 0.0 else allowed.low * 0.999)
        values.append(-1.0 if allowed.low >= 0.0 else allowed.low - 1.0)
    if allowed.high is not None:
        values.append(allowed.high if allowed.high_open else allowed.high * 1.001)
    return values


def _parameter_cases():
    cases = []
    own = {"M": (POSITIVE, "kg"), "kappa": (POSITIVE, "N/m"), "x_start": (ANY_FINITE, "m"),
           "v_start": (ANY_FINITE, "m/s"), "solver.rtol": (RTOL_RANGE, "")}
    for name, (allowed, _) in own.items():
        for value in _bad_values(allowed):
            cases.append((f"{name}={value!r}", {name: value}, name, str(allowed)))
    for kind, laws in (("kinetic", KINETIC_LAWS), ("static", STATIC_LAWS)):
        names = sorted({p for law in laws.values() for p in law.PARAMETERS})
        for parameter in names:
            code, allowed, _ = _law_owner(kind, laws, parameter)
            name = f"{kind}.{parameter}"
            for value in _bad_values(allowed):
                start = {f"{kind}.law": code, name: value}
                if kind == "static" and parameter == "F0" and isinstance(value, float) and math.isfinite(value):
                    start["kinetic.F0"] = 0.0  # keep F_K(0+) <= F_S(0) out of the way
                cases.append((f"{name}={value!r}", start, name, str(allowed)))
        for value in (0, -1, len(laws) + 1, 2**31 - 1):
            cases.append((f"{kind}.law={value}", {f"{kind}.law": value}, f"{kind}.law", "allowed are 1 ("))
    for value in (math.nan, -math.inf, math.inf):
        for name in ("v_drive", "F_ext"):
            cases.append((f"{name}={value!r}", {name: value}, name, str(ANY_FINITE)))
    return [c for c in cases if all(_key(k, v) not in COVERED for k, v in c[1].items() if k == c[2])]


PARAMETER_CASES = _parameter_cases()


def _friction_pair_cases():
    """F_K(0+) > F_S(0) for each kinetic law that can exceed it, with each static law."""
    cases = []
    kinetic = {1: {"kinetic.F0": 1.2}, 2: {"kinetic.F0": 1.2, "kinetic.gamma": 5.0},
               3: {"kinetic.F0": 0.6, "kinetic.F_stribeck": 0.6}}
    for k_code, k_values in kinetic.items():
        for s_code in sorted(STATIC_LAWS):
            start = {"kinetic.law": k_code, "static.law": s_code, "static.F0": 1.0, **k_values}
            cases.append((f"F_K(0+)>F_S(0)-kinetic{k_code}-static{s_code}", start))
    return cases


FRICTION_PAIR_CASES = _friction_pair_cases()


def test_every_real_parameter_and_input_is_covered(session):
    checked = {name for _, _, name, _ in PARAMETER_CASES} | {name for name, _ in COVERED}
    parameters = {n for n, v in session.variables.items() if v.causality in ("parameter", "input")}
    assert parameters <= checked, parameters - checked


@pytest.mark.parametrize("start, name, allowed", [c[1:] for c in PARAMETER_CASES], ids=[c[0] for c in PARAMETER_CASES])
def test_bad_parameter_error_names_variable_and_range(session, fmu_path, start, name, allowed):
    # directly: the FMI status and the FMU's log message
    with pytest.raises(FmuCallError) as direct:
        session.instantiate(session.start_values(start))
    error = direct.value
    assert error.function == ("fmi2SetReal" if name in ("v_drive", "F_ext") else "fmi2ExitInitializationMode")
    assert error.status in (fmi2Error, fmi2Fatal)
    message = "\n".join(error.messages)
    assert f"{name} = " in message and "allowed" in message and allowed in message, message
    # through FMPy: an exception carrying the same message
    with pytest.raises(FMUError) as through_fmpy:
        run_fmu(fmu_path, start, 1.0, 0.5)
    assert isinstance(through_fmpy.value, StickSlipError)
    assert f"{name} = " in str(through_fmpy.value) and allowed in str(through_fmpy.value)
    # and the process goes on
    assert _runs_normally(session)


@pytest.mark.parametrize("start", [c[1] for c in FRICTION_PAIR_CASES], ids=[c[0] for c in FRICTION_PAIR_CASES])
def test_kinetic_above_static_friction_is_an_error_for_every_law_pair(session, fmu_path, start):
    with pytest.raises(FmuCallError) as direct:
        session.instantiate(session.start_values(start))
    message = "\n".join(direct.value.messages)
    assert "F_K(0+)" in message and "exceeds static friction F_S(0) = 1.0 N" in message and "allowed" in message
    with pytest.raises(FMUError, match=r"F_K\(0\+\)"):
        run_fmu(fmu_path, start, 1.0, 0.5)
    assert _runs_normally(session)


def test_bad_parameter_status_is_fmi2Error_not_fmi2Fatal(session):
    """FMI 2.0 expects fmi2Error for a bad parameter (fmi2Fatal says ALL instances are corrupted). PythonFMU 0.7.0
    returns fmi2Fatal for every exception of the slave; the FMU's Linux loader (stickslip.fmu_loader) reports it
    as fmi2Error, since the slave balances PythonFMU's release of it and the instance can still be reset or freed."""
    machine_needs.c_compiler("the FMU's Linux loader")
    with pytest.raises(FmuCallError) as direct:
        session.instantiate(session.start_values({"M": -1.0}))
    assert direct.value.status == fmi2Error


@pytest.mark.parametrize("name, value", [("kinetic.gamma", math.nan), ("kinetic.gamma1", -1.0), ("static.n", 30.0)])
def test_parameter_of_an_unused_law_is_checked_too(session, name, value):
    """Every value set is checked, whether its law is selected or not (issue 20: kinetic.gamma = NaN with law 1
    was accepted); the run uses laws 1 and 1 here."""
    with pytest.raises(FmuCallError) as error:
        session.instantiate(session.start_values({"kinetic.law": 1, "static.law": 1, name: value}))
    message = "\n".join(error.value.messages)
    assert f"{name} = {value!r}" in message and "out of range: allowed is a finite value in" in message, message
    assert _runs_normally(session)


# ---------------------------------------------------------------------------
# inputs during the run, and misuse of fmi2DoStep
# ---------------------------------------------------------------------------

RUN_INPUTS = [(name, value) for name in ("v_drive", "F_ext") for value in (math.nan, math.inf, -math.inf)]


@pytest.mark.parametrize("name, value", RUN_INPUTS, ids=[f"{n}={v!r}" for n, v in RUN_INPUTS])
def test_bad_input_during_the_run_is_refused_when_set_naming_the_input(session, fmu_path, name, value):
    """fmi2SetReal refuses the input (fmi2Error, a message naming it and its range); the instance keeps the old
    value and steps on with it."""
    inst = session.instantiate(session.start_values(dict(STICK_SLIP, v_start=0.1)))
    try:
        for _ in range(3):
            inst.do_step(0.5)
        with pytest.raises(FmuCallError) as error:
            inst.set_value(name, value)
        assert error.value.function == "fmi2SetReal" and error.value.status == fmi2Error
        message = "\n".join(error.value.messages)
        assert f"{name} = {value!r}" in message and "allowed is a finite value" in message, message
        inst.do_step(0.5)
        row = inst.read()
        assert (row["v_drive"], row["F_ext"]) == (0.1, 0.0) and row["x"] == pytest.approx(0.2, abs=1e-14)
    finally:
        inst.free()
    assert _runs_normally(session)


@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")  # FMPy interpolating -inf
def test_bad_input_from_an_fmpy_input_table_is_an_exception(session, fmu_path):
    import numpy as np

    signal = np.array([(0.0, 0.1, 0.0), (2.0, 0.1, 0.0), (2.0, 0.1, -math.inf), (4.0, 0.1, -math.inf)],
                      dtype=[("time", float), ("v_drive", float), ("F_ext", float)])
    with pytest.raises(FMUError, match="F_ext = -inf N is out of range"):
        run_fmu(fmu_path, STICK_SLIP, 4.0, 0.5, input_signal=signal)
    assert _runs_normally(session)


@pytest.mark.parametrize("h, text", [(-0.5, "communicationStepSize = -0.5 s is out of range"),
                                     (math.nan, "communicationStepSize = nan s is out of range")],
                         ids=["negative", "nan"])
def test_bad_communication_step_is_an_error(session, fmu_path, h, text):
    inst = session.instantiate(session.start_values(STICK_SLIP))
    try:
        inst.do_step(1.0)
        with pytest.raises(FmuCallError) as error:
            inst.do_step(h)
        assert text in "\n".join(error.value.messages)
    finally:
        inst.free()
    assert _runs_normally(session)


def test_zero_communication_step_changes_nothing(session):
    inst = session.instantiate(session.start_values(dict(STICK_SLIP, v_start=0.1)))
    inst.do_step(1.0)
    before = inst.read()
    inst.do_step(0.0)
    assert inst.read() == before
    inst.free()


INFINITE_STEP = r"""
import sys
from stickslip.stress.session import FmuSession, FmuCallError
with FmuSession(sys.argv[1]) as s:
    inst = s.instantiate(s.start_values({"v_start": 0.1}))
    try:
        inst.do_step(float("inf"))
        print("RETURNED", inst.read()["x"])
    except FmuCallError as e:
        print("ERROR", " | ".join(e.messages))
"""


def test_infinite_communication_step_is_an_error_not_a_hang(fmu_path):
    try:
        proc = subprocess.run([sys.executable, "-c", INFINITE_STEP, str(fmu_path)], capture_output=True, text=True,
                              timeout=8)
    except subprocess.TimeoutExpired:
        pytest.fail("fmi2DoStep(0, inf) did not return within 8 s")
    assert "ERROR" in proc.stdout and "inf" in proc.stdout


# ---------------------------------------------------------------------------
# extreme but individually valid parameters: at the scale limits no NaN or infinity leaves the FMU and the
# motion is the closed form; beyond them, a clear error at initialization
# ---------------------------------------------------------------------------

OUTPUTS_FINITE = ("x", "v", "v_rel", "F_friction", "F_spring", "t_stick", "z_slip", "z_stick")
#: stuck at x = 0 after a slip at v_drive = 0 that starts with sqrt(kappa M) v_start = 1 N (F_K = 0.5 N,
#: F_S = 1 N): the block stops where kappa x = sqrt(F_K^2 + 1 N^2) - F_K, within F_S, and sticks there
STOP = 0.5 * (math.sqrt(5.0) - 1.0)  # N
AT_THE_LIMITS = [  # (name, start values, (x m, v m/s) at t s > 0 (M = kappa = 1 unless set), (x, v) scales)
    # a tenth of the largest force scale (1e150 N): breakaway after 1e-149 s, then a Coulomb slip about
    # x = F_K / kappa, x = F_K + (F_S - F_K) cos t + v_drive sin t (the first two terms 1e-149 of the third)
    ("drive 1e149 m/s", {"v_start": 1e149, "v_drive": 1e149}, lambda t: (1e149 * math.sin(t), 1e149 * math.cos(t)),
     (1e149, 1e149)),
    # slips at once and overshoots v_drive = 0.1 m/s after 1e-150 s: x = (F_ext - F_K) (1 - cos t), F_K negligible
    ("force 1e149 N", {"F_ext": 1e149}, lambda t: (1e149 * (1.0 - math.cos(t)), 1e149 * math.sin(t)), (1e149, 1e149)),
    # kappa / M at its limit 1e100 1/s^2 (by the mass, by the stiffness): a slip of 3e-50 s, then stuck
    ("mass 1e-100 kg", {"M": 1e-100, "v_drive": 0.0, "v_start": 1e50}, lambda t: (STOP, 0.0), (1.0, 1e50)),
    ("stiffness 1e100 N/m", {"kappa": 1e100, "v_drive": 0.0, "v_start": 1e-50}, lambda t: (STOP * 1e-100, 0.0),
     (1e-100, 1e-50)),
]


@pytest.mark.parametrize("start, exact, scales", [c[1:] for c in AT_THE_LIMITS], ids=[c[0] for c in AT_THE_LIMITS])
def test_parameters_at_the_scale_limits_give_finite_outputs_and_the_closed_form(session, start, exact, scales):
    inst = session.instantiate(session.start_values(start))
    try:
        for k in range(1, 6):
            inst.do_step(0.5)
            row = inst.read()
            assert all(math.isfinite(row[n]) for n in OUTPUTS_FINITE), row
            x, v = exact(0.5 * k)
            # measured: 2.3e-16 of the scale at most
            assert abs(row["x"] - x) <= 1e-14 * scales[0] and abs(row["v"] - v) <= 1e-14 * scales[1], (row, x, v)
        assert row["n_events"] == 1
    finally:
        inst.free()


# Each value is in its own range, but alone or together they are beyond the scale limits (forces and the products
# that build them up to 1e150 N, kappa / M in [1e-100, 1e100] 1/s^2) or overflow a float.
OVERFLOWING_COMBINATIONS = [
    ("huge-drive", {"v_start": 1e300, "v_drive": 1e300}, "sqrt(kappa M) * |v_drive| = 1e+300 N"),
    ("huge-force", {"F_ext": 1e300, "static.F0": 1.0, "kinetic.F0": 0.5}, "|F_ext| = 1e+300 N"),
    ("tiny-mass", {"M": 1e-200}, "kappa / M = 1e+200 1/s^2"),
    ("huge-stiffness", {"kappa": 1e200}, "kappa / M = 1e+200 1/s^2"),
    ("position-times-stiffness-overflows", {"x_start": 1e300, "kappa": 1e10}, "kappa * |x_start|"),
    ("forces-overflow", {"F_ext": 1e308, "static.F0": 1e308, "kinetic.F0": 1e308}, "|F_ext|"),
    ("static-force-overflows", {"static.F0": 1e200}, "static.F0"),
    ("aging-limit-overflows", {"static.law": 3, "static.F_inf": 1e200}, "static.F_inf"),
    ("speed-times-impedance-overflows", {"v_start": 1e200}, "sqrt(kappa M) * |v_start|"),
    ("drive-times-impedance-overflows", {"v_drive": 1e160, "M": 1e10, "kappa": 1e10}, "sqrt(kappa M) * |v_drive|"),
    ("mass-1e-300-stiffness-1e300", {"M": 1e-300, "kappa": 1e300, "x_start": 1.0}, "kappa / M"),
    ("mass-1e300-stiffness-1e-300", {"M": 1e300, "kappa": 1e-300}, "kappa / M"),
]


@pytest.mark.parametrize("start, scale", [c[1:] for c in OVERFLOWING_COMBINATIONS],
                         ids=[c[0] for c in OVERFLOWING_COMBINATIONS])
def test_overflowing_parameter_combinations_are_rejected_at_initialization(session, start, scale):
    with pytest.raises(FmuCallError) as error:
        session.instantiate(session.start_values(start))
    message = "\n".join(error.value.messages)
    assert scale in message and "out of range" in message and "allowed is" in message, message
    assert any(f"{name} = " in message for name in start if name != "static.law"), message
    assert _runs_normally(session)


def test_an_input_that_overflows_the_force_scale_is_rejected_during_the_run(session):
    inst = session.instantiate(session.start_values(STICK_SLIP))
    try:
        inst.do_step(0.5)
        with pytest.raises(FmuCallError) as error:
            inst.set_value("F_ext", 1e200)
        inst.do_step(0.5)
        message = "\n".join(error.value.messages)
        assert "|F_ext| = 1e+200 N" in message and "allowed is at most 1e+150 N" in message, message
    finally:
        inst.free()


def test_large_but_representable_scales_still_run(session):
    """Just inside the limits (forces of 1e149 N, kappa/M = 1e99) the FMU runs and stays finite."""
    for start in ({"x_start": 1e149, "static.F0": 1e149, "kinetic.F0": 5e148},
                  {"M": 1e-50, "kappa": 1e49, "x_start": 1e-3}):
        inst = session.instantiate(session.start_values(start))
        try:
            inst.do_step(1e-47 if "M" in start else 1.0)  # 1e-47 s: about 50 periods of this block
            row = inst.read()
            assert all(math.isfinite(row[n]) for n in OUTPUTS_FINITE), {n: row[n] for n in OUTPUTS_FINITE}
        finally:
            inst.free()


# ---------------------------------------------------------------------------
# malformed scenario files (beyond tests/test_scenario_files.py)
# ---------------------------------------------------------------------------


# (test id, text to replace, replacement, key the message must name, text that says what was expected)
MALFORMED = [
    ("description-a-number", "expected_attractor", "description = 5\nexpected_attractor", "'description'",
     "a string"),
    ("name-a-number", 'name = "case"', "name = 5", "'name'", "a string"),
    ("preset-a-number", 'name = "case"', 'name = "case"\npreset = 3', "'preset'", "elmer-fig3"),
    ("attractor-a-number", '"stick-slip"', "3", "'expected_attractor'", "stick-slip"),
    ("initial-missing", "[initial]\nx = 0.0\nv = 0.1\n", "", "'initial'", "a table"),
    ("initial-velocity-a-string", "v = 0.1", 'v = "fast"', "'initial.v'", "a finite number"),
    ("initial-unknown-key", "v = 0.1", "v = 0.1\na = 2.0", "'initial.a'", "one of the keys"),
    ("kinetic-law-boolean", 'law = "coulomb"', "law = true", "'kinetic.law'", "'coulomb' (1)"),
    ("kinetic-parameter-infinite", "F0 = 0.5", "F0 = inf", "'kinetic.F0'", "a finite number"),
    ("kinetic-parameter-out-of-range", 'law = "coulomb"\nF0 = 0.5',
     'law = "stribeck"\nF0 = 0.5\nF_stribeck = 0.1\nv_stribeck = 0.1\ndelta = 0.5\ngamma = 0.0',
     "'kinetic.delta'", "a finite number in [1, 10]"),
    ("static-law-unknown", 'law = "constant"', 'law = "aging"', "'static.law'", "'constant' (1)"),
    ("static-parameter-of-another-law", 'law = "constant"\nF0 = 1.0', 'law = "constant"\nF0 = 1.0\ntau = 2.0',
     "'static.tau'", "one of the keys"),
    ("inputs-missing", "[inputs.v_drive]\nconstant = 0.1\n", "", "'inputs'", "a table"),
    ("points-a-number", "constant = 0.1", "points = 5", "'inputs.v_drive.points'", "list of [time, value] pairs"),
    ("point-time-a-string", "constant = 0.1", 'points = [["0", 0.1]]', "'inputs.v_drive.points[0][0]'",
     "a finite number in [0, inf)"),
    ("point-value-infinite", "constant = 0.1", "points = [[0.0, inf]]", "'inputs.v_drive.points[0][1]'",
     "a finite number"),
    ("force-constant-and-points", "[simulation]", "[inputs.F_ext]\nconstant = 0.0\npoints = [[0.0, 0.0]]\n[simulation]",
     "'inputs.F_ext'", "exactly one of 'constant' or 'points'"),
    ("simulation-missing", "[simulation]\nstop_time = 10.0\noutput_interval = 0.1\n", "", "'simulation'", "a table"),
    ("interval-missing", "output_interval = 0.1", "", "'simulation.output_interval'", "a finite number in (0, 10]"),
    ("interval-negative", "output_interval = 0.1", "output_interval = -0.1", "'simulation.output_interval'",
     "a finite number in (0, 10]"),
    ("stop-time-infinite", "stop_time = 10.0", "stop_time = inf", "'simulation.stop_time'", "a finite number"),
    ("tolerance-unknown-key", "event_time = 1e-9", "event_time = 1e-9\nmax_abs_dt = 1.0", "'tolerance.max_abs_dt'",
     "one of the keys"),
    ("tolerance-a-string", "max_abs_dx = 1e-9", 'max_abs_dx = "small"', "'tolerance.max_abs_dx'",
     "a finite number in (0, inf)"),
    ("duplicate-key", "M = 1.0", "M = 1.0\nM = 2.0", "cannot read a TOML file", "Cannot overwrite a value"),
    ("empty-file", VALID, "", "'name'", "a string"),
]


def _write(tmp_path, text, name="case.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("old, new, key, expected", [c[1:] for c in MALFORMED], ids=[c[0] for c in MALFORMED])
def test_malformed_scenario_names_file_key_and_expectation(tmp_path, old, new, key, expected):
    assert old in VALID
    path = _write(tmp_path, VALID.replace(old, new, 1))
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    message = str(info.value)
    assert str(path) in message and key in message and expected in message, message


def test_scenario_directory_without_files(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(ScenarioError, match="no scenario files"):
        load_scenarios([tmp_path / "empty"])


def test_scenario_path_that_does_not_exist_or_is_a_directory(tmp_path):
    with pytest.raises(ScenarioError, match="missing.toml"):
        load_scenarios([tmp_path / "missing.toml"])
    with pytest.raises(ScenarioError, match="cannot read a TOML file"):
        load_scenario(tmp_path)


def test_one_malformed_file_in_a_directory_is_named(tmp_path):
    _write(tmp_path, VALID, "a.toml")
    bad = _write(tmp_path, VALID.replace('name = "case"', 'name = "other"').replace("M = 1.0", "M = -1.0"), "b.toml")
    with pytest.raises(ScenarioError) as info:
        load_scenarios([tmp_path])
    assert str(bad) in str(info.value) and "'model.M'" in str(info.value)


@pytest.mark.parametrize("data", [b"\xff\xfe\x00garbage", 'name = "caf\xe9"'.encode("latin-1")],
                         ids=["binary", "latin-1"])
def test_scenario_file_that_is_not_utf8(tmp_path, data):
    path = tmp_path / "case.toml"
    path.write_bytes(data)
    with pytest.raises(ScenarioError, match="case.toml"):
        load_scenario(path)


@pytest.mark.parametrize("rtol", ["1e-16", "0.5"])
def test_scenario_rtol_outside_the_solver_range(tmp_path, rtol):
    path = _write(tmp_path, VALID.replace("output_interval = 0.1", f"output_interval = 0.1\nrtol = {rtol}"))
    with pytest.raises(ScenarioError, match="'simulation.rtol'"):
        load_scenario(path)


def _law_section(law, parameters):
    return f'law = "{law.NAME}"\n' + "".join(f"{k} = {v!r}\n" for k, v in parameters.items())


def _scenario_law_cases():
    """(id, kind, law, parameter, out-of-range value, its Range) for every parameter of every law."""
    cases = []
    for kind, laws in (("kinetic", KINETIC_LAWS), ("static", STATIC_LAWS)):
        for law in laws.values():
            for parameter, (_, allowed, _) in law.PARAMETERS.items():
                bad = [v for v in _bad_values(allowed) if math.isfinite(v)][0]
                cases.append((f"{kind}.{law.NAME}.{parameter}", kind, law, parameter, bad, allowed))
    return cases


@pytest.mark.parametrize("kind, law, parameter, bad, allowed", [c[1:] for c in _scenario_law_cases()],
                         ids=[c[0] for c in _scenario_law_cases()])
def test_scenario_law_parameter_message_states_its_true_range(tmp_path, kind, law, parameter, bad, allowed):
    """A law parameter outside its range names the key and the law's range (not "(-inf, inf)")."""
    values = {name: default for name, (default, _, _) in law.PARAMETERS.items()}
    values[parameter] = bad
    old = 'law = "coulomb"\nF0 = 0.5\n' if kind == "kinetic" else 'law = "constant"\nF0 = 1.0\n'
    text = VALID.replace(old, _law_section(law, values), 1)
    if kind == "kinetic":  # keep F_K(0+) <= F_S(0) out of the way
        text = text.replace('law = "constant"\nF0 = 1.0', 'law = "constant"\nF0 = 1e6', 1)
    with pytest.raises(ScenarioError) as info:
        load_scenario(_write(tmp_path, text))
    message = str(info.value)
    assert f"'{kind}.{parameter}'" in message and f"a finite number in {allowed}" in message, message


# ---------------------------------------------------------------------------
# errors that name their cause (issue 20, "Messages and misuse")
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("start, texts", [
    ({"kinetic.law": 2, "kinetic.gamma": 1e300}, ["kinetic.gamma = 1e+300 N s/m", "steepest slope"]),
    ({"kinetic.law": 3, "kinetic.v_stribeck": 1e-300}, ["kinetic.v_stribeck = 1e-300 m/s", "steepest slope"]),
], ids=["gamma-1e300", "v_stribeck-1e-300"])
def test_law_too_steep_names_its_parameter(session, start, texts):
    """Was: "state overflowed (x = nan)" at the first breakaway, and "step size underflow ... too stiff"."""
    with pytest.raises(FmuCallError) as error:
        session.instantiate(session.start_values(start))
    message = "\n".join(error.value.messages)
    assert error.value.function == "fmi2ExitInitializationMode"
    assert all(text in message for text in texts) and "allowed is at most" in message, message
    assert _runs_normally(session)


@pytest.mark.parametrize("start_time", [1e12, 1e15, -1e13])
def test_start_time_beyond_the_resolution_of_time_is_refused(session, start_time):
    """Was: "step size underflow" or "event chain" from 1e15 s, and x silently shifted by 1.5e-3 m from 1e12 s."""
    with pytest.raises(FmuCallError) as error:
        session.instantiate(session.start_values(STICK_SLIP), start_time=start_time)
    message = "\n".join(error.value.messages)
    assert f"start time = {start_time!r} s is out of range" in message, message
    assert "floats space times there by" in message and "allowed is |start time| <= 4.504e+07 s" in message
    assert _runs_normally(session)


def test_large_start_time_within_the_bound_runs_as_from_zero(session):
    """1e6 s is inside the bound (4.5e7 sqrt(M/kappa)): the run matches the one from 0 to 1e-9 m."""
    rows = []
    for start_time in (0.0, 1e6):
        inst = session.instantiate(session.start_values(dict(STICK_SLIP, v_start=0.1)), start_time=start_time)
        for _ in range(30):
            inst.do_step(1.0)
        rows.append(inst.read())
        inst.free()
    assert rows[1]["x"] == pytest.approx(rows[0]["x"], abs=1e-9) and rows[1]["n_events"] == rows[0]["n_events"]


@pytest.mark.parametrize("first, text", [
    (5.0, "currentCommunicationPoint = 5.0 s is not the FMU's time t = 0.0 s"),  # a first step after the start
    (math.nan, "currentCommunicationPoint = nan s is out of range"),
], ids=["first-step-late", "nan"])
def test_first_step_must_start_at_the_start_time(session, first, text):
    """Was: integrated from the start time through the gap (FMI 2), restarted at t (FMI 3)."""
    inst = session.instantiate(session.start_values(STICK_SLIP))
    try:
        with pytest.raises(FmuCallError) as error:
            inst.call(inst.fmu.doStep, first, 1.0)
        assert text in "\n".join(error.value.messages)
        inst.do_step(1.0)  # from the start time: the instance goes on
    finally:
        inst.free()


@pytest.mark.parametrize("offset, kind", [(0.5, "a gap of 0.5 s"), (-0.5, "an overlap of 0.5 s")])
def test_gaps_and_overlaps_between_communication_points_are_refused(session, offset, kind):
    inst = session.instantiate(session.start_values(STICK_SLIP))
    try:
        inst.do_step(1.0)
        with pytest.raises(FmuCallError) as error:
            inst.call(inst.fmu.doStep, 1.0 + offset, 1.0)
        message = "\n".join(error.value.messages)
        assert f"currentCommunicationPoint = {1.0 + offset!r} s is not the FMU's time t = 1.0 s" in message
        assert kind in message, message
        inst.do_step(1.0)
    finally:
        inst.free()


def test_fmi3_gaps_setting_outputs_and_going_back_before_a_stick_name_the_cause(fmu3_path):
    """FMI 3 (each in a child process): a gap after the first step, setting an output (was "'NoneType' object is
    not callable") or the independent time, and fmi3SetTime before the current stick began (was "math domain
    error" from F_S at a negative stick time)."""
    cases = [
        ("cs", {}, [["step", 0.0, 1.0], ["step", 1.5, 1.0]], "currentCommunicationPoint = 1.5 s is not the FMU's time"),
        ("cs", {}, [["set", "x", 1.0]], "x (valueReference="),
        ("cs", {}, [["set", "time", 1.0]], "time (valueReference="),
        ("me", {"v_start": 0.1, "static.law": 2}, [["update"], ["time", 1.0], ["time", -2.0]],
         "time = -2.0 s is before the current stick began at t = 0.0 s"),
    ]
    for interface, start, actions, text in cases:
        report = run_probe(fmu3_path, interface, start, actions)
        assert report["failed"] == actions[-1], report
        assert any(text in message for message in report["messages"]), (text, report["messages"])
    assert "is of causality output: only parameters and inputs can be set" in "".join(
        run_probe(fmu3_path, "cs", {}, [["set", "x", 1.0]])["messages"])
