"""What FMU states cost beside a step: ``fmi2GetFMUstate``/``fmi3GetFMUState`` and the other FMU-state calls per
call, each as a ratio to a ``doStep`` of 1 ms of the same instance, in our C hosts (mode ``state_costs``) and in FMPy,
for the FMI 2 and the FMI 3 FMU.

The scene is msl-pendulum (the block slips under a Stribeck law, its slip integrated): an instance run for
:data:`WARM` s in steps of :data:`STEP` s, then blocks of ``rounds`` calls of each kind, the blocks taken in turn
:data:`REPEATS` times, CPU time per call the median over the repeats (the C host's ``state_costs`` in
``host_common.h``; :func:`fmpy_costs` does the same through FMPy's ``FMU2Slave``/``FMU3Slave``). Serialization takes
a state of its own in each call (the loader keeps the bytes of the state serialized last); deserialization takes the
bytes of one state again and again (nothing is kept between those calls). The compiled floor FMU (:mod:`.c_floor`),
whose states are copies of its two variables, measured the same way, gives the hosts' own part of each call.
"""

import statistics
import tempfile
import time
from pathlib import Path

from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave
from fmpy.simulation import apply_start_values

from ..hosts.c_host import run_host
from .c_hosts import extract
from .scenes import SCENES

SCENE = "msl-pendulum"
STEP = 1e-3  # s: the doStep the costs are measured against
WARM = 0.1  # s: run before measuring (100 steps)
REPEATS = 5
ROUNDS = 1000  # calls per block (bench-c-hosts --state-rounds)
#: the row of the compiled floor FMU, whose state calls cost next to nothing (a copy of two floats; serialized, 614
#: bytes as our FMI 2 FMU's state here): what a host's own part of each call costs as a multiple of its doStep
FLOOR = "C floor, FMI 2"
#: the calls measured, in the C host's order and labels (FMI 2 names; FMI 3's are the same calls)
CALLS = ("doStep", "GetFMUstate+FreeFMUstate", "SetFMUstate", "SetFMUstate+doStep",
         "SerializedFMUstateSize+SerializeFMUstate", "DeSerializeFMUstate+FreeFMUstate")


def measure(fmus, hosts, rounds, progress=print, floor=None):
    """``{host: {"FMI 2"|"FMI 3"|FLOOR: {call: µs per call}}}`` for ``fmus`` (``{fmi version: FMU file}``) in the C
    hosts ``hosts`` (``{fmi version: executable}``) and in FMPy; ``floor``: the compiled floor FMU (:mod:`.c_floor`),
    then measured too (in the FMI 2 host, from its start values), as row :data:`FLOOR`."""
    scene = SCENES[SCENE]
    start = scene.start_values(scene.sweep.comm_rtol)
    subjects = [(f"FMI {version}", fmu, hosts[version], start) for version, fmu in fmus.items()]
    if floor is not None:
        subjects.append((FLOOR, floor, hosts[2], {}))
    out = {"C host": {}, "FMPy": {}}
    with tempfile.TemporaryDirectory() as work:
        for number, (label, fmu, host, start_values) in enumerate(subjects):
            progress(f"FMU states, {label}: C host and FMPy, {rounds} calls per block")
            folder = extract(fmu, Path(work) / f"fmu{number}")
            out["C host"][label] = c_host_costs(host, folder, start_values, rounds)
            out["FMPy"][label] = fmpy_costs(folder, start_values, rounds)
    return out


def c_host_costs(host, folder, start_values, rounds):
    """``{call: µs}`` of the C host ``host`` on the FMU extracted to ``folder`` (mode ``state_costs``)."""
    run = run_host(host, folder, "state_costs", WARM, STEP, start_values, env={"HOST_ROUNDS": str(rounds)})
    if not run.completed:
        raise RuntimeError(f"C host state_costs failed: {run.lines[-2:]} {run.stderr[-300:]}")
    return {line[1]: float(line[2]) for line in run.lines if line[0] == "cost_us"}


