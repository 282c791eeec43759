"""Child process of ``tests/test_fmi_calls.py``: calls the exported FMI functions of an extracted FMU's Linux
binary through ctypes, with the signatures of the FMI 2.0.4 / 3.0 headers, and prints one JSON line per case.

Run as ``python fmi_call_runner.py {2|3} FOLDER CASE...`` (FOLDER: the extracted FMU). A line is
``{"case", "calls", "values"}``: every call made (its label, function, result and the log messages the
logger callback received during it, as ``[status, category, message]``) and the values the case read.
A crash ends the process: the parent then knows which case was running (the last "start" line).
"""

import ctypes
import gc
import inspect
import json
import pathlib
import sys
from ctypes import POINTER, byref, c_bool, c_char_p, c_double, c_int, c_int32, c_size_t, c_uint32, c_void_p

from fmpy import read_model_description

VR = POINTER(c_uint32)

# ---- FMI 2 --------------------------------------------------------------------------------------------------

#: fmi2CallbackLogger(env, instanceName, status, category, message, ...): the loader always passes "%s" and the
#: text as the first variadic argument, which on x86-64 arrives like a sixth fixed argument
FMI2_LOGGER = ctypes.CFUNCTYPE(None, c_void_p, c_char_p, c_int, c_char_p, c_char_p, c_void_p)


class Fmi2Callbacks(ctypes.Structure):
    """fmi2CallbackFunctions"""
    _fields_ = [("logger", FMI2_LOGGER), ("allocateMemory", c_void_p), ("freeMemory", c_void_p),
                ("stepFinished", c_void_p), ("componentEnvironment", c_void_p)]


class Fmi2EventInfo(ctypes.Structure):
    """fmi2EventInfo"""
    _fields_ = [("newDiscreteStatesNeeded", c_int), ("terminateSimulation", c_int),
                ("nominalsOfContinuousStatesChanged", c_int), ("valuesOfContinuousStatesChanged", c_int),
                ("nextEventTimeDefined", c_int), ("nextEventTime", c_double)]


def _fmi2_signatures():
    """``{function: (restype, argtypes)}`` of the FMI 2 functions, as in fmi2FunctionTypes.h (c: fmi2Component)."""
    c, status = c_void_p, c_int
    typed = {"Real": c_double, "Integer": c_int, "Boolean": c_int, "String": c_char_p}
    out = {
        "fmi2GetTypesPlatform": (c_char_p, []), "fmi2GetVersion": (c_char_p, []),
        "fmi2SetDebugLogging": (status, [c, c_int, c_size_t, POINTER(c_char_p)]),
        "fmi2Instantiate": (c_void_p, [c_char_p, c_int, c_char_p, c_char_p, POINTER(Fmi2Callbacks), c_int, c_int]),
        "fmi2FreeInstance": (None, [c]),
        "fmi2SetupExperiment": (status, [c, c_int, c_double, c_double, c_int, c_double]),
        "fmi2GetFMUstate": (status, [c, POINTER(c_void_p)]), "fmi2SetFMUstate": (status, [c, c_void_p]),
        "fmi2FreeFMUstate": (status, [c, POINTER(c_void_p)]),
        "fmi2SerializedFMUstateSize": (status, [c, c_void_p, POINTER(c_size_t)]),
        "fmi2SerializeFMUstate": (status, [c, c_void_p, c_char_p, c_size_t]),
        "fmi2DeSerializeFMUstate": (status, [c, c_char_p, c_size_t, POINTER(c_void_p)]),
        "fmi2GetDirectionalDerivative": (status, [c, VR, c_size_t, VR, c_size_t, POINTER(c_double),
                                                  POINTER(c_double)]),
        "fmi2SetRealInputDerivatives": (status, [c, VR, c_size_t, POINTER(c_int), POINTER(c_double)]),
        "fmi2GetRealOutputDerivatives": (status, [c, VR, c_size_t, POINTER(c_int), POINTER(c_double)]),
        "fmi2DoStep": (status, [c, c_double, c_double, c_int]),
        "fmi2GetStatus": (status, [c, c_int, POINTER(c_int)]),
        "fmi2SetTime": (status, [c, c_double]),
        "fmi2NewDiscreteStates": (status, [c, POINTER(Fmi2EventInfo)]),
        "fmi2CompletedIntegratorStep": (status, [c, c_int, POINTER(c_int), POINTER(c_int)]),
        "fmi2SetContinuousStates": (status, [c, POINTER(c_double), c_size_t]),
    }
    for name in ("GetContinuousStates", "GetDerivatives", "GetNominalsOfContinuousStates", "GetEventIndicators"):
        out[f"fmi2{name}"] = (status, [c, POINTER(c_double), c_size_t])
    for name in ("EnterInitializationMode", "ExitInitializationMode", "Terminate", "Reset", "CancelStep",
                 "EnterEventMode", "EnterContinuousTimeMode"):
        out[f"fmi2{name}"] = (status, [c])
    for kind, ctype in typed.items():
        out[f"fmi2Get{kind}"] = (status, [c, VR, c_size_t, POINTER(ctype)])
        out[f"fmi2Set{kind}"] = (status, [c, VR, c_size_t, POINTER(ctype)])
        out[f"fmi2Get{kind}Status"] = (status, [c, c_int, POINTER(ctype)])
    return out


# ---- FMI 3 --------------------------------------------------------------------------------------------------

FMI3_LOG_MESSAGE = ctypes.CFUNCTYPE(None, c_void_p, c_int, c_char_p, c_char_p)
FMI3_TYPES = {"Float32": ctypes.c_float, "Float64": c_double, "Int8": ctypes.c_int8, "UInt8": ctypes.c_uint8,
              "Int16": ctypes.c_int16, "UInt16": ctypes.c_uint16, "Int32": c_int32, "UInt32": c_uint32,
              "Int64": ctypes.c_int64, "UInt64": ctypes.c_uint64, "Boolean": c_bool, "String": c_char_p}


