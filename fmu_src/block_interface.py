"""What every SpringBlockFriction slave shares, whatever FMI library wraps it: the variable table and the
bookkeeping between FMI variables and the runtime.

:data:`VARIABLES` lists the FMU's variables (SPEC section 4) with their causality, type, variability,
start value, unit, description and inclusive bounds, in the order the FMUs declare them; each slave
registers them with its own library's classes. :class:`BlockInterface` keeps the parameter and input
values by FMU name, builds the runtime's parameters and :class:`Trajectory` from them, and saves and
restores them; :class:`ExchangeInterface` is both slaves' model exchange (the runtime's :class:`ExchangeBlock`,
answered by pythonfmu3 in FMI 3 and by the C loader in FMI 2). No physics here: it is all in the runtime, which the builders bundle under a name only
their FMU uses (they rewrite the import below).
"""

import functools
import math
from collections import namedtuple

from stickslip.fmu_src.loader_binding import (  # the slaves take these from here (one import of this module)
    PYTHONFMU_ENTRY_POINTS, REFUSED_STATE, balance_release, header_mismatch, offer_to_loader, refusal,
    serialized_states, state_header,
)

from stickslip.core import (
    ANY_FINITE, INDICATORS, KINETIC_LAWS, OUTPUT_NAMES, POSITIVE, RTOL_RANGE, STATIC_LAWS, BlockStateFormat,
    ExchangeBlock, ParameterError, Parameters, StateError, Trajectory, check, check_input, check_rate_scale, kinetic_law,
    saved_state, static_law,
)

#: causality "parameter" (fixed), "input" or "output"; kind "real" or "integer"; variability "fixed",
#: "continuous" or "discrete"; start None for outputs; unit "" or "1" when dimensionless; bounds inclusive
#: (min, max), None where unbounded; attribute: the Trajectory attribute an output reads (None otherwise); allowed: the
#: Range of a real parameter or input (None for law codes and outputs); enumeration: for a law code, the
#: :class:`Enumeration` type the model descriptions declare for it (None for every other variable).
Variable = namedtuple("Variable", "name causality kind variability start unit description bounds attribute allowed "
                                  "enumeration", defaults=(None,))
#: An enumeration type of the model descriptions: its ``name`` and its ``items``, ``(code, item name, description)``
#: in the order of the codes; a variable of the type holds a code (FMI 2 sets it with fmi2SetInteger, FMI 3 with
#: fmi3SetInt64).
Enumeration = namedtuple("Enumeration", "name items")
#: the enumeration type of each law selector
LAW_TYPE_NAMES = {"kinetic": "KineticLaw", "static": "StaticLaw"}

_UNBOUNDED = (None, None)

# FMU name, Trajectory attribute, kind, variability, unit, description
_OUTPUTS = (
    ("x", "x", "real", "continuous", "m", "block position from the spring's relaxed length"),
    ("v", "v", "real", "continuous", "m/s", "block velocity"),
    ("v_rel", "v_rel", "real", "continuous", "m/s", "sliding velocity v_drive - v"),
    ("F_friction", "friction_force", "real", "continuous", "N", "friction force of the surface on the block"),
    ("F_spring", "spring_force", "real", "continuous", "N", "spring force on the block, -kappa x"),
    ("mode", "mode", "integer", "discrete", "", "+1 slipping with v < v_drive, 0 stuck, -1 slipping with v > v_drive"),
    ("t_stick", "t_stick", "real", "continuous", "s", "time since the current stick began (0 while slipping)"),
    ("z_slip", "z_slip", "real", "continuous", "N", "stick-to-slip indicator F_S(t_stick) - |kappa x - F_ext|"),
    ("z_stick", "z_stick", "real", "continuous", "m/s", "slip-to-stick indicator v_rel (0 while stuck)"),
    ("n_events", "n_events", "integer", "discrete", "", "mode changes since the start"),
    ("n_stick_events", "n_stick_events", "integer", "discrete", "", "slip-to-stick events since the start"),
    ("n_slip_events", "n_slip_events", "integer", "discrete", "", "stick-to-slip events since the start"),
    ("n_overshoots", "n_overshoots", "integer", "discrete", "", "slips that passed through v_rel = 0 without sticking"),
    ("t_last_event", "t_last_event", "real", "discrete", "s", "time of the latest mode change"),
    ("n_steps", "n_steps", "integer", "discrete", "", "internal solver steps since the start"),
)


