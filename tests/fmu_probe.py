"""A child process that drives one FMU instance through FMPy and prints what happened as JSON (for tests whose
calls might crash or hang the host: tests/test_numeric_limits.py, tests/test_bad_input.py).

``python fmu_probe.py FMU INTERFACE START_JSON ACTIONS_JSON``: instantiate (interface "cs" or "me"), enter
initialization at the start time ``START_JSON["start_time"]`` (default 0), set the start values, leave
initialization, then run the actions in order, each ``[name, *arguments]``:

- ``["step", t_from, h]``: doStep from ``t_from`` by ``h`` s;
- ``["time", t]``: fmi2SetTime / fmi3SetTime (model exchange);
- ``["set", name, value]``: set a variable by name;
- ``["update"]``: fmi<N>EnterEventMode, fmi2NewDiscreteStates / fmi3UpdateDiscreteStates,
  fmi<N>EnterContinuousTimeMode;
- ``["forge", name, value]``: serialize the current FMU state, set its field ``name`` (a name of the runtime's
  ``BlockStateFormat.fields``, e.g. ``"trajectory.t"``) to ``value`` in its bytes (:func:`forged_state`), deserialize
  them and set the state (value ``"nan"``, ``"inf"``, ``"-inf"`` for those floats).

Prints one JSON object: ``{"ok": bool, "failed": the action that failed or null, "messages": [...], "outputs":
{name: value} after the last action (null if reading fails)}``; the first failing action stops the list.
"""

import json
import math
import struct
import subprocess
import sys

from stickslip.hosts.fmpy_host import ExtractedFMU, FmuCallError

SPECIAL = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}


def _setter(inst, name):
    """A function that sets the variable ``name`` of the instance ``inst`` to a value."""
    variable, fmi2 = inst.extracted.variables[name], inst.extracted.fmi_version == 2
    if variable.type in ("Integer", "Int32", "Enumeration"):  # FMI 3 sets an Enumeration as Int64
        integer = inst.fmu.setInteger if fmi2 else (inst.fmu.setInt64 if variable.type == "Enumeration" else inst.fmu.setInt32)
        return lambda value: inst.call(integer, [variable.valueReference], [int(value)])
    real = inst.fmu.setReal if fmi2 else inst.fmu.setFloat64
    return lambda value: inst.call(real, [variable.valueReference], [SPECIAL.get(value, value)])


def _initialize(inst, start):
    fmu, start_time = inst.fmu, start.pop("start_time", 0.0)
    if inst.extracted.fmi_version == 2:
        inst.call(fmu.setupExperiment, startTime=start_time)
        inst.call(fmu.enterInitializationMode)
    else:
        inst.call(fmu.enterInitializationMode, startTime=start_time)
    for name, value in start.items():
        _setter(inst, name)(value)
    inst.call(fmu.exitInitializationMode)


def _forge(inst, name, value):
    fmu, fmi = inst.fmu, inst.extracted.fmi_version
    state = inst.call(fmu.getFMUstate if fmi == 2 else fmu.getFMUState)
    data = bytes(inst.call(fmu.serializeFMUstate if fmi == 2 else fmu.serializeFMUState, state))
    forged = forged_state(data, fmi, name, SPECIAL.get(value, value) if isinstance(value, str) else value)
    restored = inst.call(fmu.deSerializeFMUstate if fmi == 2 else fmu.deserializeFMUState, forged)
    inst.call(fmu.setFMUstate if fmi == 2 else fmu.setFMUState, restored)


def forged_state(data, fmi_version, name, value):
    """The serialized state ``data`` of the block's FMU of FMI version ``fmi_version`` with its field ``name`` (a name
    of ``BlockStateFormat.fields``) set to ``value``: a real that may be None is marked as given, a list of reals
    gets ``value`` as its first."""
    from stickslip.fmu_src.block_interface import state_format

    layout = state_format("SpringBlockFriction", fmi_version, () if fmi_version == 2 else ("stepped",))
    offset, code = next((offset, code) for field, offset, code in layout.fields(data) if field == name and code != "H")
    edited = bytearray(data)
    struct.pack_into("<" + code[-1], edited, offset + len(code) - 1 if code == "Bd" else offset, value)
    if code == "Bd":
        edited[offset] = 1
    return bytes(edited)


def _act(inst, action):
    name, *arguments = action
    fmu = inst.fmu
    if name == "step":
        inst.call(fmu.doStep, SPECIAL.get(arguments[0], arguments[0]), SPECIAL.get(arguments[1], arguments[1]))
    elif name == "time":
        inst.call(fmu.setTime, arguments[0])
    elif name == "set":
        _setter(inst, arguments[0])(arguments[1])
    elif name == "update":
        inst.call(fmu.enterEventMode)
        inst.call(fmu.newDiscreteStates if inst.extracted.fmi_version == 2 else fmu.updateDiscreteStates)
        inst.call(fmu.enterContinuousTimeMode)
    elif name == "forge":
        _forge(inst, *arguments)


def _outputs(inst):
    names = [n for n, v in inst.extracted.variables.items()
             if v.causality == "output" and v.type in ("Real", "Float64")]
    read = inst.fmu.getReal if inst.extracted.fmi_version == 2 else inst.fmu.getFloat64
    values = inst.call(read, [inst.extracted.variables[n].valueReference for n in names])
    return {n: (v if math.isfinite(v) else repr(v)) for n, v in zip(names, values)}


def main(path, interface, start, actions):
    report = {"ok": True, "failed": None, "messages": [], "outputs": None}
    with ExtractedFMU(path) as fmu:
        inst = fmu.new_instance(interface=interface)
        try:
            _initialize(inst, dict(start))
            for action in actions:
                report["failed"] = action
                _act(inst, action)
            report["failed"] = None
        except FmuCallError as error:
            report["ok"], report["messages"] = False, list(error.messages)
        try:
            report["outputs"] = _outputs(inst)
        except FmuCallError as error:
            report["messages"] += list(error.messages)
    print(json.dumps(report))


def run_probe(fmu_path, interface, start, actions, timeout=120):
    """This script on ``fmu_path`` in a child process with a time limit of ``timeout`` s: its report (a crash
    or a hang fails the calling test, not the test session)."""
    done = subprocess.run([sys.executable, __file__, str(fmu_path), interface, json.dumps(start), json.dumps(actions)],
                          capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, f"the probe died with {done.returncode}: {done.stderr[-3000:]}"
    return json.loads(done.stdout.splitlines()[-1])


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], json.loads(sys.argv[3]), json.loads(sys.argv[4]))
