"""The loader's fast path (src/stickslip/fmu/loader/fast_path.c): steps and output reads that bypass PythonFMU and
pythonfmu3, and the inputs it keeps between steps (sbf_keep_inputs: F_ext, its rate and v_drive set before a step
reach the slave with the step, in one call into Python), give exactly what the slave gives through them.

Each session runs in a child process twice, with the fast path on (the default) and off (``SBF_FAST_PATH=0``):
every value read, status and message must be equal bit for bit (the trajectory, the reads between a set and its
step, the refusals and their messages, an FMU state got between a set and its step), and the counts of the slave's
methods show which path the steps took. The C hosts (a process without Python of its own) are compared the same way.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import machine_needs
from fmu_probe import forged_state
from stickslip.hosts.c_host import run_host
from stickslip.hosts.fmpy_host import ExtractedFMU, FmuCallError

RUNNER = Path(__file__).resolve().parent / "fast_path_runner.py"
OFF = {"SBF_FAST_PATH": "0"}
CELLS = 172  # the force-wave session's cells (each F_ext and its rate set, then doStep)
H = 0.05  # s, the runner's communication step


def _session(fmu, scene, env=None):
    machine_needs.c_compiler("the FMU's loader, whose fast path this tests")
    run = subprocess.run([sys.executable, str(RUNNER), str(fmu), scene], capture_output=True, text=True,
                         timeout=300, env={**os.environ, **(env or {})})
    assert run.returncode == 0, run.stderr[-3000:]
    record = json.loads(run.stdout)
    assert "failed" not in record, record
    return record


@pytest.fixture(scope="module", params=["fmi2", "fmi3"])
def fmu(request, fmu_path, fmu3_path):
    return fmu_path if request.param == "fmi2" else fmu3_path


@pytest.mark.parametrize("scene", ["stribeck-aging", "coulomb"])
def test_the_fast_path_gives_what_the_slave_gives_bit_for_bit(fmu, scene):
    fast, slow = _session(fmu, scene), _session(fmu, scene, OFF)
    assert len(fast["values"]) == 1 + 200 + 100 + 50 + 50 + 1 + 1 + 20 + 50
    assert fast["values"] == slow["values"]  # every output after every step, both types, exact
    assert fast["statuses"] == slow["statuses"]
    assert fast["messages"] == slow["messages"]


def test_every_step_takes_the_fast_path_and_the_slave_is_asked_only_after_changes(fmu):
    fast, slow = _session(fmu, "coulomb"), _session(fmu, "coulomb", OFF)
    steps = len(fast["statuses"])
    assert slow["counts"] == {"do_step": steps, "fast_step_call": 0}
    # the slave's do_step is never reached; a new step call after initialization, the input change and the reset
    # (saving a state, restoring one in place with no input pending, the refused step and the read of a parameter
    # keep it)
    assert fast["counts"] == {"do_step": 0, "fast_step_call": 3}


def test_a_refused_step_on_the_fast_path_names_the_gap_and_the_run_goes_on(fmu):
    fast = _session(fmu, "coulomb")
    refused = [s for s in fast["statuses"] if s != "OK"]
    assert len(refused) == 1 and refused[0].endswith(" 3")  # fmi2Error / fmi3Error, once
    assert len(fast["messages"]) == 1
    assert fast["messages"][0].startswith('[doStep] ParameterError("currentCommunicationPoint = ')
    assert "a gap of 1 s between communication points" in fast["messages"][0]


@pytest.mark.parametrize("fmi_version", [2, 3])
def test_c_hosts_get_the_same_run_with_and_without_the_fast_path(fmi_version, host, host3, unzipped, unzipped3):
    c_host, folder = (host, unzipped[0]) if fmi_version == 2 else (host3, unzipped3[0])
    start = {"kinetic.law": 3, "static.law": 2, "v_drive": 0.1, "F_ext": 0.2}
    fast = run_host(c_host, folder, "run", 60.0, 0.1, start)
    slow = run_host(c_host, folder, "run", 60.0, 0.1, start, env=OFF)
    assert fast.completed and slow.completed, (fast.stderr[-2000:], slow.stderr[-2000:])
    assert len(fast.series("x")[0]) == 601
    assert fast.series("x") == slow.series("x")


def test_the_loader_packs_and_unpacks_fmu_states_as_the_slave_does(fmu_path, fmu3_path):
    """The loader's own packing and unpacking of FMU states (state_bytes.c) against the slave's (the fast path off):
    the same bytes of each state (during initialization, stuck, slipping, an input and a force rate pending), the
    same bytes again after deserializing them, every output bit for bit after setting a deserialized state, and a
    state with one field forged (out of its kind, or out of range with the others) refused with the same reason
    after a good state was deserialized (whose parts the loader then holds); and the loader, not the slave's
    serializers, packs and unpacks states whose parts it saw last, after an input was set between steps too."""
    machine_needs.c_compiler("the FMU's loader, whose states' bytes this tests")

    def run(env=None):
        done = subprocess.run([sys.executable, str(RUNNER.with_name("state_bytes_runner.py")), str(fmu_path),
                               str(fmu3_path)], capture_output=True, text=True, timeout=300,
                              env={**os.environ, **(env or {})})
        assert done.returncode == 0, done.stderr[-3000:]
        return json.loads(done.stdout)

    fast, slow = run(), run(OFF)
    calls = {path: (fast[path].pop("python_calls"), slow[path].pop("python_calls")) for path in fast}
    assert fast == slow
    for on, off in calls.values():  # the loader's packing and unpacking took them, and keeps doing so
        assert (on["serializing"], on["deserializing"]) == (0, 0)
        assert off["serializing"] > 0 and off["deserializing"] > 0
        assert 0 < on["total"] < off["total"]
    for record in fast.values():
        assert len(set(record["bytes"])) == len(record["bytes"]) == 7
        assert record["again"] == record["bytes"]
        assert [status for _, status, *_ in record["forged"]] == [3] * len(record["forged"])  # fmi2Error, fmi3Error
        assert all(messages and ("saved state" in messages[-1] or "force scale |F_ext|" in messages[-1]
                                 or name.startswith("inputs.")) for name, _, messages in record["forged"]), record
        # the block's inputs out of the range their sets allow: refused with the words of those sets' refusals
        refused = {name: messages[-1] for name, _, messages in record["forged"]}
        for name, beyond in (("F_ext", "|F_ext| = 1e+200 N (F_ext = 1e+200 N) is out of range: allowed is at most "),
                             ("v_drive", "v_drive = 1e+200 m/s) is out of range: allowed is at most ")):
            assert beyond in refused[f"inputs.{name}"] and beyond in record["set_refusals"][name][-1], record
        assert "der(F_ext) = 1e+200 N/s) is out of range: allowed is at most " in refused["inputs.der(F_ext)"]


# ---- the inputs kept until the next step (scene force-wave) ----


@pytest.fixture(scope="module", params=["fmi2", "fmi3"])
def sessions(request, fmu_path, fmu3_path):
    """(FMI version, the force-wave session with the inputs kept, and with every set reaching the slave as it
    comes)"""
    fmu = fmu_path if request.param == "fmi2" else fmu3_path
    return request.param, _session(fmu, "force-wave"), _session(fmu, "force-wave", OFF)


def test_inputs_kept_until_the_step_give_the_slave_s_session_bit_for_bit(sessions):
    version, kept, forwarded = sessions
    for key in ("values", "cells", "statuses", "messages"):
        assert kept[key] == forwarded[key], key
    # every cell's sets reached the slave with its step; only the refused values went to the setters
    setters = {"fmi2": ("set_real", "set_real_input_derivatives"), "fmi3": ("set_float64",)}[version]
    assert kept["counts"]["step_kept"] == CELLS
    assert sum(kept["counts"][name] for name in setters) == 7 + 3  # the start values (one call each), the refusals
    assert forwarded["counts"]["step_kept"] == 0
    assert sum(forwarded["counts"][name] for name in setters) > CELLS  # each cell's sets, as they came


def test_a_stuck_block_holds_the_force_set_and_its_rate(sessions):
    """Closed form while stuck: the friction holds the spring against the force, F_friction = kappa x - F_ext, with
    F_ext at the cell's end the force set plus its rate times the step (kappa = 1)."""
    _, kept, _ = sessions
    stuck = [(force + rate * H, x, friction) for _, force, rate, x, friction, mode in kept["cells"] if mode == 0]
    assert 50 < len(stuck) < CELLS - 50  # it sticks and slips
    assert max(abs(friction - (x - force)) for force, x, friction in stuck) < 1e-14


