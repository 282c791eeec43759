"""Scenario files (TOML): load, validate, and turn into parameters, FMU start values and inputs.

A malformed file raises :class:`ScenarioError` naming the file, the key and
what was expected. The format is described in docs/scenarios.md.
"""

import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

from ..core import KINETIC_LAWS, RTOL_RANGE, STATIC_LAWS, Parameters
from ..core.errors import ParameterError, StickSlipError
from ..core.ranges import ANY_FINITE, NON_NEGATIVE, POSITIVE, Range
from ..fmu.variables import START_VALUES
from ..hosts.run_limits import free_period, too_many_periods, too_many_points
from .inputs import INPUT_NAMES, Signal, input_table, zoh_breakpoints

ATTRACTORS = ("continuous-sliding", "oscillatory-sliding", "stick-slip", "rest")

#: Named parameter sets: the sections they fill when a file does not give them.
PRESETS = {
    "elmer-fig3": {
        "model": {"M": 40.0, "kappa": 1.0},
        "kinetic": {"law": "lubricated", "gamma1": 3.0, "gamma2": 0.1, "v_tilde": 0.2, "dv": 0.05},
        "static": {"law": "constant", "F0": 1.0},
    },
}

START_TIME = 0.0

_TOP_KEYS = {"name", "description", "expected_attractor", "preset", "model", "initial", "kinetic",
             "static", "inputs", "simulation", "tolerance", "model_exchange"}
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,99}$")


class ScenarioError(StickSlipError, ValueError):
    """A scenario file is malformed; the message names the file, the key and what was expected."""


@dataclass(frozen=True)
class Tolerance:
    """What FMU vs reference must meet: max |dx| (m), max |dv| (m/s), event-time error (s)."""

    max_abs_dx: float
    max_abs_dv: float
    event_time: float


@dataclass(frozen=True)
class ModelExchange:
    """How the FMI 3 model-exchange run is checked: the host's CVode relative tolerance and the
    tolerances FMU vs reference it must meet (its errors are the host solver's, not the FMU's)."""

    rtol: float
    tolerance: Tolerance
    known_miss: str = ""  # why the run is known to miss its checks (a strict xfail of the suite)


DEFAULT_ME_RTOL = 1e-8


@dataclass(frozen=True)
class Scenario:
    """One validated scenario. Times in s; ``tail`` is the window at the end that is classified.

    ``params`` are the FMU runtime's objects (used for the Python API and checks); ``law_values``
    are the file's own numbers by FMU name (``M``, ``kappa``, ``kinetic.law`` as SPEC name,
    ``kinetic.<p>``, ...), from which the FMU start values and the reference's laws are built.
    """

    path: Path
    name: str
    description: str
    expected_attractor: str
    params: Parameters
    law_values: dict
    x0: float
    v0: float
    signals: dict
    stop_time: float
    output_interval: float
    rtol: float
    tail: float
    tolerance: Tolerance
    model_exchange: ModelExchange = None  # None if the file has no [model_exchange] section

    def start_values(self):
        """FMU start values: parameters, initial state, law codes and law parameters, ``solver.rtol``."""
        codes = {"kinetic.law": self.params.kinetic.CODE, "static.law": self.params.static.CODE}
        return {**self.law_values, **codes, "x_start": self.x0, "v_start": self.v0, "solver.rtol": self.rtol}

    def input_table(self):
        """FMPy input table of ``v_drive`` and ``F_ext`` over the run."""
        return input_table(self.signals, START_TIME, self.stop_time)

    def breakpoints(self):
        """Zero-order-hold inputs ``[(t, v_drive, F_ext), ...]`` the FMU integrates under FMPy."""
        return zoh_breakpoints(self.input_table(), START_TIME, self.stop_time, self.output_interval)