# what each law parameter does (the formulas are in SPEC section 2)
LAW_PARAMETER_MEANINGS = {
    "kinetic.F0": "constant part of F_K; the force scale of carlson-langer",
    "kinetic.gamma": "viscous slope of F_K",
    "kinetic.F_stribeck": "height of the Stribeck peak: F_K(0+) - F0",
    "kinetic.v_stribeck": "sliding speed over which the Stribeck peak decays",
    "kinetic.delta": "Stribeck exponent",
    "kinetic.gamma1": "slope of F_K well below v_tilde, boundary lubrication",
    "kinetic.gamma2": "slope of F_K well above v_tilde, hydrodynamic lubrication",
    "kinetic.v_tilde": "sliding speed of the transition from gamma1 to gamma2",
    "kinetic.dv": "width of that transition",
    "kinetic.sigma": "drop of F_K at the onset of slip, F_K(0+) = F0 (1 - sigma)",
    "kinetic.alpha": "velocity weakening: F_K halves at u = (1 - sigma)/(2 alpha)",
    "static.F0": "static friction F_S at the start of a stick",
    "static.A": "aging amplitude: F_S grows by A per e-fold of 1 + t/tau",
    "static.tau": "aging time scale",
    "static.F_inf": "static friction after a long stick",
    "static.n": "sigmoid exponent",
}

# each law's formula (SPEC section 2), u >= 0 the sliding speed (m/s), t >= 0 the stick time (s)
LAW_FORMULAS = {
    "coulomb": "F_K(u) = F0",
    "viscous": "F_K(u) = F0 + gamma u",
    "stribeck": "F_K(u) = F0 + F_stribeck exp(-(u/v_stribeck)^delta) + gamma u",
    "lubricated": "F_K(u) = u (gamma1 + gamma2 + (gamma2 - gamma1) w / sqrt(dv^2 + w^2)) / 2, w = u - v_tilde: "
                  "slope gamma1 well below v_tilde (boundary lubrication), gamma2 well above (hydrodynamic)",
    "carlson-langer": "F_K(u) = F0 (1 - sigma) / (1 + 2 alpha u / (1 - sigma)): velocity weakening "
                      "(Carlson and Langer's Burridge-Knopoff chain)",
    "constant": "F_S(t) = F0",
    "logarithmic": "F_S(t) = F0 + A ln(1 + t/tau)",
    "saturating": "F_S(t) = F0 + (F_inf - F0)(1 - exp(-t/tau))",
    "sigmoid": "F_S(t) = F0 + (F_inf - F0) t^n / (tau^n + t^n)",
}


def _law_parameters(kind, laws):
    """``{FMU name: (default, Range, unit, description)}`` of every parameter of the coded laws.

    A name shared by several laws takes the default of the lowest law code.
    """
    merged = {}
    for code in sorted(laws):
        for name, (default, allowed, unit) in laws[code].PARAMETERS.items():
            merged.setdefault(f"{kind}.{name}", (default, allowed, unit, []))[3].append(laws[code].NAME)
    return {name: (d, a, u, f"{LAW_PARAMETER_MEANINGS[name]} ({kind} law {', '.join(users)})")
            for name, (d, a, u, users) in merged.items()}


def _with_range(description, allowed):
    """The description with the allowed range appended, as every error message states it."""
    return f"{description}; allowed: a finite value in {allowed}"


def _inclusive_bounds(allowed):
    """``(min, max)`` of a Range that the model description can state (open bounds are left out)."""
    low = None if allowed.low is None or allowed.low_open else allowed.low
    high = None if allowed.high is None or allowed.high_open else allowed.high
    return low, high


def _variables():
    def parameter(name, kind, default, unit, description, allowed):
        return Variable(name, "parameter", kind, "fixed", default, unit, _with_range(description, allowed),
                        _inclusive_bounds(allowed), None, allowed)

    def law_code(kind, laws):
        codes = ", ".join(f"{code} {laws[code].NAME}" for code in sorted(laws))
        items = tuple((code, laws[code].NAME, LAW_FORMULAS[laws[code].NAME]) for code in sorted(laws))
        return Variable(f"{kind}.law", "parameter", "integer", "fixed", 1, "", f"{kind} friction law: {codes}",
                        (min(laws), max(laws)), None, None, Enumeration(LAW_TYPE_NAMES[kind], items))

    def input_(name, start, unit, description):
        return Variable(name, "input", "real", "continuous", start, unit, _with_range(description, ANY_FINITE),
                        _UNBOUNDED, None, ANY_FINITE)

    table = [
        parameter("M", "real", 1.0, "kg", "block mass", POSITIVE),
        parameter("kappa", "real", 1.0, "N/m", "spring stiffness", POSITIVE),
        parameter("x_start", "real", 0.0, "m", "initial position", ANY_FINITE),
        parameter("v_start", "real", 0.0, "m/s", "initial velocity (stuck if v_start = v_drive and the contact holds)",
                  ANY_FINITE),
    ]
    for kind, laws in (("kinetic", KINETIC_LAWS), ("static", STATIC_LAWS)):
        table.append(law_code(kind, laws))
        for name, (default, allowed, unit, text) in _law_parameters(kind, laws).items():
            table.append(parameter(name, "real", default, unit, text, allowed))
    table.append(parameter("solver.rtol", "real", 1e-10, "1", "relative tolerance of the internal solver", RTOL_RANGE))
    table.append(input_("v_drive", 0.1, "m/s", "surface (drive) velocity"))
    table.append(input_("F_ext", 0.0, "N", "external force on the block"))
    for name, attribute, kind, variability, unit, text in _OUTPUTS:
        table.append(Variable(name, "output", kind, variability, None, unit, text, _UNBOUNDED, attribute, None))
    return tuple(table)


