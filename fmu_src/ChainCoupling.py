"""ChainCoupling: the coupling springs that act on one block of a chain, as an FMI 2 co-simulation slave (PythonFMU).

Inputs: the positions ``x_left``, ``x``, ``x_right`` (m) of the left neighbour, the block and the right neighbour;
parameters: the stiffnesses ``kc_left``, ``kc_right`` (N/m, >= 0; 0 where the block has no neighbour, whose
position is then unused); output: ``F`` (N), the springs' force on the block, positive along +x (SPEC section 5):

    F = kc_left (x_left - x) + kc_right (x_right - x)

``F`` follows the inputs at once (direct feedthrough, no state): an engine that reads it after setting the
inputs gets the force at those positions. The step does nothing.

Derivatives (FMI 2, answered through the C loader, which PythonFMU lacks; canInterpolateInputs,
maxOutputDerivativeOrder = 1): the derivatives of the positions that a master sets (fmi2SetRealInputDerivatives, any
order; setting a position's value clears its derivatives) give ``F``'s, ``d^k F/dt^k = kc_left (x_left^(k) - x^(k))
+ kc_right (x_right^(k) - x^(k))`` (fmi2GetRealOutputDerivatives), so that a master that extrapolates inputs from
output derivatives passes the neighbours' velocities on to the block's ``F_ext``. The order declared is 1, the one
the block takes: OMSimulator asks for the declared order only (never the lower ones) and passes it on as is. The
FMU state (the inputs, the stiffnesses and the derivatives set) can be saved and restored, so that a master can
redo a step.
"""

import functools
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

from loader_binding import offer_to_loader

POSITIONS = {"x_left": "position of the left neighbour (m)", "x": "position of the block (m)",
             "x_right": "position of the right neighbour (m)"}
STIFFNESSES = {"kc_left": "stiffness of the spring to the left neighbour (N/m, >= 0)",
               "kc_right": "stiffness of the spring to the right neighbour (N/m, >= 0)"}
NAMES = (*POSITIONS, *STIFFNESSES, "F")  # in the order registered: the value references
MAX_OUTPUT_DERIVATIVE_ORDER = 1


class ChainCoupling(Fmi2Slave):
    author = "stickslip"
    description = "Coupling springs of one block in a chain: F = kc_left (x_left - x) + kc_right (x_right - x)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.rates = {name: {} for name in POSITIONS}  # position: {order: value} set since its value
        for name, text in POSITIONS.items():
            setattr(self, name, 0.0)
            self.register_variable(Real(name, causality=Fmi2Causality.input, description=text,
                                        setter=functools.partial(self._set_position, name)))
        for name, text in STIFFNESSES.items():
            setattr(self, name, 0.0)
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed, description=text))
        self.register_variable(Real("F", causality=Fmi2Causality.output, getter=self.force,
                                    description="force of the springs on the block (N, positive along +x)"))
        offer_to_loader(self, self.resources, "linux64", NAMES.index("F"), "r")

    def to_xml(self, model_options=None):
        """PythonFMU's model description with the derivatives the C loader answers."""
        root = super().to_xml({**(model_options or {}), "canInterpolateInputs": True})
        root.find("CoSimulation").set("maxOutputDerivativeOrder", str(MAX_OUTPUT_DERIVATIVE_ORDER))
        return root

    def _set_position(self, name, value):
        setattr(self, name, value)
        self.rates[name].clear()

    def force(self):
        """The springs' force on the block (N, +x)."""
        return springs(self.kc_left, self.kc_right, self.x_left, self.x, self.x_right)

    def _get_fmu_state(self):
        """PythonFMU's state (every variable's value) and the derivatives set, as ``[order, value]`` pairs."""
        return {**super()._get_fmu_state(), "rates": {name: sorted(r.items()) for name, r in self.rates.items()}}

    def _set_fmu_state(self, state):
        values = dict(state)
        rates = values.pop("rates")
        super()._set_fmu_state(values)  # setting the positions clears their derivatives: restored after
        self.rates = {name: {int(order): float(value) for order, value in pairs} for name, pairs in rates.items()}

    def exit_initialization_mode(self):
        for name in STIFFNESSES:
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} = {value!r} N/m is out of range: allowed is a finite value in [0, inf)")
        return True

    def do_step(self, current_time, step_size):
        return True

    # ---- what the C loader calls (src/stickslip/fmu/loader/fast_path.h) -------------------------

    def fast_step_call(self):
        """None: the steps go through PythonFMU (there is nothing to step)."""
        return None

    def outputs_changed(self):
        """Nothing is cached."""

    def set_real_input_derivatives(self, references, orders, values):
        """fmi2SetRealInputDerivatives: the derivatives of the positions (m/s^order), kept until the value is set."""
        for reference, order, value in zip(references, orders, values):
            name = NAMES[reference] if 0 <= reference < len(NAMES) else None
            if name not in POSITIONS:
                raise ValueError(f"valueReference={reference} is not an input: input derivatives are set for "
                                 f"{', '.join(POSITIONS)}")
            if not (order >= 1 and math.isfinite(value)):
                raise ValueError(f"der({name}, {order}) = {value!r} is out of range: allowed is a finite value, of "
                                 f"order 1 or more")
            self.rates[name][order] = float(value)

    def get_real_output_derivatives(self, references, orders):
        """fmi2GetRealOutputDerivatives: ``F``'s derivatives of order 1 to 2 (N/s^order)."""
        answers = []
        for reference, order in zip(references, orders):
            if reference != NAMES.index("F") or not 1 <= order <= MAX_OUTPUT_DERIVATIVE_ORDER:
                name = NAMES[reference] if 0 <= reference < len(NAMES) else f"valueReference={reference}"
                raise ValueError(f"no derivative of order {order} of {name}: output derivatives are given for F, of "
                                 f"order 1 to {MAX_OUTPUT_DERIVATIVE_ORDER}")
            answers.append(springs(self.kc_left, self.kc_right,
                                   *(self.rates[name].get(order, 0.0) for name in POSITIONS)))
        return tuple(answers)


def springs(kc_left, kc_right, left, middle, right):
    """``kc_left (left - middle) + kc_right (right - middle)``: the force (N) at the positions (m), or its time
    derivative of order k (N/s^k) at the positions' derivatives of order k (m/s^k): it is linear in them."""
    return kc_left * (left - middle) + kc_right * (right - middle)
