"""System files (TOML): a chain of blocks as data, loaded and validated (format: docs/systems.md).

``[system]`` holds ``stop_time`` (s), ``output_interval`` (s), ``v_drive`` (m/s, the common surface) and
``coupling`` (N/m, the ``N - 1`` springs between neighbours); each ``[[blocks]]`` table holds FMU parameter
values by the FMU's names (``M``, ``kappa``, ``"kinetic.law"``, ...; a missing one takes the FMU's start
value); an optional ``[tolerance.<master>]`` table sets ``max_rel_dx``, the largest error of that master
against the chain's reference, as a fraction of the chain's amplitude (without it ``zoh`` is not judged).
Names, kinds and law codes come from the FMU's variable table (:mod:`stickslip.fmu.variables`), value ranges from the FMU's own checks: the ranges of
that table, the runtime's checks of the parameters and of the scales they combine into with the system's
``v_drive`` and each block's starting coupling force (what the FMU would refuse at its initialization). A run
that would not finish is refused too (:mod:`stickslip.hosts.run_limits`). A malformed file raises
:class:`SystemFileError` naming the file, the key (or the block and its values) and what is allowed; block ``i``
(1-based) is ``b<i>`` in messages and in the result's columns.
"""

import functools
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core import KINETIC_LAWS, STATIC_LAWS, Parameters, kinetic_law, static_law
from ..core.errors import ParameterError, StickSlipError
from ..core.model import check_input_scales, check_scales
from ..core.ranges import ANY_FINITE, NON_NEGATIVE, POSITIVE, Range
from ..fmu.variables import INPUTS, START_VALUES, VARIABLES, check_values
from ..hosts.run_limits import free_period, too_many_periods, too_many_points
from ..reference import ChainBlock, parameters_from_values
from .template_table import expand_template, flat_table

#: {master: default max |dx| against the reference as a fraction of the chain's amplitude}, see docs/systems.md;
#: None: the master's runs are reported, not judged (zoh's held inputs are first order: its error is the step's)
DEFAULT_TOLERANCES = {"zoh": None, "me": 1e-6, "adaptive": 1e-6, "native": 1e-6}
_SYSTEM_KEYS = {"stop_time", "output_interval", "v_drive", "coupling", "description"}
_TOP_KEYS = {"system", "blocks", "template", "tolerance"}
#: {parameter name: its variable in the FMU's table}
PARAMETERS = {v.name: v for v in VARIABLES if v.causality == "parameter"}
_LAWS = {"kinetic": KINETIC_LAWS, "static": STATIC_LAWS}


class SystemFileError(StickSlipError, ValueError):
    """A system file is malformed; the message names the file, the key and what is allowed."""


@dataclass(frozen=True)
class System:
    """One validated system file. ``blocks``: every FMU parameter of each block by FMU name (file values over the
    FMU's start values); ``tolerances``: {master: max |dx| / amplitude, or None: not judged} with the defaults
    filled in."""

    path: Path
    stop_time: float
    output_interval: float
    v_drive: float
    coupling: tuple
    blocks: tuple
    tolerances: dict = field(default_factory=dict)
    description: str = ""

    @property
    def name(self):
        """The file's stem: it names the output files."""
        return self.path.stem

    @property
    def n(self):
        return len(self.blocks)

    def chain_blocks(self):
        """The blocks for :func:`stickslip.reference.simulate_chain`: the reference's own laws from the values."""
        return [ChainBlock(parameters_from_values(b), b["x_start"], b["v_start"]) for b in self.blocks]

    def times(self):
        """The output grid (s): ``k output_interval`` for ``k = 0 .. stop_time / output_interval``."""
        return np.arange(round(self.stop_time / self.output_interval) + 1) * self.output_interval

    @property
    def length_scale(self):
        """The chain's length scale (m): the largest ``F_S(0) / kappa`` of its blocks (the stretch of a block's own
        spring at breakaway)."""
        return max(b["static.F0"] / b["kappa"] for b in self.blocks)

    def shortest_period(self):
        """A lower bound (s) on the chain's free periods: ``2 pi / omega_max``, ``omega_max^2`` the largest
        ``(kappa + 2 (kc_left + kc_right)) / M`` of its blocks (Gershgorin on ``M^-1 K``)."""
        side = [0.0, *self.coupling, 0.0]
        return min(free_period(b["M"], b["kappa"] + 2.0 * (side[i] + side[i + 1])) for i, b in enumerate(self.blocks))

    def forces(self, x):
        """The coupling forces ``F_ext_i`` (N) at the positions ``x`` (m), SPEC section 5, as a list."""
        return self.force_array(np.asarray(x, dtype=float)).tolist()

    def force_array(self, x):
        """:meth:`forces` at the positions ``x`` (m, an array) as an array: each spring's pull taken from its left
        block's force after it was added to its right block's (the order of :meth:`forces`, bit for bit)."""
        f = np.zeros(x.size)
        pull = self._coupling_array * (x[1:] - x[:-1])
        f[1:] -= pull
        f[:-1] += pull
        return f

    @functools.cached_property
    def _coupling_array(self):
        return np.array(self.coupling, dtype=float)


