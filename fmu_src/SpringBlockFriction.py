"""SpringBlockFriction: FMI 2.0 co-simulation slave of the spring-block dry-friction model.

A thin adapter between PythonFMU and the runtime's :class:`Trajectory`, which
does all the physics and its own event location (SPEC sections 1, 2 and 4).
Parameters are checked when initialization ends: an invalid one raises the
runtime's ``ParameterError``, which reaches the importer as an FMI error with
the parameter's name and allowed range. The variable table and the bookkeeping
are shared with the FMI 3 slave (``block_interface``); ``build_fmu.py`` bundles
both and the runtime under names only this FMU uses and rewrites the imports.

PythonFMU (0.7.0) reports every exception of the slave as ``fmi2Fatal``. Its
only other failure status, ``fmi2Discard`` for a ``do_step`` that returns
False, comes with ``fmi2Terminated = true``, which FMPy's ``simulate_fmu``
takes for a normal early end (no exception, the results cut short), so every
failure raises. PythonFMU's release of the slave on an exception is balanced
here (``balance_release``): an importer that terminates and frees the
instance after the error, as libcosim does, does not crash.
"""

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real

from block_interface import BlockInterface, balance_release

_CAUSALITY = {"parameter": Fmi2Causality.parameter, "input": Fmi2Causality.input, "output": Fmi2Causality.output}
_VARIABILITY = {name: getattr(Fmi2Variability, name) for name in ("fixed", "continuous", "discrete")}


class SpringBlockFriction(Fmi2Slave, BlockInterface):
    """Block of mass M on a moving surface, tied to a wall by a spring; dry friction with stick, slip and aging."""

    author = "stickslip"
    description = "Spring-block dry friction (Elmer 1997) with exact stick-slip events"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.init_block()
        self.register_variables({"real": Real, "integer": Integer}, _CAUSALITY, _VARIABILITY)

    # ---- FMI ---------------------------------------------------------------------

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        """Start time in s; the solver's tolerance is the parameter ``solver.rtol``."""
        self.start_time = float(start_time)

    def exit_initialization_mode(self):
        self.trajectory = self.new_trajectory()
        self.outputs_changed()

    def do_step(self, current_time, step_size):
        """Hold the inputs and advance to ``current_time + step_size`` s (raises on failure, never discards)."""
        self.current_trajectory().advance_to(current_time + step_size)
        self.outputs_changed()
        return True

    def _get_fmu_state(self):
        return self.block_state()

    def _set_fmu_state(self, state):
        self.restore_block_state(state)


# ---- PythonFMU's release of the slave on an exception -----------------------------

# The methods PythonFMU's C++ wrapper calls on the slave (PyObject_CallMethod(pInstance_, ...) in PySlaveInstance.cpp)
ENTRY_POINTS = (
    "setup_experiment", "enter_initialization_mode", "exit_initialization_mode", "do_step", "terminate",
    "get_real", "get_integer", "get_boolean", "get_string", "set_real", "set_integer", "set_boolean", "set_string",
    "_get_fmu_state", "_set_fmu_state",
)
balance_release(SpringBlockFriction, ENTRY_POINTS)
