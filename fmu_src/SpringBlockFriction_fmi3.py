"""SpringBlockFriction: FMI 3.0 slave (co-simulation and model exchange) of the spring-block dry-friction model.

A thin adapter between pythonfmu3 and the runtime, with the variables of the FMI 2 FMU (shared table,
``block_interface``) and, for model exchange, the derivatives ``der(x)``, ``der(v)`` and three event
indicators. Co-simulation steps the runtime's :class:`Trajectory`, as the FMI 2 FMU does (the same
results). Model exchange hands the states ``x``, ``v`` and the indicators ``indicator.stick``,
``indicator.breakaway`` and ``indicator.graze`` to the host's solver and applies the transitions in
``update_discrete_states``: all of it is the runtime's :class:`ExchangeBlock`, shared with the FMI 2 slave
(``block_interface.ExchangeInterface``, first among the bases so that pythonfmu3's defaults do not hide it).
``build_fmu.py`` bundles the runtime and the shared table under names only this FMU uses.

FMI 3 co-simulation has no ``fmi3SetInputDerivatives``: the input ``der(F_ext)`` (N/s) takes the place of FMI 2's
``fmi2SetRealInputDerivatives`` of ``F_ext``. Over a ``doStep``, ``F_ext`` grows at that rate from where it was set (or
from its value when the rate was set); unlike FMI 2's input derivative it keeps its value when ``F_ext`` is set, as
any input does, so a master that sets both (in one ``fmi3SetFloat64``, in either order) steps each cell under a
straight line of force. Model exchange ignores it (the host sets ``F_ext`` at every evaluation).

pythonfmu3 0.3.4 passes no start time to the slave: a co-simulation starts at the first ``do_step``'s
time, model exchange at t = 0, unless the host (or the FMU's loader) calls ``fmi3SetTime`` during initialization. Its
``Fmi3UpdateDiscreteStatesResult`` misspells two fields that its C++ wrapper reads
(``discreteStatesNeedUpdate``, ``nominalContinuousStatesChanged``), so the update returns its own.
"""

import math

from pythonfmu3 import (CoSimulation, Fmi3Causality, Fmi3SlaveBase, Fmi3Status, Fmi3Variability, Float64, Int32, Int64,
                        ModelExchange)

from block_interface import (
    DERIVATIVES, F_EXT_RATE, INDICATORS, INPUTS, MAX_OUTPUT_DERIVATIVE_ORDER, BlockInterface, ExchangeInterface,
    balance_release, serialize_states,
)

_CAUSALITY = {"parameter": Fmi3Causality.parameter, "input": Fmi3Causality.input, "output": Fmi3Causality.output}
_VARIABILITY = {name: getattr(Fmi3Variability, name) for name in ("fixed", "continuous", "discrete")}

# model exchange only: the indicators' unit, description
INDICATOR_VARIABLES = {
    "stick": ("m/s", "event indicator: mode * v_rel while slipping (zero: v_rel reaches 0), 1 while stuck"),
    "breakaway": ("N", "event indicator: F_S(t_stick) - |kappa x - F_ext| while stuck, 1 while slipping"),
    "graze": ("m/s2", "event indicator: mode * dv_rel/dt while slipping (zero at an extremum of v_rel), 1 while stuck"),
}

_MAX_SETTABLE = 64  # sets of value references remembered as settable (_check_setting_all)


