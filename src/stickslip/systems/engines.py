"""The ``zoh`` master's engines: the system's SSP (:mod:`.ssp`) stepped with a fixed step by libcosim, ecos, FMPy's
SSP simulator or FMPy driven here.

Every engine here couples FMUs the same way (a Jacobi scheme with one data transfer per step): all instances
step from ``t_k`` to ``t_(k+1)`` with the inputs they hold, then each connection copies its source's output, as
read after the step, to its sink. A block's force comes through its coupling FMU ``c<i>``, so it takes two
transfers to reach the block: ``c<i>.F`` read after step ``k`` was computed from the positions ``x(t_k)`` set at
the previous transfer, and the block holds ``F_ext = F(x(t_(k-1)))`` over step ``k >= 1`` (``F(x(t_0))`` over the
first). The ``zoh`` master in FMPy without an engine sets ``F_ext = F(x(t_k))`` (no coupling FMU in between): the
same first order, a larger error (docs/systems.md gives both).

- ``libcosim`` (libcosimpy): ``CosimExecution.from_ssp_file`` on the ``.ssp`` with the step in ns, a last-value
  observer read after each step;
- ``ecos`` (ecospy): ``EcosSimulation(ssp_path=...)``, ``init`` with the SSP's parameter set, ``get_real`` and
  ``get_integer`` after each step; its library needs ``libtbb.so.12`` (Debian's ``libtbb12`` or PyPI's ``tbb``,
  whose ``lib/`` folder is put on ``LD_LIBRARY_PATH``);
- ``fmpy-ssp``: FMPy's SSP simulator, ``fmpy.ssp.simulation.simulate_ssp`` (:func:`run_fmpy_ssp`): it starts every
  connection at 0 (each block holds ``F_ext = 0`` over the first two steps, not the force at the start positions)
  and sums its step times, as ecos does;
- ``fmpy``: the same components and connections driven here by FMPy in the engines' order (:func:`run_fmpy`).

libcosim, ecos and FMPy's SSP simulator run in a child process (``python -m stickslip.systems.engines`` reads a JSON spec on stdin and
prints ``RESULT_MARK + json``): an engine that aborts (libcosim calls ``std::terminate`` on a failure during its
initialization) or hangs ends as an FMUError naming it, and ecos gets its ``LD_LIBRARY_PATH``. The child must
exit with status 0 after printing its result.
"""

import ctypes.util
import importlib.util
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from ..fmu.coupling import ensure_coupling_fmu
from ..hosts.fmpy_host import ExtractedFMU, FMUError
from .master import read_values, references, start_block
from .names import ENGINES
from .ssp import PARAMETER_SET, component, component_values, connections, write_ssp

RESULT_MARK = "@@ssp-engine-result@@"
#: what each block's row holds after a step: Real outputs, then Integer outputs
REALS, INTEGERS = ("x", "v", "t_last_event"), ("mode", "n_events")
#: the Python package each engine needs
PACKAGES = {"libcosim": "libcosimpy", "ecos": "ecospy", "fmpy-ssp": "fmpy"}


def run_ssp(engine, system, step, block_fmu):
    """``system`` written as an SSP (block FMU ``block_fmu``, the coupling FMU built if stale) into a temporary
    folder and run by ``engine`` with the fixed step ``step`` (s): :func:`run_engine`'s rows."""
    coupling_fmu = ensure_coupling_fmu()
    with tempfile.TemporaryDirectory(prefix="sbf_ssp_") as folder:
        ssp_path = write_ssp(system, step, block_fmu, coupling_fmu, Path(folder) / f"{system.name}.ssp")
        return run_engine(engine, ssp_path, system, step, coupling_fmu, block_fmu)


def run_engine(engine, ssp_path, system, step, coupling_fmu, block_fmu):
    """``{name: [[value per block] per step]}`` for ``REALS + INTEGERS`` after every step of ``step`` (s) from 0 to
    the stop time, run by ``engine``; FMUError naming the engine if it cannot run or fails."""
    steps = round(system.stop_time / step)
    if engine == "fmpy":
        return run_fmpy(system, step, steps, block_fmu, coupling_fmu)
    if engine not in PACKAGES:
        raise FMUError(f"zoh: engine {engine!r}: allowed are {list(ENGINES)}")
    spec = {"engine": engine, "ssp": str(ssp_path), "step": step, "steps": steps, "blocks": system.n}
    proc = subprocess.run([sys.executable, "-m", "stickslip.systems.engines"], input=json.dumps(spec),
                          capture_output=True, text=True, env=engine_environment(engine),
                          timeout=120 + 1e-3 * steps * system.n)
    lines = [line for line in proc.stdout.splitlines() if line.startswith(RESULT_MARK)]
    result = json.loads(lines[0][len(RESULT_MARK):]) if lines else {}
    if proc.returncode != 0 or not lines or result.get("error"):
        raise FMUError(f"zoh: {engine} ended with exit code {proc.returncode}, {result.get('error', 'no result')}: "
                       f"{proc.stderr[-2000:]}")
    return result


def engine_environment(engine):
    """The child's environment; FMUError naming what is missing if ``engine`` cannot run here."""
    if importlib.util.find_spec(PACKAGES[engine]) is None:
        raise FMUError(f"zoh: engine {engine} needs the Python package {PACKAGES[engine]} (pip install "
                       f"{PACKAGES[engine]}, or the test extra)")
    env = dict(os.environ)
    if engine == "ecos" and ctypes.util.find_library("tbb") is None:
        wheel_lib = Path(sys.prefix) / "lib"
        if not (wheel_lib / "libtbb.so.12").exists():
            raise FMUError("zoh: engine ecos needs libtbb.so.12: install Debian's libtbb12 or PyPI's tbb")
        env["LD_LIBRARY_PATH"] = os.pathsep.join(filter(None, [str(wheel_lib), env.get("LD_LIBRARY_PATH")]))
    return env


