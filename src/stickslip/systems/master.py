"""What every master shares: the interface a master implements, its result, and its block instances.

A master couples one FMU instance per block of a :class:`~.system_file.System` (or, ``native``, runs the chain
engine) and returns a :class:`SystemResult` on the system's output grid. It is a class with

- ``NAME`` (the ``--master`` value), ``FMI_VERSION`` (2 or 3: which FMU it runs; None: none) and ``OPTIONS`` (the
  names of the keyword arguments its constructor takes, e.g. ``("step",)``; the command's options of the same names);
- ``run(system, fmu_path, progress)``: simulate ``system`` with the FMU at ``fmu_path``; ``progress(t)`` is
  called now and then with the simulated time reached (s).

A new master is one module with such a class, listed in :data:`stickslip.systems.masters.MASTERS`.
"""

import contextlib
from dataclasses import dataclass, field
from typing import Callable, ClassVar, Protocol

import numpy as np

from ..fmu import FILE_NAMES
from ..fmu.variables import START_VALUES
from ..hosts.fmpy_host import ExtractedFMU, FMUError
from ..reference import ChainEvent

#: FMI version: {type of a variable in the model description: the setter of that type on FMPy's instance} (the law
#: selectors are Enumerations: FMI 2 sets them as Integers, FMI 3 as Int64)
_SETTERS = {2: {"Real": "setReal", "Integer": "setInteger", "Enumeration": "setInteger"},
            3: {"Float64": "setFloat64", "Int32": "setInt32", "Enumeration": "setInt64"}}
#: FMI version: the names of FMPy's (getter of reals, getter of integers, setter of reals) on an instance
ACCESSORS = {2: ("getReal", "getInteger", "setReal"), 3: ("getFloat64", "getInt32", "setFloat64")}


def checked_rtol(master, rtol, default, lowest):
    """``rtol`` of the master named ``master`` (``default`` if None), or FMUError naming it and the range
    ``[lowest, 0.01]``."""
    rtol = default if rtol is None else rtol
    if not lowest <= rtol <= 1e-2:
        raise FMUError(f"{master}: rtol = {rtol!r}: allowed is [{lowest:g}, 0.01]")
    return rtol


@dataclass
class SystemResult:
    """A master's run on the grid ``t`` (s): arrays of shape ``(len(t), N)`` of ``x`` (m), ``v`` (m/s) and ``mode``;
    ``events``: the blocks' mode changes it saw (:class:`~stickslip.reference.ChainEvent`, block 0-based),
    ``events_complete``: whether that list holds every event with its time; ``event_counts``: each block's
    ``n_events`` at the end; ``wall_time`` (s); ``settings`` (step, tolerance) and ``stats`` (step and call
    counts) as ``{label: value}`` for the report."""

    master: str
    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    mode: np.ndarray
    events: list
    events_complete: bool
    event_counts: np.ndarray
    wall_time: float
    settings: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)


class Master(Protocol):
    """A master (the module text says what each member is)."""

    NAME: ClassVar[str]
    FMI_VERSION: ClassVar[int | None]
    OPTIONS: ClassVar[tuple]

    def run(self, system, fmu_path, progress: Callable[[float], None] = ...) -> SystemResult:
        ...


def event_kind(before, after):
    """"stick" (to mode 0), "slip" (from mode 0) or "overshoot" (+1 <-> -1)."""
    return "stick" if after == 0 else "slip" if before == 0 else "overshoot"


def new_event(t, block, before, after):
    """The :class:`~stickslip.reference.ChainEvent` of ``block`` (0-based) going from mode ``before`` to ``after``."""
    return ChainEvent(float(t), int(block), event_kind(before, after), int(before), int(after))


def step_events(t_last, mode, new_mode, count, new_count):
    """``(events, complete)`` of one communication step from each block's (lists over blocks) ``t_last_event``
    (s), mode and ``n_events`` before and after it: one event per block is known exactly, more only by count
    (``complete`` False)."""
    events, complete = [], True
    for i, (before, after, n0, n1) in enumerate(zip(mode, new_mode, count, new_count)):
        if n1 == n0 + 1:
            events.append(new_event(t_last[i], i, before, after))
        elif n1 > n0:
            complete = False
    return events, complete


@contextlib.contextmanager
def block_instances(master, system, fmu_path, interface="cs", **flags):
    """``(extracted FMU, [an initialized instance per block])`` for ``master`` (its ``NAME`` and ``FMI_VERSION``):
    the FMU at ``fmu_path`` extracted once, each block's parameters, ``v_drive`` and its ``F_ext`` at the start
    positions set; ``flags``: FMI 3 co-simulation's instantiation flags (``early_return_allowed``, see
    :meth:`~stickslip.hosts.fmpy_host.ExtractedFMU.new_instance`). The instances are freed and the folder removed at
    the end. FMUError naming the file if it is no SpringBlockFriction FMU of the master's FMI version."""
    with ExtractedFMU(fmu_path, needs=START_VALUES) as fmu:
        if fmu.fmi_version != master.FMI_VERSION:
            raise FMUError(f"{master.NAME}: {fmu_path} is an FMI {fmu.fmi_version} FMU; the master runs the FMI "
                           f"{master.FMI_VERSION} FMU ({FILE_NAMES[master.FMI_VERSION]})")
        instances = []
        try:
            forces = system.forces([b["x_start"] for b in system.blocks])
            for i, (values, F) in enumerate(zip(system.blocks, forces)):
                start = {**values, "v_drive": system.v_drive, "F_ext": F}
                instances.append(start_block(fmu, f"b{i + 1}", start, interface, **flags))
            yield fmu, instances
        finally:
            for instance in instances:
                instance.free()


def start_block(extracted, name, values, interface="cs", role="block", **flags):
    """An instance named ``name`` (block ``i``, 1-based: ``b<i>``) of ``extracted`` (an ExtractedFMU), made with the
    instantiation ``flags``, its parameters and inputs ``values`` (FMU names) set in initialization mode,
    initialization done. FMUError naming the ``role`` and ``name`` if it fails."""
    instance = extracted.new_instance(name=name, interface=interface, **flags)
    variables, setters = extracted.variables, _SETTERS[extracted.fmi_version]
    try:
        if extracted.fmi_version == 2:
            instance.call(instance.fmu.setupExperiment, startTime=0.0)
            instance.call(instance.fmu.enterInitializationMode)
        else:
            instance.call(instance.fmu.enterInitializationMode, startTime=0.0)
        for variable_name, value in values.items():
            variable = variables[variable_name]
            cast = float if variable.type in ("Real", "Float64") else int
            instance.call(getattr(instance.fmu, setters[variable.type]), [variable.valueReference], [cast(value)])
        instance.call(instance.fmu.exitInitializationMode)
    except FMUError as exc:
        instance.free()
        raise FMUError(f"{role} {name}: {exc}") from None
    return instance


def references(extracted, names):
    """Value references of the variables ``names`` of ``extracted``."""
    return [extracted.variables[name].valueReference for name in names]


def read_values(instances, reals, integers):
    """``[[value of each instance] for each variable]``: the Real variables then the Integer variables whose value
    references are ``reals`` and ``integers``, read now from every instance in ``instances``."""
    values = []
    for instance in instances:
        get_real, get_integer, _ = ACCESSORS[instance.extracted.fmi_version]
        values.append(list(instance.call(getattr(instance.fmu, get_real), reals))
                      + list(instance.call(getattr(instance.fmu, get_integer), integers)))
    return [list(column) for column in zip(*values)]
