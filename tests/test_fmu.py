"""The SpringBlockFriction FMU as an importer sees it (FMPy): model description, errors, state, stepping."""

import io
import math
import subprocess
import sys
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from stickslip.core import Parameters, StickSlipError, Trajectory, kinetic_law, static_law
from stickslip.fmu import default_fmu_path, ensure_fmu, source_tag
from stickslip.fmu import sources
from stickslip.fmu.sources import sources_tag
from stickslip.hosts.fmpy_host import FMUError, run_fmu

from fmu_instances import instantiate, instantiate3

STICK_SLIP = {"M": 1.0, "kappa": 1.0, "kinetic.F0": 0.5, "static.F0": 1.0}  # coulomb, stick time 10 s
STRIBECK = {"kinetic.law": 3, "kinetic.F0": 0.4, "kinetic.F_stribeck": 0.3, "kinetic.v_stribeck": 0.05,
            "kinetic.gamma": 0.0, "static.F0": 1.0, "M": 1.0, "kappa": 1.0}
SPEC_VARIABLES = {  # SPEC section 4: name -> (causality, type, unit)
    "M": ("parameter", "Real", "kg"), "kappa": ("parameter", "Real", "N/m"),
    "x_start": ("parameter", "Real", "m"), "v_start": ("parameter", "Real", "m/s"),
    "kinetic.law": ("parameter", "Integer", None), "static.law": ("parameter", "Integer", None),
    "kinetic.F0": ("parameter", "Real", "N"), "kinetic.gamma": ("parameter", "Real", "N.s/m"),
    "kinetic.F_stribeck": ("parameter", "Real", "N"), "kinetic.v_stribeck": ("parameter", "Real", "m/s"),
    "kinetic.delta": ("parameter", "Real", None), "kinetic.gamma1": ("parameter", "Real", "N.s/m"),
    "kinetic.gamma2": ("parameter", "Real", "N.s/m"), "kinetic.v_tilde": ("parameter", "Real", "m/s"),
    "kinetic.dv": ("parameter", "Real", "m/s"), "static.F0": ("parameter", "Real", "N"),
    "static.A": ("parameter", "Real", "N"), "static.tau": ("parameter", "Real", "s"),
    "static.F_inf": ("parameter", "Real", "N"), "static.n": ("parameter", "Real", None),
    "v_drive": ("input", "Real", "m/s"), "F_ext": ("input", "Real", "N"),
    "x": ("output", "Real", "m"), "v": ("output", "Real", "m/s"), "v_rel": ("output", "Real", "m/s"),
    "F_friction": ("output", "Real", "N"), "F_spring": ("output", "Real", "N"),
    "mode": ("output", "Integer", None), "t_stick": ("output", "Real", "s"),
    "z_slip": ("output", "Real", "N"), "z_stick": ("output", "Real", "m/s"),
    "n_events": ("output", "Integer", None),
}


# ---------------------------------------------------------------------------
# direct access through FMPy's FMU2Slave
# ---------------------------------------------------------------------------


def read(fmu, unzipped, names=("x", "v")):
    variables = unzipped[2]
    return fmu.getReal([variables[name].valueReference for name in names])


def step_through(fmu, unzipped, t_start, t_end, h):
    """doStep on the grid t_start + k h up to t_end; (x, v) after every step."""
    n = round((t_end - t_start) / h)
    rows = []
    for k in range(n):
        t = t_start + k * h
        fmu.doStep(t, t_start + (k + 1) * h - t)
        rows.append(read(fmu, unzipped))
    return rows


# ---------------------------------------------------------------------------
# model description
# ---------------------------------------------------------------------------


def test_fmpy_validate_reports_no_problems(fmu_path):
    assert validate_fmu(str(fmu_path)) == []


