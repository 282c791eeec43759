"""Child process of ``tests/test_fast_path.py``: one scripted co-simulation session of an FMU through FMPy, as a
host makes it, printed as one JSON object.

Run as ``python fast_path_runner.py FMU_PATH SCENE`` with or without ``SBF_FAST_PATH=0`` in the environment (the
loader's fast path off or on). The session: parameters set, initialization, steps that read every output (real
and integer) after each, an input change, an FMU state saved and restored, a read that mixes a parameter and
outputs, a refused step (a gap), a reset and a second run. Printed: every value read (``float.hex``, exact), every
status, the log messages, and how many steps reached the slave's ``do_step`` (PythonFMU's path) and how many
step calls the slave gave the loader (``fast_step_call``).
"""

import json
import sys

from fmpy.fmi1 import FMICallException

from stickslip.hosts.fmpy_host import ExtractedFMU, FmuCallError

#: SCENE: start values (FMU names); the first has every law of the numeric path (Stribeck kinetic, aging static)
SCENES = {
    "stribeck-aging": {"M": 1.0, "kappa": 1.0, "kinetic.law": 3, "kinetic.F0": 0.4, "kinetic.gamma": 0.1,
                       "kinetic.F_stribeck": 0.3, "kinetic.v_stribeck": 0.1, "static.law": 2, "static.F0": 0.8,
                       "static.A": 0.1, "static.tau": 1.0, "v_drive": 0.1, "x_start": 0.0, "v_start": 0.1},
    "coulomb": {"M": 1.0, "kappa": 1.0, "kinetic.law": 1, "kinetic.F0": 0.5, "static.law": 1, "static.F0": 1.0,
                "v_drive": 0.1, "x_start": 0.0, "v_start": 0.1},
}
H = 0.05  # communication step, s


class Session:
    """The instance, its value references by name, and the record of the session."""

    def __init__(self, extracted):
        self.extracted = extracted
        self.v2 = extracted.fmi_version == 2
        self.refs = {name: v.valueReference for name, v in extracted.variables.items()}
        outputs = [v for v in extracted.variables.values() if v.causality == "output"]
        self.reals = [v.valueReference for v in outputs if v.type in ("Real", "Float64")]
        self.integers = [v.valueReference for v in outputs if v.type in ("Integer", "Int32")]
        self.record = {"values": [], "statuses": [], "messages": []}
        self.inst = extracted.new_instance()
        self.fmu = self.inst.fmu
        self.counts = _count_slave_calls()

    def set(self, values):
        for name, value in values.items():
            if isinstance(value, int):
                (self.fmu.setInteger if self.v2 else self.fmu.setInt64)([self.refs[name]], [value])  # law codes
            else:
                (self.fmu.setReal if self.v2 else self.fmu.setFloat64)([self.refs[name]], [value])

    def initialize(self, start):
        """Start values set, initialization at t = 0 s."""
        self.set(start)
        if self.v2:
            self.fmu.setupExperiment(startTime=0.0)
            self.fmu.enterInitializationMode()
        else:
            self.fmu.enterInitializationMode(startTime=0.0)
        self.fmu.exitInitializationMode()

    def read(self, label, refs=None):
        get_real = self.fmu.getReal if self.v2 else self.fmu.getFloat64
        get_int = self.fmu.getInteger if self.v2 else self.fmu.getInt32
        reals = get_real(self.reals if refs is None else refs)
        integers = get_int(self.integers) if refs is None else []
        self.record["values"].append([label, [float(x).hex() for x in reals], [int(i) for i in integers]])

    def step(self, t, h):
        """doStep from t by h; the status name ("OK" or the failure) is recorded."""
        try:
            self.inst.call(self.fmu.doStep, t, h)
            self.record["statuses"].append("OK")
        except FmuCallError as error:
            self.record["statuses"].append(f"{error.function} {error.status}")
            self.record["messages"].extend(error.messages)

    def run(self, start, t, n, label):
        self.set(start)
        for _ in range(n):
            self.step(t, H)
            t += H
            self.read(f"{label} {t!r}")
        return t


def _count_slave_calls():
    """Wrap the loaded slave class's ``do_step`` and ``fast_step_call`` to count calls; {name: count}."""
    counts = {"do_step": 0, "fast_step_call": 0}
    slaves = [m.SpringBlockFriction for name, m in list(sys.modules.items())
              if name.endswith(".fmu_slave") and hasattr(m, "SpringBlockFriction")]
    for cls in slaves:
        for name in counts:
            method = getattr(cls, name)

            def counted(self, *args, _method=method, _name=name):
                counts[_name] += 1
                return _method(self, *args)
            setattr(cls, name, counted)
    return counts


def session(fmu_path, scene):
    """The record of the scripted session (see the module text)."""
    start = SCENES[scene]
    with ExtractedFMU(fmu_path) as extracted:
        s = Session(extracted)
        s.initialize(start)
        s.read("initial")
        t = s.run({}, 0.0, 200, "first")
        t = s.run({"F_ext": 0.3}, t, 100, "input")  # an input change between steps
        state, saved_at = s.fmu.getFMUState(), t
        t = s.run({}, t, 50, "before restore")
        s.fmu.setFMUState(state)
        s.fmu.freeFMUState(state)
        t = s.run({}, saved_at, 50, "after restore")
        s.read("mixed", [s.refs["M"], s.refs["x"], s.refs["kappa"], s.refs["v"]])
        s.step(t + 1.0, H)  # a gap between communication points: refused
        s.read("after the refused step")
        t = s.run({}, t, 20, "after the gap")
        s.fmu.reset()
        s.initialize(start)
        s.run({}, 0.0, 50, "after reset")
        s.inst.free()
        return {**s.record, "counts": s.counts}


if __name__ == "__main__":
    try:
        print(json.dumps(session(sys.argv[1], sys.argv[2])))
    except FMICallException as error:  # an unexpected failure: the parent shows it
        print(json.dumps({"failed": str(error)}))
