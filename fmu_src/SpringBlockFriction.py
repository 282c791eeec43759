"""SpringBlockFriction: FMI 2.0 slave (co-simulation, and model exchange through the C loader) of the spring-block
dry-friction model.

A thin adapter between PythonFMU and the runtime's :class:`Trajectory`, which
does all the physics and its own event location (SPEC sections 1, 2 and 4).
Parameters are checked when initialization ends: an invalid one raises the
runtime's ``ParameterError``, which reaches the importer as an FMI error with
the parameter's name and allowed range. The variable table and the bookkeeping
are shared with the FMI 3 slave (``block_interface``); ``build_fmu.py`` bundles
both and the runtime under names only this FMU uses and rewrites the imports.

Values are answered by value reference from one list, the outputs from one
evaluation of the state per state change (:meth:`SpringBlockFriction.get_real`
and friends): PythonFMU's per-variable getters are made only to write the model
description.

Model exchange, which PythonFMU lacks, is answered by the FMU's C loader through :meth:`model_exchange`, with the
FMI 3 slave's model exchange (``block_interface.ExchangeInterface``): the states ``x`` and ``v``, their derivatives
``der(x)`` and ``der(v)`` (the two variables after the table) and three event indicators.

PythonFMU (0.7.0) reports every exception of the slave as ``fmi2Fatal``. Its
only other failure status, ``fmi2Discard`` for a ``do_step`` that returns
False, comes with ``fmi2Terminated = true``, which FMPy's ``simulate_fmu``
takes for a normal early end (no exception, the results cut short), so every
failure raises. PythonFMU's release of the slave on an exception is balanced
here (``balance_release``): an importer that terminates and frees the
instance after the error, as libcosim does, does not crash.
"""

import math
import operator
from xml.etree.ElementTree import Element

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real

from block_interface import (
    DERIVATIVES, F_EXT_RATE, FIRST_OUTPUT, INDICATORS, MAX_OUTPUT_DERIVATIVE_ORDER, PYTHONFMU_ENTRY_POINTS, STATES, VARIABLES,
    BlockInterface, ExchangeInterface, balance_release, serialize_states,
)

_CAUSALITY = {"parameter": Fmi2Causality.parameter, "input": Fmi2Causality.input, "output": Fmi2Causality.output}
_VARIABILITY = {name: getattr(Fmi2Variability, name) for name in ("fixed", "continuous", "discrete")}
_KIND = {"real": Real, "integer": Integer}

_REFERENCE_OF = {v.name: reference for reference, v in enumerate(VARIABLES)}
#: the state derivatives' value references follow the table's (model exchange: der(x), der(v))
FIRST_DERIVATIVE = len(VARIABLES)
_NAMES = tuple(v.name for v in VARIABLES) + tuple(name for name, _, _ in DERIVATIVES)
_REFERENCES = {Real: frozenset(r for r, v in enumerate(VARIABLES) if v.kind == "real") | frozenset(
    range(FIRST_DERIVATIVE, len(_NAMES))), Integer: frozenset(r for r, v in enumerate(VARIABLES) if v.kind == "integer")}
#: the inputs the C loader may keep between steps (BlockInterface.kept_inputs): (name, value reference, order), the
#: rate as F_ext's first input derivative (fmi2SetRealInputDerivatives)
_KEPT_INPUTS = (("v_drive", _REFERENCE_OF["v_drive"], 0), ("F_ext", _REFERENCE_OF["F_ext"], 0),
                (F_EXT_RATE, _REFERENCE_OF["F_ext"], 1))
_MAX_READ_PLANS = 64  # distinct sets of value references whose checked reader an instance keeps