def test_spec_variables_with_units_and_declared_types(fmu_path):
    description = fmpy.read_model_description(str(fmu_path))
    variables = {v.name: v for v in description.modelVariables}
    units = {u.name: u for u in description.unitDefinitions}
    declared = {t.name: t for t in description.typeDefinitions}
    for name, (causality, kind, unit) in SPEC_VARIABLES.items():
        variable = variables[name]
        assert (variable.causality, variable.type, variable.unit) == (causality, kind, unit), name
        if unit is not None:
            assert declared[variable.declaredType.name].unit == unit, name
    for name in ("n_stick_events", "n_slip_events", "n_overshoots", "n_steps"):
        assert (variables[name].causality, variables[name].type) == ("output", "Integer")
    assert variables["t_last_event"].unit == "s"
    assert variables["solver.rtol"].start == "1e-10"
    newton = units["N"].baseUnit
    assert (newton.kg, newton.m, newton.s) == (1, 1, -2)
    damping = units["N.s/m"].baseUnit
    assert (damping.kg, damping.m, damping.s) == (1, 0, -1)
    assert variables["kinetic.F0"].min == "0.0" and variables["M"].min is None  # M > 0 is exclusive
    assert (variables["kinetic.law"].min, variables["kinetic.law"].max) == ("1", "5")


def test_capabilities_structure_and_default_experiment(fmu_path):
    description = fmpy.read_model_description(str(fmu_path))
    cs, me = description.coSimulation, description.modelExchange
    assert cs.modelIdentifier == me.modelIdentifier == "SpringBlockFriction"  # one binary, both interfaces
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate and me.canGetAndSetFMUstate and me.canSerializeFMUstate
    outputs = {v.name for v in description.modelVariables if v.causality == "output"}
    assert {u.variable.name for u in description.outputs} == outputs
    derivatives = [u.variable for u in description.derivatives]
    assert [(d.name, d.derivative.name) for d in derivatives] == [("der(x)", "x"), ("der(v)", "v")]
    assert description.numberOfEventIndicators == 3
    assert {u.variable.name for u in description.initialUnknowns} == outputs | {"der(x)", "der(v)"}
    experiment = description.defaultExperiment
    assert (experiment.startTime, experiment.stopTime, experiment.tolerance) == ("0.0", "100.0", "1e-10")


def test_runtime_is_bundled_under_a_private_name(fmu_path):
    tag, runtime_tag = source_tag(), sources.runtime_tag()
    with zipfile.ZipFile(fmu_path) as fmu:
        names = fmu.namelist()
        loader = fmu.read(f"resources/springblockfriction_{tag}.py").decode()
        with zipfile.ZipFile(io.BytesIO(fmu.read(f"resources/sbf_slave_{tag}.zip"))) as packed:
            slave_names = packed.namelist()
            slave = packed.read(f"sbf_slave_{tag}/fmu_slave.py").decode()
            interface = packed.read(f"sbf_slave_{tag}/block_interface.py").decode()
        assert fmu.read("resources/slavemodule.txt").decode() == f"springblockfriction_{tag}"
    assert f"resources/sbf_runtime_{runtime_tag}/sources.zip" in names  # its sources, packed
    assert not [name for name in names if "__pycache__" in name]  # no folder of byte code to extract
    assert not [name for name in names if name.startswith(f"resources/sbf_slave_{tag}/")]  # one file, no folder
    assert f"sbf_slave_{tag}/block_interface.pyc" in slave_names  # its byte code beside it, as zipimport reads it
    assert f"'sbf_slave_{tag}.zip'" in loader and f"from sbf_slave_{tag}.fmu_slave import SpringBlockFriction" in loader
    assert f"from sbf_runtime_{runtime_tag} import" in interface and "stickslip.core" not in interface + slave
    assert f"from sbf_slave_{tag}.block_interface import" in slave and "from block_interface" not in slave
    # in a fresh host process, which has imported stickslip: what an earlier test imported into this one (an FMU's
    # build drops the runtime it imported, not another FMU's slave) plays no part
    probe = (f"import sys, stickslip.core; from stickslip.hosts.fmpy_host import run_fmu; "
             f"run_fmu({str(fmu_path)!r}, {{}}, 1.0, 1.0); "
             f"[print(sys.modules[name].__file__) for name in "
             f"('sbf_runtime_{runtime_tag}', 'stickslip.core', 'sbf_slave_{tag}.fmu_slave')]")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    runtime, checkout, slave_module = done.stdout.split("\n")[-4:-1]
    assert Path(runtime).parent != Path(checkout).parent  # the FMU's copy, though this host imported stickslip
    assert f"sbf_slave_{tag}.zip" in slave_module  # from its archive


