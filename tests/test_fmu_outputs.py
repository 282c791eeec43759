"""Outputs in one pass: any set of value references, in any order, reads the state the trajectory has."""

import random

import fmpy
import pytest

from stickslip.core import OUTPUT_NAMES, Parameters, Trajectory, kinetic_law, static_law

from fmu_instances import instantiate

AGING = {"M": 1.0, "kappa": 1.0, "kinetic.law": 3, "kinetic.F0": 0.4, "kinetic.F_stribeck": 0.3,
         "kinetic.v_stribeck": 0.05, "kinetic.gamma": 0.0, "static.law": 2, "static.F0": 1.0, "static.A": 0.3,
         "static.tau": 2.0, "v_drive": 0.1, "F_ext": 0.05}
FMU_NAME = {"friction_force": "F_friction", "spring_force": "F_spring"}  # Trajectory property -> FMU output


def _aging_trajectory():
    kinetic = kinetic_law(3, F0=0.4, F_stribeck=0.3, v_stribeck=0.05, gamma=0.0)
    return Trajectory(Parameters(1.0, 1.0, kinetic, static_law(2, F0=1.0, A=0.3, tau=2.0)), 0.0, 0.0,
                      v_drive=0.1, F_ext=0.05)


def test_outputs_are_the_properties_in_order_when_stuck_and_slipping():
    traj = _aging_trajectory()
    modes = set()
    for t in (0.0, 0.3, 2.0, 7.7, 11.0, 13.4, 25.0, 31.25):
        traj.advance_to(t)
        modes.add(traj.mode)
        assert traj.outputs() == tuple(getattr(traj, name) for name in OUTPUT_NAMES)
    assert modes == {0, 1}


def test_any_set_of_value_references_reads_the_state_of_the_trajectory(unzipped):
    variables = unzipped[2]
    fmu = instantiate(unzipped, "outputs", AGING)
    traj = _aging_trajectory()
    rng = random.Random(1)
    names = [FMU_NAME.get(name, name) for name in OUTPUT_NAMES]
    h = 0.7
    for k in range(40):
        fmu.doStep(k * h, h)
        traj.advance_to(k * h + h)  # the time the FMU advances to
        expected = {FMU_NAME.get(name, name): getattr(traj, name) for name in OUTPUT_NAMES}
        chosen = rng.sample(names, rng.randint(1, len(names)))  # a random subset in a random order
        for kind, get in (("Real", fmu.getReal), ("Integer", fmu.getInteger)):
            subset = [name for name in chosen if variables[name].type == kind]
            assert get([variables[name].valueReference for name in subset]) == [expected[n] for n in subset]
        assert fmu.getReal([variables["kappa"].valueReference, variables["x"].valueReference] * 2) == \
            [1.0, traj.x, 1.0, traj.x]
    fmu.terminate()
    fmu.freeInstance()


def test_reading_a_variable_as_the_wrong_type_is_an_error(unzipped):
    fmu = instantiate(unzipped, "wrong type", AGING)
    with pytest.raises(fmpy.fmi1.FMICallException):  # fatal: the instance is gone, so it is not freed
        fmu.getReal([unzipped[2]["mode"].valueReference])