def fmpy_costs(folder, start_values, rounds):
    """``{call: µs}`` through FMPy on the FMU extracted to ``folder``, as the C host's ``state_costs``."""
    description = read_model_description(str(folder))
    fmi3 = description.fmiVersion.startswith("3")
    fmu = (FMU3Slave if fmi3 else FMU2Slave)(
        guid=description.instantiationToken if fmi3 else description.guid, unzipDirectory=str(folder),
        modelIdentifier=description.coSimulation.modelIdentifier, instanceName="costs")
    fmu.instantiate()
    if fmi3:
        fmu.enterInitializationMode(startTime=0.0)
    else:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
    apply_start_values(fmu, description, start_values)
    fmu.exitInitializationMode()
    clock = [0.0]  # the instance's time (s)
    for _ in range(round(WARM / STEP)):
        _step(fmu, clock)
    blocks = _blocks(fmu, clock, rounds)
    costs = {call: [] for call in CALLS}
    for _ in range(REPEATS):
        for call in CALLS:
            costs[call].append(blocks[call]())
    fmu.terminate()
    fmu.freeInstance()
    return {call: 1e6 * statistics.median(times) for call, times in costs.items()}


def _step(fmu, clock):
    fmu.doStep(clock[0], STEP)
    clock[0] += STEP


def _state_calls(fmu):
    """FMPy's FMU-state methods of ``fmu`` under one set of names: get, set, free, serialize, deserialize."""
    if isinstance(fmu, FMU3Slave):
        return (fmu.getFMUState, fmu.setFMUState, fmu.freeFMUState, fmu.serializeFMUState,
                fmu.deserializeFMUState)
    return fmu.getFMUstate, fmu.setFMUstate, fmu.freeFMUstate, fmu.serializeFMUstate, fmu.deSerializeFMUstate


def _blocks(fmu, clock, rounds):
    """``{call: block}``: each block makes ``rounds`` calls and gives the CPU seconds per call."""
    get, restore, free, serialize, deserialize = _state_calls(fmu)

    def timed(prepare, call, finish=lambda _: None):
        def block():
            prepared = prepare()
            start = time.process_time()
            for i in range(rounds):
                call(prepared, i)
            cost = (time.process_time() - start) / rounds
            finish(prepared)
            return cost
        return block

    def saved():
        return get(), clock[0]

    def restore_and_step(prepared, _):
        restore(prepared[0])
        fmu.doStep(prepared[1], STEP)

    def after_restore_and_step(prepared):
        free(prepared[0])
        clock[0] = prepared[1] + STEP

    def serialized():
        state = get()
        data = serialize(state)
        free(state)
        return data

    return {
        "doStep": timed(lambda: None, lambda _, i: _step(fmu, clock)),
        "GetFMUstate+FreeFMUstate": timed(lambda: None, lambda _, i: free(get())),
        "SetFMUstate": timed(saved, lambda prepared, i: restore(prepared[0]), lambda prepared: free(prepared[0])),
        "SetFMUstate+doStep": timed(saved, restore_and_step, after_restore_and_step),
        "SerializedFMUstateSize+SerializeFMUstate": timed(
            lambda: [get() for _ in range(rounds)], lambda states, i: serialize(states[i]),
            lambda states: [free(state) for state in states]),
        "DeSerializeFMUstate+FreeFMUstate": timed(serialized, lambda data, i: free(deserialize(data))),
    }


def markdown_lines(results):
    """The report's table: per host and FMI version, a doStep of 1 ms in µs and each FMU-state call as a ratio to
    it."""
    lines = [f"## FMU states beside a doStep of {STEP * 1e3:g} ms ({SCENE}, slipping, after {WARM:g} s)", "",
             "CPU time per call (median of the blocks); each FMU-state call as a ratio to the doStep of the same "
             f"instance in the same run. {FLOOR}: the compiled floor FMU (its state a copy of its two variables, "
             "serialized as many bytes as ours), what the host's own part of each call costs.", "",
             "| host | FMU | doStep (µs) | " + " | ".join(f"{call} / doStep" for call in CALLS[1:]) + " |",
             "|---|---|---|" + "---|" * (len(CALLS) - 1)]
    for host, versions in results.items():
        for version, costs in versions.items():
            step = costs["doStep"]
            lines.append(f"| {host} | {version} | {step:.3g} | "
                         + " | ".join(f"{costs[call] / step:.3g} ({costs[call]:.3g} µs)" for call in CALLS[1:]) + " |")
    return lines