def test_default_fmu_path_is_stickslip_dist_else_the_checkout_s_dist_else_the_user_cache(monkeypatch, tmp_path,
                                                                                           session_dist):
    assert default_fmu_path().parent == session_dist  # the tests' own folder (conftest), not the main job's
    monkeypatch.delenv("STICKSLIP_DIST")
    monkeypatch.chdir(tmp_path)  # whatever the current folder
    checkout = Path(__file__).resolve().parents[1]
    assert default_fmu_path() == checkout / "dist" / "SpringBlockFriction.fmu"
    assert default_fmu_path(3) == checkout / "dist" / "SpringBlockFriction-fmi3.fmu"
    builder = sys.modules["stickslip.fmu.build"]  # the module (stickslip.fmu.build is its function build)
    monkeypatch.setattr(builder, "CHECKOUT", tmp_path / "site-packages")  # installed: no checkout around it
    monkeypatch.setattr(builder, "USER_CACHE", tmp_path / "cache")
    assert default_fmu_path(3) == tmp_path / "cache" / "fmus" / sources_tag() / "SpringBlockFriction-fmi3.fmu"
    monkeypatch.setenv("STICKSLIP_DIST", str(tmp_path))
    assert default_fmu_path(3) == tmp_path / "SpringBlockFriction-fmi3.fmu"


def test_ensure_fmu_builds_only_when_the_sources_changed(tmp_path, fmu_path):
    target = tmp_path / "SpringBlockFriction.fmu"
    assert ensure_fmu(target) == target and target.is_file()
    built = target.stat().st_mtime_ns
    assert ensure_fmu(target) == target and target.stat().st_mtime_ns == built
    with zipfile.ZipFile(target, "w") as stale:
        stale.writestr("resources/slavemodule.txt", "springblockfriction_0000000000")
    ensure_fmu(target)
    assert validate_fmu(str(target)) == []


# ---------------------------------------------------------------------------
# errors
# ---------------------------------------------------------------------------

INVALID = [  # start values, text the FMU's error must contain
    ({"M": -1.0}, "M = -1.0 kg"),
    ({"M": 0.0}, "M = 0.0 kg"),
    ({"M": math.nan}, "M = nan"),
    ({"kappa": 0.0}, "kappa = 0.0 N/m"),
    ({"kappa": math.inf}, "kappa = inf"),
    ({"x_start": math.nan}, "x_start = nan"),
    ({"v_start": -math.inf}, "v_start = -inf"),
    ({"kinetic.law": 7}, "kinetic.law = 7"),
    ({"static.law": 0}, "static.law = 0"),
    ({"kinetic.F0": -0.1}, "kinetic.F0 = -0.1"),
    ({"kinetic.F0": 1.5}, "F_K(0+) = 1.5 N exceeds static friction F_S(0) = 1.0 N"),
    ({"kinetic.law": 3, "kinetic.F0": 0.8, "kinetic.F_stribeck": 0.5}, "F_K(0+) = 1.3 N"),
    ({"kinetic.law": 3, "kinetic.v_stribeck": 0.0}, "kinetic.v_stribeck = 0.0"),
    ({"kinetic.law": 3, "kinetic.delta": 0.5}, "kinetic.delta = 0.5"),
    ({"kinetic.law": 4, "kinetic.dv": -0.05}, "kinetic.dv = -0.05"),
    ({"kinetic.law": 5, "kinetic.sigma": 1.0}, "kinetic.sigma = 1.0 is out of range: allowed is a finite value in "
                                               "[0, 1)"),
    ({"kinetic.law": 5, "kinetic.alpha": -0.5}, "kinetic.alpha = -0.5 s/m"),
    ({"kinetic.law": 5, "kinetic.F0": 2.0, "kinetic.sigma": 0.25}, "F_K(0+) = 1.5 N exceeds static friction"),
    ({"static.F0": 0.0}, "static.F0 = 0.0 N"),
    ({"static.law": 2, "static.tau": -1.0}, "static.tau = -1.0 s"),
    ({"static.law": 3, "static.F_inf": math.nan}, "static.F_inf = nan"),
    ({"static.law": 4, "static.n": 30.0}, "static.n = 30.0"),
    ({"solver.rtol": 0.0}, "solver.rtol = 0.0"),
    ({"v_drive": math.nan}, "v_drive = nan"),
    ({"F_ext": math.inf}, "F_ext = inf"),
]


