"""The inputs the loader keeps between steps (src/stickslip/fmu/loader/fast_path.c, sbf_keep_inputs): F_ext, its rate
and v_drive set before a step reach the slave with the step, in one call into Python, and the session is what the
slave gives when every set reaches it as it comes (``SBF_FAST_PATH=0``), bit for bit: the trajectory, the reads
between a set and its step, the refusals and their messages, an FMU state got between a set and its step.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import machine_needs
from stickslip.hosts.c_host import run_host

RUNNER = Path(__file__).resolve().parent / "kept_inputs_runner.py"
OFF = {"SBF_FAST_PATH": "0"}
CELLS = 172  # the runner's cells of the force wave (each F_ext and its rate set, then doStep)
H = 0.05  # s, the runner's communication step


def _session(fmu, env=None):
    machine_needs.c_compiler("the FMU's loader, which keeps the inputs")
    run = subprocess.run([sys.executable, str(RUNNER), str(fmu)], capture_output=True, text=True, timeout=300,
                         env={**os.environ, **(env or {})})
    assert run.returncode == 0, run.stderr[-3000:]
    record = json.loads(run.stdout)
    assert "failed" not in record, record
    return record


@pytest.fixture(scope="module", params=["fmi2", "fmi3"])
def sessions(request, fmu_path, fmu3_path):
    fmu = fmu_path if request.param == "fmi2" else fmu3_path
    return request.param, _session(fmu), _session(fmu, OFF)


def test_inputs_kept_until_the_step_give_the_slave_s_session_bit_for_bit(sessions):
    version, kept, forwarded = sessions
    for key in ("values", "cells", "statuses", "messages"):
        assert kept[key] == forwarded[key], key
    # every cell's sets reached the slave with its step; only the refused values went to the setters
    setters = {"fmi2": ("set_real", "set_real_input_derivatives"), "fmi3": ("set_float64",)}[version]
    assert kept["counts"]["step_kept"] == CELLS
    assert sum(kept["counts"][name] for name in setters) == 1 + 3  # the parameters before initialization, refusals
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

