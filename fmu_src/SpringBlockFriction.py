"""SpringBlockFriction: FMI 2.0 co-simulation slave of the spring-block dry-friction model.

A thin adapter between PythonFMU and the runtime's :class:`Trajectory`, which
does all the physics and its own event location (SPEC sections 1, 2 and 4).
Parameters are checked when initialization ends: an invalid one raises the
runtime's ``ParameterError``, which reaches the importer as an FMI error with
the parameter's name and allowed range. ``build_fmu.py`` bundles the runtime
under a name only this FMU uses and rewrites the import below to it.

PythonFMU (0.7.0) reports every exception of the slave as ``fmi2Fatal``. Its
only other failure status, ``fmi2Discard`` for a ``do_step`` that returns
False, comes with ``fmi2Terminated = true``, which FMPy's ``simulate_fmu``
takes for a normal early end (no exception, the results cut short), so every
failure raises. PythonFMU's release of the slave on an exception is balanced
here (:func:`_survives_release`): an importer that terminates and frees the
instance after the error, as libcosim does, does not crash.
"""

import copy
import ctypes
import functools
import operator

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real

from stickslip.core import (
    KINETIC_LAWS, OUTPUT_NAMES, RTOL_RANGE, STATIC_LAWS, ParameterError, Parameters, Trajectory, kinetic_law, static_law,
)

CONTINUOUS, DISCRETE = Fmi2Variability.continuous, Fmi2Variability.discrete
_MAX_READ_PLANS = 64  # distinct sets of value references whose checked reader an instance keeps

# FMU name, Trajectory attribute, type, variability, unit, description
OUTPUTS = (
    ("x", "x", Real, CONTINUOUS, "m", "block position from the spring's relaxed length"),
    ("v", "v", Real, CONTINUOUS, "m/s", "block velocity"),
    ("v_rel", "v_rel", Real, CONTINUOUS, "m/s", "sliding velocity v_drive - v"),
    ("F_friction", "friction_force", Real, CONTINUOUS, "N", "friction force of the surface on the block"),
    ("F_spring", "spring_force", Real, CONTINUOUS, "N", "spring force on the block, -kappa x"),
    ("mode", "mode", Integer, DISCRETE, "", "+1 slipping with v < v_drive, 0 stuck, -1 slipping with v > v_drive"),
    ("t_stick", "t_stick", Real, CONTINUOUS, "s", "time since the current stick began (0 while slipping)"),
    ("z_slip", "z_slip", Real, CONTINUOUS, "N", "stick-to-slip indicator F_S(t_stick) - |kappa x - F_ext|"),
    ("z_stick", "z_stick", Real, CONTINUOUS, "m/s", "slip-to-stick indicator v_rel (0 while stuck)"),
    ("n_events", "n_events", Integer, DISCRETE, "", "mode changes since the start"),
    ("n_stick_events", "n_stick_events", Integer, DISCRETE, "", "slip-to-stick events since the start"),
    ("n_slip_events", "n_slip_events", Integer, DISCRETE, "", "stick-to-slip events since the start"),
    ("n_overshoots", "n_overshoots", Integer, DISCRETE, "", "slips that passed through v_rel = 0 without sticking"),
    ("t_last_event", "t_last_event", Real, DISCRETE, "s", "time of the latest mode change"),
    ("n_steps", "n_steps", Integer, DISCRETE, "", "internal solver steps since the start"),
)


def _law_parameters(kind, laws):
    """``{FMU name: (default, Range, unit, description)}`` of every parameter of the coded laws.

    A name shared by several laws takes the default of the lowest law code.
    """
    merged = {}
    for code in sorted(laws):
        for name, (default, allowed, unit) in laws[code].PARAMETERS.items():
            merged.setdefault(f"{kind}.{name}", (default, allowed, unit, []))[3].append(laws[code].NAME)
    return {name: (d, a, u, f"{kind} law parameter ({', '.join(users)})") for name, (d, a, u, users) in merged.items()}


def _inclusive_bounds(allowed):
    """``(min, max)`` of a Range that the model description can state (open bounds are left out)."""
    low = None if allowed.low is None or allowed.low_open else allowed.low
    high = None if allowed.high is None or allowed.high_open else allowed.high
    return low, high


