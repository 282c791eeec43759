"""Child process of tests/test_fmi3_early_return.py: the FMI 3 FMU's co-simulation with early return and event mode,
driven through FMPy's FMI 3 calls the way fmusim drives them (Reference-FMUs' FMI3CSSimulation.c).

``python early_return_runner.py FMU3 FMU2 SCENE`` (SCENE: JSON of start values, ``stop`` and ``interval`` in s)
prints one JSON record with, for each way of running (``plain``: no flags; ``early``: earlyReturnAllowed;
``event``: earlyReturnAllowed and eventModeUsed), every sample ``[t, x, v, mode, n_events]`` (two at an event in
``event``: before and after Event Mode) and every doStep's ``[eventHandlingNeeded, earlyReturn,
lastSuccessfulTime]``; ``fmi2``: the FMI 2 FMU's samples on the plain grid; and the output derivatives of x and v,
orders 1 and 2, of both FMUs at each plain point.
"""

import json
import sys

from stickslip.hosts.fmpy_host import ExtractedFMU

OUTPUTS = ("x", "v")
COUNTERS = ("mode", "n_events")
DERIVATIVES = (("x", 1), ("x", 2), ("v", 1), ("v", 2))


def sample(b, vr, t):
    fmu = b.fmu
    reals = b.call(fmu.getFloat64 if hasattr(fmu, "getFloat64") else fmu.getReal, [vr[n] for n in OUTPUTS])
    integers = b.call(fmu.getInt32 if hasattr(fmu, "getInt32") else fmu.getInteger, [vr[n] for n in COUNTERS])
    return [t, *reals, *integers]


def derivatives(b, vr):
    fmu = b.fmu
    get = fmu.getOutputDerivatives if hasattr(fmu, "getOutputDerivatives") else fmu.getRealOutputDerivatives
    return b.call(get, [vr[name] for name, _ in DERIVATIVES], [order for _, order in DERIVATIVES])


def initialized(extracted, scene, **flags):
    vr = {name: v.valueReference for name, v in extracted.variables.items()}
    b = extracted.new_instance(logging_on=False, **flags)
    fmu = b.fmu
    reals = {name: value for name, value in scene["values"].items() if not name.endswith(".law")}
    laws = {name: value for name, value in scene["values"].items() if name.endswith(".law")}
    if extracted.fmi_version == 2:
        b.call(fmu.setupExperiment, startTime=0.0)
        b.call(fmu.enterInitializationMode)
        b.call(fmu.setReal, [vr[n] for n in reals], list(reals.values()))
        b.call(fmu.setInteger, [vr[n] for n in laws], list(laws.values()))
    else:
        b.call(fmu.enterInitializationMode, startTime=0.0)
        b.call(fmu.setFloat64, [vr[n] for n in reals], list(reals.values()))
        b.call(fmu.setInt64, [vr[n] for n in laws], list(laws.values()))
    b.call(fmu.exitInitializationMode)
    return b, vr


def update_until_done(b):
    """fmi3UpdateDiscreteStates until no more update is needed; the last call's outputs."""
    while True:
        result = b.call(b.fmu.updateDiscreteStates)
        if not result[0]:
            return list(result)


def fmusim_run(extracted, scene, early, event_mode):
    """fmusim's co-simulation loop with ``--early-return-allowed`` (``early``) and ``--event-mode-used``."""
    b, vr = initialized(extracted, scene, early_return_allowed=early, event_mode_used=event_mode)
    fmu = b.fmu
    record = {"samples": [], "steps": [], "updates": [], "derivatives": []}
    if event_mode:  # Event Mode after initialization (FMI 3.0 section 4.2)
        record["updates"].append(update_until_done(b))
        b.call(fmu.enterStepMode)
    t, n, interval, stop = 0.0, 0, scene["interval"], scene["stop"]
    record["samples"].append(sample(b, vr, t))
    while t < stop and abs(t - stop) > 1e-9 * stop:
        regular = (n + 1) * interval
        if extracted.fmi_version == 2:
            b.call(fmu.doStep, t, regular - t)
            handling, returned, last = False, False, regular
        else:
            handling, _, returned, last = b.call(fmu.doStep, t, regular - t)
        record["steps"].append([handling, returned, last])
        t = last if returned and last < regular else regular
        if abs(t - regular) <= 1e-9 * regular:
            n += 1
            if not early:
                record["derivatives"].append(derivatives(b, vr))
        record["samples"].append(sample(b, vr, t))
        if event_mode and handling:
            b.call(fmu.enterEventMode)
            record["updates"].append(update_until_done(b))
            b.call(fmu.enterStepMode)
            record["samples"].append(sample(b, vr, t))
    b.free()
    return record


def main(fmu3, fmu2, scene_json):
    scene = json.loads(scene_json)
    record = {}
    with ExtractedFMU(fmu3) as extracted:
        for name, early, event_mode in (("plain", False, False), ("early", True, False), ("event", True, True)):
            record[name] = fmusim_run(extracted, scene, early, event_mode)
        record["capabilities"] = {key: getattr(extracted.model_description.coSimulation, key) for key in (
            "hasEventMode", "mightReturnEarlyFromDoStep", "maxOutputDerivativeOrder")}
    with ExtractedFMU(fmu2) as extracted:
        record["fmi2"] = fmusim_run(extracted, scene, False, False)
    print(json.dumps(record))


if __name__ == "__main__":
    main(*sys.argv[1:])
