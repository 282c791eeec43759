"""A plain ctypes host of an extracted FMU's Linux binary, run as a child process by the loader's robustness tests.

    python loader_probe.py FOLDER < CASE

FOLDER is the extracted FMU; CASE is Python code run with the names below. Each :func:`say` prints one JSON line
at once, so a case that crashes or hangs still shows how far it got; every message the FMU logs is printed as
``["log", status, category, message]`` (category ``null`` if the FMU passed NULL).

- ``fmi`` (2 or 3), ``guid`` (GUID or instantiation token), ``uri`` (FMI 2: the resources folder as a file URI),
  ``path`` (FMI 3: the resources folder as a path with a trailing slash), ``vr`` ({variable name: value
  reference}), ``folder``;
- ``call(function, *arguments)``: the FMI function ``function`` of the binary (arguments converted by the
  types below), its return value; ``STATE``: the names of the FMU state functions by role ("get", "set",
  "free", "size", "serialize", "deserialize");
- ``instantiate(resources=uri or path, token=guid, name=b"probe", interface="cs", logging=False)``: the
  instance (interface "cs", "me" or an FMI 2 fmuType number), or None;
- ``start(c, **values)``: set up (start time 0) and enter initialization mode, set the Real ``values``;
- ``initialized(c, **values)``: :func:`start`, then exit initialization mode; returns that status;
- ``put(c, **values)``: the status of setting the Real (FMI 3: Float64) ``values`` in one call;
- ``get(c, name)``: (status, value) of a Real (FMI 3: Float64) variable;
- ``step(c, t, h)``: the status of one communication step from ``t`` by ``h`` s;
- ``serialized(c)``: the bytes of the current state.
"""

import ctypes
import json
import sys
import xml.etree.ElementTree as ET
from ctypes import POINTER, byref, c_bool, c_char_p, c_double, c_int, c_size_t, c_uint, c_void_p
from pathlib import Path

from fmpy.logging import addLoggerProxy


def say(*words):
    print(json.dumps(words), flush=True)


folder = Path(sys.argv[1]).resolve()
_root = ET.parse(folder / "modelDescription.xml").getroot()
fmi = int(_root.get("fmiVersion")[0])
guid = _root.get("guid" if fmi == 2 else "instantiationToken").encode()
vr = {v.get("name"): int(v.get("valueReference")) for v in _root.iter() if v.get("valueReference") is not None}
uri = (folder / "resources").as_uri().encode()
path = f"{folder / 'resources'}/".encode()
_identifier = next(_root.iter("CoSimulation")).get("modelIdentifier")
_binary = folder / "binaries" / ("linux64" if fmi == 2 else "x86_64-linux") / f"{_identifier}.so"
_lib = ctypes.CDLL(str(_binary))

if fmi == 2:
    _LOGGER = ctypes.CFUNCTYPE(None, c_void_p, c_char_p, c_int, c_char_p, c_char_p)

    class _Callbacks(ctypes.Structure):
        _fields_ = [("logger", _LOGGER), ("allocateMemory", c_void_p), ("freeMemory", c_void_p),
                    ("stepFinished", c_void_p), ("componentEnvironment", c_void_p)]

    _log = _LOGGER(lambda _env, _name, status, category, message: say(
        "log", status, None if category is None else category.decode(), message.decode(errors="replace")))
    _callbacks = _Callbacks(_log, None, None, None, None)
    addLoggerProxy(byref(_callbacks))  # FMPy's native logger formats the message (a C format with arguments)
    _REALS = (c_void_p, POINTER(c_uint), c_size_t, POINTER(c_double))
    _TYPES = {
        "fmi2Instantiate": (c_void_p, (c_char_p, c_int, c_char_p, c_char_p, c_void_p, c_int, c_int)),
        "fmi2SetupExperiment": (c_int, (c_void_p, c_int, c_double, c_double, c_int, c_double)),
        "fmi2DoStep": (c_int, (c_void_p, c_double, c_double, c_int)),
        "fmi2GetReal": (c_int, _REALS), "fmi2SetReal": (c_int, _REALS),
        **dict.fromkeys(("fmi2SetRealInputDerivatives", "fmi2GetRealOutputDerivatives"),
                        (c_int, (c_void_p, POINTER(c_uint), c_size_t, POINTER(c_int), POINTER(c_double)))),
        "fmi2FreeInstance": (None, (c_void_p,)),
    }