def _fmi3_signatures():
    """``{function: (restype, argtypes)}`` of the FMI 3 functions, as in fmi3FunctionTypes.h (c: fmi3Instance)."""
    c, status, size, b, f64 = c_void_p, c_int, c_size_t, c_bool, c_double
    out = {
        "fmi3GetVersion": (c_char_p, []),
        "fmi3InstantiateCoSimulation": (c_void_p, [c_char_p, c_char_p, c_char_p, b, b, b, b, VR, size, c_void_p,
                                                   FMI3_LOG_MESSAGE, c_void_p]),
        "fmi3InstantiateModelExchange": (c_void_p, [c_char_p, c_char_p, c_char_p, b, b, c_void_p,
                                                    FMI3_LOG_MESSAGE]),
        "fmi3InstantiateScheduledExecution": (c_void_p, [c_char_p, c_char_p, c_char_p, b, b, c_void_p,
                                                         FMI3_LOG_MESSAGE, c_void_p, c_void_p, c_void_p]),
        "fmi3FreeInstance": (None, [c]),
        "fmi3SetDebugLogging": (status, [c, b, size, POINTER(c_char_p)]),
        "fmi3EnterInitializationMode": (status, [c, b, f64, f64, b, f64]),
        "fmi3GetBinary": (status, [c, VR, size, POINTER(size), POINTER(c_void_p), size]),
        "fmi3SetBinary": (status, [c, VR, size, POINTER(size), POINTER(c_void_p), size]),
        "fmi3GetClock": (status, [c, VR, size, POINTER(b)]), "fmi3SetClock": (status, [c, VR, size, POINTER(b)]),
        "fmi3GetNumberOfVariableDependencies": (status, [c, c_uint32, POINTER(size)]),
        "fmi3GetVariableDependencies": (status, [c, c_uint32, POINTER(size), VR, POINTER(size), POINTER(c_int),
                                                 size]),
        "fmi3GetFMUState": (status, [c, POINTER(c_void_p)]), "fmi3SetFMUState": (status, [c, c_void_p]),
        "fmi3FreeFMUState": (status, [c, POINTER(c_void_p)]),
        "fmi3SerializedFMUStateSize": (status, [c, c_void_p, POINTER(size)]),
        "fmi3SerializeFMUState": (status, [c, c_void_p, c_char_p, size]),
        "fmi3DeserializeFMUState": (status, [c, c_char_p, size, POINTER(c_void_p)]),
        "fmi3GetOutputDerivatives": (status, [c, VR, size, POINTER(c_int32), POINTER(f64), size]),
        "fmi3CompletedIntegratorStep": (status, [c, b, POINTER(b), POINTER(b)]),
        "fmi3SetTime": (status, [c, f64]),
        "fmi3UpdateDiscreteStates": (status, [c] + [POINTER(b)] * 5 + [POINTER(f64)]),
        "fmi3DoStep": (status, [c, f64, f64, b, POINTER(b), POINTER(b), POINTER(b), POINTER(f64)]),
        "fmi3GetIntervalDecimal": (status, [c, VR, size, POINTER(f64), POINTER(c_int)]),
        "fmi3GetIntervalFraction": (status, [c, VR, size, POINTER(ctypes.c_uint64), POINTER(ctypes.c_uint64),
                                             POINTER(c_int)]),
        "fmi3GetShiftDecimal": (status, [c, VR, size, POINTER(f64)]),
        "fmi3GetShiftFraction": (status, [c, VR, size, POINTER(ctypes.c_uint64), POINTER(ctypes.c_uint64)]),
        "fmi3SetIntervalDecimal": (status, [c, VR, size, POINTER(f64)]),
        "fmi3SetIntervalFraction": (status, [c, VR, size, POINTER(ctypes.c_uint64), POINTER(ctypes.c_uint64)]),
        "fmi3SetShiftDecimal": (status, [c, VR, size, POINTER(f64)]),
        "fmi3SetShiftFraction": (status, [c, VR, size, POINTER(ctypes.c_uint64), POINTER(ctypes.c_uint64)]),
        "fmi3ActivateModelPartition": (status, [c, c_uint32, f64]),
    }
    for name in ("ExitInitializationMode", "EnterEventMode", "Terminate", "Reset", "EnterConfigurationMode",
                 "ExitConfigurationMode", "EnterContinuousTimeMode", "EnterStepMode", "EvaluateDiscreteStates"):
        out[f"fmi3{name}"] = (status, [c])
    for name in ("GetNumberOfEventIndicators", "GetNumberOfContinuousStates"):
        out[f"fmi3{name}"] = (status, [c, POINTER(size)])
    for name in ("SetContinuousStates", "GetEventIndicators", "GetContinuousStates", "GetNominalsOfContinuousStates",
                 "GetContinuousStateDerivatives"):
        out[f"fmi3{name}"] = (status, [c, POINTER(f64), size])
    for name in ("GetDirectionalDerivative", "GetAdjointDerivative"):
        out[f"fmi3{name}"] = (status, [c, VR, size, VR, size, POINTER(f64), size, POINTER(f64), size])
    for kind, ctype in FMI3_TYPES.items():
        out[f"fmi3Get{kind}"] = (status, [c, VR, size, POINTER(ctype), size])
        out[f"fmi3Set{kind}"] = (status, [c, VR, size, POINTER(ctype), size])
    return out


# ---- calling and recording ------------------------------------------------------------------------------------

#: a block stuck to the drive from t = 0 (v_start = v_drive = 0.1 m/s, |kappa x| < F_S = 1 N until t = 10 s),
#: with a kinetic law other than the default (code 2: viscous, SPEC section 3)
STUCK = {"v_start": 0.1, "kinetic.law": 2}


def _plain(value):
    """``value`` as JSON can hold it: bytes decoded, ctypes arrays as lists."""
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, ctypes.Array):
        return [_plain(item) for item in value]
    return value


