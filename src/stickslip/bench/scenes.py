"""The benchmark's scenes (scenario files with the benchmark's horizon and grid) and sweeps.

A scene is a scenario of ``scenarios/`` with constant inputs, a horizon
``stop_time`` (s) and a common output grid of step ``grid_step`` (s) on which
every method's ``x`` is compared with the reference. A :class:`Sweep` lists the
configurations run on a scene.
"""

from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from ..reference import parameters_from_values, simulate_reference
from ..suite.scenario import load_scenario

#: the scenario files the scenes run: the project's ``scenarios/`` (the benchmark runs in a checkout)
SCENARIO_DIR = Path("scenarios")
REFERENCE_RTOL = 1e-13  # the reference integrator's tightest useful tolerance


@dataclass(frozen=True)
class Sweep:
    """Configurations: tolerances (relative), communication steps (s), ``v_eps`` (m/s), repeats."""

    fmu_rtols: tuple = (1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12)  # every decade, like every other family
    comm_steps: tuple = (1e-3, 1e-2, 0.1, 1.0, 10.0)
    comm_rtol: float = 1e-10  # FMU tolerance of the communication steps finer than the grid's
    max_comm_steps: int = 100_000  # communication steps above this many per run are skipped
    stepper_rtols: tuple = (1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13)
    me_rtols: tuple = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11)  # FMI 3 model exchange: CVode's rtol
    ivp: dict = field(default_factory=lambda: {
        "RK45": (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12),
        "DOP853": (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12),
        "LSODA": (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12),
        "Radau": (1e-4, 1e-5, 1e-6, 1e-7, 1e-8),  # 1e-10 costs seconds per call and is never the fastest
    })
    v_eps: tuple = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6)
    regularized: dict = field(default_factory=lambda: {"LSODA": (1e-6, 1e-8, 1e-10), "Radau": (1e-8,)})
    repeats: int = 5  # timed runs after one warm-up; the median is reported
    time_limit: float = 3.0  # s per call; a configuration that exceeds it is reported as failed


LONG_SWEEP = Sweep(
    fmu_rtols=(1e-8, 1e-10, 1e-12), comm_steps=(1.0, 10.0), stepper_rtols=(1e-8, 1e-10, 1e-12, 1e-13),
    me_rtols=(1e-6, 1e-8, 1e-10),
    ivp={"DOP853": (1e-8, 1e-10, 1e-12), "LSODA": (1e-8, 1e-10, 1e-12)},
    v_eps=(1e-3, 1e-4), regularized={"LSODA": (1e-8,)}, time_limit=10.0,
)

CONTINUOUS_SWEEP = Sweep(  # every step integrated (continuous sliding): the cost of one Runge-Kutta step
    fmu_rtols=(1e-8, 1e-10), comm_steps=(1.0, 10.0), stepper_rtols=(1e-8, 1e-10),
    ivp={"DOP853": (1e-8, 1e-10), "LSODA": (1e-8, 1e-10)}, v_eps=(1e-3,), regularized={}, repeats=3,
    time_limit=10.0,
)

QUICK_SWEEP = Sweep(
    fmu_rtols=(1e-6, 1e-10), comm_steps=(0.1, 1.0), stepper_rtols=(1e-6, 1e-10), ivp={"DOP853": (1e-6, 1e-10)},
    me_rtols=(1e-6,),
    v_eps=(1e-2, 1e-4), regularized={"LSODA": (1e-8,)}, repeats=1,
)


@dataclass(frozen=True)
class Scene:
    """A scenario file run to ``stop_time`` (s), compared on a grid of step ``grid_step`` (s)."""

    name: str
    scenario_file: str
    stop_time: float
    grid_step: float
    sweep: Sweep = Sweep()

    @cached_property
    def scenario(self):
        return load_scenario(SCENARIO_DIR / self.scenario_file)

    @property
    def params(self):
        return self.scenario.params

    @property
    def inputs(self):
        """Constant ``(v_drive, F_ext)`` (m/s, N); the benchmark's peers take constant inputs only."""
        table = self.scenario.input_table()
        if len(table) != 1:
            raise ValueError(f"scene {self.name}: the benchmark needs constant inputs")
        return float(table["v_drive"][0]), float(table["F_ext"][0])

    def grid(self):
        """The common output grid (s), from 0 to ``stop_time``."""
        return np.linspace(0.0, self.stop_time, round(self.stop_time / self.grid_step) + 1)

    def start_values(self, rtol):
        """FMU start values: the scenario's parameters and state, the constant inputs, ``solver.rtol``."""
        v_drive, F_ext = self.inputs
        return {**self.scenario.start_values(), "v_drive": v_drive, "F_ext": F_ext, "solver.rtol": rtol}

    def comm_steps(self):
        """The sweep's communication steps (s) that divide ``stop_time`` and stay within ``max_comm_steps``."""
        return tuple(h for h in self.sweep.comm_steps
                     if abs(round(self.stop_time / h) * h - self.stop_time) <= 1e-9 * self.stop_time
                     and round(self.stop_time / h) <= self.sweep.max_comm_steps)

    @cached_property
    def reference(self):
        """The reference on the grid (closed forms for affine laws, else DOP853 at REFERENCE_RTOL)."""
        v_drive, F_ext = self.inputs
        return simulate_reference(parameters_from_values(self.scenario.law_values), self.scenario.x0, self.scenario.v0, [(0.0, v_drive, F_ext)],
                                  self.grid(), rtol=REFERENCE_RTOL)

    @property
    def amplitude(self):
        """Half the reference's range of ``x`` (m): errors are quoted relative to it."""
        return 0.5 * float(np.ptp(self.reference.x))


SCENES = {
    scene.name: scene for scene in (
        Scene("coulomb", "coulomb-stick-slip.toml", 100.0, 0.05),
        Scene("elmer-fig3-v0.1", "elmer-fig3-v0.1.toml", 300.0, 0.1),
        Scene("elmer-fig3-v0.3", "elmer-fig3-v0.3.toml", 300.0, 0.1),
        Scene("stribeck-release", "stationary-stribeck-release.toml", 30.0, 0.02),
        Scene("overdamped", "overdamped-stribeck.toml", 60.0, 0.02),
        Scene("elmer-fig3-v0.1-long", "elmer-fig3-v0.1.toml", 1e4, 1.0, LONG_SWEEP),
        Scene("elmer-fig3-v1.0-long", "elmer-fig3-v1.0.toml", 1e4, 1.0, CONTINUOUS_SWEEP),
        Scene("msl-pendulum", "msl-pendulum.toml", 5.0, 0.01),
    )
}


def select_scenes(names=None, quick=False):
    """Scenes by name (default: all); ``quick`` shortens them to 20 s with :data:`QUICK_SWEEP`."""
    unknown = set(names or ()) - set(SCENES)
    if unknown:
        raise ValueError(f"unknown scene(s) {sorted(unknown)}; known: {sorted(SCENES)}")
    scenes = [SCENES[n] for n in (names or SCENES)]
    if quick:
        scenes = [replace(s, stop_time=20.0, grid_step=0.1, sweep=QUICK_SWEEP) for s in scenes]
    return scenes
