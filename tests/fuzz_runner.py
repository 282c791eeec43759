"""Child process of ``tests/test_fuzz_fmi.py``: runs fuzzed sequences of FMI calls on an extracted FMU's Linux
binary, through the ctypes bindings of ``fmi_call_runner.py`` (the standard's signatures).

Run as ``python fuzz_runner.py cycles {2|3} FOLDER``, it runs the load / instantiate / step / free / unload cycles of
one case read from stdin (:func:`run_cycles`) and prints their results as ``{"cycles": [...]}``.

Run as ``python fuzz_runner.py {2|3} FOLDER``; it reads one sequence per line on stdin, JSON
``{"id": n, "calls": [[operation, *arguments], ...]}`` (operations: :data:`OPERATIONS`), and prints
``{"start": n}`` before it and ``{"id": n, "calls": [...]}`` after it: every call made (label, function, result,
the log messages received during it as ``[status, category, message]``, and ``values``, what it wrote to the
host's buffers). A crash or a hang shows as a ``start`` without its result. Every sequence begins with an
instantiation and ends with fmi<N>FreeInstance of its instance, whatever its calls returned; after a failed
instantiation the rest of the sequence is skipped (there is no instance to call).
"""

import _ctypes
import ctypes
import json
import struct
import sys
import threading
from ctypes import byref, c_bool, c_char_p, c_double, c_size_t, c_void_p

from fmi_call_runner import Fmi2, Fmi2EventInfo, Fmi3

#: doubles past the count a call was given: a call that writes beyond it changes them
SENTINEL, SLACK = -12345.678, 4


class Sequence:
    """The FMU instance of one sequence, its saved FMU states (by slot) and serialized states (by slot)."""

    def __init__(self, binary):
        self.b, self.c = binary, None
        self.states, self.blobs = {}, {}

    def record(self, values):
        """Attach ``values`` (what the latest call wrote) to its record."""
        self.b.calls[-1]["values"] = values

    def call(self, name, *args, label=None):
        """The function ``name`` (FMI 3's spelling without its prefix) on the instance."""
        return self.b(self.b.fn(name), self.c, *args, label=label)


# ---- operations of both FMI versions ------------------------------------------------------------------------


def instantiate(s, variant="plain"):
    """A new instance; ``variant``: "plain", "logging" (loggingOn), "me-plain" (model exchange), "me-logging",
    "early" (FMI 3 co-simulation with earlyReturnAllowed), "events" (with eventModeUsed as well)."""
    interface = "ModelExchange" if variant.startswith("me") else "CoSimulation"
    if s.b.PREFIX == "fmi2":
        s.c = s.b.instantiate(logging_on=variant.endswith("logging"), interface=interface)
    else:
        s.c = s.b.instantiate(interface, logging_on=variant.endswith("logging"), event_mode_used=variant == "events",
                              early_return=variant in ("early", "events"))


def enter_initialization(s, tolerance_defined=False, tolerance=0.0, start=0.0, stop_defined=False, stop=0.0):
    """fmi2SetupExperiment + fmi2EnterInitializationMode (FMI 2), fmi3EnterInitializationMode (FMI 3)."""
    if s.b.PREFIX == "fmi2":
        s.call("SetupExperiment", tolerance_defined, tolerance, start, stop_defined, stop)
        s.call("EnterInitializationMode")
    else:
        s.call("EnterInitializationMode", tolerance_defined, tolerance, start, stop_defined, stop)


def setup_experiment(s, tolerance_defined=False, tolerance=0.0, start=0.0, stop_defined=False, stop=0.0):
    s.call("SetupExperiment", tolerance_defined, tolerance, start, stop_defined, stop)


def set_value(s, name, value):
    """fmi<N>Set<type> of one variable (any causality: setting an output or a local is an error)."""
    kind = s.b.kinds[name]
    s.b.access("Set", kind, s.c, [name], (s.b.TYPES[kind] * 1)(value))


def get_values(s, names):
    """fmi<N>Get<type> of ``names`` (one call per type, in the order of first appearance)."""
    for kind in dict.fromkeys(s.b.kinds[name] for name in names):
        chosen = [name for name in names if s.b.kinds[name] == kind]
        values = (s.b.TYPES[kind] * len(chosen))()
        s.b.access("Get", kind, s.c, chosen, values)
        s.record(dict(zip(chosen, values)))


def do_step(s, t, h):
    if s.b.PREFIX == "fmi2":
        s.call("DoStep", t, h, True)
        return
    flags, last = [c_bool() for _ in range(3)], c_double(SENTINEL)
    s.call("DoStep", t, h, True, *map(byref, flags), byref(last))
    s.record({"lastSuccessfulTime": last.value} if flags[2].value else {})