class SpringBlockFriction(ExchangeInterface, Fmi2Slave, BlockInterface):
    """Block of mass M on a moving surface, tied to a wall by a spring; dry friction with stick, slip and aging."""

    author = "stickslip"
    description = "Spring-block dry friction (Elmer 1997) with exact stick-slip events"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.init_block()
        self.init_exchange()
        for name, unit, _ in DERIVATIVES:
            self.variable_units[name], self.variable_bounds[name] = unit, (None, None)
        # every value by value reference, the state derivatives last; outputs and derivatives may be stale
        self._by_reference = [v.start for v in VARIABLES] + [0.0] * len(DERIVATIVES)
        self._outputs_stale = True  # the outputs' part needs an evaluation at the current state
        self._values_stale = False  # the parameters' and inputs' part needs their values (a state was restored)
        self._derivatives_stale = True  # and the state derivatives' part
        self._read_plans = {}  # (type, value references) -> (read, needs), see _read_plan
        self.offer_to_loader(2)

    def to_xml(self, model_options=None):
        """PythonFMU's model description, with the variables registered for it first, and what the C loader answers:
        the input and output derivatives (canInterpolateInputs, maxOutputDerivativeOrder) and model exchange (a
        ModelExchange element of the same model identifier, the state derivatives, the event indicators)."""
        if not self.vars:
            self.register_variables(_KIND, _CAUSALITY, _VARIABILITY)
            for index, (name, _, text) in enumerate(DERIVATIVES):
                self.register_variable(Real(name, causality=Fmi2Causality.local, variability=Fmi2Variability.continuous,
                                            description=text, getter=lambda i=index: self._state_derivative(i)),
                                       nested=False)
        root = super().to_xml({**(model_options or {}), "canInterpolateInputs": True})
        co_simulation = root.find("CoSimulation")
        co_simulation.set("maxOutputDerivativeOrder", str(MAX_OUTPUT_DERIVATIVE_ORDER))
        exchange = {key: co_simulation.get(key) for key in ("modelIdentifier", "canNotUseMemoryManagementFunctions")}
        exchange["completedIntegratorStepNotNeeded"] = "true"  # the FMU state capabilities: the builder's
        root.insert(list(root).index(co_simulation), Element("ModelExchange", exchange))
        root.set("numberOfEventIndicators", str(len(INDICATORS)))
        for (name, _, _), state in zip(DERIVATIVES, STATES):
            self._scalar(root, name).find("Real").set("derivative", str(_REFERENCE_OF[state] + 1))
        return root

    @staticmethod
    def _scalar(root, name):
        """The ScalarVariable ``name`` of the model description ``root``."""
        return next(v for v in root.find("ModelVariables") if v.get("name") == name)

    # ---- values of any set of variables ------------------------------------------

    def _read(self, kind, references):
        """The values of the variables ``references`` of type ``kind`` as a list (TypeError for another type)."""
        key = (kind, tuple(references))
        plan = self._read_plans.get(key)
        if plan is None:
            plan = self._read_plan(kind, key[1])
        read, needs = plan
        if self._values_stale:
            self._by_reference[:FIRST_OUTPUT] = [self.values[v.name] for v in VARIABLES[:FIRST_OUTPUT]]
            self._values_stale = False
        if needs >= FIRST_OUTPUT and self._outputs_stale:
            self._by_reference[FIRST_OUTPUT:FIRST_DERIVATIVE] = self.current_state().outputs()
            self._outputs_stale = False
        if needs >= FIRST_DERIVATIVE and self._derivatives_stale:
            self._by_reference[FIRST_DERIVATIVE:] = [self._state_derivative(i) for i in range(len(DERIVATIVES))]
            self._derivatives_stale = False
        return read(self._by_reference)

    def _state_derivative(self, index):
        """``der(x)`` (m/s, index 0) or ``der(v)`` (m/s2, index 1) at the current state: the model-exchange block's
        once the host made a model-exchange call, else as the trajectory's mode continues."""
        if self.exchange:
            return self._block_now().derivatives()[index]
        trajectory = self.current_trajectory()
        return trajectory.v if index == 0 else trajectory.acceleration()[0]

    def _read_plan(self, kind, references):
        """``(read, needs)`` for a set of value references, checked once and remembered: ``needs`` is the highest
        reference (the outputs or the state derivatives need an evaluation at the current state, see :meth:`_read`)."""
        _check_kind(kind, references)
        if len(references) == 1:
            reference = references[0]
            plan = (lambda values: [values[reference]]), reference
        else:
            pick = operator.itemgetter(*references) if references else lambda values: ()
            plan = (lambda values: list(pick(values))), max(references, default=-1)
        if len(self._read_plans) >= _MAX_READ_PLANS:  # an importer reads a few fixed sets; bound the rest
            self._read_plans.clear()
        self._read_plans[(kind, references)] = plan
        return plan

    def _write(self, kind, references, values):
        """Set the variables ``references`` of type ``kind`` to ``values``, all or nothing (TypeError for another type
        or an output, :meth:`BlockInterface.set_values` for the values)."""
        _check_kind(kind, references)
        if max(references, default=-1) >= FIRST_OUTPUT:
            reference = next(r for r in references if r >= FIRST_OUTPUT)
            what = "an output" if reference < FIRST_DERIVATIVE else "a state derivative"
            raise TypeError(f"{_NAMES[reference]} (valueReference={reference}) is {what}: it cannot be set")
        self.set_values([VARIABLES[r].name for r in references], values)

    def take_value(self, name, value, kept=False):
        """Take a parameter (before initialization ends) or an input, checked: the outputs follow at the next read."""
        super().take_value(name, value, kept)
        self._by_reference[_REFERENCE_OF[name]] = value
        self._outputs_stale = self._derivatives_stale = True

    def outputs_changed(self):
        """The state moved, or values were restored: the outputs and derivatives need a new evaluation (and
        :meth:`BlockInterface.outputs_changed`'s cache is forgotten, without super()'s cost at every step and
        restore)."""
        self._output_cache.clear()
        self._outputs_stale = self._derivatives_stale = True

    def get_real(self, vrs):
        """The Real variables ``vrs`` (value references), outputs from one evaluation per state."""
        return self._read(Real, vrs)

    def get_integer(self, vrs):
        """The Integer variables ``vrs`` (value references), outputs from one evaluation per state."""
        return self._read(Integer, vrs)

    def set_real(self, vrs, values):
        """Set the Real parameters (before initialization ends) or inputs ``vrs`` to ``values``."""
        self._write(Real, vrs, values)

    def set_integer(self, vrs, values):
        """Set the Integer parameters ``vrs`` (before initialization ends) to ``values``."""
        self._write(Integer, vrs, values)

    # ---- FMI ---------------------------------------------------------------------

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        """Start time in s, of both interfaces; the solver's tolerance is the parameter ``solver.rtol``."""
        self.time = self.start_time = float(start_time)

    def exit_initialization_mode(self):
        self.trajectory = self.new_trajectory()
        self.start_exchange()
        self.outputs_changed()

    def do_step(self, current_time, step_size):
        """Hold the inputs and advance to ``current_time + step_size`` s (raises on failure, never discards)."""
        self.advance(current_time, step_size)
        return True

    def set_real_input_derivatives(self, vrs, orders, values):
        """fmi2SetRealInputDerivatives (the C loader calls it: PythonFMU has none): see
        :meth:`BlockInterface.set_input_derivatives`; returns a warning's text or None."""
        return self.set_input_derivatives(_names(vrs), orders, values)

    def kept_input_references(self):
        """``(name, value reference, order)`` of the inputs the C loader may keep (:meth:`BlockInterface.kept_inputs`):
        v_drive and F_ext set by fmi2SetReal, F_ext's rate by fmi2SetRealInputDerivatives of order 1."""
        return _KEPT_INPUTS

    def get_real_output_derivatives(self, vrs, orders):
        """fmi2GetRealOutputDerivatives (the C loader calls it): see :meth:`BlockInterface.output_derivatives`."""
        return self.output_derivatives(_names(vrs), orders)

    def model_exchange(self, function, values, count):
        """The FMI 2 model-exchange call ``function`` ("fmi2GetDerivatives"...), which PythonFMU lacks: the C loader
        makes it through its binding, with the numbers the host gave (``values``) and the length ``count`` of the
        call's array (0 for none). Returns the numbers the call answers, as a tuple (ValueError for a ``count`` that
        is not the FMU's, or a non-finite answer; the shared model exchange's errors, each naming its value)."""
        array, call = _EXCHANGE_CALLS[function]
        if array is not None and count != _ARRAY_LENGTHS[array][0]:
            raise ValueError(f"{function}: {array} = {count}, but this FMU has {_ARRAY_LENGTHS[array][0]} "
                             f"{_ARRAY_LENGTHS[array][1]}")
        answer = tuple(float(value) for value in call(self, values) or ())
        if not all(math.isfinite(value) for value in answer):
            raise ValueError(f"{function}: the model answered {answer!r}: not every value is finite")
        return answer

    # ---- FMU state: the C loader calls save_state and restore_state; PythonFMU the two after them -------------

    def save_state(self):
        """An FMU state (:meth:`ExchangeInterface.fmu_state`): a tuple that nothing changes, nothing copied."""
        return self.fmu_state()

    def restore_state(self, state):
        """Go back to a state from :meth:`save_state` (StateError for a refused one); True if the C loader's step
        call still holds (the same trajectory, restored in place, and no input waits for the next step). The values
        of the parameters and inputs by value reference follow at the next read."""
        trajectory = self.trajectory
        self.restore_fmu_state(state)
        self._values_stale = True
        return self.trajectory is trajectory and not self._inputs_set

    def _get_fmu_state(self):
        return self.save_state()

    def _set_fmu_state(self, state):
        self.restore_state(state)


