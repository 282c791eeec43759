"""The fields of a decoded saved state, checked before the runtime continues from it.

A saved state (:meth:`.trajectory.Trajectory.snapshot`, :meth:`.exchange.ExchangeBlock.snapshot`, decoded from
JSON by an FMU's host interface) may come from anywhere. Each field must be present and of its kind: a finite
real (an int is taken as a float), a count (an int >= 0), a flag (a bool), a mode (-1, 0 or +1), or None where
the kind allows it, or any value for a nested field checked on its own. :class:`~.errors.StateError` names the
first field that is not. Ranges that depend on the
parameters (the time resolution, force scales) are checked by the model's own checks.
"""

import math

from .errors import StateError

#: kinds of field: what each accepts (its value, converted)
REAL, TIME_END, COUNT, FLAG, MODE, OPTIONAL_REAL, OPTIONAL_STEP, REALS, NESTED = (
    "a finite real", "a finite real or inf", "an int >= 0", "a bool", "-1, 0 or 1", "None or a finite real",
    "None or a finite real > 0", "a non-empty list of finite reals", "present (checked on its own)")


def _real(value):
    """``value`` as a float if it is a finite real (not a bool), else None."""
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
        return float(value)
    return None


def _converted(value, kind):
    """``(ok, value converted)`` for a field of ``kind``."""
    if kind == NESTED:
        return True, value
    if kind == FLAG:
        return isinstance(value, bool), value
    if kind in (COUNT, MODE):
        if not isinstance(value, int) or isinstance(value, bool):
            return False, value
        return (value >= 0 if kind == COUNT else value in (-1, 0, 1)), value
    if kind == REALS:
        reals = [_real(item) for item in value] if isinstance(value, list) else []
        return bool(reals) and None not in reals, reals
    if value is None and kind in (OPTIONAL_REAL, OPTIONAL_STEP):
        return True, None
    if kind == TIME_END and value == math.inf:
        return True, math.inf
    real = _real(value)
    return real is not None and (kind != OPTIONAL_STEP or real > 0.0), real


def field(name, value, kind):
    """``value`` of the field ``name`` converted to ``kind``; StateError unless it is one."""
    ok, converted = _converted(value, kind)
    if not ok:
        raise StateError(f"saved state {name} = {value!r} is not {kind}")
    return converted


def record(name, saved, kinds):
    """The fields ``kinds`` (``{key: kind}``) of the saved dict ``saved`` (named ``name``), checked and converted;
    StateError if a field is missing or one is not among ``kinds``."""
    label = f"saved state {name}" if name else "saved state"
    if not isinstance(saved, dict):
        raise StateError(f"{label} is {type(saved).__name__}, not a dict")
    missing = [key for key in kinds if key not in saved]
    unknown = sorted(key for key in saved if key not in kinds)
    if missing or unknown:
        problems = [f"lacks the fields {missing}"] if missing else []
        problems += [f"has unknown fields {unknown}"] if unknown else []
        raise StateError(f"{label} {' and '.join(problems)}")
    return {key: field(f"{name}.{key}" if name else key, saved[key], kind) for key, kind in kinds.items()}


def sequence(name, saved, kinds):
    """The entries of the saved list (or tuple) ``saved`` (named ``name``), one per ``(entry name, kind)`` of
    ``kinds``."""
    if not isinstance(saved, (list, tuple)) or len(saved) != len(kinds):
        raise StateError(f"saved state {name} = {saved!r} is not a list of {len(kinds)} entries "
                         f"({', '.join(entry for entry, _ in kinds)})")
    return [field(f"{name}.{entry}", value, kind) for (entry, kind), value in zip(kinds, saved)]
