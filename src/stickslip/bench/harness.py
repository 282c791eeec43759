"""Run every configuration of every scene: time it and measure its error against the reference.

A configuration is timed as one whole simulation call (build, integrate, record
the outputs on its grid), once as warm-up and then ``repeats`` times with the
garbage collector off; the median is reported. Each call is cut off after the
sweep's ``time_limit`` (SIGALRM: Unix, main thread). The warm-up's result is the one
compared with the reference: max |dx| on the scene's grid (m, and relative to the
amplitude), event-time error (s), final |dx| (m) and |dv| (m/s).
"""

import gc
import signal
import statistics
import time
import traceback
from dataclasses import dataclass
from typing import Callable

import numpy as np
from tqdm import tqdm

from .. import core as compiled_core
from ..suite.compare import Event, fmu_events, match_events, reference_events, transition_kind
from . import c_host_family
from .bare_cvode import simulate_bare_cvode
from .peers import Run, hybrid_solve_ivp, regularized_solve_ivp
from .results import coarse_step
from .runtimes import PURE_CORE, in_core

FMU_OUTPUTS = ("x", "v", "n_stick_events", "n_slip_events", "n_overshoots", "t_last_event")  # the floor has them too


@dataclass
class Config:
    """One configuration: ``simulate()`` is the timed call, ``to_run`` turns its result into a :class:`Run`
    (None for the floor, which has nothing to compare); ``extra`` turns it into more fields of the record."""

    family: str
    label: str
    settings: dict
    simulate: Callable
    to_run: Callable | None
    extra: Callable | None = None


def stepper_call(scene, rtol, reuse_steps=True, core=compiled_core):
    """The timed call of our stepper (the runtime package ``core``: compiled where built, or its pure-Python
    copy) on the scene's grid, returning a Run with its recorded events (their exact times);
    ``reuse_steps=False`` integrates every step instead of replaying steps from bit-identical states. What the
    call need not redo is prepared here, as for the solve_ivp peers: the parameters in ``core``'s classes, the
    inputs, the grid as a list of floats."""
    p, (v_drive, F_ext), x0, v0 = in_core(core, scene.params), scene.inputs, scene.scenario.x0, scene.scenario.v0
    grid = scene.grid()
    times = grid.tolist()

    def run():
        traj = core.Trajectory(p, x0, v0, v_drive, F_ext, 0.0, rtol, record_events=True, reuse_steps=reuse_steps)
        x, v = traj.sample(times)
        events = [Event(kind, t, t) for t, before, after in traj.events
                  if (kind := transition_kind(before, after)) is not None]
        return Run(grid, np.array(x, dtype=float), np.array(v, dtype=float), events, traj.n_steps)

    return run


def _from_columns(result):
    return Run(result["time"], result["x"], result["v"], fmu_events(result))


def configs(scene, fmu, floor, host=None, fmu3=None, pure_fmu=None):
    """Every configuration of ``scene``'s sweep; ``fmu``, ``floor``, (if given) the FMI 3 FMU ``fmu3``, run
    through model exchange (beside it the same CVode with no FMU, :mod:`.bare_cvode`), and ``pure_fmu`` (the FMU
    built without compiling its runtime) are :class:`~.fmus.ExtractedFMU`, ``host`` the compiled C host (None:
    no C host family)."""
    return (_fmu_configs(scene, fmu, fmu3, pure_fmu) + _stepper_configs(scene) + _solve_ivp_configs(scene)
            + _regularized_configs(scene)
            + [Config("floor", f"floor h={h:g}", {"comm_step": h},
                      lambda h=h: floor.simulate({}, scene.stop_time, h, FMU_OUTPUTS), None)
               for h in sorted(set(scene.comm_steps()) | {scene.grid_step})]
            + c_host_family.configs(scene, fmu, floor, host, Config))