class _File:
    """Checks of one file's values; errors name the file and the key."""

    def __init__(self, path):
        self.path = Path(path)

    def error(self, key, allowed, got):
        got = "nothing (the key is missing)" if got is None else repr(got)
        return SystemFileError(f"{self.path}: key '{key}': allowed is {allowed}, got {got}")

    def read(self):
        """The file's TOML content."""
        try:
            return tomllib.loads(self.path.read_text())
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
            raise SystemFileError(f"{self.path}: cannot read a TOML file: {exc}") from exc

    def table(self, value, key, allowed):
        """``value`` if it is a table whose keys are all in ``allowed`` (``key`` "": the file's top level)."""
        if not isinstance(value, dict):
            raise self.error(key, "a table", value)
        for name in sorted(value):
            if name not in allowed:
                raise self.error(f"{key}.{name}".lstrip("."), f"one of the keys {sorted(allowed)}", value[name])
        return value

    def number(self, value, key, allowed=ANY_FINITE):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not allowed.contains(value):
            raise self.error(key, f"a finite number in {allowed}", value)
        return float(value)


def load_system(path, *, check_run_length=True):
    """Read and validate a system file; return a :class:`System` (``check_run_length``: as for
    :func:`system_from_data`)."""
    return system_from_data(_File(path).read(), path, check_run_length=check_run_length)


def system_from_data(data, path, *, check_run_length=True):
    """Validate a system given as the content of a system file (``data``, as TOML reads it); ``path`` names it in
    messages and results. ``check_run_length`` False: no refusal of a long run (for a run that does not go through
    the FMUs)."""
    f = _File(path)
    data = f.table(data, "", _TOP_KEYS)
    system = f.table(data.get("system"), "system", _SYSTEM_KEYS)
    stop_time = f.number(system.get("stop_time"), "system.stop_time", POSITIVE)
    blocks = _blocks(f, data)
    output_interval = f.number(system.get("output_interval"), "system.output_interval",
                               Range(0.0, stop_time, low_open=True))
    ratio = stop_time / output_interval
    if abs(ratio - round(ratio)) > 1e-9 * ratio:
        raise f.error("system.output_interval", f"stop_time ({stop_time!r} s) divided by a whole number",
                      output_interval)
    description = system.get("description", "")
    if not isinstance(description, str):
        raise f.error("system.description", "a string", description)
    checked = [_block(f, i + 1, b) for i, b in enumerate(blocks)]
    result = System(
        path=Path(path),
        stop_time=stop_time,
        output_interval=output_interval,
        v_drive=f.number(system.get("v_drive"), "system.v_drive"),
        coupling=_coupling(f, system.get("coupling"), len(blocks)),
        blocks=tuple(values for values, _ in checked),
        tolerances=_tolerances(f, data),
        description=description,
    )
    _check_scales(f, result, [params for _, params in checked])
    if check_run_length:
        _check_run_length(f, result)
    return result


def _blocks(f, data):
    """The ``[[blocks]]`` tables, or those the ``[template]`` table stands for (:mod:`.template_table`)."""
    if "template" in data:
        if "blocks" in data:
            raise f.error("blocks", "no [[blocks]] tables beside a [template] table", data["blocks"])
        return expand_template(f, data["template"], _is_integer)
    blocks = data.get("blocks")
    if not isinstance(blocks, list) or not blocks or not all(isinstance(b, dict) for b in blocks):
        raise f.error("blocks", "one or more [[blocks]] tables, or a [template] table", blocks)
    return blocks


def _is_integer(name):
    """Whether the FMU parameter ``name`` is an integer (a law code)."""
    return name in PARAMETERS and PARAMETERS[name].kind == "integer"