#: Every variable of the FMU, in declaration order.
VARIABLES = _variables()
#: The value reference of the first output (the outputs end the table, in :meth:`Trajectory.outputs` order) and the
#: outputs' kinds, "r" real or "i" integer: what the C loader's fast path reads (see offer_to_loader).
FIRST_OUTPUT = next(reference for reference, v in enumerate(VARIABLES) if v.causality == "output")
OUTPUT_KINDS = "".join(v.kind[0] for v in VARIABLES[FIRST_OUTPUT:])
if tuple(v.attribute for v in VARIABLES[FIRST_OUTPUT:]) != OUTPUT_NAMES:
    raise ImportError("block_interface.VARIABLES must end with the outputs in Trajectory.outputs() order")


#: The key of ``BlockInterface.values`` that holds ``der(F_ext)`` (N/s), the first time derivative of ``F_ext`` that an
#: FMI 2 master set (fmi2SetRealInputDerivatives): F_ext grows at that rate from where it was set, until set again.
F_EXT_RATE = "der(F_ext)"
#: The inputs, by FMU name.
INPUTS = ("v_drive", "F_ext")
#: The outputs whose time derivatives the FMU gives (fmi2GetRealOutputDerivatives), by order 1, 2: x (v, dv/dt) and v
#: (dv/dt, d2v/dt2); MAX_OUTPUT_DERIVATIVE_ORDER is the model description's maxOutputDerivativeOrder.
OUTPUT_DERIVATIVES = {"x": ("v", "a"), "v": ("a", "jerk")}
MAX_OUTPUT_DERIVATIVE_ORDER = 2
#: The outputs that depend directly on fewer inputs than all (the model description's dependencies): the position and
#: the spring force move only with time; the velocity jumps with v_drive while the block sticks. An engine can then
#: tell that a block in a loop of couplings is no algebraic loop.
OUTPUT_DEPENDENCIES = {"x": (), "F_spring": (), "v": ("v_drive",)}