class _File:
    """Typed access to the keys of one parsed file, raising ScenarioError with file and key.

    ``key`` arguments are dotted paths (``inputs.v_drive.points``) used in messages;
    the value is looked up in ``data`` under the last component.
    """

    def __init__(self, path):
        self.path = Path(path)

    def error(self, key, expected, got):
        got = "nothing (the key is missing)" if got is None else repr(got)  # TOML has no null
        return ScenarioError(f"{self.path}: key '{key}': expected {expected}, got {got}")

    def table(self, data, key, allowed, required=True):
        """A sub-table whose keys are all in ``allowed`` (``{}`` if absent and not required)."""
        value = data.get(key.rsplit(".", 1)[-1])
        if value is None and not required:
            return {}
        if not isinstance(value, dict):
            raise self.error(key, "a table", value)
        unknown = sorted(set(value) - set(allowed))
        if unknown:
            raise self.error(f"{key}.{unknown[0]}", f"one of the keys {sorted(allowed)}", value[unknown[0]])
        return value

    def number(self, data, key, allowed=ANY_FINITE, default=None):
        """A finite number in the Range ``allowed``."""
        return self.check_number(data.get(key.rsplit(".", 1)[-1], default), key, allowed)

    def check_number(self, value, key, allowed=ANY_FINITE):
        if isinstance(value, bool) or not allowed.contains(value):
            raise self.error(key, f"a finite number in {allowed}", value)
        return float(value)

    def string(self, data, key, choices=None, default=None):
        value = data.get(key.rsplit(".", 1)[-1], default)
        if not isinstance(value, str) or (choices is not None and value not in choices):
            raise self.error(key, "a string" + (f", one of {list(choices)}" if choices else ""), value)
        return value


def load_scenario(path):
    """Read and validate one scenario file; return a :class:`Scenario`."""
    f = _File(path)
    try:
        with open(path, "rb") as stream:
            data = tomllib.load(stream)
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ScenarioError(f"{path}: cannot read a TOML file: {exc}") from exc
    unknown = sorted(set(data) - _TOP_KEYS)
    if unknown:
        raise f.error(unknown[0], f"one of the keys {sorted(_TOP_KEYS)}", data[unknown[0]])
    name = f.string(data, "name")
    if not _NAME.match(name):
        raise f.error("name", "at most 100 letters, digits, '.', '_' or '-' (it names the output files)", name)
    preset = PRESETS[f.string(data, "preset", choices=PRESETS)] if "preset" in data else {}
    simulation = f.table(data, "simulation", {"stop_time", "output_interval", "rtol", "tail"})
    initial = f.table(data, "initial", {"x", "v"})
    params, law_values = _parameters(f, data, preset)
    stop_time, output_interval = _run_length(f, simulation, params)
    up_to_stop = Range(0.0, stop_time, low_open=True)
    return Scenario(
        path=Path(path),
        name=name,
        description=f.string(data, "description", default=""),
        expected_attractor=f.string(data, "expected_attractor", choices=ATTRACTORS),
        params=params,
        law_values=law_values,
        x0=f.number(initial, "initial.x"),
        v0=f.number(initial, "initial.v"),
        signals=_signals(f, data),
        stop_time=stop_time,
        output_interval=output_interval,
        rtol=f.number(simulation, "simulation.rtol", RTOL_RANGE,
                      default=START_VALUES["solver.rtol"]),
        tail=f.number(simulation, "simulation.tail", up_to_stop, default=stop_time / 3.0),
        tolerance=_tolerance(f, data),
        model_exchange=_model_exchange(f, data),
    )


def _run_length(f, simulation, params):
    """``(stop_time, output_interval)`` (s) of [simulation], refused if the run would not finish
    (:mod:`stickslip.hosts.run_limits`: output points, periods ``2 pi sqrt(M/kappa)`` of the block)."""
    stop_time = f.number(simulation, "simulation.stop_time", POSITIVE)
    output_interval = f.number(simulation, "simulation.output_interval", Range(0.0, stop_time, low_open=True))
    for key, why in (("simulation.output_interval", too_many_points(stop_time, output_interval)),
                     ("simulation.stop_time", too_many_periods(stop_time, free_period(params.M, params.kappa)))):
        if why:
            raise ScenarioError(f"{f.path}: key '{key}': {why}")
    return stop_time, output_interval


def load_scenarios(paths):
    """Scenarios from files and directories (``*.toml`` in name order); names must be unique."""
    files = []
    for path in map(Path, paths):
        found = sorted(path.glob("*.toml")) if path.is_dir() else [path]
        if not found:
            raise ScenarioError(f"{path}: no scenario files (*.toml) in this directory")
        files.extend(found)
    scenarios = [load_scenario(p) for p in files]
    seen = {}
    for s in scenarios:
        if s.name in seen:
            raise ScenarioError(f"{s.path}: key 'name': expected a name not used by {seen[s.name]}, got {s.name!r}")
        seen[s.name] = s.path
    return scenarios


