"""Child process of tests/test_fmi2_derivatives.py: an FMI 2 session with input and output derivatives.

``python derivatives_runner.py FMU`` prints one JSON record: the model description's capabilities; the ramp scene
(a block at rest at x = 0 on a still surface, Coulomb friction F_K = 0.5 N, F_S = 1 N, F_ext = 0 with
der(F_ext) = 0.25 N/s set once) stepped by 0.1 s to 7.5 s, x and v after each step and the output derivatives
at 6 s; the same scene restored from a state saved at 5 s; a force set at 7.5 s and held; and the status and
message of every refused or warned call.
"""

import json
import sys

from stickslip.hosts.fmpy_host import ExtractedFMU, FmuCallError


def main(path):
    with ExtractedFMU(path) as extracted:
        md = extracted.model_description
        vr = {name: v.valueReference for name, v in extracted.variables.items()}
        b = extracted.new_instance("ramp", logging_on=False)
        fmu = b.fmu
        b.call(fmu.setReal, [vr["v_drive"], vr["kinetic.F0"], vr["static.F0"]], [0.0, 0.5, 1.0])
        b.call(fmu.setupExperiment, startTime=0.0)
        b.call(fmu.enterInitializationMode)
        b.call(fmu.setRealInputDerivatives, [vr["F_ext"]], [1], [0.25])  # before initialization ends: from t = 0
        b.call(fmu.exitInitializationMode)
        record = {"canInterpolateInputs": md.coSimulation.canInterpolateInputs,
                  "maxOutputDerivativeOrder": md.coSimulation.maxOutputDerivativeOrder, "steps": [], "restored": []}
        state = None
        for k in range(75):
            b.call(fmu.doStep, k * 0.1, 0.1)
            record["steps"].append([(k + 1) * 0.1, *b.call(fmu.getReal, [vr["x"], vr["v"]])])
            if k + 1 == 50:
                state = b.call(fmu.getFMUstate)
            if k + 1 == 60:
                record["derivatives"] = list(b.call(fmu.getRealOutputDerivatives,
                                                    [vr["x"], vr["x"], vr["v"], vr["v"]], [1, 2, 1, 2]))
        b.call(fmu.setFMUstate, state)
        for k in range(50, 75):
            b.call(fmu.doStep, k * 0.1, 0.1)
            record["restored"].append(b.call(fmu.getReal, [vr["x"], vr["v"]]))
        b.call(fmu.setReal, [vr["F_ext"]], [1.875])  # a force set is held: the rate ends
        b.call(fmu.doStep, 7.5, 0.5)
        record["held"] = b.call(fmu.getReal, [vr["x"], vr["v"]])
        record["calls"] = _refusals(b, vr)
        b.free()
    print(json.dumps(record))


def _refusals(b, vr):
    """Each call that is refused or warned: [label, status, its messages]."""
    fmu = b.fmu
    calls = {
        "der(F_ext) of order 2": (fmu.setRealInputDerivatives, [vr["F_ext"]], [2], [1.0]),
        "der(F_ext) of order 2 again": (fmu.setRealInputDerivatives, [vr["F_ext"]], [2], [2.0]),
        "der(F_ext) of order 2 = 0": (fmu.setRealInputDerivatives, [vr["F_ext"]], [2], [0.0]),
        "der(v_drive)": (fmu.setRealInputDerivatives, [vr["v_drive"]], [1], [0.1]),
        "der(x) set": (fmu.setRealInputDerivatives, [vr["x"]], [1], [0.1]),
        "der(F_ext) NaN": (fmu.setRealInputDerivatives, [vr["F_ext"]], [1], [float("nan")]),
        "der(F_ext) of order 0": (fmu.setRealInputDerivatives, [vr["F_ext"]], [0], [1.0]),
        "der(F_friction)": (fmu.getRealOutputDerivatives, [vr["F_friction"]], [1]),
        "der(x) of order 3": (fmu.getRealOutputDerivatives, [vr["x"]], [3]),
    }
    results = []
    for label, (function, *args) in calls.items():
        first = len(b.messages())
        try:
            b.call(function, *args)
            status = 1 if b.messages()[first:] else 0
        except FmuCallError as error:
            status = error.status
        results.append([label, status, b.messages()[first:]])
    return results


if __name__ == "__main__":
    main(sys.argv[1])