def _coupling(f, value, n):
    """The ``n - 1`` coupling stiffnesses: the file's list, or one number for every spring."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        value = [value] * (n - 1)
    if not isinstance(value, list) or len(value) != n - 1:
        raise f.error("system.coupling", f"a list of {n - 1} stiffnesses (N/m) for {n} blocks, or one for all",
                      value)
    return tuple(f.number(kc, f"system.coupling[{i}]", NON_NEGATIVE) for i, kc in enumerate(value))


def _block(f, number, table):
    """Every FMU parameter of block ``number`` (1-based): the file's values over the FMU's start values."""
    label = f"b{number}"
    given = flat_table(table)
    for name, value in given.items():
        variable = PARAMETERS.get(name)
        if variable is None:
            why = " (the master sets it)" if name in START_VALUES else ""
            raise f.error(f"{label}.{name}", f"an FMU parameter{why}: one of {sorted(PARAMETERS)}", value)
        if variable.kind == "integer":
            low, high = variable.bounds
            if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
                raise f.error(f"{label}.{name}", f"an integer in [{low}, {high}]: {variable.description}", value)
        else:
            f.number(value, f"{label}.{name}")
    values = {name: START_VALUES[name] for name in PARAMETERS} | given
    params = _check_parameters(f, label, values, given)
    return {name: (int(v) if PARAMETERS[name].kind == "integer" else float(v)) for name, v in values.items()}, params


def _check_parameters(f, label, values, given):
    """The block's runtime Parameters after the runtime's range checks (the FMU's own); parameters of a law not
    selected are refused."""
    laws = []
    for kind, table in _LAWS.items():
        cls = table[values[f"{kind}.law"]]
        unused = sorted(n for n in given if n.startswith(f"{kind}.") and n != f"{kind}.law"
                        and n.split(".", 1)[1] not in cls.PARAMETERS)
        if unused:
            takes = ", ".join(f"{kind}.{p}" for p in cls.PARAMETERS)
            raise f.error(f"{label}.{unused[0]}", f"a parameter of {kind} law {cls.CODE} ({cls.NAME}): {takes}",
                          given[unused[0]])
        build = kinetic_law if kind == "kinetic" else static_law
        laws.append(build(cls.CODE, **{p: values[f"{kind}.{p}"] for p in cls.PARAMETERS}))
    params = Parameters(values["M"], values["kappa"], *laws)
    try:
        params.check()
        check_values(values | {name: START_VALUES[name] for name in INPUTS})
    except ParameterError as exc:
        raise SystemFileError(f"{f.path}: block {label}: {exc}") from None
    return params


def _check_scales(f, system, params):
    """The runtime's checks of what the values combine into (the FMU's own at its initialization): each block's
    scales with the system's ``v_drive`` (:func:`stickslip.core.check_scales`), then the coupling force it starts
    with (its ``F_ext``, the runtime's input check)."""
    for i, (block, p) in enumerate(zip(system.blocks, params), start=1):
        try:
            check_scales(block["x_start"], block["v_start"], system.v_drive, 0.0, p, ("x_start", "v_start"))
        except ParameterError as exc:
            raise SystemFileError(f"{f.path}: block b{i}: {exc}") from None
    forces = system.forces([b["x_start"] for b in system.blocks])
    for i, (p, force) in enumerate(zip(params, forces), start=1):
        try:
            check_input_scales(0.0, force, p)
        except ParameterError as exc:
            raise SystemFileError(f"{f.path}: key 'system.coupling': block b{i} starts with the coupling force "
                                  f"F_ext = {force!r} N: {exc}") from None


def _check_run_length(f, system):
    """Refuse a run that would not finish (:mod:`stickslip.hosts.run_limits`): too many output points, or too many
    periods of the chain's fastest oscillation, summed over its blocks."""
    checks = (("system.output_interval", too_many_points(system.stop_time, system.output_interval)),
              ("system.stop_time", too_many_periods(system.stop_time, system.shortest_period(), system.n)))
    for key, why in checks:
        if why:
            raise SystemFileError(f"{f.path}: key '{key}': {why}")


def _tolerances(f, data):
    section = f.table(data.get("tolerance", {}), "tolerance", set(DEFAULT_TOLERANCES))
    out = dict(DEFAULT_TOLERANCES)
    for master, table in section.items():
        table = f.table(table, f"tolerance.{master}", {"max_rel_dx"})
        out[master] = f.number(table.get("max_rel_dx"), f"tolerance.{master}.max_rel_dx", POSITIVE)
    return out