else:
    _LOGGER = ctypes.CFUNCTYPE(None, c_void_p, c_int, c_char_p, c_char_p)
    _log = _LOGGER(lambda _env, status, category, message: say(
        "log", status, None if category is None else category.decode(), message.decode(errors="replace")))
    _REALS = (c_void_p, POINTER(c_uint), c_size_t, POINTER(c_double), c_size_t)
    _TYPES = {
        "fmi3InstantiateCoSimulation": (c_void_p, (c_char_p, c_char_p, c_char_p, c_bool, c_bool, c_bool, c_bool,
                                                   c_void_p, c_size_t, c_void_p, _LOGGER, c_void_p)),
        "fmi3InstantiateModelExchange": (c_void_p, (c_char_p, c_char_p, c_char_p, c_bool, c_bool, c_void_p,
                                                    _LOGGER)),
        "fmi3EnterInitializationMode": (c_int, (c_void_p, c_bool, c_double, c_double, c_bool, c_double)),
        "fmi3DoStep": (c_int, (c_void_p, c_double, c_double, c_bool, POINTER(c_bool), POINTER(c_bool),
                               POINTER(c_bool), POINTER(c_double))),
        "fmi3GetFloat64": (c_int, _REALS), "fmi3SetFloat64": (c_int, _REALS),
        "fmi3FreeInstance": (None, (c_void_p,)),
    }


_STATE_NAMES = {2: ("GetFMUstate", "SetFMUstate", "FreeFMUstate", "SerializedFMUstateSize", "SerializeFMUstate",
                    "DeSerializeFMUstate"),
                3: ("GetFMUState", "SetFMUState", "FreeFMUState", "SerializedFMUStateSize", "SerializeFMUState",
                    "DeserializeFMUState")}
#: The FMU state functions of this FMI version, by their role
STATE = {role: f"fmi{fmi}{name}"
         for role, name in zip(("get", "set", "free", "size", "serialize", "deserialize"), _STATE_NAMES[fmi])}
_TYPES.update(zip(STATE.values(), (
    (c_int, (c_void_p, POINTER(c_void_p))), (c_int, (c_void_p, c_void_p)), (c_int, (c_void_p, POINTER(c_void_p))),
    (c_int, (c_void_p, c_void_p, POINTER(c_size_t))), (c_int, (c_void_p, c_void_p, c_char_p, c_size_t)),
    (c_int, (c_void_p, c_char_p, c_size_t, POINTER(c_void_p))))))


def call(function, *arguments):
    """The FMI function ``function`` called with ``arguments`` (one-argument functions take the instance)."""
    f = getattr(_lib, function)
    f.restype, f.argtypes = _TYPES.get(function, (c_int, (c_void_p,)))
    return f(*arguments)


def instantiate(resources=..., token=guid, name=b"probe", interface="cs", logging=False):
    resources = (uri if fmi == 2 else path) if resources is ... else resources
    if fmi == 2:
        return call("fmi2Instantiate", name, {"me": 0, "cs": 1}.get(interface, interface), token, resources,
                    byref(_callbacks), 0, logging)
    if interface == "me":
        return call("fmi3InstantiateModelExchange", name, token, resources, False, logging, None, _log)
    return call("fmi3InstantiateCoSimulation", name, token, resources, False, logging, False, False, None, 0, None,
                _log, None)


def _vrs(names):
    return (c_uint * len(names))(*(vr[name] for name in names))


def start(c, **values):
    if fmi == 2:
        call("fmi2SetupExperiment", c, 0, 0.0, 0.0, 0, 0.0)
        call("fmi2EnterInitializationMode", c)
    else:
        call("fmi3EnterInitializationMode", c, False, 0.0, 0.0, False, 0.0)
    if values:
        status = put(c, **values)
        assert status == 0, status


def put(c, **values):
    """The status of setting the Real (FMI 3: Float64) ``values`` in one call."""
    numbers = (c_double * len(values))(*values.values())
    return call(f"fmi{fmi}Set{'Real' if fmi == 2 else 'Float64'}", c, _vrs(list(values)), len(values), numbers,
                *(() if fmi == 2 else (len(values),)))


def initialized(c, **values):
    start(c, **values)
    return call(f"fmi{fmi}ExitInitializationMode", c)


def get(c, name):
    value = c_double()
    status = call(f"fmi{fmi}Get{'Real' if fmi == 2 else 'Float64'}", c, _vrs([name]), 1, byref(value),
                  *(() if fmi == 2 else (1,)))
    return status, value.value


def step(c, t, h):
    if fmi == 2:
        return call("fmi2DoStep", c, t, h, 1)
    flags, last = [c_bool() for _ in range(3)], c_double()
    return call("fmi3DoStep", c, t, h, True, *(byref(flag) for flag in flags), byref(last))


def serialized(c):
    state, size = c_void_p(), c_size_t()
    assert call(STATE["get"], c, byref(state)) == 0
    assert call(STATE["size"], c, state, byref(size)) == 0
    data = ctypes.create_string_buffer(size.value)
    assert call(STATE["serialize"], c, state, data, size) == 0
    call(STATE["free"], c, byref(state))
    return data.raw


exec(compile(sys.stdin.read(), "case", "exec"))
say("done")
