"""The FMU's variables as the code around the FMU needs them: names by causality and kind, units and start values,
all read from the one variable table, :data:`stickslip.fmu_src.block_interface.VARIABLES` (SPEC section 4), and
the FMU's range check of its parameters and inputs by that table, ``check_values(values)`` (ParameterError naming
the first value out of its range).

The runtime keeps its own list (``stickslip.core.OUTPUT_NAMES``): it stays independent of the FMU's glue.
"""

from ..fmu_src.block_interface import F_EXT_RATE, VARIABLES, check_values


def names(causality, kind=None):
    """Names of the variables of ``causality`` ("parameter", "input" or "output") and, if given, ``kind`` ("real"
    or "integer"), in the order the FMUs declare them."""
    return tuple(v.name for v in VARIABLES if v.causality == causality and kind in (None, v.kind))


#: every output, in declaration order
OUTPUTS = names("output")
REAL_OUTPUTS = names("output", "real")
INTEGER_OUTPUTS = names("output", "integer")
#: the inputs, ``v_drive`` (m/s) and ``F_ext`` (N)
INPUTS = names("input")
#: the FMI 3 FMU's input ``der(F_ext)`` (N/s), the rate ``F_ext`` grows at over a doStep (FMI 2 takes it through
#: fmi2SetRealInputDerivatives)
RATE_INPUT = F_EXT_RATE
#: {variable name: unit} ("" or "1" when dimensionless)
UNITS = {v.name: v.unit for v in VARIABLES}
#: {parameter or input name: start value}
START_VALUES = {v.name: v.start for v in VARIABLES if v.causality != "output"}


def axis_label(name):
    """``"<name> (<unit>)"``, e.g. ``"v (m/s)"``, for a plot axis of the variable ``name``."""
    return f"{name} ({UNITS[name]})"
