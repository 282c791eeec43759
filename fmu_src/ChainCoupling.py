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

Refusals (fmi2Error through the C loader, with a message naming the value and the allowed range; the instance goes
on): a position that is not finite, a stiffness that is not finite and >= 0 (or is set after initialization), when
it is set, the values of a call checked before any is taken; a force (or derivative) that overflows, when it is
read; bytes or a state that hold no state of this FMU, when they are deserialized or restored.
"""

import math
import struct

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

from loader_binding import (
    PYTHONFMU_ENTRY_POINTS, StateBytes, balance_release, offer_to_loader, refusal, serialized_states,
)

POSITIONS = {"x_left": "position of the left neighbour (m)", "x": "position of the block (m)",
             "x_right": "position of the right neighbour (m)"}
STIFFNESSES = {"kc_left": "stiffness of the spring to the left neighbour (N/m, >= 0)",
               "kc_right": "stiffness of the spring to the right neighbour (N/m, >= 0)"}
NAMES = (*POSITIONS, *STIFFNESSES, "F")  # in the order registered: the value references
MAX_OUTPUT_DERIVATIVE_ORDER = 1
#: what a position or a stiffness may be, as the refusals state it: (unit, lowest value or None, range's text)
ALLOWED = {**{name: ("m", None, "(-inf, inf)") for name in POSITIONS},
           **{name: ("N/m", 0.0, "[0, inf)") for name in STIFFNESSES}}


class ChainCoupling(Fmi2Slave):
    author = "stickslip"
    description = "Coupling springs of one block in a chain: F = kc_left (x_left - x) + kc_right (x_right - x)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.rates = {name: {} for name in POSITIONS}  # position: {order: value} set since its value
        self.initialized = False  # initialization ended: the stiffnesses are fixed
        for name, text in POSITIONS.items():
            setattr(self, name, 0.0)
            self.register_variable(Real(name, causality=Fmi2Causality.input, description=text))
        for name, text in STIFFNESSES.items():
            setattr(self, name, 0.0)
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed, description=text))
        self.register_variable(Real("F", causality=Fmi2Causality.output, getter=self.force,
                                    description="force of the springs on the block (N, positive along +x)"))
        offer_to_loader(self, self.resources, 2, NAMES.index("F"), "r")

    def to_xml(self, model_options=None):
        """PythonFMU's model description with the derivatives the C loader answers."""
        root = super().to_xml({**(model_options or {}), "canInterpolateInputs": True})
        root.find("CoSimulation").set("maxOutputDerivativeOrder", str(MAX_OUTPUT_DERIVATIVE_ORDER))
        return root

    def set_real(self, vrs, values):
        """Set positions (m, at any time) and stiffnesses (N/m, until initialization ends); every value is checked
        before any is taken, so a refused call changes nothing. Setting a position clears its derivatives."""
        changes = [(_name_in(reference, ALLOWED, "cannot be set: the settable variables are"), value)
                   for reference, value in zip(vrs, values)]
        for name, value in changes:
            if name in STIFFNESSES and self.initialized:
                raise ValueError(f"{name} is a fixed parameter: it cannot change after initialization")
            check_value(name, value)
        for name, value in changes:
            setattr(self, name, float(value))
            if name in POSITIONS:
                self.rates[name].clear()

    def force(self):
        """The springs' force on the block (N, +x); ValueError naming the values where it overflows."""
        return checked_springs(0, self.kc_left, self.kc_right, self.x_left, self.x, self.x_right)

    def save_state(self):
        """An FMU state, a tuple that nothing changes: the positions and stiffnesses (in :data:`ALLOWED` order) and
        each position's derivatives set, ``(order, value)`` pairs (no output)."""
        return (tuple(getattr(self, name) for name in ALLOWED),
                tuple(tuple(self.rates[name].items()) for name in POSITIONS))

    def restore_state(self, state):
        """Go back to a state from :meth:`save_state` (bytes that were no state: ValueError with their reason); True:
        the C loader has no step call to forget."""
        reason = refusal(state)
        if reason is not None:
            raise ValueError(reason)
        values, rates = state
        for name, value in zip(ALLOWED, values):
            setattr(self, name, value)
        self.rates = {name: dict(pairs) for name, pairs in zip(POSITIONS, rates)}
        return True

    def _get_fmu_state(self):
        return self.save_state()

    def _set_fmu_state(self, state):
        self.restore_state(state)

    def exit_initialization_mode(self):
        self.initialized = True

    def do_step(self, current_time, step_size):
        return True

    # ---- what the C loader calls (src/stickslip/fmu/loader/fast_path.h) -------------------------

    def fast_step_call(self):
        """None: the steps go through PythonFMU (there is nothing to step)."""
        return None

    def outputs_changed(self):
        """Nothing is cached."""

    def set_real_input_derivatives(self, references, orders, values):
        """fmi2SetRealInputDerivatives: the derivatives of the positions (m/s^order), kept until the value is set;
        every one is checked before any is taken."""
        changes = [(_name_in(reference, POSITIONS, "is not an input: input derivatives are set for"), order, value)
                   for reference, order, value in zip(references, orders, values)]
        for name, order, value in changes:
            if not (order >= 1 and math.isfinite(value)):
                raise ValueError(f"der({name}, {order}) = {value!r} is out of range: allowed is a finite value, of "
                                 f"order 1 or more")
        for name, order, value in changes:
            self.rates[name][order] = float(value)

    def get_real_output_derivatives(self, references, orders):
        """fmi2GetRealOutputDerivatives: ``F``'s derivatives of order 1 to :data:`MAX_OUTPUT_DERIVATIVE_ORDER`
        (N/s^order); ValueError naming the values where one overflows."""
        answers = []
        for reference, order in zip(references, orders):
            if reference != NAMES.index("F") or not 1 <= order <= MAX_OUTPUT_DERIVATIVE_ORDER:
                name = NAMES[reference] if 0 <= reference < len(NAMES) else f"valueReference={reference}"
                raise ValueError(f"no derivative of order {order} of {name}: output derivatives are given for F, of "
                                 f"order 1 to {MAX_OUTPUT_DERIVATIVE_ORDER}")
            answers.append(checked_springs(order, self.kc_left, self.kc_right,
                                           *(self.rates[name].get(order, 0.0) for name in POSITIONS)))
        return tuple(answers)


