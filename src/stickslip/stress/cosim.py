"""The FMU under libcosim (Open Simulation Platform's C++ co-simulation engine, via libcosimpy).

A *system* is a dict (JSON-serializable)::

    {"fmu": "/path/SpringBlockFriction.fmu", "step": 0.25, "steps": 120,
     "instances": {"a": {start values}, "b": {...}},
     "connections": [["a", "F_spring", "b", "F_ext"], ...],      # output -> input, Real
     "overrides": [[k, "a", "v_drive", value], ...],              # set an input before step k
     "record": ["x", "v", "mode", "n_events"]}

:func:`run_libcosim` runs it in this process with libcosim's fixed-step
algorithm and returns ``{"ok", "error", "time", "series": {instance: {var: [...]}}}``
with one sample after every step.
:func:`run_fmpy` runs the same system with FMPy as master, in libcosim's
order (start values; in initialization mode the connected inputs take the
outputs once per instance; then every step: all instances step, the outputs
are recorded, then transferred to the connected inputs), so the two can be
compared value by value. (libcosim's observer records an input as the value
the instance stepped with, before the transfer: a stuck block's ``v`` is
recorded before a new ``v_drive`` reaches it.)

libcosim runs its FMU calls in worker threads and catches their errors only
during steps: an FMU that fails during initialization (for this FMU: an
invalid parameter) makes libcosim call std::terminate. Tests therefore run
libcosim in a child process (:func:`run_in_child`): ``python -m
stickslip.stress.cosim`` reads a list of systems as JSON on stdin, runs them
one after the other in the same process, and prints the results as JSON.
A failed step is an error in the result (libcosim's message carries the FMU's
log message), and the process goes on with the next system.
"""

import ctypes
import gc
import json
import math
import os
import subprocess
import sys

from ..fmu.variables import INTEGER_OUTPUTS
from ..hosts.fmpy_host import FMUError
from .session import FmuSession

RESULT_MARK = "@@cosim-results@@"
#: the file name of libcosim's C library (libcosimc), which libcosimpy loads
LIBCOSIMC = "cosimc.dll" if os.name == "nt" else "libcosimc.so"


def _ns(seconds):
    return int(round(seconds * 1e9))


def libcosim_last_error():
    """libcosim's text of its last error in this thread: libcosimc's public C function ``cosim_last_error_message``
    (cosim.h), called in the libcosimc that libcosimpy has loaded.

    libcosimpy (0.0.6) has no public Python function for that text: it wraps ``cosim_last_error_message`` only
    in its private module ``libcosimpy._internal``. So it is called here through ctypes; ``RTLD_NOLOAD`` finds the
    copy already loaded (the error is kept per library copy) and never loads a second one.
    """
    function = ctypes.CDLL(LIBCOSIMC, mode=getattr(os, "RTLD_NOLOAD", 0)).cosim_last_error_message
    function.restype = ctypes.c_char_p
    return function().decode("utf-8")


def overrides_by_step(system):
    """The system's overrides as ``{step k: [(instance, variable, value), ...]}``."""
    overrides = {}
    for k, name, var, value in system.get("overrides", []):
        overrides.setdefault(int(k), []).append((name, var, value))
    return overrides


def _new_result():
    """A result with no samples yet; ``series`` gets an instance once it is initialized."""
    return {"ok": True, "error": "", "time": [], "series": {}}


class _LibcosimRun:
    """One system in libcosim: the execution at the system's step, its instances (slave index and variables by
    name), an observer of the last values and a manipulator that overrides inputs."""

    def __init__(self, system):
        from libcosimpy.CosimExecution import CosimExecution
        from libcosimpy.CosimManipulator import CosimManipulator
        from libcosimpy.CosimObserver import CosimObserver

        self.system = system
        self.execution = CosimExecution.from_step_size(_ns(system["step"]))
        self.observer = CosimObserver.create_last_value()
        self.manipulator = CosimManipulator.create_override()
        self.slaves, self.index, self.variables = {}, {}, {}

    def add_instance(self, name, start):
        """Add the instance ``name`` with the start values ``start``; RuntimeError with libcosim's message."""
        from libcosimpy.CosimEnums import CosimVariableType
        from libcosimpy.CosimSlave import CosimLocalSlave

        execution = self.execution
        self.slaves[name] = CosimLocalSlave(fmu_path=self.system["fmu"], instance_name=name)
        index = self.index[name] = execution.add_local_slave(self.slaves[name])
        if index < 0:
            raise RuntimeError(f"cannot add instance {name}: {libcosim_last_error()}")
        variables = self.variables[name] = {v.name.decode(): v for v in execution.slave_variables(index)}
        for key, value in start.items():
            v = variables[key]
            if v.type == CosimVariableType.INTEGER.value:
                ok = execution.integer_initial_value(index, v.reference, int(value))
            else:
                ok = execution.real_initial_value(index, v.reference, float(value))
            if not ok:
                raise RuntimeError(f"cannot set {name}.{key}: {libcosim_last_error()}")

    def connect(self, src, out, dst, inp):
        """Connect the Real output ``src.out`` to the input ``dst.inp``; RuntimeError with libcosim's message."""
        status = self.execution.connect_real_variables(self.index[src], self.variables[src][out].reference,
                                                       self.index[dst], self.variables[dst][inp].reference)
        if status != 0:
            raise RuntimeError(f"cannot connect {src}.{out} -> {dst}.{inp}: {libcosim_last_error()}")

    def start_observing(self):
        """Add the observer and the manipulator (after the instances and connections, as libcosim wants)."""
        self.execution.add_observer(self.observer)
        self.execution.add_manipulator(self.manipulator)

    def step(self):
        """One step of every instance (the first one also initializes them); False if it failed."""
        return self.execution.step(1)

    def time(self):
        """The execution's time (s)."""
        return self.execution.status().current_time * 1e-9

    def override(self, name, var, value):
        self.manipulator.slave_real_values(self.index[name], [self.variables[name][var].reference], [float(value)])

    def sample(self, name, record):
        """``{variable: value}`` of the instance ``name``'s variables ``record`` as the observer saw them last."""
        index, variables = self.index[name], self.variables[name]
        reals = [v for v in record if v not in INTEGER_OUTPUTS]
        ints = [v for v in record if v in INTEGER_OUTPUTS]
        values = dict(zip(reals, self.observer.last_real_values(index, [variables[v].reference for v in reals])))
        values.update(zip(ints, self.observer.last_integer_values(index, [variables[v].reference for v in ints])))
        return values

    def close(self):
        """Destroy the execution now rather than at interpreter shutdown: libcosim terminates and frees every
        instance, also one that returned fmi2Fatal, so that the next system starts from a clean engine (the FMU
        balances PythonFMU's release of a failed slave, which makes that free safe)."""
        del self.manipulator, self.observer, self.execution
        self.slaves.clear()
        gc.collect()


