"""ChainCoupling: the coupling springs that act on one block of a chain, as an FMI 2 co-simulation slave (PythonFMU).

Inputs: the positions ``x_left``, ``x``, ``x_right`` (m) of the left neighbour, the block and the right neighbour;
parameters: the stiffnesses ``kc_left``, ``kc_right`` (N/m, >= 0; 0 where the block has no neighbour, whose
position is then unused); output: ``F`` (N), the springs' force on the block, positive along +x (SPEC section 5):

    F = kc_left (x_left - x) + kc_right (x_right - x)

``F`` follows the inputs at once (direct feedthrough, no state): an engine that reads it after setting the
inputs gets the force at those positions. The step does nothing.
"""

import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

POSITIONS = {"x_left": "position of the left neighbour (m)", "x": "position of the block (m)",
             "x_right": "position of the right neighbour (m)"}
STIFFNESSES = {"kc_left": "stiffness of the spring to the left neighbour (N/m, >= 0)",
               "kc_right": "stiffness of the spring to the right neighbour (N/m, >= 0)"}


class ChainCoupling(Fmi2Slave):
    author = "stickslip"
    description = "Coupling springs of one block in a chain: F = kc_left (x_left - x) + kc_right (x_right - x)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for name, text in POSITIONS.items():
            setattr(self, name, 0.0)
            self.register_variable(Real(name, causality=Fmi2Causality.input, description=text))
        for name, text in STIFFNESSES.items():
            setattr(self, name, 0.0)
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed, description=text))
        self.register_variable(Real("F", causality=Fmi2Causality.output, getter=self.force,
                                    description="force of the springs on the block (N, positive along +x)"))

    def force(self):
        """The springs' force on the block (N, +x)."""
        return self.kc_left * (self.x_left - self.x) + self.kc_right * (self.x_right - self.x)

    def exit_initialization_mode(self):
        for name in STIFFNESSES:
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} = {value!r} N/m is out of range: allowed is a finite value in [0, inf)")
        return True

    def do_step(self, current_time, step_size):
        return True