class Binary:
    """The FMU's Linux binary, its functions typed by ``signatures``; every call and its log messages recorded.

    A subclass names its FMI version: ``PREFIX`` of the functions, ``REAL`` and ``INTEGER`` (the variable types),
    ``TYPES`` (their C types), ``NAMES`` (FMI 3's spellings of the FMU-state functions mapped to its own) and
    ``VALUE_COUNT`` (fmi<N>Get/Set<T> take the number of values after the values); ``ENUMERATION``: the type of
    the functions that access an Enumeration variable."""

    PREFIX, REAL, INTEGER, ENUMERATION, TYPES, NAMES, VALUE_COUNT = "", "", "", "", {}, {}, False

    def __init__(self, folder, platform, signatures):
        self.folder = pathlib.Path(folder)
        self.description = read_model_description(folder)
        interface = self.description.coSimulation or self.description.modelExchange
        self.refs = {v.name: v.valueReference for v in self.description.modelVariables}
        self.kinds = {v.name: self.ENUMERATION if v.type == "Enumeration" else v.type
                      for v in self.description.modelVariables}
        self.lib = ctypes.CDLL(str(self.folder / "binaries" / platform / f"{interface.modelIdentifier}.so"))
        for name, (restype, argtypes) in signatures.items():
            function = getattr(self.lib, name)
            function.restype, function.argtypes = restype, argtypes
        self.log = []  # [status, category, message] as the logger callback received them
        self.calls = []

    def received(self, status, category, message):
        """The logger callback's part: record one message (category None if the FMU passed NULL)."""
        self.log.append([int(status), _plain(category), _plain(message)])

    def __call__(self, function, *args, label=None):
        """``function(*args)``, recorded under ``label`` (default: the function's name) with the messages logged
        during the call; returns the function's result."""
        before = len(self.log)
        result = getattr(self.lib, function)(*args)
        recorded = result if isinstance(result, (int, bytes)) or result is None else "pointer"
        if "Instantiate" in function:
            recorded = "NULL" if result is None else "instance"
        self.calls.append({"label": label or function, "function": function, "result": _plain(recorded),
                           "messages": self.log[before:]})
        return result

    def fn(self, name):
        """The name of the function ``name`` (FMI 3's spelling, no prefix) in this version."""
        return self.NAMES.get(name, self.PREFIX + name)

    def vrs(self, *names):
        """The value references of the variables ``names`` as a C array."""
        return (c_uint32 * len(names))(*(self.refs[name] for name in names))

    def access(self, way, kind, c, names, values, label=None):
        """fmi<N><way><kind> (way: Get or Set) of the variables ``names`` with the C array ``values``."""
        count = (len(names),) if self.VALUE_COUNT else ()
        self(f"{self.PREFIX}{way}{kind}", c, self.vrs(*names), len(names), values, *count, label=label)

    def get(self, c, kind, *names, label=None):
        """fmi<N>Get<kind> of the variables ``names`` as a list."""
        values = (self.TYPES[kind] * len(names))()
        self.access("Get", kind, c, names, values, label)
        return list(values)

    def set_values(self, c, values, label=None):
        """fmi<N>Set<type> of ``{name: value}``, one call per variable."""
        for name, value in values.items():
            kind = self.kinds[name]
            self.access("Set", kind, c, [name], (self.TYPES[kind] * 1)(value), label)

    def initialized(self, values=(), **instantiation):
        """A new instance (``instantiate(**instantiation)``) initialized with ``values``."""
        c = self.instantiate(**instantiation)
        self.initialize(c, values)
        return c

    def after(self, name, what):
        """The label ``fmi<N><name> <what>``."""
        return f"{self.fn(name)} {what}"


def run(binary, cases, names):
    """Run the cases ``names`` one after the other, printing a line per case. A name is a function of ``cases``
    or ``log`` followed by the JSON of a logging setting (see :func:`logging_setting`)."""
    for name in names:
        print(json.dumps({"start": name}), flush=True)
        binary.calls = []
        if name.startswith("log"):
            values = cases["log"](binary, *json.loads(name[3:]))
        else:
            values = cases[name](binary)
        print(json.dumps({"case": name, "calls": binary.calls, "values": values}), flush=True)


# ---- cases of both versions ---------------------------------------------------------------------------------


def stuck_step(b):
    """Initialize a stuck block, step 0.5 s, read outputs and the Integer parameter set; terminate."""
    c = b.initialized(STUCK)
    at_start = b.get(c, b.REAL, "x", "v", label=b.after(f"Get{b.REAL}", "at t=0"))
    law = b.get(c, b.INTEGER, "kinetic.law")
    step = b.do_step(c, 0.0, 0.5)
    after = b.get(c, b.REAL, "x", "v", "t_stick", label=b.after(f"Get{b.REAL}", "at t=0.5"))
    mode = b.get(c, b.INTEGER, "mode", label=b.after(f"Get{b.INTEGER}", "mode"))
    b(b.fn("Terminate"), c)
    b(b.fn("FreeInstance"), c)
    return {"at_start": at_start, "law": law, "step": step, "after": after, "mode": mode}


def reset(b):
    """Step with M = 40 kg, reset, initialize again with the defaults: M and x are the start values."""
    c = b.initialized({"M": 40.0, **STUCK})
    b.do_step(c, 0.0, 0.5)
    b(b.fn("Reset"), c)
    b.initialize(c, after="after reset")
    values = b.get(c, b.REAL, "M", "x", label=b.after(f"Get{b.REAL}", "after reset"))
    b.do_step(c, 0.0, 0.5, label=b.after("DoStep", "after reset"))
    b(b.fn("FreeInstance"), c)
    return {"M_x": values}


def fmu_state(b):
    """Save the state at t = 0, step, restore it; serialize it, deserialize it, restore that; free both, then a
    freed (NULL) state and a null pointer."""
    c = b.initialized(STUCK)
    state, copy, size = c_void_p(), c_void_p(), c_size_t()
    b(b.fn("GetFMUState"), c, byref(state))
    b.do_step(c, 0.0, 0.5)
    stepped = b.get(c, b.REAL, "x", label=b.after(f"Get{b.REAL}", "stepped"))
    b(b.fn("SetFMUState"), c, state)
    restored = b.get(c, b.REAL, "x", label=b.after(f"Get{b.REAL}", "restored"))
    b(b.fn("SerializedFMUStateSize"), c, state, byref(size))
    data = ctypes.create_string_buffer(size.value)
    b(b.fn("SerializeFMUState"), c, state, data, size.value)
    b(b.fn("DeserializeFMUState"), c, data, size.value, byref(copy))
    b.do_step(c, 0.0, 0.5, label=b.after("DoStep", "again"))
    b(b.fn("SetFMUState"), c, copy, label=b.after("SetFMUState", "deserialized"))
    deserialized = b.get(c, b.REAL, "x", label=b.after(f"Get{b.REAL}", "deserialized"))
    b(b.fn("FreeFMUState"), c, byref(state))
    b(b.fn("FreeFMUState"), c, byref(copy), label=b.after("FreeFMUState", "deserialized"))
    b(b.fn("FreeFMUState"), c, byref(state), label=b.after("FreeFMUState", "of a NULL state"))
    b(b.fn("FreeFMUState"), c, None, label=b.after("FreeFMUState", "of a null pointer"))
    b(b.fn("FreeInstance"), c)
    return {"stepped": stepped, "restored": restored, "deserialized": deserialized, "size": size.value,
            "freed_states": [state.value, copy.value]}


