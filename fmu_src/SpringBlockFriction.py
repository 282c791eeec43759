"""SpringBlockFriction: FMI 2.0 co-simulation slave of the spring-block dry-friction model.

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

PythonFMU (0.7.0) reports every exception of the slave as ``fmi2Fatal``. Its
only other failure status, ``fmi2Discard`` for a ``do_step`` that returns
False, comes with ``fmi2Terminated = true``, which FMPy's ``simulate_fmu``
takes for a normal early end (no exception, the results cut short), so every
failure raises. PythonFMU's release of the slave on an exception is balanced
here (``balance_release``): an importer that terminates and frees the
instance after the error, as libcosim does, does not crash.
"""

import operator

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real

from block_interface import (
    BLOCK_STATE_KEYS, FIRST_OUTPUT, MAX_OUTPUT_DERIVATIVE_ORDER, PYTHONFMU_ENTRY_POINTS, VARIABLES, BlockInterface,
    balance_release, check_state, serialized_states,
)

_CAUSALITY = {"parameter": Fmi2Causality.parameter, "input": Fmi2Causality.input, "output": Fmi2Causality.output}
_VARIABILITY = {name: getattr(Fmi2Variability, name) for name in ("fixed", "continuous", "discrete")}
_KIND = {"real": Real, "integer": Integer}

_REFERENCE_OF = {v.name: reference for reference, v in enumerate(VARIABLES)}
_REFERENCES = {kind: frozenset(r for r, v in enumerate(VARIABLES) if _KIND[v.kind] is kind) for kind in (Real, Integer)}
_MAX_READ_PLANS = 64  # distinct sets of value references whose checked reader an instance keeps


class SpringBlockFriction(Fmi2Slave, BlockInterface):
    """Block of mass M on a moving surface, tied to a wall by a spring; dry friction with stick, slip and aging."""

    author = "stickslip"
    description = "Spring-block dry friction (Elmer 1997) with exact stick-slip events"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.init_block()
        self._by_reference = [v.start for v in VARIABLES]  # every value by value reference; outputs may be stale
        self._outputs_stale = True  # the outputs' part needs an evaluation at the current state
        self._read_plans = {}  # (type, value references) -> (read, needs_outputs), see _read_plan
        self.offer_to_loader(2)

    def to_xml(self, model_options=None):
        """PythonFMU's model description, with the variables registered for it first, and the input and output
        derivatives that the C loader answers (canInterpolateInputs, maxOutputDerivativeOrder)."""
        if not self.vars:
            self.register_variables(_KIND, _CAUSALITY, _VARIABILITY)
        root = super().to_xml({**(model_options or {}), "canInterpolateInputs": True})
        root.find("CoSimulation").set("maxOutputDerivativeOrder", str(MAX_OUTPUT_DERIVATIVE_ORDER))
        return root

    # ---- values of any set of variables ------------------------------------------

    def _read(self, kind, references):
        """The values of the variables ``references`` of type ``kind`` as a list (TypeError for another type)."""
        key = (kind, tuple(references))
        plan = self._read_plans.get(key)
        if plan is None:
            plan = self._read_plan(kind, key[1])
        read, needs_outputs = plan
        if needs_outputs and self._outputs_stale:
            self._by_reference[FIRST_OUTPUT:] = self.current_trajectory().outputs()
            self._outputs_stale = False
        return read(self._by_reference)

    def _read_plan(self, kind, references):
        """``(read, needs_outputs)`` for a set of value references, checked once and remembered."""
        _check_kind(kind, references)
        if len(references) == 1:
            reference = references[0]
            plan = (lambda values: [values[reference]]), reference >= FIRST_OUTPUT
        else:
            pick = operator.itemgetter(*references) if references else lambda values: ()
            plan = (lambda values: list(pick(values))), max(references, default=-1) >= FIRST_OUTPUT
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
            raise TypeError(f"{VARIABLES[reference].name} (valueReference={reference}) is an output: it cannot be set")
        self.set_values([VARIABLES[r].name for r in references], values)

    def set_variable(self, name, value):
        """Set a parameter (before initialization ends) or an input: the outputs follow at the next read."""
        super().set_variable(name, value)
        self._by_reference[_REFERENCE_OF[name]] = value
        self._outputs_stale = True

    def outputs_changed(self):
        """The state moved, or values were restored: the outputs need a new evaluation."""
        super().outputs_changed()
        self._outputs_stale = True

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
        """Start time in s; the solver's tolerance is the parameter ``solver.rtol``."""
        self.start_time = float(start_time)

    def exit_initialization_mode(self):
        self.trajectory = self.new_trajectory()
        self.outputs_changed()

    def do_step(self, current_time, step_size):
        """Hold the inputs and advance to ``current_time + step_size`` s (raises on failure, never discards)."""
        self.advance(current_time, step_size)
        return True

    def set_real_input_derivatives(self, vrs, orders, values):
        """fmi2SetRealInputDerivatives (the C loader calls it: PythonFMU has none): see
        :meth:`BlockInterface.set_input_derivatives`; returns a warning's text or None."""
        return self.set_input_derivatives(_names(vrs), orders, values)

    def get_real_output_derivatives(self, vrs, orders):
        """fmi2GetRealOutputDerivatives (the C loader calls it): see :meth:`BlockInterface.output_derivatives`."""
        return self.output_derivatives(_names(vrs), orders)

    def _get_fmu_state(self):
        return self.block_state()

    def _set_fmu_state(self, state):
        check_state(state)
        self.restore_block_state(state)
        self._by_reference[:FIRST_OUTPUT] = [self.values[v.name] for v in VARIABLES[:FIRST_OUTPUT]]


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


balance_release(SpringBlockFriction, PYTHONFMU_ENTRY_POINTS)
serialized_states(SpringBlockFriction, BLOCK_STATE_KEYS)
