"""One FMU run in a third-party engine, as a child process of the tests (a crash or hang of the engine shows as
a return code or a timeout, never as a dead pytest).

``python engine_child.py ENGINE`` reads ``{"fmu", "start": {name: value}, "step" (s), "steps", "log_level"}`` as
JSON on stdin and prints one line ``RESULT_MARK + json`` with ``{"ok", "error", "time": [s], "x": [m],
"n_events": [...]}``, one sample after every step. ENGINE is

- ``ecos``: ecospy's Python API (the engine's ``libecosc``), one instance ``a``, fixed step ``step``, the start
  values as a parameter set applied at ``init``, ecos's log level ``log_level`` (its default if absent);
- ``fmpy``: ``fmpy.simulate_fmu`` with communication step ``step`` (for an FMU that the tests built around ours,
  e.g. an FMU container).
"""

import json
import sys

RESULT_MARK = "@@engine-result@@"


def run_ecos(spec):
    """The run under ecos; ``ok`` is what ecos's API reports (``init``'s return value)."""
    from ecospy import EcosLib, EcosSimulation
    from ecospy.EcosSimulationStructure import EcosSimulationStructure

    if spec.get("log_level"):
        EcosLib.set_log_level(spec["log_level"])
    result = {"ok": True, "error": "", "time": [], "x": [], "n_events": []}
    with EcosSimulationStructure() as structure:
        structure.add_model("a", spec["fmu"])
        structure.add_parameter_set("start", {f"a::{name}": value for name, value in spec["start"].items()})
        with EcosSimulation(structure=structure, step_size=spec["step"]) as simulation:
            if not simulation.init(parameter_set="start"):
                return dict(result, ok=False, error=EcosLib.get_last_error())
            for _ in range(spec["steps"]):
                result["time"].append(simulation.step())
                result["x"].append(simulation.get_real("a::x"))
                result["n_events"].append(simulation.get_integer("a::n_events"))
            simulation.terminate()
    return result


def run_fmpy(spec):
    """The run under ``fmpy.simulate_fmu``; a failure is ``ok = False`` with FMPy's exception text."""
    import fmpy

    try:
        out = fmpy.simulate_fmu(spec["fmu"], start_values=spec["start"], stop_time=spec["step"] * spec["steps"],
                                output_interval=spec["step"], output=["x", "n_events"])
    except Exception as exc:  # FMPy raises a plain Exception for a failed FMI call
        return {"ok": False, "error": str(exc), "time": [], "x": [], "n_events": []}
    return {"ok": True, "error": "", "time": out["time"][1:].tolist(), "x": out["x"][1:].tolist(),
            "n_events": out["n_events"][1:].tolist()}


if __name__ == "__main__":
    engine = {"ecos": run_ecos, "fmpy": run_fmpy}[sys.argv[1]]
    print(RESULT_MARK + json.dumps(engine(json.loads(sys.stdin.read()))), flush=True)