def get_state(s, slot):
    state = s.states.setdefault(slot, c_void_p())
    s.call("GetFMUState", byref(state))


def set_state(s, slot):
    s.call("SetFMUState", s.states.get(slot, c_void_p()))


def free_state(s, slot):
    s.call("FreeFMUState", byref(s.states.setdefault(slot, c_void_p())))


def serialize(s, slot, into):
    """Size and serialize the state ``slot`` into the byte slot ``into`` (a NULL state if there is none)."""
    state, size = s.states.get(slot, c_void_p()), c_size_t()
    if s.call("SerializedFMUStateSize", state, byref(size)) > 1:
        return
    data = ctypes.create_string_buffer(size.value)
    if s.call("SerializeFMUState", state, data, size.value) <= 1:
        s.blobs[into] = data.raw


def deserialize(s, source, edit, slot):
    """Deserialize the bytes of ``source`` (a byte slot, empty if unset) after ``edit`` into the state ``slot``.

    ``edit``: ["none"], ["truncate", n], ["flip", index, mask], ["overwrite", index, value] (an 8-byte float
    written at ``index`` modulo the room for it: a field of the state forged), ["raw", latin-1 text] (those bytes
    instead)."""
    data = edited(s.blobs.get(source, b""), edit)
    state = s.states.setdefault(slot, c_void_p())
    s.call("DeserializeFMUState", data, len(data), byref(state))


def edited(data, edit):
    kind, *args = edit
    if kind == "truncate":
        return data[:args[0]]
    if kind == "flip" and data:
        index = args[0] % len(data)
        return data[:index] + bytes([data[index] ^ args[1]]) + data[index + 1:]
    if kind == "overwrite" and len(data) >= 8:
        index = args[0] % (len(data) - 7)
        return data[:index] + struct.pack("<d", args[1]) + data[index + 8:]
    if kind == "raw":
        return args[0].encode("latin-1")
    return data


def set_input_derivatives(s, names, orders, values):
    """fmi2SetRealInputDerivatives of ``names`` (any variables) at ``orders``."""
    s.call("SetRealInputDerivatives", s.b.vrs(*names), len(names), (ctypes.c_int * len(names))(*orders),
           (c_double * len(names))(*values))


def get_output_derivatives(s, names, orders):
    """fmi2GetRealOutputDerivatives or fmi3GetOutputDerivatives of ``names`` (any variables) at ``orders``; the values
    written and past them."""
    buffer = (c_double * (len(names) + SLACK))(*[SENTINEL] * (len(names) + SLACK))
    references, order_array = s.b.vrs(*names), (ctypes.c_int * len(names))(*orders)
    if s.b.PREFIX == "fmi2":
        s.call("GetRealOutputDerivatives", references, len(names), order_array, buffer)
    else:
        s.call("GetOutputDerivatives", references, len(names), order_array, buffer, len(names))
    s.record({"values": list(buffer[:len(names)]), "past the end": [v for v in buffer[len(names):] if v != SENTINEL]})


def set_debug_logging(s, on, categories):
    names = (c_char_p * len(categories))(*(name.encode() for name in categories)) if categories else None
    s.call("SetDebugLogging", on, len(categories), names)


def plain(name):
    """An operation that is the call ``name`` on the instance and nothing else."""
    return lambda s: s.call(name)


# ---- model exchange (FMI 2 and 3) and event mode (FMI 3) --------------------------------------------------------


def reals_out(s, name, n):
    """A call writing ``n`` doubles (``name``: GetContinuousStates, ...); the values and any write past them."""
    buffer = (c_double * (n + SLACK))(*[SENTINEL] * (n + SLACK))
    s.call(name, buffer, n)
    s.record({"values": list(buffer[:n]), "past the end": [v for v in buffer[n:] if v != SENTINEL]})


def set_states(s, values):
    s.call("SetContinuousStates", (c_double * max(len(values), 1))(*values), len(values))


def set_time(s, t):
    s.call("SetTime", t)


def counts(s):
    for name in ("GetNumberOfContinuousStates", "GetNumberOfEventIndicators"):
        n = c_size_t(12345)
        s.call(name, byref(n))
        s.record({"n": n.value})


def update(s):
    """fmi3UpdateDiscreteStates, fmi2NewDiscreteStates; the next event time if it says one is defined."""
    if s.b.PREFIX == "fmi2":
        info = Fmi2EventInfo(0, 0, 0, 0, 0, SENTINEL)
        s.call("UpdateDiscreteStates", byref(info))
        s.record({"nextEventTime": info.nextEventTime} if info.nextEventTimeDefined else {})
        return
    flags, next_time = [c_bool() for _ in range(5)], c_double(SENTINEL)
    s.call("UpdateDiscreteStates", *map(byref, flags), byref(next_time))
    s.record({"nextEventTime": next_time.value} if flags[4].value else {})