class SpringBlockFriction(ExchangeInterface, Fmi3SlaveBase, ModelExchange, CoSimulation, BlockInterface):
    """Block of mass M on a moving surface, tied to a wall by a spring; dry friction with stick, slip and aging."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.author = "stickslip"
        self.description = "Spring-block dry friction (Elmer 1997) with exact stick-slip events"
        self.init_exchange()
        self._stepped = False  # a co-simulation step was taken, or the host gave the start time
        self._settable = set()  # (type, value references) of the calls whose variables can be set (_check_setting_all)
        self.init_block()
        # the law selectors as Int64, the type of an Enumeration's values (pythonfmu3 0.3.4's Enumeration cannot be
        # read or set); the builder declares them Enumerations
        self.register_variables({"real": Float64, "integer": Int32, "enumeration": Int64}, _CAUSALITY, _VARIABILITY)
        state_refs = {v.name: v.value_reference for v in self.vars.values()}
        for index, (name, unit, text) in enumerate(DERIVATIVES):
            self._local(name, unit, text, lambda i=index: self._block_now().derivatives()[i],
                        derivative=state_refs[name[4:-1]])
        for index, name in enumerate(INDICATORS):
            unit, text = INDICATOR_VARIABLES[name]
            self._local(f"indicator.{name}", unit, text, lambda i=index: self._block_now().indicators()[i])
            self.register_event_indicator(len(self.vars) - 1)
        self._rate_input()
        self.variable_units["time"], self.variable_bounds["time"] = "s", (None, None)
        self.register_variable(Float64("time", causality=Fmi3Causality.independent,
                                       variability=Fmi3Variability.continuous, description="simulation time",
                                       getter=lambda: self.time), nested=False)
        references = {v.name: v.value_reference for v in self.vars.values()}
        self._kept_inputs = tuple((name, references[name], 0) for name in INPUTS + (F_EXT_RATE,))
        self.offer_to_loader(3)

    def to_xml(self, model_options=None):
        """pythonfmu3's model description, with the co-simulation capabilities that the C loader answers: event mode
        and early return from fmi3DoStep (hasEventMode, mightReturnEarlyFromDoStep) and the output derivatives
        (maxOutputDerivativeOrder)."""
        root = super().to_xml(model_options or {})
        co_simulation = root.find("CoSimulation")
        co_simulation.set("hasEventMode", "true")
        co_simulation.set("mightReturnEarlyFromDoStep", "true")
        co_simulation.set("maxOutputDerivativeOrder", str(MAX_OUTPUT_DERIVATIVE_ORDER))
        return root

    def _rate_input(self):
        """The input ``der(F_ext)`` (N/s; see the module text)."""
        self.variable_units[F_EXT_RATE], self.variable_bounds[F_EXT_RATE] = "N/s", (None, None)
        self.register_variable(
            Float64(F_EXT_RATE, causality=Fmi3Causality.input, variability=Fmi3Variability.continuous, start=0.0,
                    description="rate of change of F_ext over a doStep: F_ext grows at this rate from where it was "
                                "set (co-simulation; FMI 3 has no fmi3SetInputDerivatives); allowed: a finite value, "
                                "sqrt(M/kappa) |der(F_ext)| at most 1e150 N",
                    getter=lambda: self.values[F_EXT_RATE], setter=self._set_rate),
            nested=False,
        )

    def _set_rate(self, value):
        self.set_input_derivatives(["F_ext"], [1], [value])

    def check_setting(self, name, value):
        """:meth:`BlockInterface.check_setting`, and ``der(F_ext)`` checked as FMI 2's input derivative."""
        if name == F_EXT_RATE:
            self._check_input_derivative("F_ext", 1, value)
        else:
            super().check_setting(name, value)

    def take_value(self, name, value, kept=False):
        """:meth:`ExchangeInterface.take_value`; setting ``F_ext`` keeps ``der(F_ext)``, an input of its own."""
        if name == F_EXT_RATE:
            self.take_rate(value)
            return
        rate = self.values[F_EXT_RATE]
        super().take_value(name, value, kept)
        self.values[F_EXT_RATE] = rate

    def _local(self, name, unit, description, getter, derivative=None):
        self.variable_units[name] = unit
        self.variable_bounds[name] = (None, None)
        self.register_variable(
            Float64(name, causality=Fmi3Causality.local, variability=Fmi3Variability.continuous,
                    description=description, getter=getter, derivative=derivative),
            nested=False,
        )

    def set_float64(self, vrs, values):
        """Set Float64 parameters (before initialization ends) or inputs, all or nothing (:meth:`_check_setting_all`)."""
        self._check_setting_all(Float64, vrs, values)
        for reference, value in zip(vrs, values):  # scalars, each checked: taken as pythonfmu3's setters would
            self.take_value(self.vars[reference].name, value)

    def set_int32(self, vrs, values):
        """Set Int32 parameters (before initialization ends), all or nothing (:meth:`_check_setting_all`). The law
        selectors, Enumerations (fmi3SetInt64: Int64 here), are taken too, as FMUs whose selectors were Int32 took
        them."""
        enumerations = self._enumerations_only(vrs)
        self._check_setting_all(Int64 if enumerations else Int32, vrs, values)
        (super().set_int64 if enumerations else super().set_int32)(vrs, values)

    def set_int64(self, vrs, values):
        """Set the law selectors (Enumerations: fmi3SetInt64), all or nothing (:meth:`_check_setting_all`)."""
        self._check_setting_all(Int64, vrs, values)
        super().set_int64(vrs, values)

    def get_int32(self, vrs):
        """Int32 values; the law selectors' codes too (see :meth:`set_int32`)."""
        return (super().get_int64 if self._enumerations_only(vrs) else super().get_int32)(vrs)

    def _enumerations_only(self, references):
        return all(isinstance(self.vars.get(reference), Int64) for reference in references)

    def _check_setting_all(self, kind, references, values):
        """Check a set of ``values`` of the variables ``references`` of type ``kind`` before any is taken: TypeError
        unless each is a parameter or an input of that type (pythonfmu3 would call an output's missing setter,
        "'NoneType' object is not callable", and set ``time`` through the slave's attribute); then each value
        (:meth:`BlockInterface.check_setting`: ParameterError naming it and its range). The references of a call
        that passed are remembered (an importer sets a few fixed sets, each checked once; the variables never
        change)."""
        if (kind, tuple(references)) not in self._settable:
            self._check_settable(kind, references)
        for reference, value in zip(references, values):
            self.check_setting(self.vars[reference].name, value)

    def _check_settable(self, kind, references):
        """TypeError unless each of ``references`` is a parameter or an input of type ``kind``; remember them."""
        for reference in references:
            variable = self.vars.get(reference)
            if variable is None:
                raise TypeError(f"no variable has valueReference={reference}")
            if variable.causality not in (Fmi3Causality.parameter, Fmi3Causality.input):
                raise TypeError(f"{variable.name} (valueReference={reference}) is of causality "
                                f"{variable.causality.name}: only parameters and inputs can be set")
            if not isinstance(variable, kind):
                raise TypeError(f"Variable with valueReference={reference} is not of type {kind.__name__}!")
        if len(self._settable) >= _MAX_SETTABLE:  # bound what an importer that sets ever new sets leaves
            self._settable.clear()
        self._settable.add((kind, tuple(references)))

    # ---- FMI: both interfaces ------------------------------------------------------

    def exit_initialization_mode(self):
        self.trajectory = self.new_trajectory()  # raises ParameterError for a bad parameter
        self.start_exchange()
        self.outputs_changed()

    def save_state(self):
        """An FMU state (:meth:`ExchangeInterface.fmu_state`, then whether a step was taken): a tuple that nothing
        changes, nothing copied. The C loader calls this and :meth:`restore_state`; pythonfmu3 the two after them."""
        return self.fmu_state() + (self._stepped,)

    def restore_state(self, state):
        """Go back to a state from :meth:`save_state` (StateError for a refused one); True if the C loader's step
        call still holds (the same trajectory, restored in place, stepped, and no input waits for the next step)."""
        trajectory = self.trajectory
        self.restore_fmu_state(state)
        self._stepped = state[2]
        return self.trajectory is trajectory and self._stepped and not self._inputs_set

    def _get_fmu_state(self):
        return self.save_state()

    def _set_fmu_state(self, state):
        self.restore_state(state)

    # ---- FMI: co-simulation ----------------------------------------------------------

    def do_step(self, current_time, step_size):
        """Hold the inputs and advance to ``current_time + step_size`` s (raises on failure, never discards). Each
        step starts where the last ended (:meth:`Trajectory.communicate`); the first starts the trajectory at
        ``current_time`` unless the host gave the start time (fmi3SetTime during initialization)."""
        self._start_at(current_time)
        self.advance(current_time, step_size)
        return True

    def _start_at(self, current_time):
        """Before a step from ``current_time`` (s): the first starts the trajectory there unless the host gave the
        start time."""
        if not self._stepped and current_time != self.trajectory.t:
            self.trajectory = self.new_trajectory(t0=current_time)
        self._stepped = True

    def step_to_event(self, current_time, step_size, event_mode, sets=()):
        """fmi3DoStep with early return (the C loader calls it for an instance made with earlyReturnAllowed), with the
        inputs the loader kept since the last step taken first (``sets``, :meth:`BlockInterface.take_kept_for_step`):
        the step of :meth:`do_step` that stops at the first stick, breakaway or overshoot inside it. ``event_mode``: the
        instance uses event mode, so the step also stops at an event at its end, and the event is left for
        :meth:`apply_step_events` (the outputs are its left limit); else it is applied at once. ``(time reached (s),
        True if it stopped at an event, every output there)`` (:meth:`Trajectory.outputs`, the values the getters
        answer: the loader keeps them)."""
        self.take_kept_for_step(sets)
        self._start_at(current_time)
        self.outputs_changed()
        trajectory = self.current_trajectory()
        stopped = trajectory.communicate_to_event(current_time, step_size, bool(event_mode))
        if stopped and not event_mode:
            trajectory.apply_events()
        return trajectory.t, stopped, trajectory.outputs()

    def apply_step_events(self):
        """fmi3UpdateDiscreteStates of a co-simulation instance in event mode (the C loader calls it): the inputs set
        in event mode and the events due now applied."""
        self.outputs_changed()
        self.current_trajectory().apply_events()

    def kept_input_references(self):
        """``(name, value reference, order)`` of the inputs the C loader may keep (:meth:`BlockInterface.kept_inputs`):
        v_drive, F_ext and der(F_ext), each set by fmi3SetFloat64."""
        return self._kept_inputs

    def get_output_derivatives(self, vrs, orders):
        """fmi3GetOutputDerivatives (the C loader calls it): see :meth:`BlockInterface.output_derivatives`."""
        return self.output_derivatives([self._variable(reference).name for reference in vrs], orders)

    def _variable(self, reference):
        """The variable of value reference ``reference`` (ValueError naming it if there is none)."""
        variable = self.vars.get(reference)
        if variable is None:
            raise ValueError(f"no variable has valueReference={reference}")
        return variable

    def fast_step_call(self):
        """The C loader's call for the next doSteps (:meth:`BlockInterface.fast_step_call`); None before the first
        step, which may move the start time (:meth:`do_step`)."""
        return super().fast_step_call() if self._stepped else None

    # ---- FMI: model exchange ---------------------------------------------------------

    def set_time(self, time):
        """The model's time (s) (:meth:`ExchangeInterface.set_time`); before initialization ends, a co-simulation then
        starts there, not at its first doStep."""
        super().set_time(time)
        if self.block is None:
            self._stepped = True  # the first doStep starts at the start time, not wherever it says

    def get_continuous_state_derivatives(self):
        """``[der(x), der(v)]``; never raises: pythonfmu3 0.3.4 crashes the host when this method raises (any
        other reports the exception), so a failure is logged as an error and answered with NaN, which the
        FMU's binary returns as fmi3Error."""
        try:
            return self.continuous_state_derivatives()
        except Exception as exc:  # noqa: BLE001 - every failure must become a status, see the docstring
            self.log(f"[getContinuousStateDerivatives] {exc!r}", Fmi3Status.error)
            return [math.nan, math.nan]


# The methods pythonfmu3's C++ wrapper calls on the slave (PyObject_CallMethod(pInstance_, ...) in PySlaveInstance.cpp)
ENTRY_POINTS = (
    "setup_experiment", "enter_initialization_mode", "exit_initialization_mode", "do_step", "terminate",
    "get_float64", "get_int32", "get_int64", "get_uint64", "get_boolean", "get_string",
    "set_float64", "set_int32", "set_int64", "set_uint64", "set_boolean", "set_string",
    "get_continuous_states", "get_continuous_state_derivatives", "get_nominals_of_continuous_states",
    "set_continuous_states", "get_number_of_continuous_states", "get_number_of_event_indicators",
    "get_event_indicators", "set_time", "update_discrete_states", "_get_fmu_state", "_set_fmu_state",
)
balance_release(SpringBlockFriction, ENTRY_POINTS)
serialize_states(SpringBlockFriction, 3, extras=("stepped",))