class BlockInterface:
    """Parameter and input values by FMU name, and the runtime objects built from them.

    A slave class derives from its FMI library's base class and from this one, calls
    :meth:`init_block` in its constructor, and registers :data:`VARIABLES` with getters and setters
    that call :meth:`read_output` and :meth:`set_variable`. ``variable_units`` and ``variable_bounds`` (by FMU name) are
    read by the builders to complete the model description.
    """

    def init_block(self):
        self.values = {v.name: v.start for v in VARIABLES if v.causality != "output"}
        self.values[F_EXT_RATE] = 0.0
        self.variable_units = {v.name: v.unit for v in VARIABLES}
        self.variable_bounds = {v.name: v.bounds for v in VARIABLES}
        self.variable_enumerations = {v.name: v.enumeration for v in VARIABLES if v.enumeration is not None}
        self.output_dependencies = OUTPUT_DEPENDENCIES
        self.start_time = 0.0
        self.trajectory = None  # built when initialization ends
        self._inputs_set = set()  # the inputs set since the trajectory last saw them (F_EXT_RATE for der(F_ext))
        self._ignored_derivatives = set()  # (input, order) of the derivatives ignored so far (warned about once)
        self._output_cache = {}  # {output name: value} at the current state, filled as outputs are read
        self._saved_parameters = None  # the parameters' (name, value) pairs of the FMU states saved (block_state)
        self._kept_rules = None  # (Parameters, kept_inputs' answer for them), see kept_inputs

    def register_variables(self, classes, causalities, variabilities):
        """Register :data:`VARIABLES` with the FMI library: ``classes`` maps a kind ("real", "integer", and
        "enumeration" where the library has that class: the law codes) to the library's variable class,
        ``causalities`` and ``variabilities`` our names to its enumerations."""
        for variable in VARIABLES:
            name, attribute = variable.name, variable.attribute
            kind = "enumeration" if variable.enumeration is not None and "enumeration" in classes else variable.kind
            if variable.causality == "output":
                accessors = {"getter": functools.partial(self.read_output, name, attribute)}
            else:
                accessors = {"getter": functools.partial(self.values.get, name),
                             "setter": functools.partial(self.set_variable, name)}
            self.register_variable(
                classes[kind](
                    name, causality=causalities[variable.causality], variability=variabilities[variable.variability],
                    description=variable.description, **accessors,
                ),
                nested=False,
            )

    def set_variable(self, name, value):
        """Set a parameter (only before initialization ends) or an input, checked first (:meth:`check_setting`)."""
        self.check_setting(name, value)
        self.take_value(name, value)

    def take_value(self, name, value, kept=False):
        """Take the value of a parameter or input that :meth:`check_setting` allowed (a slave extends this, not
        :meth:`set_variable`, so that a value is checked once); ``kept``: an input the C loader kept
        (:meth:`take_kept`), which the runtime need not check again."""
        self.values[name] = value
        if name not in INPUTS:
            self._saved_parameters = None  # the next state saved has parameters of its own
        if name == "F_ext":
            self.values[F_EXT_RATE] = 0.0  # a force set is held, until a rate is set for it
        if name in INPUTS:
            self._inputs_set.add(name)
        self._output_cache.clear()

    def set_values(self, names, values):
        """Set the parameters or inputs ``names`` to ``values``, all or nothing: each is checked
        (:meth:`check_setting`) before any is taken."""
        pairs = list(zip(names, values))
        for name, value in pairs:
            self.check_setting(name, value)
        for name, value in pairs:
            self.take_value(name, value)

    def check_setting(self, name, value):
        """Raise ParameterError naming ``name`` and its allowed range unless it can be set to ``value`` now: a
        parameter only before initialization ends; an input finite, and once initialization ended within the force
        scales of the parameters (the runtime's :func:`check_input`), as the next step would need it."""
        if name in INPUTS:
            check_input(name, value, None if self.trajectory is None else self.trajectory.params)
        elif self.trajectory is not None and name in self.values:
            raise ParameterError(f"{name} is a fixed parameter: it cannot change after initialization")

    def read_output(self, name, attribute):
        """An output at the current state, computed on its first read after a change (none is ever None)."""
        value = self._output_cache.get(name)
        if value is None:
            value = self._output_cache[name] = getattr(self.current_state(), attribute)
        return value

    def outputs_changed(self):
        """Forget the cached outputs (the state moved)."""
        self._output_cache.clear()

    def current_state(self):
        """The object the outputs are read from (by their Trajectory attribute names)."""
        return self.current_trajectory()

    # ---- runtime objects -----------------------------------------------------------

    def parameters(self):
        """The runtime's Parameters from the current values (:func:`parameters_of`)."""
        return parameters_of(self.values)

    def new_trajectory(self, t0=None):
        """A Trajectory from the parameters, start state and inputs, starting at ``t0`` (default start_time)."""
        v = self.values
        return Trajectory(
            self.parameters(), v["x_start"], v["v_start"], v_drive=v["v_drive"], F_ext=v["F_ext"],
            t0=self.start_time if t0 is None else t0, rtol=v["solver.rtol"], F_ext_rate=v[F_EXT_RATE],
        )

    def current_trajectory(self):
        """The trajectory with the latest inputs applied (a fresh one during initialization)."""
        if self.trajectory is None:
            return self.new_trajectory()
        if self._inputs_set:
            self._apply_inputs(self.trajectory.set_inputs)
        return self.trajectory

    def _apply_inputs(self, set_inputs):
        """Hand the inputs to the trajectory through ``set_inputs`` (its :meth:`Trajectory.set_inputs`, or
        :meth:`Trajectory.take_checked_inputs` where each is known to pass its checks): ``F_ext`` goes on from now
        unless it was set."""
        v = self.values
        force = v["F_ext"] if "F_ext" in self._inputs_set else self.trajectory.F_ext_now
        set_inputs(v["v_drive"], force, v[F_EXT_RATE])
        self._inputs_set.clear()

    # ---- input and output derivatives (FMI 2) -------------------------------------------

    def set_input_derivatives(self, names, orders, values):
        """fmi2SetRealInputDerivatives on the inputs ``names``, all or nothing (each checked first,
        :meth:`_check_input_derivative`): ``der(F_ext)`` (N/s, order 1) is taken, from the current time on; a
        derivative the block does not follow (F_ext's of order 2 and more, v_drive's, which is held over a step) is
        ignored, with a warning returned the first time one of its name and order is not 0 (None if none: a master
        that sets them at every step is told once)."""
        entries = list(zip(names, orders, values))
        for name, order, value in entries:
            self._check_input_derivative(name, order, value)
        ignored = []
        for name, order, value in entries:
            if name == "F_ext" and order == 1:
                self.take_rate(value)
            elif value != 0.0 and (name, order) not in self._ignored_derivatives:
                self._ignored_derivatives.add((name, order))
                ignored.append(f"der({name}, {order}) = {value!r}")
        if not ignored:
            return None
        return (f"fmi2SetRealInputDerivatives: ignored {', '.join(ignored)}: the block follows F_ext to first order "
                f"(F_ext and der(F_ext) from where they were set) and holds v_drive over a step (said once for each "
                f"derivative)")

    def take_rate(self, value):
        """Take ``der(F_ext)`` (N/s) that :meth:`_check_input_derivative` allowed, from the current time on."""
        self.values[F_EXT_RATE] = float(value)
        self._inputs_set.add(F_EXT_RATE)
        self._output_cache.clear()

    def _check_input_derivative(self, name, order, value):
        """Raise ValueError or ParameterError naming the derivative of order ``order`` of ``name`` unless it is one
        of an input, of order 1 or more, and finite; der(F_ext) once initialization ended also within the force
        scale of the parameters (the runtime's :func:`check_rate_scale`), as the next step would need it."""
        if name not in INPUTS:
            raise ValueError(f"{name} is not an input: input derivatives are set for the inputs v_drive and F_ext")
        if not order >= 1:
            raise ValueError(f"the order of der({name}) is {order}: allowed is 1 or more (1: the first derivative)")
        check(f"der({name}, {order})", value, ANY_FINITE)
        if name == "F_ext" and order == 1 and self.trajectory is not None:
            check_rate_scale(value, self.trajectory.params)

    def output_derivatives(self, names, orders):
        """fmi2GetRealOutputDerivatives: the derivatives of order 1 or 2 of the outputs ``names`` (x: m/s, m/s^2;
        v: m/s^2, m/s^3) at the current time, as the mode there continues (see Trajectory.acceleration)."""
        trajectory = self.current_trajectory()
        a, jerk = trajectory.acceleration()
        known = {"v": trajectory.v, "a": a, "jerk": jerk}
        answers = []
        for name, order in zip(names, orders):
            if name not in OUTPUT_DERIVATIVES:
                raise ValueError(f"no derivatives of {name}: output derivatives are given for "
                                 f"{' and '.join(OUTPUT_DERIVATIVES)}")
            if not 1 <= order <= MAX_OUTPUT_DERIVATIVE_ORDER:
                raise ValueError(f"the order of der({name}) is {order}: allowed is 1 to {MAX_OUTPUT_DERIVATIVE_ORDER} "
                                 f"(maxOutputDerivativeOrder)")
            answers.append(known[OUTPUT_DERIVATIVES[name][order - 1]])
        return tuple(answers)

    def advance(self, current_time, step_size):
        """``doStep``: hold the inputs and advance the trajectory from ``current_time`` by ``step_size`` s
        (:meth:`Trajectory.communicate`: the step must start where the last one ended)."""
        self.outputs_changed()
        self.current_trajectory().communicate(current_time, step_size)

    # ---- the C loader's fast path ----------------------------------------------------

    def offer_to_loader(self, fmi_version):
        """Offer this slave to the FMU's C loader (:func:`loader_binding.offer_to_loader`), which then takes each doStep
        through :meth:`fast_step_call`, answers reads of the outputs (value references from :data:`FIRST_OUTPUT`,
        kinds :data:`OUTPUT_KINDS`) itself and the FMI 2 derivatives through the slave's methods."""
        offer_to_loader(self, self.resources, fmi_version, FIRST_OUTPUT, OUTPUT_KINDS)

    def fast_step_call(self):
        """The C loader's calls for the next doSteps: the current trajectory's :meth:`Trajectory.communicate` and
        :meth:`Trajectory.outputs` (every output, in :data:`VARIABLES` order), the inputs set so far applied (the
        loader asks again after any other call that may change them); and its :meth:`Trajectory.restore`, with which
        the loader sets again an FMU state got since, while only steps and reads came after it (the state differs
        from the instance in the trajectory's part alone)."""
        self.outputs_changed()
        trajectory = self.current_trajectory()
        return trajectory.communicate, trajectory.outputs, trajectory.restore

    def fmu_time(self):
        """The time the FMU is at (s), which the C loader answers fmi2LastSuccessfulTime with (and fmi3DoStep's
        lastSuccessfulTime after a failed step): the end of the last step, or of the part of a failed step it went,
        or of a restored state; the start time until initialization ends."""
        return self.start_time if self.trajectory is None else self.trajectory.t

    # ---- inputs the C loader keeps until the next step ------------------------------

    def kept_inputs(self):
        """What the C loader may keep of the inputs a host sets between steps, handing them over with the next step
        (:meth:`step_kept`) or before any other call (:meth:`take_kept`) in one call into Python: one ``(value
        reference, order, bound)`` per input of :meth:`kept_input_references`, ``order`` 0 where the value is set
        (fmi2SetReal, fmi3SetFloat64), 1 for FMI 2's first input derivative; a finite value of magnitude at most
        ``bound`` passes :meth:`check_setting` now (:func:`sure_bound`), so the loader keeps it, and forwards any
        other (the slave refuses it as before). None during initialization, when the checks may still change. The
        loader asks once per instance and again after a state is set (its parameters may differ)."""
        if self.trajectory is None:
            return None
        params = self.trajectory.params
        if self._kept_rules is None or self._kept_rules[0] is not params:
            rules = tuple((reference, order, sure_bound(name, params))
                          for name, reference, order in self.kept_input_references())
            self._kept_rules = params, rules
        return self._kept_rules[1]

    def take_kept(self, sets):
        """Take the inputs the C loader kept, ``((index, value), ...)`` in the order they were last set, ``index``
        into :meth:`kept_input_references`; each value one :meth:`kept_inputs` allows, so nothing is checked again
        (the trajectory takes them at the next step, :meth:`current_trajectory`)."""
        names = self.kept_input_references()
        for index, value in sets:
            name = names[index][0]
            if name == F_EXT_RATE:
                self.take_rate(value)
            else:
                self.take_value(name, value, kept=True)

    def take_kept_for_step(self, sets):
        """:meth:`take_kept` right before a step: the trajectory takes them at once, unchecked
        (:meth:`Trajectory.take_checked_inputs`), where no input was set otherwise since it last took them, ``F_ext``
        is among them and each other input is too or is the one the trajectory holds (else ``F_ext`` going on from
        now, a value set otherwise or one of a state set, is checked as the trajectory takes it)."""
        sure = self.trajectory is not None and not self._inputs_set
        self.take_kept(sets)
        if sure and self._kept_inputs_complete():
            self._apply_inputs(self.trajectory.take_checked_inputs)

    def _kept_inputs_complete(self):
        """Whether the inputs just kept (:meth:`take_kept_for_step`) give the trajectory every input it would take:
        ``F_ext``, and ``v_drive`` and ``der(F_ext)`` each kept or equal to the trajectory's."""
        values, kept, trajectory = self.values, self._inputs_set, self.trajectory
        return ("F_ext" in kept and ("v_drive" in kept or values["v_drive"] == trajectory.v_drive)
                and (F_EXT_RATE in kept or values[F_EXT_RATE] == trajectory.F_ext_rate))

    def step_kept(self, current_time, step_size, sets):
        """The C loader's doStep with the inputs it kept (:meth:`take_kept`), one call: the first outputs after the
        step, as the step call of :meth:`fast_step_call` gives them; None if the loader cannot take this step itself
        (the inputs taken, it forwards the step)."""
        self.take_kept_for_step(sets)
        calls = self.fast_step_call()
        return None if calls is None else calls[0](current_time, step_size)

    # ---- FMU state ---------------------------------------------------------------

    def block_state(self):
        """The block's part of an FMU state, a tuple that nothing changes: ``(parameters, v_drive, F_ext, der(F_ext),
        start time, trajectory state, inputs pending)``. The parameters are ``(name, value)`` pairs shared by every
        state saved while they stay as they are; the trajectory's is :meth:`Trajectory.state` (None during
        initialization); the inputs pending are those set since the trajectory last saw them (the next step applies
        them). Nothing is copied or checked: :meth:`take_block_state` goes back to it."""
        values, trajectory = self.values, self.trajectory
        if self._saved_parameters is None:
            self._saved_parameters = tuple((name, value) for name, value in values.items() if name not in _INPUT_KEYS)
        return (self._saved_parameters, values["v_drive"], values["F_ext"], values[F_EXT_RATE], self.start_time,
                None if trajectory is None else trajectory.state(), frozenset(self._inputs_set))

    def take_block_state(self, saved):
        """Go back to a :meth:`block_state` (of this instance or another, or one deserialized); True if the parameter
        values changed. A state saved during initialization (no trajectory yet) is refused once initialization has
        ended (StateError): the instance would go on without a trajectory, every step discarded (FMI does not say
        what it means)."""
        parameters, v_drive, F_ext, rate, start_time, trajectory, pending = saved
        if trajectory is None and self.trajectory is not None:
            raise StateError("this FMU state was saved during initialization mode and cannot be restored after "
                             "initialization ended: reset the instance first, or restore a state saved after "
                             "initialization")
        values, changed = self.values, parameters is not self._saved_parameters
        if changed:
            values.update(parameters)
            self._saved_parameters = parameters
        values["v_drive"], values["F_ext"], values[F_EXT_RATE] = v_drive, F_ext, rate
        self.start_time = start_time
        if trajectory is None:
            self.trajectory = None
        elif trajectory[0] is self.trajectory:
            self.trajectory.restore(trajectory)
        else:
            self.trajectory = Trajectory.resumed(trajectory)
        if pending or self._inputs_set:  # else the set stays empty
            self._inputs_set = set(pending)
        self.outputs_changed()
        return changed