def _parameters(f, data, preset):
    """``(Parameters, law_values)`` from [model], [kinetic], [static]; a preset fills what the file does not give.

    ``law_values`` holds the file's numbers by FMU name, the laws by SPEC name.
    """
    model = {**preset.get("model", {}), **f.table(data, "model", {"M", "kappa"}, required=not preset)}
    values = {"M": f.number(model, "model.M", POSITIVE), "kappa": f.number(model, "model.kappa", POSITIVE)}
    laws = []
    for kind, table in (("kinetic", KINETIC_LAWS), ("static", STATIC_LAWS)):
        law, numbers = _law(f, data.get(kind, preset.get(kind)), kind, table)
        laws.append(law)
        values.update({f"{kind}.law": law.NAME, **{f"{kind}.{k}": v for k, v in numbers.items()}})
    params = Parameters(values["M"], values["kappa"], *laws)
    try:
        params.check()
    except ParameterError as exc:
        raise ScenarioError(f"{f.path}: {exc}") from exc
    return params, values


def _law(f, section, kind, laws):
    """``(law, {parameter: value})`` from its table: ``law`` (name or code) and every parameter of that law."""
    section = f.table({kind: section}, kind, {"law"} | {p for law in laws.values() for p in law.PARAMETERS})
    law_id = section.get("law")
    cls = next((law for law in laws.values() if law_id in (law.NAME, law.CODE) and not isinstance(law_id, bool)),
               None)
    if cls is None:
        choices = ", ".join(f"{law.NAME!r} ({law.CODE})" for law in laws.values())
        raise f.error(f"{kind}.law", f"one of {choices}", law_id)
    f.table({kind: section}, kind, {"law"} | set(cls.PARAMETERS))
    numbers = {p: f.number(section, f"{kind}.{p}", allowed) for p, (_, allowed, _) in cls.PARAMETERS.items()}
    return cls(**numbers), numbers


def _signals(f, data):
    """Input signals from [inputs.v_drive] (required) and [inputs.F_ext] (default: the FMU's start value, 0 N)."""
    inputs = f.table(data, "inputs", set(INPUT_NAMES))
    signals = {"F_ext": Signal.constant(START_VALUES["F_ext"])}
    for name in INPUT_NAMES:
        key = f"inputs.{name}"
        section = f.table(inputs, key, {"constant", "points"}, required=name == "v_drive")
        if not section:
            continue
        if len(section) != 1:
            raise f.error(key, "exactly one of 'constant' or 'points'", section)
        if "constant" in section:
            signals[name] = Signal.constant(f.number(section, f"{key}.constant"))
        else:
            signals[name] = Signal(_points(f, section["points"], f"{key}.points"))
    return signals


def _points(f, points, key):
    """``[[t, value], ...]``: sorted times >= 0, a time at most twice (a step), no step at t = 0."""
    if not isinstance(points, list) or not points:
        raise f.error(key, "a non-empty list of [time, value] pairs", points)
    result = []
    for i, point in enumerate(points):
        if not isinstance(point, list) or len(point) != 2:
            raise f.error(f"{key}[{i}]", "a [time, value] pair", point)
        t = f.check_number(point[0], f"{key}[{i}][0]", NON_NEGATIVE)
        value = f.check_number(point[1], f"{key}[{i}][1]")
        if result and t < result[-1][0]:
            raise f.error(f"{key}[{i}][0]", f"a time >= the previous one ({result[-1][0]})", point[0])
        if result and t == START_TIME:
            raise f.error(f"{key}[{i}][0]", "no step at the start time (give the after-step value first)", t)
        if len(result) >= 2 and t == result[-1][0] == result[-2][0]:
            raise f.error(f"{key}[{i}][0]", "a time given at most twice (a step)", t)
        result.append((t, value))
    return result


def _tolerance(f, data, key="tolerance", extra=()):
    section = f.table(data, key, {"max_abs_dx", "max_abs_dv", "event_time", *extra})
    return Tolerance(*(f.number(section, f"{key}.{k}", POSITIVE)
                       for k in ("max_abs_dx", "max_abs_dv", "event_time")))


def _model_exchange(f, data):
    if "model_exchange" not in data:
        return None
    tolerance = _tolerance(f, data, "model_exchange", extra=("rtol", "known_miss"))
    section = data["model_exchange"]
    rtol = f.number(section, "model_exchange.rtol", Range(1e-14, 1e-2), default=DEFAULT_ME_RTOL)
    known_miss = section.get("known_miss", "")
    if not isinstance(known_miss, str):
        raise f.error("model_exchange.known_miss", "a string saying why the run misses its checks", known_miss)
    return ModelExchange(rtol, tolerance, known_miss)