def _fmu_configs(scene, fmu, fmu3, pure_fmu):
    """The FMU over its rtols and communication steps; FMI 3 model exchange and bare CVode over CVode's rtols;
    the FMU with its runtime in pure Python (if ``pure_fmu``)."""
    s, T = scene.sweep, scene.stop_time
    out = []
    coarse = [h for h in scene.comm_steps() if h >= scene.grid_step] + [scene.grid_step]
    fmu_points = {(rtol, h) for rtol in s.fmu_rtols for h in coarse} | {(s.comm_rtol, h) for h in scene.comm_steps()}
    for rtol, h in sorted(fmu_points, key=lambda c: (-c[0], c[1])):
        out.append(Config("fmu", f"FMU rtol={rtol:.0e} h={h:g}", {"rtol": rtol, "comm_step": h},
                          lambda rtol=rtol, h=h: fmu.simulate(scene.start_values(rtol), T, h, FMU_OUTPUTS),
                          _from_columns))
    for rtol in s.me_rtols if fmu3 is not None else ():
        out.append(Config("fmi3-me", f"FMI 3 ME, CVode rtol={rtol:.0e}", {"rtol": rtol},
                          lambda rtol=rtol: fmu3.simulate(scene.start_values(s.comm_rtol), T, scene.grid_step,
                                                          FMU_OUTPUTS, fmi_type="ModelExchange",
                                                          relative_tolerance=rtol, record_events=False),
                          _from_columns))
    for rtol in s.me_rtols:  # the same CVode with no FMU: the model-exchange error that is the solver's own
        out.append(Config("cvode-bare", f"bare CVode rtol={rtol:.0e}", {"rtol": rtol},
                          lambda rtol=rtol: simulate_bare_cvode(scene, rtol), lambda run: run))
    if pure_fmu is not None:
        for rtol in s.fmu_rtols:
            out.append(Config("fmu-pure", f"pure FMU rtol={rtol:.0e} h={scene.grid_step:g}",
                              {"rtol": rtol, "comm_step": scene.grid_step},
                              lambda rtol=rtol: pure_fmu.simulate(scene.start_values(rtol), T, scene.grid_step,
                                                                  FMU_OUTPUTS),
                              _from_columns))
    return out


def _stepper_configs(scene):
    """Our stepper, compiled and in pure Python, replaying steps and integrating every one."""
    out = []
    for rtol in scene.sweep.stepper_rtols:
        for suffix, core in (("", compiled_core), ("-pure", PURE_CORE)):
            out.append(Config(f"stepper{suffix}", f"stepper{suffix} rtol={rtol:.0e}", {"rtol": rtol},
                              stepper_call(scene, rtol, core=core), lambda run: run))
            out.append(Config(f"stepper-integrating{suffix}", f"stepper{suffix}, no replay, rtol={rtol:.0e}",
                              {"rtol": rtol},
                              stepper_call(scene, rtol, reuse_steps=False, core=core),
                              lambda run: run))
    return out


def _peer_problem(scene):
    """What the solve_ivp peers take: ``(params, x0 m, v0 m/s, v_drive m/s, F_ext N, common grid s)``."""
    v_drive, F_ext = scene.inputs
    return scene.params, scene.scenario.x0, scene.scenario.v0, v_drive, F_ext, scene.grid()


def _solve_ivp_configs(scene):
    """The hybrid solve_ivp peer on the common grid, and on the coarse grid of the sweep (if it has one)."""
    s = scene.sweep
    p, x0, v0, v_drive, F_ext, grid = _peer_problem(scene)
    out = []
    for method, rtols in s.ivp.items():
        for rtol in rtols:
            out.append(Config("solve_ivp", f"{method} rtol={rtol:.0e}", {"method": method, "rtol": rtol, "atol": rtol},
                              lambda m=method, r=rtol: hybrid_solve_ivp(p, x0, v0, v_drive, F_ext, grid, m, r, r),
                              lambda run: run))
    h_c = coarse_step(scene)
    if h_c is not None:  # like with like for the FMU at h = h_c: solve_ivp asked for the same output times only
        every = round(h_c / scene.grid_step)
        for method, rtols in s.ivp.items():
            for rtol in rtols:
                out.append(Config(
                    "solve_ivp", f"{method} rtol={rtol:.0e} on the {h_c:g} s grid",
                    {"method": method, "rtol": rtol, "atol": rtol, "out_step": h_c},
                    lambda m=method, r=rtol: hybrid_solve_ivp(p, x0, v0, v_drive, F_ext, grid[::every], m, r, r),
                    lambda run: run))
    return out