def test_a_read_between_a_set_and_its_step_sees_the_value_set(sessions):
    version, kept, _ = sessions
    values = {label: [float.fromhex(v) for v in numbers] for label, numbers in kept["values"]}
    assert values["inputs between"] == ([0.25] if version == "fmi2" else [0.25, -0.5])
    # a refused set changes nothing (FMI 3: F_ext of the refused call neither): the last cell's force and rate hold
    last = next(cell for cell in kept["cells"] if cell[0] == "after beyond the force scale")
    assert values["inputs after the refused rate"] == (last[1:2] if version == "fmi2" else last[1:3])


def test_a_state_got_between_a_set_and_its_step_holds_the_value_set(sessions):
    _, kept, _ = sessions
    saved = [numbers for label, numbers in kept["values"] if label.startswith("saved ")]
    restored = [numbers for label, numbers in kept["values"] if label.startswith("restored ")]
    assert len(saved) == 21 and saved == restored


def test_a_value_the_slave_refuses_is_refused_at_its_set_with_its_message(sessions):
    version, kept, _ = sessions
    set_real = {"fmi2": "fmi2SetReal", "fmi3": "fmi3SetFloat64"}[version]
    rate_call = {"fmi2": "fmi2SetRealInputDerivatives", "fmi3": "fmi3SetFloat64"}[version]
    assert [s for s in kept["statuses"] if not s.endswith(" OK")] == [
        f"NaN {set_real} 3", f"beyond the force scale {set_real} 3", f"rate beyond {rate_call} 3"]
    nan, beyond, rate = kept["messages"]
    assert "F_ext = nan N is out of range: allowed is a finite value" in nan
    assert "|F_ext| = 2e+150 N" in beyond and "allowed is at most 1e+150 N" in beyond
    assert "der(F_ext" in rate and "allowed is" in rate