def other_types(b, kinds):
    """The accessors of types the model has no variable of (``kinds``): zero variables, then a Real variable; the
    instance steps on after the refusals."""
    c = b.initialized(STUCK)
    for kind in kinds:
        values = (b.TYPES[kind] * 1)()
        for way in ("Get", "Set"):
            b.access(way, kind, c, [], values, b.after(f"{way}{kind}", "of none"))
        values[0] = b"0.2" if kind == "String" else 1
        b.access("Get", kind, c, ["x"], values, b.after(f"Get{kind}", f"of a {b.REAL}"))
        b.access("Set", kind, c, ["v_drive"], values, b.after(f"Set{kind}", f"of a {b.REAL}"))
    step = b.do_step(c, 0.0, 0.5, label=b.after("DoStep", "after the refusals"))
    x_v_drive = b.get(c, b.REAL, "x", "v_drive", label=b.after(f"Get{b.REAL}", "after the refusals"))
    b(b.fn("FreeInstance"), c)
    return {"step": step, "x_v_drive": x_v_drive}


def logging_setting(b, c, debug_logging_calls):
    """fmi<N>SetDebugLogging(c, on, n, categories) for each ``[on, categories]`` of ``debug_logging_calls`` (a
    category None is passed as NULL)."""
    for index, (on, categories) in enumerate(debug_logging_calls):
        names = (c_char_p * len(categories))(*(name and name.encode() for name in categories)) if categories else None
        b(b.fn("SetDebugLogging"), c, on, len(categories), names, label=b.after("SetDebugLogging", f"#{index}"))


def slaves():
    """The model's Python objects (the slaves PythonFMU / pythonfmu3 made) alive in this process, by id."""
    return {id(item): item for item in gc.get_objects() if type(item).__name__ == "SpringBlockFriction"}


def log_from_the_slave(b, c, before):
    """Queue one message of every status through the slave's own logging (``log(msg, status)``, the category
    PythonFMU derives from the status) in the slave made since ``before`` (:func:`slaves`), and make a call into
    the slave, at which the library passes them to the logger. Returns ``{message: status}``."""
    slave = next(item for key, item in slaves().items() if key not in before)
    statuses = type(inspect.signature(slave.log).parameters["status"].default)
    queued = {f"message from the slave with status {status.name}": status for status in statuses}
    for message, status in queued.items():
        slave.log(message, status)
    b.get(c, b.REAL, "x", label=b.after(f"Get{b.REAL}", "after the slave logged"))
    return {message: int(status) for message, status in queued.items()}


def exchange_round(b, c, boolean):
    """Continuous-time mode of an initialized stuck block after its first event update: its states, nominals and
    derivatives at t = 0; then t = 0.5 s, x = 0.05 m, v = 0.1 m/s: its indicators and an integrator step (``boolean``:
    the version's Boolean type); event mode again. Returns what the calls gave."""
    b(b.fn("EnterContinuousTimeMode"), c)
    states, derivatives, nominals, indicators = (c_double * 2)(), (c_double * 2)(), (c_double * 2)(), (c_double * 3)()
    b(b.fn("GetContinuousStates"), c, states, 2)
    b(b.fn("GetNominalsOfContinuousStates"), c, nominals, 2)
    b(b.fn("GetContinuousStateDerivatives"), c, derivatives, 2)
    b(b.fn("SetTime"), c, 0.5)
    b(b.fn("SetContinuousStates"), c, (c_double * 2)(0.05, 0.1), 2)
    b(b.fn("GetEventIndicators"), c, indicators, 3)
    flags = [boolean(True), boolean(True)]
    b(b.fn("CompletedIntegratorStep"), c, True, *map(byref, flags))
    b(b.fn("EnterEventMode"), c)
    return {"states": list(states), "nominals": list(nominals), "derivatives": list(derivatives),
            "indicators": list(indicators), "completed": [flag.value for flag in flags]}


# ---- FMI 2 ----------------------------------------------------------------------------------------------------

FMI2_DO_STEP_STATUS, FMI2_PENDING_STATUS, FMI2_LAST_SUCCESSFUL_TIME, FMI2_TERMINATED = range(4)