def _regularized_configs(scene):
    """The regularized-friction peer over its methods, regularization speeds and rtols."""
    s = scene.sweep
    p, x0, v0, v_drive, F_ext, grid = _peer_problem(scene)
    out = []
    for method, rtols in s.regularized.items():
        for v_eps in s.v_eps:
            for rtol in rtols:
                out.append(Config(
                    "regularized", f"{method} v_eps={v_eps:.0e} rtol={rtol:.0e}",
                    {"method": method, "v_eps": v_eps, "rtol": rtol, "atol": rtol},
                    lambda m=method, e=v_eps, r=rtol:
                        regularized_solve_ivp(p, x0, v0, v_drive, F_ext, grid, e, m, r, r),
                    lambda run: run))
    return out


def timed(call, repeats, limit):
    """``(result of the warm-up call, [seconds of each of the repeats])``; TimeoutError past ``limit`` s a call."""
    result = _limited(call, limit)
    gc.collect()  # once, before the repeats: a collection before each would also empty CPython's free lists
    seconds = []  # (of floats, tuples, ...) and charge every call their refill, as no caller pays it (cf. timeit)
    for _ in range(repeats):
        gc.disable()
        try:
            seconds.append(_limited(call, limit, clock=True))
        finally:
            gc.enable()
    return result, seconds


def _limited(call, limit, clock=False):
    """``call()`` (or, with ``clock``, its duration in s), interrupted by SIGALRM after ``limit`` s."""

    def expire(signum, frame):
        raise TimeoutError(f"exceeded the time limit of {limit:g} s per call")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, limit)
    try:
        start = time.perf_counter()
        result = call()
        return time.perf_counter() - start if clock else result
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)


def accuracy(run, scene, window):
    """Errors of ``run`` against the scene's reference; event pairs within ``window`` s."""
    ref, step = scene.reference, scene.grid_step
    k = np.rint(run.t / step).astype(int)
    on_grid = (np.abs(run.t - k * step) <= 1e-9 * scene.stop_time) & (k < ref.t.size)
    dx = float(np.abs(run.x[on_grid] - ref.x[k[on_grid]]).max())
    errors = {"max_abs_dx": dx, "rel_dx": dx / scene.amplitude, "final_abs_dx": float(abs(run.x[-1] - ref.x[-1])),
              "final_abs_dv": float(abs(run.v[-1] - ref.v[-1]))}
    if run.events is not None:
        match = match_events(run.events, reference_events(ref), window)
        timed_events = sum(e.timed for e in run.events)
        errors.update(event_time_error=float(match.max_time_error) if timed_events else None,
                      events_timed=int(timed_events), events_matched=int(match.n_matched),
                      events_unmatched=int(match.n_unmatched))
    return errors


def measure(config, scene):
    """The JSON record of one configuration (``error`` holds the exception text if it failed)."""
    record = {"family": config.family, "label": config.label, "settings": config.settings}
    if "comm_step" in config.settings:
        record["n_comm_steps"] = round(scene.stop_time / config.settings["comm_step"])
    try:
        result, seconds = timed(config.simulate, scene.sweep.repeats, scene.sweep.time_limit)
    except Exception as exc:  # a peer that fails is a result, not a crash of the benchmark
        record["error"] = "".join(traceback.format_exception_only(exc)).strip()
        return record
    record.update(times_s=seconds, median_s=statistics.median(seconds), min_s=min(seconds), error=None)
    if config.extra is not None:
        record.update(config.extra(result))
    if config.to_run is not None:
        window = max(config.settings.get("comm_step", 0.0), scene.grid_step)
        run = config.to_run(result)
        record.update(accuracy(run, scene, window))
        if run.n_steps is not None:
            record["n_steps"] = run.n_steps
    return record


def run_scenes(scenes, fmu, floor, host=None, fmu3=None, pure_fmu=None):
    """``{scene name: [record, ...]}`` for every configuration, with a tqdm progress bar."""
    plan = [(scene, config) for scene in scenes for config in configs(scene, fmu, floor, host, fmu3, pure_fmu)]
    records = {scene.name: [] for scene in scenes}
    with tqdm(plan, unit="config", dynamic_ncols=True) as bar:
        for scene, config in bar:
            bar.set_postfix_str(f"{scene.name}: {config.label}")
            scene.reference  # noqa: B018 -- computed once, outside every timing
            records[scene.name].append(measure(config, scene))
    return records
