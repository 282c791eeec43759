"""A model-exchange host as the Modelica Association's fmusim drives an FMI 3 FMU with ``--solver cvode``.

SUNDIALS' CVode (BDF, dense Newton, through FMPy's ``fmpy.sundials.CVodeSolver``) on the FMU's states,
derivatives and event indicators, its own C root finding on the indicators, and the loop of fmusim's
``FMI3MESimulate``: CVode to the next output point (``CV_NORMAL``); at a root, Event Mode and
``fmi3UpdateDiscreteStates`` until no update is needed, and a solver restart (``CVodeReInit``) only if the
FMU reports ``valuesOfContinuousStatesChanged``; without one CVode goes on from its own history, and its
root check right after the event (``cvRcheck2``) fails on an indicator that stays exactly 0 there. As
fmusim's solver, the absolute tolerance is the relative one (nominals 1) and the step size is unlimited.

Run as a script (each run a child process of the tests, so a crash or hang of the host fails one test):
``python cvode_me_host.py FOLDER SPEC`` with the extracted FMU's folder and a JSON spec ``{"start":
{name: value}, "stop": s, "interval": s, "rtol": r, "repeats": n}`` (``repeats``: extra Event Mode entries
with an update, nothing changed, after each event, as a host that re-enters it at the same instant);
prints one JSON line ``{"t": [...], "x": [...], "events": [[t, n_events], ...], "indicators": [[z...], ...],
"error": null or text}`` (``events`` and ``indicators``: after the initial event iteration, then after each root).
"""

import ctypes
import json
import sys

from fmpy import read_model_description
from fmpy.fmi3 import FMU3Model
from fmpy.sundials import CVodeSolver


class NoInput:
    """The inputs are start values, constant: nothing to apply at the root function's times."""

    @staticmethod
    def apply(t):
        return None


def ones(out, n):
    """fmusim's CVode: absolute tolerance = relative tolerance, whatever the FMU's nominals."""
    for i in range(n):
        out[i] = 1.0


def instantiate(folder, start):
    """An FMU3Model of the extracted FMU in ``folder``, initialized with ``start`` (at t = 0), and its variables."""
    description = read_model_description(folder)
    variables = {v.name: v for v in description.modelVariables}
    fmu = FMU3Model(guid=description.instantiationToken, unzipDirectory=folder,
                    modelIdentifier=description.modelExchange.modelIdentifier, instanceName="cvode")
    fmu.instantiate()
    fmu.enterInitializationMode(startTime=0.0)
    for name, value in start.items():
        setter = {"Int32": fmu.setInt32, "Enumeration": fmu.setInt64}.get(variables[name].type, fmu.setFloat64)
        setter([variables[name].valueReference], [value])
    fmu.exitInitializationMode()
    return fmu, description, variables


def event_iteration(fmu, repeats):
    """Event Mode: updates until none is needed (``repeats`` more Event Mode entries after it); True if the
    solver must restart (the FMU changed the states' values or nominals)."""
    restart = False
    for _ in range(1 + repeats):
        fmu.enterEventMode()
        need = True
        while need:
            need, terminate, nominals, values, _, _ = fmu.updateDiscreteStates()
            assert not terminate
            restart = restart or nominals or values
    fmu.enterContinuousTimeMode()
    return restart


def simulate(folder, spec):
    """fmusim's loop (see the module docstring); the result as the script prints it."""
    fmu, description, variables = instantiate(folder, spec["start"])
    x_ref, n_ref = variables["x"].valueReference, variables["n_events"].valueReference
    result = {"t": [], "x": [], "events": [], "indicators": [], "error": None}
    nx, nz = description.numberOfContinuousStates, description.numberOfEventIndicators
    indicators = (ctypes.c_double * nz)()

    def sample(t):
        result["t"].append(t)
        result["x"].append(fmu.getFloat64([x_ref])[0])

    def after_event(t):
        result["events"].append([t, fmu.getInt32([n_ref])[0]])
        fmu.getEventIndicators(indicators, nz)
        result["indicators"].append(list(indicators))

    event_iteration(fmu, 0)
    after_event(0.0)
    solver = CVodeSolver(nx=nx, nz=nz, get_x=fmu.getContinuousStates, set_x=fmu.setContinuousStates,
                         get_dx=fmu.getContinuousStateDerivatives, get_z=fmu.getEventIndicators,
                         get_nominals=ones, set_time=fmu.setTime, input=NoInput(), startTime=0.0,
                         relativeTolerance=spec["rtol"], maxNumSteps=100000)
    t, k = 0.0, 0
    sample(t)
    try:
        while t < spec["stop"]:
            t_next = (k + 1) * spec["interval"]
            event, _, t = solver.step(t, t_next)
            fmu.setTime(t)
            if t == t_next:
                k += 1
            if event:
                if event_iteration(fmu, spec["repeats"]):
                    solver.reset(t)
                after_event(t)
            if t == t_next:
                sample(t)
    except RuntimeError as exc:  # CVode's error, as fmusim reports it and stops
        result["error"] = str(exc)
    fmu.terminate()
    fmu.freeInstance()
    return result


if __name__ == "__main__":
    print(json.dumps(simulate(sys.argv[1], json.loads(sys.argv[2]))), flush=True)