def run_libcosim(system):
    """Run ``system`` with libcosim in this process (see the module text)."""
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level

    log_output_level(CosimLogLevel.ERROR)
    result = _new_result()
    run = _LibcosimRun(system)
    try:
        for name, start in system["instances"].items():
            run.add_instance(name, start)
            result["series"][name] = {var: [] for var in system["record"]}
        for src, out, dst, inp in system.get("connections", []):
            run.connect(src, out, dst, inp)
        run.start_observing()
        overrides = overrides_by_step(system)
        for k in range(system["steps"]):
            for name, var, value in overrides.get(k, []):
                run.override(name, var, value)
            if not run.step():
                result["ok"], result["error"] = False, libcosim_last_error()
                break
            result["time"].append(run.time())
            for name, series in result["series"].items():
                values = run.sample(name, system["record"])
                for v in system["record"]:
                    series[v].append(values[v])
    except RuntimeError as exc:
        result["ok"], result["error"] = False, str(exc)
    finally:
        run.close()
    return result


def run_fmpy(system):
    """Run ``system`` with FMPy as master, in libcosim's order (see the module text)."""
    result = _new_result()
    h = system["step"]
    with FmuSession(system["fmu"]) as session:
        instances = {}
        try:
            for name, start in system["instances"].items():  # libcosim's order: the start values first
                instances[name] = inst = session.new_instance(name)
                inst.set_values(start)
                inst.enter_initialization(0.0)
            for _ in range(len(instances)):
                _transfer(instances, system)
            for inst in instances.values():
                inst.exit_initialization()
            _transfer(instances, system)
            for name in instances:
                result["series"][name] = {var: [] for var in system["record"]}
            overrides = overrides_by_step(system)
            for k in range(system["steps"]):
                for name, var, value in overrides.get(k, []):
                    instances[name].set_value(var, value)
                for inst in instances.values():
                    inst.call(inst.fmu.doStep, k * h, h)
                result["time"].append((k + 1) * h)
                for name, inst in instances.items():  # read before the transfer, as libcosim's observer does
                    row = inst.read()
                    for v in system["record"]:
                        result["series"][name][v].append(row[v])
                _transfer(instances, system)
        except FMUError as exc:
            result["ok"], result["error"] = False, str(exc)
        finally:
            for inst in instances.values():
                inst.free()
    return result


def _transfer(instances, system):
    values = {}
    for src, out, dst, inp in system.get("connections", []):
        values[(dst, inp)] = instances[src].real_value(out)
    for (dst, inp), value in values.items():
        instances[dst].set_value(inp, value)


def run_in_child(systems, timeout=300):
    """Run ``systems`` with libcosim, one after the other, in ONE child process.

    Returns ``{"returncode", "results" (list, one per system that finished), "stderr"}``.
    A crash of the child (libcosim aborting, a segmentation fault) shows as a negative
    ``returncode`` (the signal) and fewer results than systems.
    """
    proc = subprocess.run([sys.executable, "-m", "stickslip.stress.cosim"], input=json.dumps(systems),
                          capture_output=True, text=True, timeout=timeout)
    results = []
    for line in proc.stdout.splitlines():
        if line.startswith(RESULT_MARK):
            results.append(json.loads(line[len(RESULT_MARK):]))
    return {"returncode": proc.returncode, "results": results, "stderr": proc.stderr[-4000:]}


def compare(a, b, variables=("x", "v")):
    """Largest absolute difference of ``variables`` between two results, over instances and samples."""
    worst = 0.0
    for name in a["series"]:
        for var in variables:
            for u, w in zip(a["series"][name][var], b["series"][name][var]):
                worst = max(worst, abs(u - w)) if not (math.isnan(u) or math.isnan(w)) else math.inf
    return worst


def _main():
    systems = json.loads(sys.stdin.read())
    for system in systems:
        result = run_libcosim(system)
        print(RESULT_MARK + json.dumps(result), flush=True)


if __name__ == "__main__":
    _main()
