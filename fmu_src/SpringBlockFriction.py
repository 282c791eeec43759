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
from typing import NamedTuple

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real

from stickslip.core import (
    KINETIC_LAWS, OUTPUT_NAMES, RTOL_RANGE, STATIC_LAWS, ParameterError, Parameters, Trajectory, kinetic_law, static_law,
)

CONTINUOUS, DISCRETE = Fmi2Variability.continuous, Fmi2Variability.discrete

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


class Declaration(NamedTuple):
    """One FMU variable: its value reference is its position in :data:`DECLARATIONS`."""

    name: str
    kind: type  # pythonfmu Real or Integer
    causality: Fmi2Causality
    variability: Fmi2Variability
    start: object  # float or int; None for an output
    unit: str
    bounds: tuple  # inclusive (min, max), None where unbounded
    description: str


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


def _declarations():
    """Every variable in value-reference order: parameters, inputs, then the outputs in OUTPUT_NAMES order."""
    fixed, parameter = Fmi2Variability.fixed, Fmi2Causality.parameter
    out = [
        Declaration("M", Real, parameter, fixed, 1.0, "kg", (None, None), "block mass"),
        Declaration("kappa", Real, parameter, fixed, 1.0, "N/m", (None, None), "spring stiffness"),
        Declaration("x_start", Real, parameter, fixed, 0.0, "m", (None, None), "initial position"),
        Declaration("v_start", Real, parameter, fixed, 0.0, "m/s", (None, None),
                    "initial velocity (stuck if v_start = v_drive and the contact holds)"),
    ]
    for kind, laws in (("kinetic", KINETIC_LAWS), ("static", STATIC_LAWS)):
        codes = ", ".join(f"{code} {laws[code].NAME}" for code in sorted(laws))
        out.append(Declaration(f"{kind}.law", Integer, parameter, fixed, 1, "", (min(laws), max(laws)),
                               f"{kind} friction law: {codes}"))
        for name, (default, allowed, unit, text) in _law_parameters(kind, laws).items():
            out.append(Declaration(name, Real, parameter, fixed, float(default), unit, _inclusive_bounds(allowed), text))
    out.append(Declaration("solver.rtol", Real, parameter, fixed, 1e-10, "1", _inclusive_bounds(RTOL_RANGE),
                           "relative tolerance of the internal solver"))
    for name, start, unit, text in (("v_drive", 0.1, "m/s", "surface (drive) velocity"),
                                    ("F_ext", 0.0, "N", "external force on the block")):
        out.append(Declaration(name, Real, Fmi2Causality.input, CONTINUOUS, start, unit, (None, None), text))
    by_attribute = {attribute: (name, *rest) for name, attribute, *rest in OUTPUTS}
    for attribute in OUTPUT_NAMES:
        name, kind, variability, unit, text = by_attribute[attribute]
        out.append(Declaration(name, kind, Fmi2Causality.output, variability, None, unit, (None, None), text))
    return tuple(out)


DECLARATIONS = _declarations()
OUTPUTS_AT = len(DECLARATIONS) - len(OUTPUT_NAMES)  # the outputs' first value reference
_REFERENCES = {kind: frozenset(r for r, d in enumerate(DECLARATIONS) if d.kind is kind) for kind in (Real, Integer)}
_MAX_READ_PLANS = 64  # distinct sets of value references whose checked reader an instance keeps


class SpringBlockFriction(Fmi2Slave):
    """Block of mass M on a moving surface, tied to a wall by a spring; dry friction with stick, slip and aging.

    The variables are :data:`DECLARATIONS`, answered from one list of values by value reference
    (:meth:`get_real` and friends); PythonFMU's per-variable objects are made only to write the model
    description (:meth:`to_xml`).
    """

    author = "stickslip"
    description = "Spring-block dry friction (Elmer 1997) with exact stick-slip events"
    units = {d.name: d.unit for d in DECLARATIONS}  # "" or "1": dimensionless; read by stickslip.fmu_build
    bounds = {d.name: d.bounds for d in DECLARATIONS}  # read by stickslip.fmu_build

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.values = {d.name: d.start for d in DECLARATIONS[:OUTPUTS_AT]}  # parameters and inputs by FMU name
        self.start_time = 0.0
        self.trajectory = None  # built when initialization ends
        self._by_reference = [d.start for d in DECLARATIONS]  # every value by value reference; outputs may be stale
        self._outputs_stale = True  # the outputs' part needs an evaluation at the current state
        self._inputs_changed = False  # a parameter or input was set since the trajectory last saw the inputs
        self._read_plans = {}  # (type, value references) -> (read, needs_outputs), see _read_plan

    def to_xml(self, model_options=None):
        """PythonFMU's model description, with the variables registered for it first."""
        if not self.vars:
            for d in DECLARATIONS:
                self.register_variable(
                    d.kind(d.name, causality=d.causality, variability=d.variability, description=d.description),
                    nested=False,
                )
        return super().to_xml({} if model_options is None else model_options)

    # ---- values of any set of variables ------------------------------------------

    def _current_values(self):
        """Every variable's value by value reference, the outputs from one evaluation at the current state."""
        if self._outputs_stale:
            self._by_reference[OUTPUTS_AT:] = self._current().outputs()
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
        _check_kind(kind, references)
        if len(references) == 1:
            reference = references[0]
            plan = (lambda values: [values[reference]]), reference >= OUTPUTS_AT
        else:
            pick = operator.itemgetter(*references) if references else lambda values: ()
            plan = (lambda values: list(pick(values))), max(references, default=-1) >= OUTPUTS_AT
        if len(self._read_plans) >= _MAX_READ_PLANS:  # an importer reads a few fixed sets; bound the rest
            self._read_plans.clear()
        self._read_plans[(kind, references)] = plan
        return plan

    def _write(self, kind, references, values):
        _check_kind(kind, references)
        for reference, value in zip(references, values):
            if reference >= OUTPUTS_AT:
                raise TypeError(f"Variable with valueReference={reference} is an output: it cannot be set!")
            name, causality = DECLARATIONS[reference].name, DECLARATIONS[reference].causality
            if causality is Fmi2Causality.parameter and self.trajectory is not None:
                raise ParameterError(f"{name} is a fixed parameter: it cannot change after initialization")
            self._set_value(name, value)

    def _set_value(self, name, value):
        self.values[name] = value
        self._by_reference[_REFERENCE_OF[name]] = value
        self._inputs_changed = True
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


_REFERENCE_OF = {d.name: reference for reference, d in enumerate(DECLARATIONS)}


def _check_kind(kind, references):
    """Raise TypeError unless every value reference is a variable of type ``kind``."""
    if not _REFERENCES[kind].issuperset(references):
        wrong = next(r for r in references if r not in _REFERENCES[kind])
        raise TypeError(f"Variable with valueReference={wrong} is not of type {kind.__name__}!")


def hold_loader_namespace(namespace):
    """Take one reference to ``namespace``, the globals of the module PythonFMU loads the slave from.

    PythonFMU 0.7.0 (``findClass`` in its fmi2Instantiate) runs that module's source again in its globals,
    which it gets from ``PyModule_GetDict`` (a borrowed reference) and then releases, once per instance.
    A module whose source creates nothing that keeps its globals (a one-line import, see
    stickslip.fmu_staging) loses its namespace after a few instances unless each run takes that reference.
    """
    ctypes.pythonapi.Py_IncRef(ctypes.py_object(namespace))


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