def test_a_c_host_that_sets_the_force_before_every_step_gets_the_slave_s_run(host, unzipped):
    folder = unzipped[0]
    start = {"kinetic.F0": 0.5, "static.F0": 0.6, "v_drive": 0.1, "v_start": 0.1}
    wave = {"HOST_WAVE": f"{unzipped[2]['F_ext'].valueReference} 0.5"}
    kept = run_host(host, folder, "wave", 30.0, 0.1, start, output="F_friction", env=wave)
    forwarded = run_host(host, folder, "wave", 30.0, 0.1, start, output="F_friction", env={**wave, **OFF})
    assert kept.completed and forwarded.completed, (kept.stderr[-2000:], forwarded.stderr[-2000:])
    assert len(kept.series("x")[0]) == 301
    assert kept.series("x") == forwarded.series("x")



def test_a_state_holding_a_forged_drive_is_refused_naming_it_and_a_kept_force_goes_on(fmu_path):
    """A state whose held ``v_drive`` (not pending) is finite but beyond its force scale, the trajectory's own in
    range (its bytes forged): deserializing it is refused naming v_drive, as setting that drive is, and the instance
    goes on with the force the loader keeps until its step."""
    machine_needs.c_compiler("the FMU's loader, whose kept inputs this tests")
    with ExtractedFMU(fmu_path) as extracted:
        inst = extracted.new_instance()
        fmu, ref = inst.fmu, {name: v.valueReference for name, v in extracted.variables.items()}
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        fmu.doStep(0.0, H)
        state = fmu.getFMUstate()
        forged = forged_state(bytes(fmu.serializeFMUstate(state)), 2, "inputs.v_drive", 1e200)
        fmu.freeFMUstate(state)
        with pytest.raises(FmuCallError) as refused:
            inst.call(fmu.deSerializeFMUstate, forged)
        assert any("v_drive = 1e+200 m/s" in message for message in refused.value.messages), refused.value.messages
        fmu.setReal([ref["F_ext"]], [0.3])
        inst.call(fmu.doStep, H, H)
        assert fmu.getReal([ref["F_ext"]]) == [0.3]  # the step took the force it kept, nothing refused
        inst.free()
