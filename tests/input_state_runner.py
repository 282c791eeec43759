"""Child process of tests/test_input_state.py: inputs, FMU states and the FMU's time through the real FMU.

``python input_state_runner.py FMU`` (FMI 2 or FMI 3 co-simulation, FMPy's classes on the extracted FMU) prints one
JSON record of four parts:

- ``restore``: per input (F_ext, v_drive; FMI 2 also der(F_ext) through fmi2SetRealInputDerivatives), a block at rest
  on a still surface (Coulomb F_K = 0.5 N, F_S = 1 N, M = kappa = 1) stepped to 1 s; the input set to its value,
  the FMU state got, the input set to another value, the state restored, the input's value read, then 0.1 s steps
  to 6 s: ``[t, x, v]`` after each; and the same run without the change and the restore.
- ``refused``: per bad value set after initialization (a stuck block carried at 0.1 m/s), the call's status and
  messages, the inputs read after it, and ``x``, ``mode`` after stepping on to 5 s.
- ``time`` (FMI 2): fmi2LastSuccessfulTime after restoring a state saved at 5 s, after a reset and a new
  initialization at 2 s, and after a refused step that stopped part of the way (then whether a step from there is
  taken and one from the refused step's start is not).
- ``failed_step_time`` (FMI 3): fmi3DoStep's lastSuccessfulTime after such a refused step, and whether a step from
  there is taken.

A status is 0 for a call that succeeded, else the FMI status of the FmuCallError.
"""

import json
import math
import sys
from ctypes import byref, c_bool, c_double

from fmpy.fmi2 import fmi2LastSuccessfulTime

from stickslip.hosts.fmpy_host import ExtractedFMU, FmuCallError

COULOMB_AT_REST = {"kinetic.law": 1, "kinetic.F0": 0.5, "static.F0": 1.0, "v_drive": 0.0, "v_start": 0.0}
CARRIED = {"kinetic.law": 1, "kinetic.F0": 0.5, "static.F0": 1.0, "v_drive": 0.1, "v_start": 0.1}
#: input: (the value saved with the state, the value it is changed to before the restore)
#: stick-slip for ever (the carried block breaks away at 10 s): a step to 1e16 s stops after 1000 segments
STICK_SLIP = CARRIED
RESTORED = {"F_ext": (1.5, 0.0), "v_drive": (0.1, 0.0), "der(F_ext)": (0.25, 0.0)}


class Session:
    """One co-simulation instance of the FMU through FMPy, its calls by FMI version."""

    def __init__(self, extracted, start):
        self.extracted, self.version = extracted, extracted.fmi_version
        self.refs = {name: v.valueReference for name, v in extracted.variables.items()}
        self.instance = extracted.new_instance(logging_on=False)
        self.fmu = self.instance.fmu
        self.initialize(start)

    def initialize(self, start, start_time=0.0):
        if self.version == 2:
            self.call(self.fmu.setupExperiment, startTime=start_time)
        self.call(self.fmu.enterInitializationMode, **({} if self.version == 2 else {"startTime": start_time}))
        self.set(start)
        self.call(self.fmu.exitInitializationMode)

    def call(self, function, *args, **kwargs):
        return self.instance.call(function, *args, **kwargs)

    def attempt(self, function, *args):
        """``[status, messages]`` of a call (status 0 if it succeeded)."""
        first = len(self.instance.messages())
        try:
            self.call(function, *args)
            status = 0
        except FmuCallError as error:
            status = error.status
        return [status, self.instance.messages()[first:]]

    def setter(self, name):
        if self.version == 3:
            return self.fmu.setInt32 if name.endswith(".law") else self.fmu.setFloat64
        return self.fmu.setInteger if name.endswith(".law") else self.fmu.setReal

    def set(self, values):
        """Set ``{name: value}``, one call per variable (der(F_ext): fmi2SetRealInputDerivatives)."""
        for name, value in values.items():
            if name == "der(F_ext)":
                self.call(self.fmu.setRealInputDerivatives, [self.refs["F_ext"]], [1], [value])
            else:
                self.call(self.setter(name), [self.refs[name]], [value])

    def get(self, *names):
        getter = self.fmu.getReal if self.version == 2 else self.fmu.getFloat64
        return list(self.call(getter, [self.refs[name] for name in names]))

    def step(self, t, h):
        return self.call(self.fmu.doStep, t, h)

    def steps(self, t0, t1, h=0.1):
        """0.1 s steps from ``t0`` to ``t1``: ``[t, x, v]`` after each."""
        out = []
        for k in range(round((t1 - t0) / h)):
            t = t0 + k * h
            self.step(t, h)
            out.append([t + h, *self.get("x", "v")])
        return out

    def free(self):
        self.instance.free()