class Fmi2(Binary):
    """The FMI 2 binary with a logger and memory callbacks."""

    PREFIX, REAL, INTEGER, ENUMERATION = "fmi2", "Real", "Integer", "Integer"
    TYPES = {"Real": c_double, "Integer": c_int, "Boolean": c_int, "String": c_char_p}
    NAMES = {"GetFMUState": "fmi2GetFMUstate", "SetFMUState": "fmi2SetFMUstate", "FreeFMUState": "fmi2FreeFMUstate",
             "SerializedFMUStateSize": "fmi2SerializedFMUstateSize", "SerializeFMUState": "fmi2SerializeFMUstate",
             "DeserializeFMUState": "fmi2DeSerializeFMUstate", "GetContinuousStateDerivatives": "fmi2GetDerivatives",
             "UpdateDiscreteStates": "fmi2NewDiscreteStates"}

    def __init__(self, folder):
        super().__init__(folder, "linux64", _fmi2_signatures())
        libc = ctypes.CDLL(None)
        self._logger = FMI2_LOGGER(self._log)
        self.callbacks = Fmi2Callbacks(self._logger, ctypes.cast(libc.calloc, c_void_p),
                                       ctypes.cast(libc.free, c_void_p), None, None)

    def _log(self, environment, instance_name, status, category, message, first_argument):
        text = ctypes.string_at(first_argument) if message == b"%s" and first_argument else message
        self.received(status, category, text)

    def instantiate(self, logging_on=False, interface="CoSimulation", label=None):
        """A new instance of ``interface`` (fmi2Instantiate with fmuType fmi2CoSimulation or fmi2ModelExchange) or
        None."""
        resources = (self.folder / "resources").as_uri().encode()
        return self("fmi2Instantiate", b"calls", int(interface == "CoSimulation"), self.description.guid.encode(),
                    resources, byref(self.callbacks), 0, int(logging_on), label=label)

    def initialize(self, c, values=(), after=""):
        """fmi2SetupExperiment, fmi2EnterInitializationMode, ``values`` set, fmi2ExitInitializationMode; the labels
        end in ``after`` if given."""
        label = (lambda name: f"{name} {after}") if after else (lambda name: None)
        self("fmi2SetupExperiment", c, 0, 0.0, 0.0, 0, 0.0, label=label("fmi2SetupExperiment"))
        self("fmi2EnterInitializationMode", c, label=label("fmi2EnterInitializationMode"))
        self.set_values(c, dict(values))
        self("fmi2ExitInitializationMode", c, label=label("fmi2ExitInitializationMode"))

    def do_step(self, c, t, h, label=None):
        """fmi2DoStep(t, h); no result (see fmi2GetRealStatus)."""
        self("fmi2DoStep", c, t, h, 1, label=label)

    def update(self, c, label=None):
        """fmi2NewDiscreteStates; returns its fmi2EventInfo's six fields."""
        info = Fmi2EventInfo(1, 1, 1, 1, 1, -1.0)
        self("fmi2NewDiscreteStates", c, byref(info), label=label)
        return [getattr(info, name) for name, _ in Fmi2EventInfo._fields_]


def fmi2_version(b):
    return {"version": _plain(b("fmi2GetVersion")), "platform": _plain(b("fmi2GetTypesPlatform"))}


def fmi2_derivatives(b):
    """The derivative calls: directional derivatives, which the model description rules out (not provided); input
    derivatives (canInterpolateInputs: der(F_ext) of order 1) and output derivatives (maxOutputDerivativeOrder = 2;
    their values: tests/test_input_output_derivatives.py)."""
    c = b.initialized(STUCK)
    seed, out, order = (c_double * 1)(1.0), (c_double * 1)(), (c_int * 1)(1)
    b("fmi2GetDirectionalDerivative", c, b.vrs("x"), 1, b.vrs("v_drive"), 1, seed, out)
    b("fmi2SetRealInputDerivatives", c, b.vrs("F_ext"), 1, order, seed)
    b("fmi2GetRealOutputDerivatives", c, b.vrs("x"), 1, order, out)
    b("fmi2FreeInstance", c)


def fmi2_status(b):
    """After a completed step (none pending, none discarded): cancel and the status inquiries of every kind."""
    c = b.initialized(STUCK)
    b.do_step(c, 0.0, 0.5)
    b("fmi2CancelStep", c)
    status, real, integer, flag, text = c_int(-1), c_double(), c_int(-1), c_int(-1), c_char_p()
    b("fmi2GetStatus", c, FMI2_DO_STEP_STATUS, byref(status))
    b("fmi2GetRealStatus", c, FMI2_LAST_SUCCESSFUL_TIME, byref(real))
    b("fmi2GetRealStatus", c, FMI2_DO_STEP_STATUS, byref(c_double()), label="fmi2GetRealStatus of fmi2DoStepStatus")
    b("fmi2GetIntegerStatus", c, FMI2_DO_STEP_STATUS, byref(integer))
    b("fmi2GetBooleanStatus", c, FMI2_TERMINATED, byref(flag))
    b("fmi2GetStringStatus", c, FMI2_PENDING_STATUS, byref(text))
    b("fmi2FreeInstance", c)
    return {"last_successful_time": real.value, "terminated": flag.value}


def fmi2_log(b, logging_on, debug_logging_calls):
    """Messages of every kind under one logging setting: instantiate with ``logging_on``, the
    fmi2SetDebugLogging calls ``debug_logging_calls``; messages from the slave of every status, an unsupported
    call, fmi2Reset and a mass out of range (fmi2ExitInitializationMode fails)."""
    before = slaves()
    c = b.instantiate(logging_on)
    logging_setting(b, c, debug_logging_calls)
    b.initialize(c)
    queued = log_from_the_slave(b, c, before)
    seed, out = (c_double * 1)(1.0), (c_double * 1)()
    b("fmi2GetDirectionalDerivative", c, b.vrs("x"), 1, b.vrs("v_drive"), 1, seed, out)
    b("fmi2Reset", c)
    b("fmi2SetupExperiment", c, 0, 0.0, 0.0, 0, 0.0, label="fmi2SetupExperiment after reset")
    b("fmi2EnterInitializationMode", c, label="fmi2EnterInitializationMode after reset")
    b.set_values(c, {"M": -1.0}, label="fmi2SetReal of M = -1 kg")
    b("fmi2ExitInitializationMode", c, label="fmi2ExitInitializationMode with M = -1 kg")
    b("fmi2FreeInstance", c)
    return {"queued": queued}


#: the model-exchange functions, each with the arguments of a stuck block's call (``values``: an array of 3)
def fmi2_exchange_arguments(values, flags):
    return {"fmi2EnterEventMode": (), "fmi2EnterContinuousTimeMode": (), "fmi2SetTime": (0.5,),
            "fmi2SetContinuousStates": ((c_double * 2)(0.05, 0.1), 2), "fmi2GetContinuousStates": (values, 2),
            "fmi2GetNominalsOfContinuousStates": (values, 2), "fmi2GetDerivatives": (values, 2),
            "fmi2GetEventIndicators": (values, 3), "fmi2NewDiscreteStates": (byref(Fmi2EventInfo()),),
            "fmi2CompletedIntegratorStep": (1, *map(byref, flags))}


FMI2_EXCHANGE_ONLY = tuple(fmi2_exchange_arguments(None, [c_int(), c_int()]))


