"""Child process of ``tests/test_kept_inputs.py``: a co-simulation session of an FMU through FMPy that sets ``F_ext``
and its rate before every step, as a master sets a coupling force, printed as one JSON object.

Run as ``python kept_inputs_runner.py FMU_PATH`` with or without ``SBF_FAST_PATH=0`` in the environment (the loader
keeps the inputs until the next step, or every set goes to the slave as it comes). The session: cells of a force
wave (FMI 2: ``fmi2SetReal`` and ``fmi2SetRealInputDerivatives``; FMI 3: ``F_ext`` and ``der(F_ext)`` in one
``fmi3SetFloat64``), each followed by ``doStep`` and a read of every output; reads of the inputs and outputs
between a set and its step; an FMU state got between a set and its step, the cells after it run twice (the state set
again in between, after a set it must undo); values the slave refuses (NaN, beyond the force scale), each followed by
a cell; a set of ``v_drive`` and ``F_ext`` together. Printed: every value read (``float.hex``), each cell's force at
its force and rate set and the outputs at its end, every status and log message, and how often the slave's setters and ``step_kept``
were called.
"""

import json
import math
import sys

from fmpy.fmi1 import FMICallException

from stickslip.hosts.fmpy_host import ExtractedFMU, FmuCallError

# the default laws, coulomb and constant, the static a little above the kinetic: the wave of F_ext makes the block
# stick and slip
START = {"M": 1.0, "kappa": 1.0, "kinetic.F0": 0.5, "static.F0": 0.6, "v_drive": 0.1, "x_start": 0.0, "v_start": 0.1}
H = 0.05  # communication step, s
AMPLITUDE = 0.5  # N: F_ext = AMPLITUDE sin(t) with its rate AMPLITUDE cos(t) at each cell's start
COUNTED = ("set_real", "set_real_input_derivatives", "set_float64", "step_kept")


class Session:
    """The instance, its value references by name, and the record of the session."""

    def __init__(self, extracted):
        self.v2 = extracted.fmi_version == 2
        self.refs = {name: v.valueReference for name, v in extracted.variables.items()}
        outputs = [v for v in extracted.variables.values() if v.causality == "output"]
        self.names = [v.name for v in outputs if v.type in ("Real", "Float64")]
        self.reals = [self.refs[name] for name in self.names]
        self.record = {"values": [], "cells": [], "statuses": [], "messages": []}
        self.inst = extracted.new_instance()
        self.fmu = self.inst.fmu
        self.counts = _count_slave_calls()

    def call(self, label, function, *args):
        """``function(*args)`` through the instance; its status name ("OK" or the failure) recorded under ``label``."""
        try:
            self.inst.call(function, *args)
            self.record["statuses"].append(f"{label} OK")
        except FmuCallError as error:
            self.record["statuses"].append(f"{label} {error.function} {error.status}")
            self.record["messages"].extend(error.messages)

    def set_reals(self, label, values):
        """The real inputs or parameters ``{name: value}`` set in one call."""
        refs, numbers = [self.refs[name] for name in values], list(values.values())
        self.call(label, self.fmu.setReal if self.v2 else self.fmu.setFloat64, refs, numbers)

    def set_force(self, label, force, rate):
        """``F_ext`` and its rate (N, N/s) set as a master sets them before a cell."""
        if self.v2:
            self.set_reals(label, {"F_ext": force})
            self.call(label, self.fmu.setRealInputDerivatives, [self.refs["F_ext"]], [1], [rate])
        else:
            self.set_reals(label, {"F_ext": force, "der(F_ext)": rate})

    def read(self, label, names=None):
        names = self.names if names is None else names
        values = (self.fmu.getReal if self.v2 else self.fmu.getFloat64)([self.refs[name] for name in names])
        self.record["values"].append([label, [float(x).hex() for x in values]])
        return dict(zip(names, values))

    def cells(self, t, n, label):
        """``n`` cells of the force wave from ``t`` (s); each cell's end recorded with the force there."""
        for _ in range(n):
            force, rate = AMPLITUDE * math.sin(t), AMPLITUDE * math.cos(t)
            self.set_force(label, force, rate)
            self.call(label, self.fmu.doStep, t, H)
            t += H
            outputs = self.read(f"{label} {t!r}", ["x", "F_friction", "z_slip"])
            mode = (self.fmu.getInteger if self.v2 else self.fmu.getInt32)([self.refs["mode"]])[0]
            self.record["cells"].append([label, force, rate, outputs["x"], outputs["F_friction"], mode])
        return t


def _count_slave_calls():
    """Wrap the loaded slave class's setters and ``step_kept`` to count calls; {name: count}."""
    counts = dict.fromkeys(COUNTED, 0)
    slaves = [m.SpringBlockFriction for name, m in list(sys.modules.items())
              if name.endswith(".fmu_slave") and hasattr(m, "SpringBlockFriction")]
    for cls in slaves:
        for name in COUNTED:
            method = getattr(cls, name, None)
            if method is None:
                continue

            def counted(self, *args, _method=method, _name=name):
                counts[_name] += 1
                return _method(self, *args)
            setattr(cls, name, counted)
    return counts


def session(fmu_path):
    """The record of the session (see the module text)."""
    with ExtractedFMU(fmu_path) as extracted:
        s = Session(extracted)
        s.set_reals("start", START)
        if s.v2:
            s.fmu.setupExperiment(startTime=0.0)
            s.fmu.enterInitializationMode()
        else:
            s.fmu.enterInitializationMode(startTime=0.0)
        s.fmu.exitInitializationMode()
        t = s.cells(0.0, 100, "wave")
        s.set_force("read between", 0.25, -0.5)
        s.read("inputs between", ["F_ext"] if s.v2 else ["F_ext", "der(F_ext)"])
        s.read("outputs between")
        t = s.cells(t, 10, "after the read")
        s.set_force("state between", 0.2, 0.1)
        state = s.fmu.getFMUState()
        for label in ("saved", "restored"):  # the first step under the force set before the state was got
            s.call(label, s.fmu.doStep, t, H)
            s.read(f"{label} {t + H!r}", ["x", "F_friction", "z_slip", "F_spring"])
            end = s.cells(t + H, 20, label)
            if label == "saved":
                s.set_force("set before the restore", 0.9, 0.0)  # undone by the state
                s.fmu.setFMUState(state)
        s.fmu.freeFMUState(state)
        t = end
        for label, force in (("NaN", math.nan), ("beyond the force scale", 2e150)):
            s.set_reals(label, {"F_ext": force})
            t = s.cells(t, 1, f"after {label}")
        if s.v2:
            s.call("rate beyond", s.fmu.setRealInputDerivatives, [s.refs["F_ext"]], [1], [1e200])
        else:
            s.set_reals("rate beyond", {"F_ext": 0.1, "der(F_ext)": math.inf})  # all or nothing: F_ext kept too
        s.read("inputs after the refused rate", ["F_ext"] if s.v2 else ["F_ext", "der(F_ext)"])
        s.call("rate beyond", s.fmu.doStep, t, H)
        t += H
        s.set_reals("drive and force", {"v_drive": 0.05, "F_ext": 0.1})
        s.cells(t, 20, "after the drive")
        s.inst.free()
        return {**s.record, "counts": s.counts}


if __name__ == "__main__":
    try:
        print(json.dumps(session(sys.argv[1])))
    except FMICallException as error:  # an unexpected failure: the parent shows it
        print(json.dumps({"failed": str(error)}))