@pytest.mark.parametrize("start, text", INVALID, ids=[text.split(" ")[0] for _, text in INVALID])
def test_invalid_parameter_gives_fmu_error_then_valid_run_works(fmu_path, start, text):
    with pytest.raises(FMUError) as error:
        run_fmu(fmu_path, start, 10.0, 1.0)
    assert isinstance(error.value, StickSlipError)
    assert text in str(error.value)
    assert "allowed" in str(error.value)
    result = run_fmu(fmu_path, STICK_SLIP, 10.0, 1.0)
    assert result["n_events"][-1] == 1 and result["mode"][-1] == 0


def test_nan_input_during_the_run_names_the_input(fmu_path):
    signal = np.array([(0.0, 0.1, 0.0), (2.0, 0.1, 0.0), (2.0, math.nan, 0.0), (5.0, math.nan, 0.0)],
                      dtype=[("time", float), ("v_drive", float), ("F_ext", float)])
    with pytest.raises(FMUError, match="v_drive = nan"):
        run_fmu(fmu_path, STICK_SLIP, 5.0, 0.5, input_signal=signal)


def test_fixed_parameter_cannot_change_after_initialization(unzipped):
    fmu = instantiate(unzipped, "fixed", STICK_SLIP)
    with pytest.raises(fmpy.fmi1.FMICallException):  # an error: the instance is not used again
        fmu.setReal([unzipped[2]["M"].valueReference], [2.0])


# ---------------------------------------------------------------------------
# results
# ---------------------------------------------------------------------------


def test_fmu_matches_the_python_trajectory_bit_for_bit(fmu_path):
    result = run_fmu(fmu_path, STRIBECK, 30.0, 0.5, outputs=["x", "v", "mode", "n_events"])
    kinetic = kinetic_law(3, F0=0.4, F_stribeck=0.3, v_stribeck=0.05, gamma=0.0, delta=1.0)
    traj = Trajectory(Parameters(1.0, 1.0, kinetic, static_law(1, F0=1.0)), 0.0, 0.0, v_drive=0.1)
    for row in result:
        traj.advance_to(row["time"])
        assert (row["x"], row["v"], row["mode"], row["n_events"]) == (traj.x, traj.v, traj.mode, traj.n_events)


@pytest.mark.parametrize("start", [STICK_SLIP, STRIBECK], ids=["coulomb", "stribeck"])
def test_communication_step_does_not_change_the_results(fmu_path, start):
    fine = run_fmu(fmu_path, start, 100.0, 1e-3, outputs=["x", "v", "n_events"])
    coarse = run_fmu(fmu_path, start, 100.0, 10.0, outputs=["x", "v", "n_events"])
    fine = fine[np.isclose(np.mod(fine["time"] + 5.0, 10.0), 5.0)]  # t = 0, 10, ..., 100
    np.testing.assert_array_equal(np.round(fine["time"], 9), coarse["time"])
    # measured: equal bit for bit (the internal steps do not depend on the communication points); |x|, |v| < 1,
    # so 1e-14 is about 50 ulps
    np.testing.assert_allclose(fine["x"], coarse["x"], rtol=0, atol=1e-14)
    np.testing.assert_allclose(fine["v"], coarse["v"], rtol=0, atol=1e-14)
    assert coarse["n_events"][-1] >= 10  # many stick-slip cycles were crossed