def fmi2_cs_exchange_calls(b):
    """The model-exchange functions with a stuck block's arguments on an initialized co-simulation instance: each
    refused, and the next step's outputs are those of the co-simulation."""
    c = b.initialized(STUCK)
    arguments = fmi2_exchange_arguments((c_double * 3)(), [c_int(), c_int()])
    for name in FMI2_EXCHANGE_ONLY:
        b(name, c, *arguments[name], label=f"{name} in co-simulation")
    b.do_step(c, 0.0, 0.5, label="fmi2DoStep after the refusal")
    x = b.get(c, "Real", "x", label="fmi2GetReal after the refusal")
    b("fmi2FreeInstance", c)
    return {"x": x}


def fmi2_model_exchange(b):
    """Model exchange of a stuck block, as fmi3_model_exchange: event mode after initialization, continuous-time
    mode, states, derivatives, nominals, indicators at t = 0.5 s, an integrator step, event mode again; then the
    co-simulation calls on the model-exchange instance; terminate."""
    c = b.initialized(STUCK, interface="ModelExchange")
    first_update = b.update(c)
    values = exchange_round(b, c, c_int)
    second_update = b.update(c, label="fmi2NewDiscreteStates at t=0.5")
    outputs = b.get(c, "Real", "x", "v", "t_stick", label="fmi2GetReal at t=0.5")
    der = b.get(c, "Real", "der(x)", "der(v)", label="fmi2GetReal of der(x), der(v)")
    b("fmi2DoStep", c, 0.5, 0.5, 1, label="fmi2DoStep in model exchange")
    order, seed = (c_int * 1)(1), (c_double * 1)(1.0)
    b("fmi2SetRealInputDerivatives", c, b.vrs("F_ext"), 1, order, seed,
      label="fmi2SetRealInputDerivatives in model exchange")
    b("fmi2GetRealOutputDerivatives", c, b.vrs("x"), 1, order, seed,
      label="fmi2GetRealOutputDerivatives in model exchange")
    b("fmi2Terminate", c, label="fmi2Terminate in model exchange")
    b("fmi2FreeInstance", c)
    return {"first_update": first_update, **values, "second_update": second_update, "outputs": outputs, "der": der}


def fmi2_exchange_refusals(b):
    """Refusals of a model-exchange instance: a mass out of range (fmi2GetDerivatives during initialization and
    fmi2ExitInitializationMode), then, initialized, arrays of the wrong length, a non-finite time, a NULL array."""
    c = b.instantiate(interface="ModelExchange", label="fmi2Instantiate of model exchange")
    b("fmi2SetupExperiment", c, 0, 0.0, 0.0, 0, 0.0, label="fmi2SetupExperiment of model exchange")
    b("fmi2EnterInitializationMode", c, label="fmi2EnterInitializationMode of model exchange")
    b.set_values(c, {"M": -1.0}, label="fmi2SetReal of M = -1 kg")
    values = (c_double * 5)()
    b("fmi2GetDerivatives", c, values, 2, label="fmi2GetDerivatives with M = -1 kg")
    b("fmi2ExitInitializationMode", c, label="fmi2ExitInitializationMode with M = -1 kg")
    b("fmi2FreeInstance", c, label="fmi2FreeInstance of model exchange")
    c = b.initialized(STUCK, interface="ModelExchange")
    b("fmi2GetDerivatives", c, values, 5, label="fmi2GetDerivatives of nx = 5")
    b("fmi2GetEventIndicators", c, values, 2, label="fmi2GetEventIndicators of ni = 2")
    b("fmi2SetContinuousStates", c, values, 1, label="fmi2SetContinuousStates of nx = 1")
    b("fmi2SetTime", c, float("nan"), label="fmi2SetTime of NaN")
    b("fmi2GetContinuousStates", c, None, 2, label="fmi2GetContinuousStates into NULL")
    b("fmi2SetContinuousStates", c, (c_double * 2)(float("inf"), 0.1), 2, label="fmi2SetContinuousStates of inf")
    b("fmi2GetContinuousStates", c, values, 2, label="fmi2GetContinuousStates after the refusals")
    b("fmi2FreeInstance", c, label="fmi2FreeInstance of model exchange")
    return {"states": list(values)[:2]}


FMI2_CASES = {"version": fmi2_version, "stuck_step": stuck_step, "reset": reset, "fmu_state": fmu_state,
              "boolean_string": lambda b: other_types(b, ("Boolean", "String")), "derivatives": fmi2_derivatives,
              "status": fmi2_status, "cs_exchange_calls": fmi2_cs_exchange_calls,
              "model_exchange": fmi2_model_exchange, "exchange_refusals": fmi2_exchange_refusals, "log": fmi2_log}


# ---- FMI 3 ----------------------------------------------------------------------------------------------------

#: the functions pythonfmu3 does not implement and the FMU's binary refuses (fmi3_front.c, UNSUPPORTED)
FMI3_REFUSED = (
    *(f"fmi3{way}{kind}" for kind in ("Float32", "Int8", "UInt8", "Int16", "UInt16", "UInt32", "Binary", "Clock")
      for way in ("Get", "Set")),
    "fmi3GetNumberOfVariableDependencies", "fmi3GetVariableDependencies", "fmi3GetAdjointDerivative",
    *(f"fmi3{way}{what}{unit}" for way in ("Get", "Set") for what in ("Interval", "Shift")
      for unit in ("Decimal", "Fraction")),
    "fmi3EvaluateDiscreteStates", "fmi3ActivateModelPartition",
)
#: the model-exchange functions FMI 3.0 does not allow in co-simulation (section 2.3)
FMI3_EXCHANGE_ONLY = (
    "fmi3EnterContinuousTimeMode", "fmi3SetTime", "fmi3SetContinuousStates", "fmi3GetContinuousStates",
    "fmi3GetNominalsOfContinuousStates", "fmi3GetContinuousStateDerivatives", "fmi3GetEventIndicators",
    "fmi3GetNumberOfContinuousStates", "fmi3GetNumberOfEventIndicators", "fmi3CompletedIntegratorStep",
)
#: the types pythonfmu3 implements that the model has no variable of
FMI3_OTHER_TYPES = ("Int64", "UInt64", "Boolean", "String")