def restore_case(extracted, name):
    """The input ``name`` saved with the state and changed before its restore, then the run; and the run
    without the change and the restore."""
    saved, other = RESTORED[name]
    runs = {}
    for label in ("restored", "unchanged"):
        session = Session(extracted, COULOMB_AT_REST)
        session.step(0.0, 1.0)
        session.set({name: saved})
        if label == "restored":
            state = session.call(session.fmu.getFMUstate if session.version == 2 else session.fmu.getFMUState)
            session.set({name: other})
            session.call(session.fmu.setFMUstate if session.version == 2 else session.fmu.setFMUState, state)
            runs["reported"] = None if name == "der(F_ext)" else session.get(name)[0]
        runs[label] = session.steps(1.0, 6.0)
        session.free()
    return runs


def refused_cases(extracted):
    """Each bad value set after initialization: its status, messages, the inputs after it, x and mode at 5 s."""
    ref = extracted.variables
    bad = [("F_ext", math.nan), ("F_ext", math.inf), ("F_ext", 1e151), ("v_drive", math.nan),
           ("v_drive", -math.inf), ("v_drive", 1e151)]
    cases = {f"{name} = {value!r}": ("set", [name], [value]) for name, value in bad}
    cases["F_ext = 0.3 with v_drive = nan"] = ("set", ["F_ext", "v_drive"], [0.3, math.nan])
    if extracted.fmi_version == 2:
        cases.update({f"der(F_ext) = {value!r}": ("derivatives", ["F_ext"], [1], [value]) for value in (1e151, 1e300)})
        cases["der(F_ext) = 1.0 with der(x)"] = ("derivatives", ["F_ext", "x"], [1, 1], [1.0, 0.0])
    out = {}
    for label, (kind, names, *arguments) in cases.items():
        session = Session(extracted, CARRIED)
        session.step(0.0, 0.5)
        references = [ref[name].valueReference for name in names]
        if kind == "set":
            call = session.attempt(session.setter(names[0]), references, *arguments)
        else:
            call = session.attempt(session.fmu.setRealInputDerivatives, references, *arguments)
        inputs = session.get("v_drive", "F_ext")
        session.step(0.5, 4.5)
        out[label] = {"call": call, "inputs": inputs, "x": session.get("x")[0],
                      "mode": session.call(session.fmu.getInteger if session.version == 2 else session.fmu.getInt32,
                                           [session.refs["mode"]])[0]}
        session.free()
    return out


def failed_step(session):
    """A step from 0.001 s by 1e16 s, beyond the time resolution: refused after it went part of the way."""
    session.step(0.0, 0.001)
    return session.attempt(session.fmu.doStep, 0.001, 1e16)


def time_cases(extracted):
    """fmi2LastSuccessfulTime where it used to go stale (see the module docstring)."""
    last = lambda s: s.call(s.fmu.getRealStatus, fmi2LastSuccessfulTime)  # noqa: E731
    out = {}
    session = Session(extracted, CARRIED)
    for k in range(10):
        session.step(k * 0.5, 0.5)
        if k == 9:
            break
        if k == 8:
            state = session.call(session.fmu.getFMUstate)
    out["before restore"] = last(session)
    session.call(session.fmu.setFMUstate, state)
    out["restored at 4.5"] = last(session)
    session.call(session.fmu.reset)
    session.initialize(CARRIED, start_time=2.0)
    out["reset, initialized at 2"] = last(session)
    session.step(2.0, 0.5)
    out["stepped to 2.5"] = last(session)
    session.free()
    session = Session(extracted, STICK_SLIP)
    out["refused step"] = failed_step(session)
    out["after the refused step"] = reached = last(session)
    out["step from there"] = session.attempt(session.fmu.doStep, reached, 0.1)
    out["step from 0.001"] = session.attempt(session.fmu.doStep, 0.001, 0.1)
    session.free()
    return out


def failed_step_time(extracted):
    """fmi3DoStep's lastSuccessfulTime after a refused step that went part of the way, and a step from there."""
    session = Session(extracted, STICK_SLIP)
    session.step(0.0, 0.001)
    flags, last = [c_bool() for _ in range(3)], c_double(-1.0)
    call = session.attempt(session.fmu.fmi3DoStep, session.fmu.component, 0.001, 1e16, True, *map(byref, flags),
                           byref(last))
    out = {"refused step": call, "reached": last.value,
           "step from there": session.attempt(session.fmu.doStep, last.value, 0.1)}
    session.free()
    return out


def main(path):
    with ExtractedFMU(path) as extracted:
        names = ["F_ext", "v_drive"] + (["der(F_ext)"] if extracted.fmi_version == 2 else [])
        record = {"restore": {name: restore_case(extracted, name) for name in names},
                  "refused": refused_cases(extracted)}
        if extracted.fmi_version == 2:
            record["time"] = time_cases(extracted)
        else:
            record["failed_step_time"] = failed_step_time(extracted)
    print(json.dumps(record))


if __name__ == "__main__":
    main(sys.argv[1])
