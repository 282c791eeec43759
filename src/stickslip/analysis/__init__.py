"""Nonlinear-dynamics analysis of the spring-block model (SPEC section 3): the Python API.

Attractors of long runs (:mod:`.classify`), continuous sliding and its Hopf points
(:mod:`.steady_sliding`), sliding limit cycles by shooting and continuation (:mod:`.sliding_limit_cycles`),
the stick-slip cycle and its existence margin (:mod:`.stickslip_cycle`), the special
stick-slip boundary (:mod:`.boundary`), the bifurcation diagram (:mod:`.bifurcation`),
critical drive velocities (:mod:`.critical`), the stick-slip map of aging static
friction (:mod:`.aging_map`), the strongly overdamped limit (:mod:`.overdamped`) and
parallel scans (:mod:`.parallel_scan`). Every slip is integrated by the batched exact-event
integrator of :mod:`.flow`.

Names are imported lazily (``stickslip.analysis.hopf_points`` loads :mod:`.steady_sliding`
on first use), so the command line starts fast.
"""

import importlib

_EXPORTS = {
    "classify": ("Attractor", "classify_run", "classify_samples", "simulate"),
    "steady_sliding": ("HopfPoint", "SlidingState", "continuous_sliding", "hopf_points"),
    "sliding_limit_cycles": ("Branch", "CyclePoint", "ReturnMap", "continue_branches", "cycle_at", "refine_folds",
                             "refine_grazings", "scan_cycles", "sliding_cycles"),
    "stickslip_cycle": ("OvershootCycle", "StickSlipCycle", "existence_changes", "grazing_margin", "onset",
                        "overshoot_cycles", "stick_slip_cycles"),
    "boundary": ("BoundaryOrbit", "boundary_margin", "boundary_switches", "graze_point", "special_boundary"),
    "bifurcation": ("Diagram", "bifurcation_diagram", "write_outputs"),
    "critical": ("CriticalVelocities", "critical_velocities"),
    "aging_map": ("StickSlipMap", "critical_velocity", "fixed_points", "lyapunov_exponent", "map_orbit",
                  "orbit_diagram", "saddle_nodes"),
    "overdamped": ("SlowManifold", "slow_manifold"),
    "parallel_scan": ("Chart", "Executor", "stability_chart"),
    "kinetic": ("derivatives", "extrema"),
}
_WHERE = {name: module for module, names in _EXPORTS.items() for name in names}
__all__ = sorted(_WHERE)


def __getattr__(name):
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'stickslip.analysis' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return __all__