class Fmi3(Binary):
    """The FMI 3 binary with a logMessage callback."""

    # the law selectors (Enumerations) through fmi3Get/SetInt32, which the FMU takes too (fmi3SetInt64: its own cases)
    PREFIX, REAL, INTEGER, ENUMERATION, TYPES, VALUE_COUNT = "fmi3", "Float64", "Int32", "Int32", FMI3_TYPES, True

    def __init__(self, folder):
        super().__init__(folder, "x86_64-linux", _fmi3_signatures())
        self._log_message = FMI3_LOG_MESSAGE(lambda env, status, category, message:
                                             self.received(status, category, message))
        self.resources = (str(self.folder / "resources") + "/").encode()

    def instantiate(self, interface="CoSimulation", logging_on=False, event_mode_used=False, early_return=False,
                    label=None):
        """A new instance of ``interface`` (fmi3Instantiate<interface>) or None."""
        token = self.description.guid.encode()
        if interface == "CoSimulation":
            return self("fmi3InstantiateCoSimulation", b"calls", token, self.resources, False, logging_on,
                        event_mode_used, early_return, None, 0, None, self._log_message, None, label=label)
        return self("fmi3InstantiateModelExchange", b"calls", token, self.resources, False, logging_on, None,
                    self._log_message)

    def initialize(self, c, values=(), after=""):
        """fmi3EnterInitializationMode, ``values`` set, fmi3ExitInitializationMode; the labels end in ``after`` if
        given."""
        label = (lambda name: f"{name} {after}") if after else (lambda name: None)
        self("fmi3EnterInitializationMode", c, False, 0.0, 0.0, False, 0.0, label=label("fmi3EnterInitializationMode"))
        self.set_values(c, dict(values))
        self("fmi3ExitInitializationMode", c, label=label("fmi3ExitInitializationMode"))

    def do_step(self, c, t, h, label=None):
        """fmi3DoStep(t, h); returns its outputs: event handling needed, terminate, early return, last time."""
        flags, last = [c_bool(True) for _ in range(3)], c_double(-1.0)
        self("fmi3DoStep", c, t, h, True, *map(byref, flags), byref(last), label=label)
        return [flag.value for flag in flags] + [last.value]

    def update(self, c, label=None):
        """fmi3UpdateDiscreteStates; returns its six outputs."""
        flags, next_time = [c_bool(True) for _ in range(5)], c_double(-1.0)
        self("fmi3UpdateDiscreteStates", c, *map(byref, flags), byref(next_time), label=label)
        return [flag.value for flag in flags] + [next_time.value]


def fmi3_version(b):
    return {"version": _plain(b("fmi3GetVersion"))}


def fmi3_refused(b):
    """Every function pythonfmu3 leaves out, called with zeroed arguments of the right types on an initialized
    co-simulation instance; then the directional derivatives, which the model description rules out, and the
    output derivatives it offers (maxOutputDerivativeOrder = 2), of an order and an output it does not."""
    c = b.initialized(STUCK)
    for name in FMI3_REFUSED:
        function = getattr(b.lib, name)
        args = [c] + [typ() if typ is not c_void_p else None for typ in function.argtypes[1:]]
        b(name, *args)
    seed, out, order = (c_double * 2)(1.0), (c_double * 2)(), (c_int32 * 2)(1, 2)
    b("fmi3GetDirectionalDerivative", c, b.vrs("x"), 1, b.vrs("v_drive"), 1, seed, 1, out, 1)
    b("fmi3GetOutputDerivatives", c, b.vrs("x", "v"), 2, order, out, 2)
    derivatives = list(out)
    b("fmi3GetOutputDerivatives", c, b.vrs("x"), 1, (c_int32 * 1)(3), out, 1,
      label="fmi3GetOutputDerivatives of order 3")
    b("fmi3GetOutputDerivatives", c, b.vrs("mode"), 1, order, out, 1, label="fmi3GetOutputDerivatives of mode")
    b("fmi3GetOutputDerivatives", c, b.vrs("x", "v"), 2, order, out, 1,
      label="fmi3GetOutputDerivatives with nValues short")
    step = b.do_step(c, 0.0, 0.5, label="fmi3DoStep after the refusals")
    b("fmi3FreeInstance", c)
    return {"step": step, "derivatives": derivatives}


def fmi3_modes(b):
    """The mode changes a co-simulation instance without event mode must refuse: configuration mode (the model
    has no structural parameter), event mode and step mode (eventModeUsed = false); scheduled execution (not
    offered)."""
    c = b.instantiate()
    b("fmi3EnterConfigurationMode", c)
    b("fmi3ExitConfigurationMode", c)
    b.initialize(c, STUCK)
    b("fmi3EnterEventMode", c, label="fmi3EnterEventMode in co-simulation")
    b("fmi3EnterStepMode", c)
    step = b.do_step(c, 0.0, 0.5, label="fmi3DoStep after the refusals")
    x = b.get(c, "Float64", "x", label="fmi3GetFloat64 after the refusals")
    b("fmi3FreeInstance", c)
    b("fmi3InstantiateScheduledExecution", b"calls", b.description.guid.encode(), b.resources, False, False, None,
      b._log_message, None, None, None)
    return {"step": step, "x": x}


#: a block of the elmer-fig3 preset (M = 40 kg, lubricated friction) breaking away at x = 1 m: it sticks at t = 29.27 s
SLIDING = {"M": 40.0, "x_start": 1.0, "v_start": 0.1, "kinetic.law": 4, "kinetic.gamma1": 3.0, "kinetic.gamma2": 0.1,
           "kinetic.v_tilde": 0.2, "kinetic.dv": 0.05}