class SpringBlockFriction(Fmi2Slave):
    """Block of mass M on a moving surface, tied to a wall by a spring; dry friction with stick, slip and aging."""

    author = "stickslip"
    description = "Spring-block dry friction (Elmer 1997) with exact stick-slip events"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.values = {}  # parameter and input values by FMU name
        self.units = {}  # FMU name -> unit ("" or "1": dimensionless); read by stickslip.fmu_build
        self.bounds = {}  # FMU name -> inclusive (min, max), None where unbounded; read by stickslip.fmu_build
        self.start_time = 0.0
        self.trajectory = None  # built when initialization ends
        self._by_reference = []  # every variable's value by value reference; the outputs' part may be stale
        self._outputs_stale = True  # the outputs' part needs an evaluation at the current state
        self._inputs_changed = False  # a parameter or input was set since the trajectory last saw the inputs
        self._references = {Real: set(), Integer: set()}  # value references by variable type
        self._reference_of = {}  # FMU name -> value reference
        self._read_plans = {}  # (type, value references) -> (read, needs_outputs), see _read_plan

        self._parameter("M", Real, 1.0, "kg", "block mass")
        self._parameter("kappa", Real, 1.0, "N/m", "spring stiffness")
        self._parameter("x_start", Real, 0.0, "m", "initial position")
        self._parameter("v_start", Real, 0.0, "m/s", "initial velocity (stuck if v_start = v_drive and the contact holds)")
        for kind, laws in (("kinetic", KINETIC_LAWS), ("static", STATIC_LAWS)):
            codes = ", ".join(f"{code} {laws[code].NAME}" for code in sorted(laws))
            self._parameter(f"{kind}.law", Integer, 1, "", f"{kind} friction law: {codes}", (min(laws), max(laws)))
            for name, (default, allowed, unit, text) in _law_parameters(kind, laws).items():
                self._parameter(name, Real, default, unit, text, _inclusive_bounds(allowed))
        self._parameter(
            "solver.rtol", Real, 1e-10, "1", "relative tolerance of the internal solver", _inclusive_bounds(RTOL_RANGE)
        )
        self._input("v_drive", 0.1, "m/s", "surface (drive) velocity")
        self._input("F_ext", 0.0, "N", "external force on the block")
        self._outputs_at = len(self._by_reference)  # the outputs take the value references from here on
        for name, attribute, kind, variability, unit, text in OUTPUTS:
            self._output(name, attribute, kind, variability, unit, text)

    # ---- variable declarations -------------------------------------------------

    def _declare(self, variable, value, unit, bounds=(None, None)):
        self.register_variable(variable, nested=False)
        self._by_reference.append(value)
        self._reference_of[variable.name] = variable.value_reference
        self._references[type(variable)].add(variable.value_reference)
        self.units[variable.name] = unit
        self.bounds[variable.name] = bounds

    def _parameter(self, name, kind, default, unit, description, bounds=(None, None)):
        self.values[name] = default = float(default) if kind is Real else int(default)
        self._declare(
            kind(
                name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed, description=description,
                getter=lambda: self.values[name], setter=lambda value: self._set_parameter(name, value),
            ),
            default, unit, bounds,
        )

    def _input(self, name, start, unit, description):
        self.values[name] = start
        self._declare(
            Real(
                name, causality=Fmi2Causality.input, variability=CONTINUOUS, description=description,
                getter=lambda: self.values[name], setter=lambda value: self._set_value(name, value),
            ),
            start, unit,
        )

    def _output(self, name, attribute, kind, variability, unit, description):
        index = OUTPUT_NAMES.index(attribute)
        reference = len(self._by_reference)
        if reference != self._outputs_at + index:
            raise ValueError(f"output {name} must come at position {index} of OUTPUTS, the order of OUTPUT_NAMES")
        self._declare(
            kind(
                name, causality=Fmi2Causality.output, variability=variability, description=description,
                getter=lambda: self._current_values()[reference],
            ),
            None, unit,
        )

    def _set_parameter(self, name, value):
        if self.trajectory is not None:
            raise ParameterError(f"{name} is a fixed parameter: it cannot change after initialization")
        self._set_value(name, value)

    def _set_value(self, name, value):
        self.values[name] = value
        self._inputs_changed = True
        self._by_reference[self._reference_of[name]] = value
        self._outputs_stale = True

    # ---- values of any set of variables ------------------------------------------

    def _current_values(self):
        """Every variable's value by value reference, the outputs from one evaluation at the current state."""
        if self._outputs_stale:
            self._by_reference[self._outputs_at:] = self._current().outputs()
            self._outputs_stale = False
        return self._by_reference

    def _read(self, kind, references):
        """The values of the variables ``references`` of type ``kind`` as a list (TypeError for another type)."""
        key = (kind, tuple(references))
        plan = self._read_plans.get(key)
        if plan is None:
            plan = self._read_plan(kind, key[1])
        read, needs_outputs = plan
        if needs_outputs and self._outputs_stale:
            self._current_values()
        return read(self._by_reference)

    def _read_plan(self, kind, references):
        """``(read, needs_outputs)`` for a set of value references, checked once and remembered."""
        wrong = [r for r in references if r not in self._references[kind]]
        if wrong:
            raise TypeError(f"Variable with valueReference={wrong[0]} is not of type {kind.__name__}!")
        if len(references) == 1:
            reference = references[0]
            plan = (lambda values: [values[reference]]), reference >= self._outputs_at
        else:
            pick = operator.itemgetter(*references) if references else lambda values: ()
            plan = (lambda values: list(pick(values))), max(references, default=-1) >= self._outputs_at
        if len(self._read_plans) >= _MAX_READ_PLANS:  # an importer reads a few fixed sets; bound the rest
            self._read_plans.clear()
        self._read_plans[(kind, references)] = plan
        return plan

    def get_real(self, vrs):
        """The Real variables ``vrs`` (value references), outputs from one evaluation per state."""
        return self._read(Real, vrs)

    def get_integer(self, vrs):
        """The Integer variables ``vrs`` (value references), outputs from one evaluation per state."""
        return self._read(Integer, vrs)

    # ---- model -------------------------------------------------------------------

    def _law(self, kind, build):
        code = self.values[f"{kind}.law"]
        names = build(code).PARAMETERS  # raises ParameterError for an unknown code
        return build(code, **{name: self.values[f"{kind}.{name}"] for name in names})

    def _parameters(self):
        v = self.values
        return Parameters(v["M"], v["kappa"], self._law("kinetic", kinetic_law), self._law("static", static_law))

    def _new_trajectory(self):
        v = self.values
        return Trajectory(
            self._parameters(), v["x_start"], v["v_start"], v_drive=v["v_drive"], F_ext=v["F_ext"],
            t0=self.start_time, rtol=v["solver.rtol"],
        )

    def _current(self):
        """The trajectory with the latest inputs applied (a fresh one during initialization)."""
        if self.trajectory is None:
            return self._new_trajectory()
        if self._inputs_changed:
            self.trajectory.set_inputs(self.values["v_drive"], self.values["F_ext"])
            self._inputs_changed = False
        return self.trajectory

    # ---- FMI ---------------------------------------------------------------------

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        """Start time in s; the solver's tolerance is the parameter ``solver.rtol``."""
        self.start_time = float(start_time)

    def exit_initialization_mode(self):
        self.trajectory = self._new_trajectory()
        self._outputs_stale = True

    def do_step(self, current_time, step_size):
        """Hold the inputs and advance to ``current_time + step_size`` s (raises on failure, never discards)."""
        self._current().advance_to(current_time + step_size)
        self._outputs_stale = True
        return True

    def _get_fmu_state(self):
        snapshot = None if self.trajectory is None else self.trajectory.snapshot()
        return {"values": dict(self.values), "start_time": self.start_time, "trajectory": snapshot}

    def _set_fmu_state(self, state):
        state = copy.deepcopy(state)  # the importer may restore the same state again
        for name, value in state["values"].items():
            self._set_value(name, value)
        self.start_time = state["start_time"]
        snapshot = state["trajectory"]
        self.trajectory = None if snapshot is None else Trajectory.from_snapshot(self._parameters(), snapshot)
        self._outputs_stale = True


