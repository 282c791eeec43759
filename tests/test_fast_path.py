"""The loader's fast path (src/stickslip/fmu/loader/fast_path.c): steps and output reads that bypass PythonFMU and
pythonfmu3 give exactly what the slave gives through them.

Each session runs in a child process twice, with the fast path on (the default) and off (``SBF_FAST_PATH=0``):
every value read, status and message must be equal bit for bit, and the counts of the slave's methods show which
path the steps took. The C hosts (a process without Python of its own) are compared the same way.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import machine_needs
from stickslip.hosts.c_host import run_host

RUNNER = Path(__file__).resolve().parent / "fast_path_runner.py"
OFF = {"SBF_FAST_PATH": "0"}


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
        assert all(messages and ("saved state" in messages[-1] or "force scale |F_ext|" in messages[-1])
                   for _, _, messages in record["forged"]), record["forged"]