def test_input_steps_are_applied_at_the_same_time_for_any_step(fmu_path):
    signal = np.array([(0.0, 0.1, 0.0), (30.0, 0.1, 0.0), (30.0, 0.3, 0.2), (60.0, 0.3, 0.2)],
                      dtype=[("time", float), ("v_drive", float), ("F_ext", float)])
    runs = [run_fmu(fmu_path, STICK_SLIP, 60.0, h, input_signal=signal, outputs=["x", "v"]) for h in (1e-2, 10.0)]
    fine, coarse = runs[0][::1000], runs[1]
    # measured: 5.6e-15 m and 7.8e-16 m/s
    np.testing.assert_allclose(fine["x"], coarse["x"], rtol=0, atol=2e-13)
    np.testing.assert_allclose(fine["v"], coarse["v"], rtol=0, atol=3e-14)


def test_stuck_block_follows_a_new_drive_velocity_before_the_next_step(unzipped):
    fmu = instantiate(unzipped, "feedthrough", dict(STICK_SLIP, v_start=0.1))
    variables = unzipped[2]
    assert fmu.getInteger([variables["mode"].valueReference]) == [0]
    fmu.setReal([variables["v_drive"].valueReference], [0.25])
    assert read(fmu, unzipped, ("v", "v_rel")) == [0.25, 0.0]
    fmu.terminate()
    fmu.freeInstance()


# ---------------------------------------------------------------------------
# FMU state and instances
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("fmi, t_save, start", [(2, 18.0, STRIBECK), (2, 11.5, STICK_SLIP), (3, 18.0, STICK_SLIP),
                                                 (3, 11.5, STRIBECK)],
                         ids=["fmi2-stick-stribeck", "fmi2-slip-coulomb", "fmi3-stick-coulomb", "fmi3-slip-stribeck"])
def test_restored_state_is_the_saved_one(unzipped, unzipped3, fmi, t_save, start):
    """A state saved mid stick or mid slip, with inputs set and (FMI 2) a force rate set that the next step has yet to
    take: restored into its instance (twice), deserialized there and by an instance of other parameters (whose bytes
    of it are the same), each continues with every output bit for bit as the original did, through events and an
    input changed after it."""
    extracted = unzipped if fmi == 2 else unzipped3
    variables = extracted[2]
    outputs = [v for v in variables.values() if v.causality == "output"]
    mode = outputs.index(variables["mode"])

    def run(fmu, steps=60, h=0.25):  # from t_save, F_ext set again halfway; every output after each step
        api, rows = _StateApi(fmu, fmi), []
        for k in range(steps):
            if k == steps // 2:
                api.set_real([variables["F_ext"].valueReference], [-0.03])
            fmu.doStep(t_save + k * h, h)
            rows.append([api.get[v.type]([v.valueReference])[0] for v in outputs])
        return rows

    made = instantiate if fmi == 2 else instantiate3
    fmu, other = made(extracted, "saved", start), made(extracted, "other", {})  # other: default parameters
    saved_api, other_api = _StateApi(fmu, fmi), _StateApi(other, fmi)
    for k in range(round(t_save / 0.25)):
        fmu.doStep(k * 0.25, 0.25)
    assert (saved_api.get["integer"]([variables["mode"].valueReference])[0] == 0) == (t_save == 18.0)
    saved_api.set_real([variables["v_drive"].valueReference, variables["F_ext"].valueReference], [0.12, 0.05])
    if fmi == 2:
        fmu.setRealInputDerivatives([variables["F_ext"].valueReference], [1], [0.002])
    state = fmu.getFMUState()
    serialized = saved_api.serialize(state)
    original = run(fmu)
    assert len({row[mode] for row in original}) >= 2  # an event in the continuation
    for restored in (state, state, saved_api.deserialize(serialized)):
        fmu.setFMUState(restored)
        assert run(fmu) == original
    deserialized = other_api.deserialize(serialized)
    assert serialized.startswith(b"SBFstate") and other_api.serialize(deserialized) == serialized
    other.setFMUState(deserialized)
    assert run(other) == original
    for instance in (fmu, other):
        instance.terminate()
        instance.freeInstance()


