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

import gc
import json
import math
import subprocess
import sys

from ..hosts.fmpy_host import FMUError, fmi2_callbacks
from .session import INTEGER_OUTPUTS, FmuSession, Instance

RESULT_MARK = "@@cosim-results@@"


def _ns(seconds):
    return int(round(seconds * 1e9))


def run_libcosim(system):
    """Run ``system`` with libcosim in this process (see the module text)."""
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave
    from libcosimpy._internal import get_last_error_message

    log_output_level(CosimLogLevel.ERROR)
    result = {"ok": True, "error": "", "time": [], "series": {}}
    execution = CosimExecution.from_step_size(_ns(system["step"]))
    slaves, index, variables = {}, {}, {}
    observer = CosimObserver.create_last_value()
    manipulator = CosimManipulator.create_override()
    try:
        for name, start in system["instances"].items():
            slaves[name] = CosimLocalSlave(fmu_path=system["fmu"], instance_name=name)
            index[name] = execution.add_local_slave(slaves[name])
            if index[name] < 0:
                raise RuntimeError(f"cannot add instance {name}: {get_last_error_message()}")
            variables[name] = {v.name.decode(): v for v in execution.slave_variables(index[name])}
            for key, value in start.items():
                v = variables[name][key]
                if v.type == CosimVariableType.INTEGER.value:
                    ok = execution.integer_initial_value(index[name], v.reference, int(value))
                else:
                    ok = execution.real_initial_value(index[name], v.reference, float(value))
                if not ok:
                    raise RuntimeError(f"cannot set {name}.{key}: {get_last_error_message()}")
            result["series"][name] = {var: [] for var in system["record"]}
        for src, out, dst, inp in system.get("connections", []):
            status = execution.connect_real_variables(index[src], variables[src][out].reference,
                                                      index[dst], variables[dst][inp].reference)
            if status != 0:
                raise RuntimeError(f"cannot connect {src}.{out} -> {dst}.{inp}: {get_last_error_message()}")
        execution.add_observer(observer)
        execution.add_manipulator(manipulator)
        overrides = {}
        for k, name, var, value in system.get("overrides", []):
            overrides.setdefault(int(k), []).append((name, var, value))

        def record():
            result["time"].append(execution.status().current_time * 1e-9)
            for name, series in result["series"].items():
                reals = [v for v in system["record"] if v not in INTEGER_OUTPUTS]
                ints = [v for v in system["record"] if v in INTEGER_OUTPUTS]
                values = dict(zip(reals, observer.last_real_values(index[name], [variables[name][v].reference
                                                                                  for v in reals])))
                values.update(zip(ints, observer.last_integer_values(index[name], [variables[name][v].reference
                                                                                  for v in ints])))
                for v in system["record"]:
                    series[v].append(values[v])

        for k in range(system["steps"]):
            for name, var, value in overrides.get(k, []):
                manipulator.slave_real_values(index[name], [variables[name][var].reference], [float(value)])
            if not execution.step(1):  # the first step also initializes the instances
                result["ok"] = False
                result["error"] = get_last_error_message()
                break
            record()
    except RuntimeError as exc:
        result["ok"], result["error"] = False, str(exc)
    finally:
        # destroy the execution now rather than at interpreter shutdown: libcosim terminates and frees every
        # instance, also one that returned fmi2Fatal, so that the next system starts from a clean engine (the
        # FMU balances PythonFMU's release of a failed slave, which makes that free safe)
        del manipulator, observer, execution
        slaves.clear()
        gc.collect()
    return result


def run_fmpy(system):
    """Run ``system`` with FMPy as master, in libcosim's order (see the module text)."""
    result = {"ok": True, "error": "", "time": [], "series": {}}
    h, n = system["step"], system["steps"]
    with FmuSession(system["fmu"]) as session:
        instances = {}
        try:
            for name, start in system["instances"].items():
                instances[name] = _instantiate_in_init(session, name, start)
            for _ in range(len(instances)):
                _transfer(instances, system)
            for name, inst in instances.items():
                inst.call("fmi2ExitInitializationMode", inst.fmu.exitInitializationMode)
            _transfer(instances, system)
            overrides = {}
            for k, name, var, value in system.get("overrides", []):
                overrides.setdefault(int(k), []).append((name, var, value))
            for name in instances:
                result["series"][name] = {var: [] for var in system["record"]}
            for k in range(n):
                for name, var, value in overrides.get(k, []):
                    instances[name].set_value(var, value)
                for inst in instances.values():
                    inst.call("fmi2DoStep", inst.fmu.doStep, k * h, h)
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


def _instantiate_in_init(session, name, start):
    """An instance in initialization mode with ``start`` set (exit is left to the caller)."""
    from fmpy.fmi2 import FMU2Slave

    fmu = FMU2Slave(guid=session.description.guid, unzipDirectory=session.folder,
                    modelIdentifier=session.description.coSimulation.modelIdentifier, instanceName=name)
    fmu.instantiate(callbacks=fmi2_callbacks(), loggingOn=True)
    inst = Instance(session, fmu, name)
    for key, value in start.items():
        inst.set_value(key, value)
    inst.call("fmi2SetupExperiment", fmu.setupExperiment, startTime=0.0)
    inst.call("fmi2EnterInitializationMode", fmu.enterInitializationMode)
    return inst


def _transfer(instances, system):
    values = {}
    for src, out, dst, inp in system.get("connections", []):
        variable = instances[src].session.variables[out]
        values[(dst, inp)] = instances[src].call("fmi2GetReal", instances[src].fmu.getReal,
                                                 [variable.valueReference])[0]
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
