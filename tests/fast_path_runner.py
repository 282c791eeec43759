"""Child process of ``tests/test_fast_path.py``: one scripted co-simulation session of an FMU through FMPy, as a
host makes it, printed as one JSON object.

Run as ``python fast_path_runner.py FMU_PATH SCENE`` with or without ``SBF_FAST_PATH=0`` in the environment (the
loader's fast path off or on). The session of a scene of :data:`SCENES`: parameters set, initialization, steps that
read every output (real and integer) after each, an input change, an FMU state saved and restored, a read that mixes
a parameter and outputs, a refused step (a gap), a reset and a second run. Printed: every value read (``float.hex``,
exact), every status, the log messages, and how many steps reached the slave's ``do_step`` (PythonFMU's path) and
how many step calls the slave gave the loader (``fast_step_call``).

The scene ``force-wave`` is a session that sets ``F_ext`` and its rate before every step, as a master sets a
coupling force (:func:`force_wave_session`): cells of a force wave (FMI 2: ``fmi2SetReal`` and
``fmi2SetRealInputDerivatives``; FMI 3: ``F_ext`` and ``der(F_ext)`` in one ``fmi3SetFloat64``), each followed by
``doStep`` and reads; reads of the inputs and outputs between a set and its step; an FMU state got between a set and
its step, the cells after it run twice (the state set again in between, after a set it must undo); values the slave
refuses (NaN, beyond the force scale), each followed by a cell; a set of ``v_drive`` and ``F_ext`` together.
Printed: the values read, each cell's force and rate set and the outputs at its end, every status and log message,
and how often the slave's setters and ``step_kept`` (the loader's step with the inputs it kept) were called.
"""

import json
import math
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
# force-wave: the default laws, coulomb and constant, the static a little above the kinetic: the wave of F_ext makes
# the block stick and slip
WAVE_START = {"M": 1.0, "kappa": 1.0, "kinetic.F0": 0.5, "static.F0": 0.6, "v_drive": 0.1, "x_start": 0.0,
              "v_start": 0.1}
AMPLITUDE = 0.5  # N: F_ext = AMPLITUDE sin(t) with its rate AMPLITUDE cos(t) at each cell's start
SETTERS = ("set_real", "set_real_input_derivatives", "set_float64", "step_kept")  # counted in force-wave


class Session:
    """The instance, its value references by name, and the record of the session."""

    def __init__(self, extracted, counted=("do_step", "fast_step_call")):
        self.extracted = extracted
        self.v2 = extracted.fmi_version == 2
        self.refs = {name: v.valueReference for name, v in extracted.variables.items()}
        outputs = [v for v in extracted.variables.values() if v.causality == "output"]
        self.reals = [v.valueReference for v in outputs if v.type in ("Real", "Float64")]
        self.integers = [v.valueReference for v in outputs if v.type in ("Integer", "Int32")]
        self.record = {"values": [], "statuses": [], "messages": []}
        self.inst = extracted.new_instance()
        self.fmu = self.inst.fmu
        self.counts = _count_slave_calls(counted)

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


def _count_slave_calls(names):
    """Wrap the loaded slave class's methods ``names`` (those it has) to count calls; {name: count}."""
    counts = dict.fromkeys(names, 0)
    slaves = [m.SpringBlockFriction for name, m in list(sys.modules.items())
              if name.endswith(".fmu_slave") and hasattr(m, "SpringBlockFriction")]
    for cls in slaves:
        for name in counts:
            method = getattr(cls, name, None)
            if method is None:
                continue

            def counted(self, *args, _method=method, _name=name):
                counts[_name] += 1
                return _method(self, *args)
            setattr(cls, name, counted)
    return counts


class WaveSession(Session):
    """A session of scene force-wave: the statuses by label, the cells' record."""

    def __init__(self, extracted):
        super().__init__(extracted, SETTERS)
        self.names = [name for name, v in extracted.variables.items()
                      if v.causality == "output" and v.type in ("Real", "Float64")]
        self.record["cells"] = []

    def call(self, label, function, *args):
        """``function(*args)`` through the instance; its status name ("OK" or the failure) recorded under ``label``."""
        try:
            self.inst.call(function, *args)
            self.record["statuses"].append(f"{label} OK")
        except FmuCallError as error:
            self.record["statuses"].append(f"{label} {error.function} {error.status}")
            self.record["messages"].extend(error.messages)

    def set_reals(self, label, values):
        """The real inputs ``{name: value}`` set in one call."""
        refs, numbers = [self.refs[name] for name in values], list(values.values())
        self.call(label, self.fmu.setReal if self.v2 else self.fmu.setFloat64, refs, numbers)

    def set_force(self, label, force, rate):
        """``F_ext`` and its rate (N, N/s) set as a master sets them before a cell."""
        if self.v2:
            self.set_reals(label, {"F_ext": force})
            self.call(label, self.fmu.setRealInputDerivatives, [self.refs["F_ext"]], [1], [rate])
        else:
            self.set_reals(label, {"F_ext": force, "der(F_ext)": rate})

    def read_names(self, label, names=None):
        """The real variables ``names`` (default every real output) read and recorded: {name: value}."""
        names = self.names if names is None else names
        values = (self.fmu.getReal if self.v2 else self.fmu.getFloat64)([self.refs[name] for name in names])
        self.record["values"].append([label, [float(x).hex() for x in values]])
        return dict(zip(names, values))

    def cells(self, t, n, label):
        """``n`` cells of the force wave from ``t`` (s); each cell's force and rate recorded with its end."""
        for _ in range(n):
            force, rate = AMPLITUDE * math.sin(t), AMPLITUDE * math.cos(t)
            self.set_force(label, force, rate)
            self.call(label, self.fmu.doStep, t, H)
            t += H
            outputs = self.read_names(f"{label} {t!r}", ["x", "F_friction", "z_slip"])
            mode = (self.fmu.getInteger if self.v2 else self.fmu.getInt32)([self.refs["mode"]])[0]
            self.record["cells"].append([label, force, rate, outputs["x"], outputs["F_friction"], mode])
        return t


def force_wave_session(fmu_path):
    """The record of scene force-wave (see the module text)."""
    with ExtractedFMU(fmu_path) as extracted:
        s = WaveSession(extracted)
        s.initialize(WAVE_START)
        t = s.cells(0.0, 100, "wave")
        inputs = ["F_ext"] if s.v2 else ["F_ext", "der(F_ext)"]
        s.set_force("read between", 0.25, -0.5)
        s.read_names("inputs between", inputs)
        s.read_names("outputs between")
        t = s.cells(t, 10, "after the read")
        s.set_force("state between", 0.2, 0.1)
        state = s.fmu.getFMUState()
        for label in ("saved", "restored"):  # the first step under the force set before the state was got
            s.call(label, s.fmu.doStep, t, H)
            s.read_names(f"{label} {t + H!r}", ["x", "F_friction", "z_slip", "F_spring"])
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
        s.read_names("inputs after the refused rate", inputs)
        s.call("rate beyond", s.fmu.doStep, t, H)
        s.set_reals("drive and force", {"v_drive": 0.05, "F_ext": 0.1})
        s.cells(t + H, 20, "after the drive")
        s.inst.free()
        return {**s.record, "counts": s.counts}


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
        scene = sys.argv[2]
        print(json.dumps(force_wave_session(sys.argv[1]) if scene == "force-wave" else session(sys.argv[1], scene)))
    except FMICallException as error:  # an unexpected failure: the parent shows it
        print(json.dumps({"failed": str(error)}))