@pytest.mark.parametrize("fmi", [2, 3])
def test_a_state_set_again_after_steps_is_the_saved_one(unzipped, unzipped3, fmi):
    """A state got between steps and set after more steps and reads only (the loader then rewinds the trajectory
    alone), set after an input was set, and set after another state was got and set: each time every output of the
    steps after it bit for bit as after the save (mid slip of a Stribeck law, its steps integrated)."""
    extracted = unzipped if fmi == 2 else unzipped3
    variables = extracted[2]
    outputs = [v for v in variables.values() if v.causality == "output"]
    fmu = (instantiate if fmi == 2 else instantiate3)(extracted, "rewind", STRIBECK)
    api = _StateApi(fmu, fmi)

    def run(t0, steps=12, h=0.25):
        rows = []
        for k in range(steps):
            fmu.doStep(t0 + k * h, h)
            rows.append([api.get[v.type]([v.valueReference])[0] for v in outputs])
        return rows

    run(0.0, steps=46)
    state = fmu.getFMUState()  # at 11.5 s, only steps before it since the start
    original = run(11.5)
    fmu.setFMUState(state)
    assert run(11.5) == original
    api.set_real([variables["F_ext"].valueReference], [0.05])
    fmu.setFMUState(state)
    assert run(11.5) == original
    other = fmu.getFMUState()  # at 14.5 s
    fmu.setFMUState(state)
    fmu.setFMUState(other)
    fmu.setFMUState(state)
    assert run(11.5) == original
    for held in (state, other):
        fmu.freeFMUState(held)
    fmu.terminate()
    fmu.freeInstance()


class _StateApi:
    """FMPy's calls of an FMI 2 or FMI 3 instance under one set of names: getters by variable type (and "integer"),
    set_real, serialize, deserialize."""

    def __init__(self, fmu, fmi):
        if fmi == 2:
            self.get = {"Real": fmu.getReal, "Integer": fmu.getInteger, "integer": fmu.getInteger}
            self.set_real, self.serialize = fmu.setReal, fmu.serializeFMUstate
            self.deserialize = fmu.deSerializeFMUstate
        else:
            self.get = {"Float64": fmu.getFloat64, "Int32": fmu.getInt32, "integer": fmu.getInt32}
            self.set_real, self.serialize = fmu.setFloat64, fmu.serializeFMUState
            self.deserialize = fmu.deserializeFMUState


def test_two_instances_in_one_process_stay_independent(unzipped):
    alone = {}
    for name, start in (("a", STICK_SLIP), ("b", dict(STRIBECK, M=4.0, v_start=-0.2))):
        fmu = instantiate(unzipped, name, start)
        alone[name] = step_through(fmu, unzipped, 0.0, 30.0, 0.5)
        fmu.terminate()
        fmu.freeInstance()

    a = instantiate(unzipped, "a", STICK_SLIP)
    b = instantiate(unzipped, "b", dict(STRIBECK, M=4.0, v_start=-0.2))
    together = {"a": [], "b": []}
    for k in range(60):
        for name, fmu in (("a", a), ("b", b)):
            fmu.doStep(k * 0.5, (k + 1) * 0.5 - k * 0.5)
            together[name].append(read(fmu, unzipped))
    assert together == alone
    assert alone["a"] != alone["b"]
    for fmu in (a, b):
        fmu.terminate()
        fmu.freeInstance()