def fmi3_event_mode(b):
    """A co-simulation instance with event mode and early return (fmusim's calls): Event Mode after initialization
    (fmi3UpdateDiscreteStates, fmi3EnterStepMode); a step of 40 s that returns early at the first stick, there the
    calls Step Mode refuses (fmi3UpdateDiscreteStates, fmi3EnterStepMode), then Event Mode (a step refused in it,
    the output derivatives), fmi3UpdateDiscreteStates, fmi3EnterStepMode and the rest of the step."""
    c = b.instantiate(event_mode_used=True, early_return=True, label="fmi3InstantiateCoSimulation with event mode")
    b.initialize(c, SLIDING, after="with event mode")
    first = b.update(c, label="fmi3UpdateDiscreteStates after initialization")
    b("fmi3EnterStepMode", c, label="fmi3EnterStepMode after initialization")
    early = b.do_step(c, 0.0, 40.0, label="fmi3DoStep to the first event")
    before = b.get(c, "Float64", "v", label="fmi3GetFloat64 before the event")
    mode_before = b.get(c, "Int32", "mode", label="fmi3GetInt32 before the event")
    b.update(c, label="fmi3UpdateDiscreteStates in Step Mode")
    b("fmi3EnterStepMode", c, label="fmi3EnterStepMode in Step Mode")
    b("fmi3EnterEventMode", c, label="fmi3EnterEventMode at the event")
    b.do_step(c, early[3], 1.0, label="fmi3DoStep in Event Mode")
    b("fmi3EnterEventMode", c, label="fmi3EnterEventMode in Event Mode")
    update = b.update(c, label="fmi3UpdateDiscreteStates at the event")
    mode_after = b.get(c, "Int32", "mode", label="fmi3GetInt32 after the event")
    b("fmi3EnterStepMode", c, label="fmi3EnterStepMode after the event")
    rest = b.do_step(c, early[3], 40.0 - early[3], label="fmi3DoStep after the event")
    b("fmi3FreeInstance", c)
    return {"first_update": first, "early": early, "v_before": before, "modes": [mode_before, mode_after],
            "update": update, "rest": rest}


def fmi3_cs_exchange_calls(b):
    """The model-exchange functions (FMI 3.0 section 2.3: not allowed in co-simulation, :data:`FMI3_EXCHANGE_ONLY`)
    with a stuck block's arguments, and fmi3UpdateDiscreteStates (no event mode), on an initialized co-simulation
    instance: each refused, and the next step's outputs are those of the co-simulation."""
    c = b.initialized(STUCK)
    count, flags, values = c_size_t(), [c_bool(), c_bool()], (c_double * 3)()
    arguments = {"fmi3EnterContinuousTimeMode": (), "fmi3SetTime": (0.5,),
                 "fmi3SetContinuousStates": ((c_double * 2)(0.05, 0.1), 2), "fmi3GetContinuousStates": (values, 2),
                 "fmi3GetNominalsOfContinuousStates": (values, 2), "fmi3GetContinuousStateDerivatives": (values, 2),
                 "fmi3GetEventIndicators": (values, 3), "fmi3GetNumberOfContinuousStates": (byref(count),),
                 "fmi3GetNumberOfEventIndicators": (byref(count),),
                 "fmi3CompletedIntegratorStep": (True, *map(byref, flags))}
    for name in FMI3_EXCHANGE_ONLY:
        b(name, c, *arguments[name], label=f"{name} in co-simulation")
    b.update(c, label="fmi3UpdateDiscreteStates in co-simulation")
    step = b.do_step(c, 0.0, 0.5, label="fmi3DoStep after the refusal")
    x = b.get(c, "Float64", "x", label="fmi3GetFloat64 after the refusal")
    b("fmi3FreeInstance", c)
    return {"step": step, "x": x}


def fmi3_model_exchange(b):
    """Model exchange of a stuck block: event mode after initialization, continuous-time mode, states,
    derivatives, nominals, indicators at t = 0.5 s, an integrator step, event mode again; terminate."""
    c = b.initialized(STUCK, interface="ModelExchange")
    first_update = b.update(c)
    counts = [c_size_t(), c_size_t()]
    b("fmi3GetNumberOfContinuousStates", c, byref(counts[0]))
    b("fmi3GetNumberOfEventIndicators", c, byref(counts[1]))
    values = exchange_round(b, c, c_bool)
    second_update = b.update(c, label="fmi3UpdateDiscreteStates at t=0.5")
    outputs = b.get(c, "Float64", "x", "v", "t_stick", label="fmi3GetFloat64 at t=0.5")
    b("fmi3Terminate", c)
    b("fmi3FreeInstance", c)
    return {"first_update": first_update, "counts": [n.value for n in counts], **values,
            "second_update": second_update, "outputs": outputs}


def fmi3_log(b, logging_on, debug_logging_calls):
    """Messages of every kind under one logging setting (a model-exchange instance): instantiate with
    ``logging_on``, the fmi3SetDebugLogging calls ``debug_logging_calls``; messages from the slave of every
    status, an unsupported call of pythonfmu3 and one of the binary, fmi3Reset and a mass out of range (the
    derivatives and fmi3ExitInitializationMode fail)."""
    before = slaves()
    c = b.instantiate("ModelExchange", logging_on)
    logging_setting(b, c, debug_logging_calls)
    b.initialize(c)
    queued = log_from_the_slave(b, c, before)
    seed, out = (c_double * 1)(1.0), (c_double * 2)()
    b("fmi3GetDirectionalDerivative", c, b.vrs("x"), 1, b.vrs("v_drive"), 1, seed, 1, out, 1)
    b("fmi3GetFloat32", c, b.vrs(), 0, (ctypes.c_float * 1)(), 0)
    b("fmi3Reset", c)
    b("fmi3EnterInitializationMode", c, False, 0.0, 0.0, False, 0.0, label="fmi3EnterInitializationMode after reset")
    b.set_values(c, {"M": -1.0}, label="fmi3SetFloat64 of M = -1 kg")
    b("fmi3GetContinuousStateDerivatives", c, out, 2, label="fmi3GetContinuousStateDerivatives with M = -1 kg")
    b("fmi3ExitInitializationMode", c, label="fmi3ExitInitializationMode with M = -1 kg")
    b("fmi3FreeInstance", c)
    return {"queued": queued}


FMI3_CASES = {"version": fmi3_version, "cs_stuck_step": stuck_step, "reset": reset, "fmu_state": fmu_state,
              "other_types": lambda b: other_types(b, FMI3_OTHER_TYPES),
              "refused": fmi3_refused, "modes": fmi3_modes, "cs_exchange_calls": fmi3_cs_exchange_calls,
              "event_mode": fmi3_event_mode,
              "model_exchange": fmi3_model_exchange, "log": fmi3_log}

if __name__ == "__main__":
    version, folder, *case_names = sys.argv[1:]
    binary, cases = (Fmi2(folder), FMI2_CASES) if version == "2" else (Fmi3(folder), FMI3_CASES)
    run(binary, cases, case_names or list(cases))