#: The model-exchange form's state derivatives (name, unit, description), each of the state its name holds, and the
#: number of its event indicators (:data:`INDICATORS`, the runtime's ExchangeBlock)
DERIVATIVES = (("der(x)", "m/s", "dx/dt"), ("der(v)", "m/s2", "dv/dt"))
STATES = ("x", "v")
#: What fmi2NewDiscreteStates (FMI 2's fmi2EventInfo) and fmi3UpdateDiscreteStates answer, in FMI 3's names
DiscreteUpdate = namedtuple(
    "DiscreteUpdate", "discreteStatesNeedUpdate terminateSimulation nominalContinuousStatesChanged "
                      "valuesOfContinuousStatesChanged nextEventTimeDefined nextEventTime")


class ExchangeInterface:
    """Model exchange beside co-simulation, whatever FMI version fronts it (FMI 3: pythonfmu3's calls; FMI 2: the C
    loader's, since PythonFMU has none): the states ``x`` (m), ``v`` (m/s), their derivatives and the event indicators
    :data:`INDICATORS` handed to the host's solver, the transitions applied in :meth:`update_discrete_states`; all
    of it is the runtime's :class:`ExchangeBlock`. Which interface the host uses shows in its calls: the outputs
    follow the trajectory until the first model-exchange call. A slave class puts this before
    :class:`BlockInterface` in its bases, calls :meth:`init_exchange` in its constructor and :meth:`start_exchange`
    when initialization ends."""

    def init_exchange(self):
        self.time = 0.0  # the model's time (s)
        self.block = None  # the ExchangeBlock, built when initialization ends
        self.exchange = False  # True once the host made a model-exchange call
        self._block_saved = None  # the block's state (ExchangeBlock.state) while the block stays as it is, or None

    def start_exchange(self):
        """Initialization ends: the ExchangeBlock of the current values (ParameterError for a bad parameter)."""
        self.block, self._block_saved = self._new_block(), None

    def take_value(self, name, value, kept=False):
        """A parameter or an input, checked (:meth:`BlockInterface.take_value`); after initialization an input is also
        held by the model-exchange block, both interfaces alike (one ``kept`` by the C loader taken unchecked, beside
        the other input the block holds, checked)."""
        super().take_value(name, value, kept)
        if name in INPUTS and self.block is not None:
            self._block_saved = None
            if kept:
                self.block.take_checked_input(name, value)
            else:
                self.block.set_inputs(self.values["v_drive"], self.values["F_ext"])

    def current_state(self):
        """What the outputs are read from: the trajectory until the first model-exchange call, then the block (during
        initialization, the one the current values start)."""
        return self._block_now() if self.exchange else self.current_trajectory()

    def _new_block(self):
        """The ExchangeBlock the current values start at :attr:`time` (ParameterError for a bad parameter)."""
        v = self.values
        return ExchangeBlock(self.parameters(), v["x_start"], v["v_start"], v["v_drive"], v["F_ext"], self.time)

    def _block_now(self):
        """The ExchangeBlock at the current state; before initialization ends, the one the current values start
        (ParameterError naming a bad parameter)."""
        return self._new_block() if self.block is None else self.block

    def _exchange_call(self):
        """The block a model-exchange call reads; during initialization, the one the current values start."""
        self.exchange, self._block_saved = True, None  # the call may change the block
        self.outputs_changed()
        return self._block_now()

    def set_time(self, time):
        """The model's time (s); before initialization ends, the start time of both interfaces: ParameterError for
        a time the block cannot take."""
        if not math.isfinite(time):
            raise ValueError(f"time = {time!r} s is out of range: allowed is a finite value")
        if self.block is None:
            self.time = self.start_time = float(time)
        else:
            self._exchange_call().set_time(time)
            self.time = float(time)

    def get_number_of_continuous_states(self):
        """``x`` and ``v``: 2 (pythonfmu3 asks before every call that passes the states or their derivatives, and its
        own answer scans every variable: half of a model-exchange host's time)."""
        return len(STATES)

    def get_continuous_states(self):
        return self._exchange_call().states()

    def set_continuous_states(self, values):
        if self.block is None:
            raise RuntimeError("the continuous states are set after initialization; during it, set x_start and "
                               "v_start")
        self._exchange_call().set_states(values[0], values[1])

    def continuous_state_derivatives(self):
        """``[der(x), der(v)]`` (m/s, m/s2)."""
        return self._exchange_call().derivatives()

    def get_nominals_of_continuous_states(self, size=len(STATES)):
        return self._exchange_call().nominals()

    def get_event_indicators(self):
        return self._exchange_call().indicators()

    def update_discrete_states(self):
        """The event update (:meth:`ExchangeBlock.update`): never another update needed, no nominals changed."""
        changed = self._exchange_call().update()
        return DiscreteUpdate(False, False, False, changed, False, 0.0)

    # ---- FMU state -----------------------------------------------------------------

    def exchange_state(self):
        """The model exchange's part of an FMU state: ``(the block's state or None, the time, the interface)``, the
        block's :meth:`ExchangeBlock.state`, the same one while the block stays as it is (only the inputs and the
        model-exchange calls change it)."""
        if self._block_saved is None and self.block is not None:
            self._block_saved = self.block.state()
        return self._block_saved, self.time, self.exchange

    def fmu_state(self):
        """An FMU state, a tuple that nothing changes: ``(block_state(), exchange_state())``; a slave adds its own
        fields after them."""
        return self.block_state(), self.exchange_state()

    def restore_fmu_state(self, state):
        """Go back to an FMU state from :meth:`fmu_state` (with the slave's fields after; StateError for a refused one,
        see :func:`check_state`); True if the parameter values changed."""
        if state.__class__ is not tuple:
            check_state(state)
        changed = self.take_block_state(state[0])
        block, self.time, self.exchange = state[1]
        if block is None:
            self.block = None
        elif self.block is None:
            self.block = ExchangeBlock.resumed(block)
        elif block is not self._block_saved:  # else the block is as saved
            self.block.restore(block)
        self._block_saved = block
        return changed


