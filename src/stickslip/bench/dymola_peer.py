"""The compiled peer of the C-host benchmarks: the Modelica Standard Library's friction pendulum as Dymola 2023x exports it
(``SpringFrictionPendulum1D.fmu`` of ThummeTo/FMIZoo.jl, ``models/bin/Dymola/2023x/2.0/``), a benchmark input
read from a path, never a test dependency.

Its block is ``mass`` (``MassWithStopAndFriction``, L = 0) on ``spring`` (rest length ``s_rel0``) from
``fixed`` (at ``s0``): our ``x`` is ``mass.s - (fixed.s0 + spring.s_rel0)`` (m). The MSL friction force
``F_Coulomb + F_prop |v| + F_Stribeck exp(-fexp |v|)`` is our Stribeck law with ``F0 = F_Coulomb``,
``F_stribeck = F_Stribeck``, ``v_stribeck = 1/fexp``, ``delta = 1``, ``gamma = F_prop``, and it sticks while
the force stays within ``F_Coulomb + F_Stribeck`` (our constant ``F_S``).
"""

import math

import fmpy

from .c_hosts import Subject

#: our start value: the peer's quantity it equals, from the peer's values at t = 0 (see the module text)
MAPPING = {
    "M": lambda p: p["mass.m"],
    "kappa": lambda p: p["spring.c"],
    "x_start": lambda p: p["mass.s"] - p["fixed.s0"] - p["spring.s_rel0"],
    "v_start": lambda p: p["mass.v"],
    "kinetic.F0": lambda p: p["mass.F_Coulomb"],
    "kinetic.F_stribeck": lambda p: p["mass.F_Stribeck"],
    "kinetic.v_stribeck": lambda p: 1.0 / p["mass.fexp"],
    "kinetic.delta": lambda p: 1.0,
    "kinetic.gamma": lambda p: p["mass.F_prop"],
    "static.F0": lambda p: p["mass.F_Coulomb"] + p["mass.F_Stribeck"],
}
READ = ("mass.m", "spring.c", "mass.s", "fixed.s0", "spring.s_rel0", "mass.v", "mass.F_Coulomb", "mass.F_Stribeck",
        "mass.fexp", "mass.F_prop")


def peer_values(fmu_path):
    """The peer's quantities of :data:`READ` at t = 0, read through FMPy from an instance after initialization."""
    result = fmpy.simulate_fmu(str(fmu_path), stop_time=0.01, output_interval=0.01, output=list(READ))
    return {name: float(result[name][0]) for name in READ}


def mismatches(fmu_path, scene):
    """``[(our name, ours, the peer's)]`` where the scene's start values and the peer's differ (relative 1e-12):
    empty when the peer runs the scene."""
    values, ours = peer_values(fmu_path), scene.start_values(1e-10)
    out = []
    for name, peer_value in MAPPING.items():
        theirs = peer_value(values)
        if not math.isclose(ours[name], theirs, rel_tol=1e-12, abs_tol=1e-15):
            out.append((name, ours[name], theirs))
    return out


def subject(fmu_path):
    """The peer as a host runs it: ``mass.s`` read each step, offset to our ``x``, its own start values."""
    values = peer_values(fmu_path)
    return Subject("peer (Dymola)", fmu_path, "mass.s", {}, values["fixed.s0"] + values["spring.s_rel0"])