# ---- PythonFMU's release of the slave on an exception -----------------------------

# The methods PythonFMU's C++ wrapper calls on the slave (PyObject_CallMethod(pInstance_, ...) in PySlaveInstance.cpp).
# Not covered: the static _fmu_state_to_bytes/_fmu_state_from_bytes, called on the class; an exception there
# (corrupt serialized state) still releases the slave unbalanced.
ENTRY_POINTS = (
    "setup_experiment", "enter_initialization_mode", "exit_initialization_mode", "do_step", "terminate",
    "get_real", "get_integer", "get_boolean", "get_string", "set_real", "set_integer", "set_boolean", "set_string",
    "_get_fmu_state", "_set_fmu_state",
)


def _survives_release(method):
    """``method``, which on an exception first takes the references that PythonFMU will drop once too often.

    PythonFMU 0.7.0 (PySlaveInstance.cpp) turns an exception into fmi2Fatal in ``handle_py_exception``, which
    calls ``cleanPyObject``: that releases the wrapper's references to the slave (``pInstance_``), its class
    (``pClass_``, ``type(slave)``) and its log queue (``pMessages_``) but keeps the pointers, and
    ``fmi2FreeInstance`` (the destructor) releases them a second time. Each failed instance that is then
    freed takes one reference too many from the slave and from the class, and the process crashes once the
    garbage collector frees them while they are in use (libcosim, which terminates and frees every instance,
    died with SIGSEGV after a few failed runs). One extra reference to each, taken here before the exception
    leaves the slave, balances the release: the slave stays usable until it is freed and is freed exactly
    then. An importer that never frees an instance after fmi2Fatal (stickslip's FMPy hosts) leaves that slave
    allocated until the process ends.
    """

    @functools.wraps(method)
    def entry_point(self, *args):
        try:
            return method(self, *args)
        except BaseException:
            for reference in (self, type(self), self.log_queue):
                ctypes.pythonapi.Py_IncRef(ctypes.py_object(reference))
            raise

    return entry_point


for _name in ENTRY_POINTS:
    setattr(SpringBlockFriction, _name, _survives_release(getattr(SpringBlockFriction, _name)))
del _name