def check_state(state):
    """Raise :class:`StateError` with the reason for a refused state (:func:`loader_binding.refusal`)."""
    reason = refusal(state)
    if reason is not None:
        raise StateError(reason)


def serialize_states(cls, fmi_version, extras=()):
    """Give the slave class ``cls`` of FMI version ``fmi_version`` its FMU states as bytes
    (:func:`loader_binding.serialized_states`): the states of :meth:`ExchangeInterface.fmu_state` with the flags named
    ``extras`` after them, in the runtime's :class:`BlockStateFormat` after the header of
    :func:`loader_binding.state_header`, whose identity names the class, the FMI version and every field (bytes of
    another FMU or layout are refused), and the plan by which the C loader makes and reads most of those bytes itself
    (``state_plan``, :meth:`BlockStateFormat.loader_plan`)."""
    layout = state_format(cls.__name__, fmi_version, extras)
    serialized_states(cls, layout.to_bytes, layout.from_bytes)
    cls.state_plan = layout.loader_plan()  # the C loader packs and unpacks most states itself by it


def state_format(class_name, fmi_version, extras=()):
    """The :class:`BlockStateFormat` of the FMU states of the slave class named ``class_name``
    (:func:`serialize_states`; its :meth:`~BlockStateFormat.fields` tells where each field of a state's bytes lies)."""
    return BlockStateFormat(_PARAMETER_FIELDS, _INPUT_KEYS_IN_ORDER, extras, parameters_of,
                            f"{class_name} FMI {fmi_version}:", state_header, REFUSED_STATE, header_mismatch)


