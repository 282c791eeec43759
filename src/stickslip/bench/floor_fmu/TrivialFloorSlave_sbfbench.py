"""The benchmark's floor: a PythonFMU co-simulation slave that does no work.

It has outputs of the same names and kinds as those the benchmark records from
SpringBlockFriction (3 Real, 3 Integer), all constant, and an empty ``do_step``:
driving it with FMPy measures what one communication step costs FMPy, PythonFMU
and the recording alone. The module name is unique so that it never collides
with another FMU's module in the importing process.
"""

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real

REALS = ("x", "v", "v_rel", "F_friction", "F_spring", "t_stick", "z_slip", "z_stick")
DISCRETE_REALS = ("t_last_event",)
INTEGERS = ("mode", "n_events", "n_stick_events", "n_slip_events", "n_overshoots", "n_steps")


class TrivialFloor(Fmi2Slave):
    """Constant outputs (0); every step succeeds at once."""

    author = "stickslip benchmarks"
    description = "Empty co-simulation slave: the per-step cost floor of FMPy + PythonFMU"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for names, kind, zero, variability in ((REALS, Real, 0.0, Fmi2Variability.continuous),
                                               (DISCRETE_REALS, Real, 0.0, Fmi2Variability.discrete),
                                               (INTEGERS, Integer, 0, Fmi2Variability.discrete)):
            for name in names:
                setattr(self, name, zero)
                self.register_variable(kind(name, causality=Fmi2Causality.output, variability=variability))

    def do_step(self, current_time, step_size):
        return True