def completed(s, no_prior):
    flags = [ctypes.c_int(), ctypes.c_int()] if s.b.PREFIX == "fmi2" else [c_bool(), c_bool()]
    s.call("CompletedIntegratorStep", no_prior, *map(byref, flags))


OPERATIONS = {
    "enter_initialization": enter_initialization, "setup_experiment": setup_experiment,
    "exit_initialization": plain("ExitInitializationMode"), "set": set_value, "get": get_values, "step": do_step,
    "get_state": get_state, "set_state": set_state, "free_state": free_state, "serialize": serialize,
    "deserialize": deserialize, "reset": plain("Reset"), "terminate": plain("Terminate"),
    "debug_logging": set_debug_logging,
    # FMI 2
    "set_input_derivatives": set_input_derivatives, "get_output_derivatives": get_output_derivatives,
    # model exchange (counts: FMI 3 only)
    "set_time": set_time, "set_states": set_states, "counts": counts, "update": update, "completed": completed,
    "enter_event_mode": plain("EnterEventMode"), "enter_continuous_time_mode": plain("EnterContinuousTimeMode"),
    "enter_step_mode": plain("EnterStepMode"),
    **{f"read {name}": (lambda s, n, name=name: reals_out(s, name, n)) for name in (
        "GetContinuousStates", "GetContinuousStateDerivatives", "GetEventIndicators",
        "GetNominalsOfContinuousStates")},
}


def run_sequence(binary, calls, trace=False):
    """The calls of one sequence on a new instance, which is freed at the end; returns the records. ``trace``:
    print each operation before it is made."""
    binary.calls, s = [], Sequence(binary)
    first, *rest = calls
    instantiate(s, *first[1:])
    if s.c is None:
        return binary.calls
    for operation, *args in rest:
        if trace:
            print(json.dumps({"operation": [operation, *args]}), flush=True)
        OPERATIONS[operation](s, *args)
    if trace:
        print(json.dumps({"operation": "free"}), flush=True)
    for state in s.states.values():
        s.call("FreeFMUState", byref(state), label="FreeFMUState at the end")
    binary(binary.fn("FreeInstance"), s.c)
    return binary.calls


# ---- load / instantiate / step on threads / free / unload / reload ------------------------------------------


def run_cycles(version, folder, case):
    """The cycles of ``case`` (``{"values": start values, "output": a Real output, "cycles": [...]}``), each
    ``{"instances": n, "steps": k, "threads": bool, "free": order, "unload": bool}``: load the binary (again, if the
    last cycle unloaded it), make and initialize n instances, step each k times by 0.1 s (each on its own thread, all
    at once, if "threads"), read the output, free the instances in the order "free" (indices) and unload the binary
    if "unload". Returns per cycle the output of each instance and the calls that did not return OK."""
    binary, results = None, []
    for cycle in case["cycles"]:
        binary = binary or (Fmi2(folder) if version == "2" else Fmi3(folder))
        binary.calls = []
        instances = [binary.initialized(case["values"]) for _ in range(cycle["instances"])]
        steppers = [threading.Thread(target=_steps, args=(binary, c, cycle["steps"])) for c in instances]
        for stepper in steppers:
            stepper.start()
            if not cycle["threads"]:
                stepper.join()  # one after the other
        for stepper in steppers:
            stepper.join()
        outputs = [binary.get(c, binary.REAL, case["output"])[0] for c in instances]
        for index in cycle["free"]:
            binary(binary.fn("FreeInstance"), instances[index])
        failed = [call for call in binary.calls if call["result"] not in (0, "instance", None)]
        results.append({"outputs": outputs, "failed": failed})
        if cycle["unload"]:
            _ctypes.dlclose(binary.lib._handle)
            binary = None
    return results


def _steps(binary, c, count):
    for n in range(count):
        binary.do_step(c, 0.1 * n, 0.1)


def main(*arguments):
    if arguments[0] == "cycles":
        _, version, folder = arguments
        print(json.dumps({"cycles": run_cycles(version, folder, json.loads(sys.stdin.read()))}), flush=True)
        return 0
    version, folder, trace = (*arguments, "")[:3]
    binary = Fmi2(folder) if version == "2" else Fmi3(folder)
    for line in sys.stdin:
        sequence = json.loads(line)
        print(json.dumps({"start": sequence["id"]}), flush=True)
        calls = run_sequence(binary, sequence["calls"], trace == "trace")
        print(json.dumps({"id": sequence["id"], "calls": calls}, default=repr), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