_INPUT_KEYS_IN_ORDER = INPUTS + (F_EXT_RATE,)  # the values an FMU state keeps apart from the parameters
_INPUT_KEYS = frozenset(_INPUT_KEYS_IN_ORDER)
#: the parameters of an FMU state (:meth:`BlockInterface.block_state`'s pairs, in their order) and their kinds
_PARAMETER_FIELDS = tuple((v.name, saved_state.COUNT if v.kind == "integer" else saved_state.REAL) for v in VARIABLES
                          if v.causality == "parameter")


def sure_bound(name, params):
    """The largest power of two (N, m/s or N/s) that the runtime's :func:`check_input` allows for the input ``name``
    ("v_drive", "F_ext", "der(F_ext)") with the parameters ``params``; the checks bound the magnitude (finite, a force
    scale at most its limit, monotone in it), so every finite value of magnitude up to it is allowed too. -1.0 if
    not even the smallest positive float is allowed (no value is surely allowed)."""
    def allowed(exponent):
        try:
            check_input(name, math.ldexp(1.0, exponent), params)
        except ValueError:  # ParameterError is one
            return False
        return True

    low, high = _FLOAT_EXPONENTS  # 2**low allowed, 2**high not (2**1024 overflows: no float)
    if not allowed(low):
        return -1.0
    while high - low > 1:
        middle = (low + high) // 2
        low, high = (middle, high) if allowed(middle) else (low, middle)
    return math.ldexp(1.0, low)


_FLOAT_EXPONENTS = (-1074, 1024)  # the smallest positive float is 2**-1074; floats end below 2**1024


def _law(values, kind, build):
    """The ``kind`` ("kinetic" or "static") law that ``values`` select (``build``: kinetic_law or static_law)."""
    code = values[f"{kind}.law"]
    names = build(code).PARAMETERS  # raises ParameterError for an unknown code
    return build(code, **{name: values[f"{kind}.{name}"] for name in names})


def parameters_of(values):
    """The runtime's Parameters from ``values`` (by FMU name), each value checked first (:func:`check_values`)."""
    check_values(values)
    return Parameters(values["M"], values["kappa"], _law(values, "kinetic", kinetic_law),
                      _law(values, "static", static_law))


def check_values(values):
    """Raise ParameterError naming the first real parameter or input in ``values`` (by FMU name) outside its
    range, whether its law is selected or not: every value the FMU accepted is one it checked (the law codes,
    and ranges that join several values, are the runtime's checks)."""
    for variable in VARIABLES:
        if variable.allowed is not None:
            check(variable.name, values[variable.name], variable.allowed, variable.unit)