def _blocks(n):
    """The SSP's block components of a chain of ``n`` blocks, in order."""
    return [component("b", i, n) for i in range(1, n + 1)]


def _new_rows():
    return {name: [] for name in REALS + INTEGERS}


def run_fmpy(system, step, steps, block_fmu, coupling_fmu):
    """The SSP's components and connections driven by FMPy in the engines' order (see the module text): each
    component started with its values and, for a coupling, the positions its connections hand it during the
    engines' initialization (the start positions); one transfer; then each step, the blocks' rows read before
    the transfer (as libcosim's observer does)."""
    values, wires, blocks = component_values(system), connections(system.n), _blocks(system.n)
    x_start = {name: block["x_start"] for name, block in zip(blocks, system.blocks)}
    for start, out, end, into in wires:
        if out == "x":
            values[end][into] = x_start[start]
    rows = _new_rows()
    with ExtractedFMU(block_fmu) as block_fmu, ExtractedFMU(coupling_fmu) as couplings:
        instances = {}
        try:
            for name, start in values.items():
                extracted, role = (block_fmu, "block") if name.startswith("b") else (couplings, "coupling")
                instances[name] = start_block(extracted, name, start, role=role)
            block_list = [instances[name] for name in blocks]
            reals, integers = references(block_fmu, REALS), references(block_fmu, INTEGERS)
            _transfer(instances, wires)
            for k in range(steps):
                for instance in instances.values():
                    instance.call(instance.fmu.doStep, k * step, step)
                for name, row in zip(REALS + INTEGERS, read_values(block_list, reals, integers)):
                    rows[name].append(row)
                _transfer(instances, wires)
        finally:
            for instance in instances.values():
                instance.free()
    return rows


def _transfer(instances, wires):
    """Every connection's source value read first, then every sink set (all are Real): one transfer of the
    outputs as they are now."""
    values = []
    for start, out, end, into in wires:
        source, sink = instances[start], instances[end]
        reference = source.extracted.variables[out].valueReference
        value = source.call(source.fmu.getReal, [reference])[0]
        values.append((sink, sink.extracted.variables[into].valueReference, value))
    for sink, reference, value in values:
        sink.call(sink.fmu.setReal, [reference], [value])


def run_libcosim(spec):
    """The SSP in libcosim (in this process), one row per step."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.ERROR)
    execution = CosimExecution.from_ssp_file(spec["ssp"], step_size=round(spec["step"] * 1e9))
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    blocks = []
    for name in _blocks(spec["blocks"]):
        index = execution.slave_index_from_instance_name(name)
        references = {v.name.decode(): v.reference for v in execution.slave_variables(index)}
        blocks.append((index, [references[n] for n in REALS], [references[n] for n in INTEGERS]))
    rows = _new_rows()
    for _ in range(spec["steps"]):
        if not execution.step(1):
            return {"error": "a step failed (libcosim's log above)"}
        read = [observer.last_real_values(i, reals) + observer.last_integer_values(i, ints)
                for i, reals, ints in blocks]
        for column, name in enumerate(REALS + INTEGERS):
            rows[name].append([row[column] for row in read])
    return rows


def run_ecos(spec):
    """The SSP in ecos (in this process), one row per step."""
    from ecospy import EcosLib, EcosSimulation

    rows = _new_rows()
    with EcosSimulation(step_size=spec["step"], ssp_path=spec["ssp"]) as simulation:
        if simulation.init(parameter_set=PARAMETER_SET) is False:
            return {"error": EcosLib.get_last_error()}
        for _ in range(spec["steps"]):
            simulation.step()
            for name in REALS + INTEGERS:
                get = simulation.get_integer if name in INTEGERS else simulation.get_real
                rows[name].append([get(f"{block}::{name}") for block in _blocks(spec["blocks"])])
        simulation.terminate()
    return rows


def run_fmpy_ssp(spec):
    """The SSP in FMPy's SSP simulator (in this process), one row per step. FMPy reads each component's parameter
    set (its ParameterBinding's ``.ssv``); its simulator applies one set to all components by their names, so the
    components' sets go to it with each parameter's name behind its component's. It sums its step times, and
    steps while the sum is below the stop time: half a step short of the last step's end gives ``steps`` steps."""
    from fmpy.ssp.simulation import simulate_ssp
    from fmpy.ssp.ssd import Parameter, ParameterSet, read_ssd

    parameters = ParameterSet(name=PARAMETER_SET)
    for element in read_ssd(spec["ssp"]).system.elements:
        for binding in element.parameterBindings:
            for values in binding.parameterValues:
                parameters.parameters += [Parameter(name=f"{element.name}.{p.name}", type=p.type, value=p.value)
                                          for p in values.parameters]
    result = simulate_ssp(spec["ssp"], stop_time=(spec["steps"] - 0.5) * spec["step"], step_size=spec["step"],
                          parameter_set=parameters)
    blocks = _blocks(spec["blocks"])
    return {name: [[row[f"{block}.{name}"].item() for block in blocks] for row in result]
            for name in REALS + INTEGERS}


if __name__ == "__main__":
    job = json.loads(sys.stdin.read())
    run = {"libcosim": run_libcosim, "ecos": run_ecos, "fmpy-ssp": run_fmpy_ssp}[job["engine"]]
    print(RESULT_MARK + json.dumps(run(job)), flush=True)
