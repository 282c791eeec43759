"""Child process of ``tests/test_fast_path.py``: FMU states serialized and deserialized through FMPy, printed as one
JSON object, to compare the loader's own packing and unpacking (``src/stickslip/fmu/loader/state_bytes.c``) with the
slave's (``SBF_FAST_PATH=0`` in the environment).

Run as ``python state_bytes_runner.py FMU_PATH...``. For each FMU, one instance of ``stribeck-aging``
(``fast_path_runner.SCENES``): a state got during initialization, then states got every 20 steps of 0.05 s, one
with an input set that the next step has yet to take (and, FMI 2, a force rate); printed: each state's bytes, the
bytes of each deserialized and serialized again, every output read over 10 steps after setting a deserialized
state, and, after a good state was deserialized, the status and messages of deserializing it with one field
forged (``fmu_probe.forged_state``: out of its kind, or out of range together with the others, the block's inputs
among them) and, after those, the messages of setting each input of :data:`SET_BEYOND` to 1e200. Apart
(``python_calls``): how many calls of the slave's serializers (counted by wrapping them on its class before the
instance is made) serializing a state took whose parts the state got just before holds, and deserializing bytes
deserialized just before, after an input was set between steps: none where the loader packs and unpacks them.
"""

import functools
import json
import sys

from fast_path_runner import SCENES
from fmu_probe import forged_state
from stickslip.hosts.fmpy_host import ExtractedFMU, FmuCallError

H = 0.05  # s
FORGED = [("trajectory.t", "nan"), ("trajectory.t", 1e9), ("head.time", "inf"), ("inputs.v_drive", "-inf"),
          ("trajectory.counts.n_stick_events", -1), ("trajectory.stepper.h", -0.5), ("trajectory.rtol", 0.5),
          ("trajectory.F_ext", 1e200), ("inputs.F_ext", 1e200), ("inputs.v_drive", 1e200),
          ("inputs.der(F_ext)", 1e200)]
SET_BEYOND = ("F_ext", "v_drive")  # inputs set beyond their force scale, for the sets' refusals
SPECIAL = {"nan": float("nan"), "inf": float("inf"), "-inf": float("-inf")}


def counted_serializers(extracted):
    """The calls of the slave's serializers so far, ``{name: count}``, counted from now on: each wrapped on the
    slave's class, which a first instance imports (the instances made after it bind the wrappers)."""
    extracted.new_instance().free()
    classes = {value for module in list(sys.modules.values()) for value in vars(module).values()
               if isinstance(value, type) and hasattr(value, "state_plan")}
    counts = {}
    for cls in classes:
        for name in ("_fmu_state_to_bytes", "state_from_bytes", "_fmu_state_from_bytes"):
            counts[name] = 0
            setattr(cls, name, staticmethod(functools.partial(_counted, counts, name, getattr(cls, name))))
    return counts


def _counted(counts, name, call, *args):
    counts[name] += 1
    return call(*args)


def session(path):
    with ExtractedFMU(path) as extracted:
        counts = counted_serializers(extracted)
        inst = extracted.new_instance()
        fmu, v2 = inst.fmu, extracted.fmi_version == 2
        refs = {name: v.valueReference for name, v in extracted.variables.items()}
        outputs = [v.valueReference for v in extracted.variables.values()
                   if v.causality == "output" and v.type in ("Real", "Float64")]
        get, free = (fmu.getFMUstate, fmu.freeFMUstate) if v2 else (fmu.getFMUState, fmu.freeFMUState)
        to_bytes = fmu.serializeFMUstate if v2 else fmu.serializeFMUState
        from_bytes = fmu.deSerializeFMUstate if v2 else fmu.deserializeFMUState
        set_real, get_real = (fmu.setReal, fmu.getReal) if v2 else (fmu.setFloat64, fmu.getFloat64)

        def serialized():
            state = get()
            data = bytes(to_bytes(state))
            free(state)
            return data

        for name, value in SCENES["stribeck-aging"].items():
            (fmu.setInteger if v2 else fmu.setInt64)([refs[name]], [value]) if isinstance(value, int) else \
                set_real([refs[name]], [value])
        if v2:
            fmu.setupExperiment(startTime=0.0)
            fmu.enterInitializationMode()
        else:
            fmu.enterInitializationMode(startTime=0.0)
        record = {"bytes": [serialized()], "times": [0.0]}
        fmu.exitInitializationMode()
        for k in range(120):
            if k == 40:
                set_real([refs["F_ext"]], [0.05])
                if v2:
                    fmu.setRealInputDerivatives([refs["F_ext"]], [1], [0.01])
            if k % 20 == 0 or k == 40:
                record["bytes"].append(serialized())
                record["times"].append(k * H)
            if k == 60:
                record["python_calls"] = python_calls(get, free, to_bytes, from_bytes, counts)
            fmu.doStep(k * H, H)
        record["again"] = []
        for data in record["bytes"]:
            state = from_bytes(data)
            record["again"].append(bytes(to_bytes(state)).hex())
            free(state)
        state = from_bytes(record["bytes"][4])
        fmu.setFMUState(state) if not v2 else fmu.setFMUstate(state)
        free(state)
        record["outputs"] = []
        for k in range(10):
            fmu.doStep(record["times"][4] + k * H, H)
            record["outputs"].append([x.hex() for x in get_real(outputs)])
        record["forged"] = []
        for name, value in FORGED:
            free(from_bytes(record["bytes"][5]))  # the good state first: its parts are the ones seen last
            try:
                state = inst.call(from_bytes, forged_state(record["bytes"][5], extracted.fmi_version, name,
                                                           SPECIAL.get(value, value)))
                record["forged"].append([name, "accepted"])
                free(state)
            except FmuCallError as error:
                record["forged"].append([name, error.status, list(error.messages)])
        record["set_refusals"] = {}
        for name in SET_BEYOND:
            try:
                inst.call(set_real, [refs[name]], [1e200])
            except FmuCallError as error:
                record["set_refusals"][name] = list(error.messages)
        record["bytes"] = [data.hex() for data in record["bytes"]]
        record["python_calls"]["total"] = sum(counts.values())
        inst.free()
        return record


def python_calls(get, free, to_bytes, from_bytes, counts):
    """The serializers' calls of serializing the second of two states got one after the other, and of
    deserializing bytes a second time."""
    first, second = get(), get()
    to_bytes(first)
    before = sum(counts.values())
    data = bytes(to_bytes(second))
    serializing = sum(counts.values()) - before
    free(from_bytes(data))
    before = sum(counts.values())
    free(from_bytes(data))
    for state in (first, second):
        free(state)
    return {"serializing": serializing, "deserializing": sum(counts.values()) - before}


if __name__ == "__main__":
    print(json.dumps({path: session(path) for path in sys.argv[1:]}))