def _check_kind(kind, references):
    """Raise TypeError unless every value reference is a variable of type ``kind``."""
    if not _REFERENCES[kind].issuperset(references):
        wrong = next(r for r in references if r not in _REFERENCES[kind])
        raise TypeError(f"Variable with valueReference={wrong} is not of type {kind.__name__}!")


def _names(references):
    """The FMU names of the value references (ValueError for one that is no variable)."""
    if not all(0 <= r < len(VARIABLES) for r in references):
        wrong = next(r for r in references if not 0 <= r < len(VARIABLES))
        raise ValueError(f"valueReference={wrong} is no variable of this FMU")
    return [VARIABLES[r].name for r in references]


#: array name in FMI 2: (its length, what it holds)
_ARRAY_LENGTHS = {"nx": (len(STATES), "continuous states"), "ni": (len(INDICATORS), "event indicators")}
#: FMI 2 model-exchange function: (the name of its array's length or None, the slave's answer to it)
_EXCHANGE_CALLS = {
    "fmi2SetTime": (None, lambda slave, values: slave.set_time(values[0])),
    "fmi2SetContinuousStates": ("nx", lambda slave, values: slave.set_continuous_states(values)),
    "fmi2GetContinuousStates": ("nx", lambda slave, values: slave.get_continuous_states()),
    "fmi2GetDerivatives": ("nx", lambda slave, values: slave.continuous_state_derivatives()),
    "fmi2GetNominalsOfContinuousStates": ("nx", lambda slave, values: slave.get_nominals_of_continuous_states()),
    "fmi2GetEventIndicators": ("ni", lambda slave, values: slave.get_event_indicators()),
    # fmi2EventInfo: newDiscreteStatesNeeded, terminateSimulation, nominalsOfContinuousStatesChanged,
    # valuesOfContinuousStatesChanged, nextEventTimeDefined, nextEventTime (FMI 3's DiscreteUpdate, in order)
    "fmi2NewDiscreteStates": (None, lambda slave, values: slave.update_discrete_states()),
    # the indicators locate every event: enterEventMode and terminateSimulation false
    "fmi2CompletedIntegratorStep": (None, lambda slave, values: (False, False)),
}

balance_release(SpringBlockFriction, PYTHONFMU_ENTRY_POINTS)
serialize_states(SpringBlockFriction, 2)
