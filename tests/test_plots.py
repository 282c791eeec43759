"""Helpers of the scenario figure (issue 11): the initial stick and the held drive velocities."""

import numpy as np

from stickslip.suite.scenario_plots import held_levels, initial_stick


def test_initial_stick_is_the_stick_before_the_first_slip():
    assert initial_stick([0, 0, 0, 1, 1, 0, 0]).tolist() == [True, True, True, False, False, False, False]
    assert not initial_stick([1, 0, 0]).any()  # starts slipping: its later sticks are real sticks
    assert initial_stick([0, 0]).all()  # never slips
    assert initial_stick([]).size == 0


def test_held_levels_skip_a_ramp():
    ramp = np.linspace(0.0, 0.5, 20)
    v_drive = np.r_[ramp, [0.5] * 10, [0.05] * 10, [0.2] * 3]
    assert held_levels(v_drive).tolist() == [0.05, 0.5]  # 0.2 is held for 3 samples only
    assert held_levels(v_drive, samples=3).tolist() == [0.05, 0.2, 0.5]