def _name_in(reference, names, refusal):
    """The name of the variable with value reference ``reference`` if it is one of ``names``, else a ValueError
    naming it, with the text ``refusal`` and ``names`` after it."""
    name = NAMES[reference] if 0 <= reference < len(NAMES) else None
    if name not in names:
        raise ValueError(f"valueReference={reference}{f' ({name})' if name else ''} {refusal} {', '.join(names)}")
    return name


def check_value(name, value):
    """Raise ValueError naming ``name`` (a position or a stiffness) unless ``value`` is in its range
    (:data:`ALLOWED`)."""
    unit, lowest, text = ALLOWED[name]
    if not (isinstance(value, (int, float)) and math.isfinite(value) and (lowest is None or value >= lowest)):
        raise ValueError(f"{name} = {value!r} {unit} is out of range: allowed is a finite value in {text}")


def pack_state(state):
    """The bytes of a state from :meth:`ChainCoupling.save_state` after its header (loader_binding), as a list of
    parts, little-endian: the positions and stiffnesses (:data:`ALLOWED` order), 8-byte floats; then for each position
    the count of its derivatives set (2 bytes) and each one's order (8-byte integer) and value (8-byte float)."""
    values, rates = state
    parts = [_VALUES.pack(*values)]
    for pairs in rates:
        parts.append(_COUNT.pack(len(pairs)))
        parts += [_RATE.pack(order, value) for order, value in sorted(pairs)]
    return parts


def unpack_state(data, offset):
    """The state (:meth:`ChainCoupling.save_state`) that :func:`pack_state` packed at ``offset`` of ``data``, up to
    its end, every field checked (ValueError naming the first out of place or range)."""
    values = _unpacked(_VALUES, data, offset, "positions and stiffnesses")
    offset += _VALUES.size
    for name, value in zip(ALLOWED, values):
        check_value(name, value)
    rates = []
    for name in POSITIONS:
        (count,) = _unpacked(_COUNT, data, offset, f"count of the derivatives of {name}")
        offset += _COUNT.size
        pairs = {}
        for _ in range(count):
            order, value = _unpacked(_RATE, data, offset, f"derivatives of {name}")
            offset += _RATE.size
            if not (order >= 1 and math.isfinite(value)):
                raise ValueError(f"saved state der({name}, {order}) = {value!r}: allowed is a finite value, of order "
                                 f"1 or more")
            pairs[order] = value
        rates.append(tuple(pairs.items()))
    if offset != len(data):
        raise ValueError(f"the {len(data)} bytes are not a serialized FMU state of this FMU: they go on after the "
                         f"state, which ends at byte {offset}")
    return values, tuple(rates)


_VALUES, _COUNT, _RATE = struct.Struct(f"<{len(ALLOWED)}d"), struct.Struct("<H"), struct.Struct("<qd")


def _unpacked(layout, data, offset, what):
    """The values of ``layout`` at ``offset`` of ``data`` (ValueError naming ``what`` if the bytes end before)."""
    if offset + layout.size > len(data):
        raise ValueError(f"the {len(data)} bytes are not a serialized FMU state of this FMU: they end within its "
                         f"{what} (bytes {offset} to {offset + layout.size})")
    return layout.unpack_from(data, offset)


def springs(kc_left, kc_right, left, middle, right):
    """``kc_left (left - middle) + kc_right (right - middle)``: the force (N) at the positions (m), or its time
    derivative of order k (N/s^k) at the positions' derivatives of order k (m/s^k): it is linear in them. A spring of
    stiffness 0 adds nothing, whatever its neighbour's position."""
    return (kc_left * (left - middle) if kc_left else 0.0) + (kc_right * (right - middle) if kc_right else 0.0)


def checked_springs(order, kc_left, kc_right, left, middle, right):
    """:func:`springs` of the positions' derivatives of order ``order`` (0: the positions), with a ValueError naming
    the values where it is not finite."""
    value = springs(kc_left, kc_right, left, middle, right)
    if not math.isfinite(value):
        name, unit = ("F", "N") if order == 0 else (f"der(F, {order})", f"N/s^{order}")
        inputs = ", ".join(name if order == 0 else f"der({name}, {order})" for name in POSITIONS)
        raise ValueError(f"{name} = {value!r} {unit} is not finite: the springs' force overflows at kc_left = "
                         f"{kc_left!r} N/m, kc_right = {kc_right!r} N/m and {inputs} = {left!r}, {middle!r}, "
                         f"{right!r}; allowed are values whose force is a finite value in (-inf, inf)")
    return value


balance_release(ChainCoupling, PYTHONFMU_ENTRY_POINTS)
_STATE_BYTES = StateBytes(f"ChainCoupling FMI 2: {' '.join(ALLOWED)} der({', '.join(POSITIONS)})", pack_state,
                          unpack_state)
serialized_states(ChainCoupling, _STATE_BYTES.to_bytes, _STATE_BYTES.from_bytes)
