"""Friction laws (SPEC section 2): pure functions of the sliding speed or the stick time.

Kinetic laws give ``F_K(u) >= 0`` in N for the sliding speed ``u = |v_rel| >= 0``
in m/s, with ``slope(u) = dF_K/du`` in N s/m. Static laws give the largest holding
force ``F_S(t) > 0`` in N after sticking for ``t >= 0`` s, with ``rate(t) = dF_S/dt``
in N/s.

Every law is a small immutable object built from keyword parameters whose names
are the FMU's (``kinetic.F0`` is ``F0`` of the kinetic law). ``check()`` raises
:class:`~.errors.ParameterError` naming the parameter and its allowed range.
A Python user may pass any callable through :class:`CallableKinetic` or
:class:`CallableStatic`.
"""

from __future__ import annotations  # annotations stay unevaluated: the FMU runs on CPython 3.8+

import math
from typing import ClassVar, Final

from .errors import ParameterError
from .ranges import NON_NEGATIVE, POSITIVE, Range, check


_LARGEST_LOG_RATIO: Final = 230.0  # ln of the largest (t/tau)^n a sigmoid law raises to powers directly (e^230 ~ 1e100)
_LOG_LARGEST_FLOAT: Final = 709.782712893384  # ln(1.7976931348623157e308)
_SMALLEST_RATIO: Final = 1e-290  # below it t/tau or (t/tau)^n may have lost digits to underflow: the sigmoid takes logarithms


def _exp(x: float) -> float:
    """``e^x``, inf where it exceeds the floats (``math.exp`` raises OverflowError there)."""
    return math.exp(x) if x < _LOG_LARGEST_FLOAT else math.inf


def _norm(a: float, b: float) -> float:
    """``sqrt(a^2 + b^2)``: through ``math.sqrt``, which compiled code calls natively (``math.hypot`` it calls as
    a Python function), unless the squares could overflow or underflow; there ``math.hypot``."""
    s = math.sqrt(a * a + b * b)
    if 1e-150 < s < 1e150:
        return s
    return math.hypot(a, b)


class _Law:
    """Common parts: parameter storage, validation and a readable repr."""

    PREFIX: ClassVar[str] = ""
    CODE: ClassVar[int] = 0
    NAME: ClassVar[str] = ""
    PARAMETERS: ClassVar[dict] = {}  # name -> (default, allowed Range, unit); each is an attribute (float)

    def __init__(self, **values):
        unknown = set(values) - set(self.PARAMETERS)
        if unknown:
            raise ParameterError(
                f"{self.NAME} law has no parameter {sorted(unknown)}; "
                f"its parameters are {sorted(self.PARAMETERS)}"
            )
        for name, (default, _, _) in self.PARAMETERS.items():
            setattr(self, name, float(values.get(name, default)))

    def __reduce__(self):  # pickling (process pools, dask); compiled classes have no default
        return _rebuild, (type(self), self.parameters())

    def parameters(self):
        """The law's parameters as ``{name: value}``."""
        return {name: getattr(self, name) for name in self.PARAMETERS}

    def named_values(self):
        """The parameters as text, ``kinetic.F0 = 0.5 N, ...``, for messages."""
        return ", ".join(f"{self.PREFIX}.{name} = {getattr(self, name)!r}" + ("" if unit in ("", "1") else f" {unit}")
                         for name, (_, _, unit) in self.PARAMETERS.items())

    def check(self):
        """Raise ParameterError for the first parameter outside its range."""
        for name, (_, allowed, unit) in self.PARAMETERS.items():
            check(f"{self.PREFIX}.{name}", getattr(self, name), allowed, unit)

    def __repr__(self):
        args = ", ".join(f"{k}={v!r}" for k, v in self.parameters().items())
        return f"{type(self).__name__}({args})"


# --------------------------------------------------------------------------
# kinetic laws
# --------------------------------------------------------------------------


class KineticLaw(_Law):
    """Base of the kinetic laws ``F_K(u)``, ``u >= 0`` in m/s, force in N."""

    PREFIX: ClassVar[str] = "kinetic"

    def force(self, u: float) -> float:
        raise NotImplementedError

    def slope(self, u: float) -> float:
        raise NotImplementedError

    def affine(self):
        """``(F0, gamma)`` if ``F_K(u) = F0 + gamma u`` exactly, else None.

        Affine laws make slip a (damped) harmonic oscillation with a closed form.
        """
        return None

    def at_rest(self) -> float:
        """``F_K(0+)`` in N, the kinetic force just after sliding starts."""
        return self.force(0.0)

    def steepest_slope(self) -> float:
        """An upper bound (N s/m) of ``|F_K'|`` where slips start and end and along them: the viscous slopes and
        the drop of a Stribeck peak; 0 where the law says nothing (a Python callable)."""
        return 0.0


class Coulomb(KineticLaw):
    """``F_K(u) = F0``."""

    CODE: ClassVar[int] = 1
    NAME: ClassVar[str] = "coulomb"
    PARAMETERS: ClassVar[dict] = {"F0": (0.5, NON_NEGATIVE, "N")}
    F0: float

    def force(self, u: float) -> float:
        return self.F0

    def slope(self, u: float) -> float:
        return 0.0

    def affine(self):
        return self.F0, 0.0


class Viscous(KineticLaw):
    """``F_K(u) = F0 + gamma u``."""

    CODE: ClassVar[int] = 2
    NAME: ClassVar[str] = "viscous"
    PARAMETERS: ClassVar[dict] = {"F0": (0.5, NON_NEGATIVE, "N"), "gamma": (0.1, NON_NEGATIVE, "N s/m")}
    F0: float
    gamma: float

    def force(self, u: float) -> float:
        return self.F0 + self.gamma * u

    def slope(self, u: float) -> float:
        return self.gamma

    def affine(self):
        return self.F0, self.gamma

    def steepest_slope(self) -> float:
        return self.gamma


class Stribeck(KineticLaw):
    """``F_K(u) = F0 + F_stribeck exp(-(u/v_stribeck)^delta) + gamma u`` (``u >= 0``; powers by ``math.pow``,
    which compiled code calls natively, where ``**`` goes through Python's number protocol)."""

    CODE: ClassVar[int] = 3
    NAME: ClassVar[str] = "stribeck"
    PARAMETERS: ClassVar[dict] = {
        "F0": (0.5, NON_NEGATIVE, "N"),
        "F_stribeck": (0.3, NON_NEGATIVE, "N"),
        "v_stribeck": (0.1, POSITIVE, "m/s"),
        "delta": (1.0, Range(1.0, 10.0), "1"),
        "gamma": (0.1, NON_NEGATIVE, "N s/m"),
    }
    F0: float
    F_stribeck: float
    v_stribeck: float
    delta: float
    gamma: float

    def force(self, u: float) -> float:
        return self.F0 + self.F_stribeck * math.exp(-math.pow(u / self.v_stribeck, self.delta)) + self.gamma * u

    def slope(self, u: float) -> float:
        s = u / self.v_stribeck
        decay = math.exp(-math.pow(s, self.delta))
        return self.gamma - self.F_stribeck * self.delta * math.pow(s, self.delta - 1.0) * decay / self.v_stribeck

    def affine(self):
        return (self.F0 + self.F_stribeck, self.gamma) if self.F_stribeck == 0.0 else None

    def steepest_slope(self) -> float:
        return self.gamma + self.F_stribeck * self.delta / self.v_stribeck  # s^(delta-1) e^(-s^delta) <= 1


class Lubricated(KineticLaw):
    """Boundary lubrication (Elmer 1997, fig. 3).

    ``F_K(u) = u (g1 + g2 + (g2 - g1) w / sqrt(dv^2 + w^2)) / 2`` with ``w = u - v_tilde``.
    """

    CODE: ClassVar[int] = 4
    NAME: ClassVar[str] = "lubricated"
    PARAMETERS: ClassVar[dict] = {
        "gamma1": (3.0, NON_NEGATIVE, "N s/m"),
        "gamma2": (0.1, NON_NEGATIVE, "N s/m"),
        "v_tilde": (0.2, NON_NEGATIVE, "m/s"),
        "dv": (0.05, POSITIVE, "m/s"),
    }
    gamma1: float
    gamma2: float
    v_tilde: float
    dv: float

    def force(self, u: float) -> float:
        w = u - self.v_tilde
        return 0.5 * u * (self.gamma1 + self.gamma2 + (self.gamma2 - self.gamma1) * w / _norm(self.dv, w))

    def slope(self, u: float) -> float:
        w = u - self.v_tilde
        s = _norm(self.dv, w)
        half_jump = 0.5 * (self.gamma2 - self.gamma1)
        return 0.5 * (self.gamma1 + self.gamma2) + half_jump * (w / s + u * self.dv * self.dv / (s * s * s))

    def steepest_slope(self) -> float:
        """The larger viscous slope: the transition at ``v_tilde``, however sharp, is crossed within a slip (a
        kink the stepper's step control handles), not where slips start and end."""
        return self.gamma1 if self.gamma1 > self.gamma2 else self.gamma2


class CarlsonLanger(KineticLaw):
    """Velocity weakening of Carlson and Langer's Burridge-Knopoff chain (Phys. Rev. A 40 (1989) 6470):
    ``F_K(u) = F0 (1 - sigma) / (1 + 2 alpha u / (1 - sigma))``, a drop ``sigma F0`` at the onset of slip, then
    weakening with speed; ``F_K'(u) = -2 alpha F0 / (1 + 2 alpha u / (1 - sigma))^2 < 0`` for ``alpha > 0``, so
    continuous sliding is unstable at every drive velocity."""

    CODE: ClassVar[int] = 5
    NAME: ClassVar[str] = "carlson-langer"
    PARAMETERS: ClassVar[dict] = {
        "F0": (1.0, NON_NEGATIVE, "N"),
        "sigma": (0.01, Range(0.0, 1.0, high_open=True), "1"),
        "alpha": (2.5, NON_NEGATIVE, "s/m"),
    }
    F0: float
    sigma: float
    alpha: float

    def force(self, u: float) -> float:
        rest = 1.0 - self.sigma
        return self.F0 * rest / (1.0 + 2.0 * self.alpha * u / rest)

    def slope(self, u: float) -> float:
        weakening = 1.0 + 2.0 * self.alpha * u / (1.0 - self.sigma)
        return -2.0 * self.alpha * self.F0 / (weakening * weakening)

    def affine(self):
        return (self.F0 * (1.0 - self.sigma), 0.0) if self.alpha == 0.0 or self.F0 == 0.0 else None

    def steepest_slope(self) -> float:
        return 2.0 * self.alpha * self.F0  # |F_K'| is largest at u = 0


class CallableKinetic(KineticLaw):
    """Any Python callable ``force(u)`` with its derivative ``slope(u)`` (Python API only)."""

    CODE: ClassVar[int] = 0
    NAME: ClassVar[str] = "callable"
    PARAMETERS: ClassVar[dict] = {}

    def __init__(self, force, slope):  # no parameters: the base's __init__ has nothing to set
        self._force = force
        self._slope = slope

    def __reduce__(self):
        return CallableKinetic, (self._force, self._slope)

    def force(self, u: float) -> float:
        return float(self._force(u))

    def slope(self, u: float) -> float:
        return float(self._slope(u))

    def check(self):
        for u in (0.0, 1e-6, 1.0):
            value = self.force(u)
            if not math.isfinite(value) or value < 0.0:
                raise ParameterError(f"kinetic law callable gives F_K({u}) = {value!r}; allowed is a finite value >= 0")

    def __repr__(self):
        return f"CallableKinetic({self._force!r})"


# --------------------------------------------------------------------------
# static laws
# --------------------------------------------------------------------------


class StaticLaw(_Law):
    """Base of the static laws ``F_S(t)``, stick time ``t >= 0`` in s, force in N."""

    PREFIX: ClassVar[str] = "static"

    def force(self, t: float) -> float:
        raise NotImplementedError

    def rate(self, t: float) -> float:
        raise NotImplementedError

    def is_constant(self) -> bool:
        """True when ``F_S`` does not age: no stick-time bookkeeping is needed."""
        return False

    def curvature(self, t: float) -> float:
        """``d2F_S/dt2`` in N/s^2; its sign tells whether ``F_S`` is convex or concave at ``t``."""
        raise NotImplementedError

    def convexity_breaks(self):
        """Stick times in s where ``F_S''`` changes sign (empty: convex or concave throughout)."""
        return ()


class Constant(StaticLaw):
    """``F_S(t) = F0``."""

    CODE: ClassVar[int] = 1
    NAME: ClassVar[str] = "constant"
    PARAMETERS: ClassVar[dict] = {"F0": (1.0, POSITIVE, "N")}
    F0: float

    def force(self, t: float) -> float:
        return self.F0

    def rate(self, t: float) -> float:
        return 0.0

    def curvature(self, t: float) -> float:
        return 0.0

    def is_constant(self) -> bool:
        return True


class Logarithmic(StaticLaw):
    """``F_S(t) = F0 + A ln(1 + t/tau)``: concave aging."""

    CODE: ClassVar[int] = 2
    NAME: ClassVar[str] = "logarithmic"
    PARAMETERS: ClassVar[dict] = {"F0": (1.0, POSITIVE, "N"), "A": (0.1, NON_NEGATIVE, "N"), "tau": (1.0, POSITIVE, "s")}
    F0: float
    A: float
    tau: float

    def force(self, t: float) -> float:
        s = t / self.tau
        if s != math.inf:
            return self.F0 + self.A * math.log1p(s)
        return self.F0 + self.A * (math.log(t) - math.log(self.tau))  # t/tau beyond floats: ln(1 + s) = ln s

    def rate(self, t: float) -> float:
        return self.A / (self.tau + t)

    def curvature(self, t: float) -> float:
        return -self.rate(t) / (self.tau + t)  # not A/(tau + t)^2: the square over- or underflows

    def is_constant(self) -> bool:
        return self.A == 0.0


class Saturating(StaticLaw):
    """``F_S(t) = F0 + (F_inf - F0)(1 - exp(-t/tau))``: concave (or convex if F_inf < F0)."""

    CODE: ClassVar[int] = 3
    NAME: ClassVar[str] = "saturating"
    PARAMETERS: ClassVar[dict] = {"F0": (1.0, POSITIVE, "N"), "F_inf": (1.5, POSITIVE, "N"), "tau": (1.0, POSITIVE, "s")}
    F0: float
    F_inf: float
    tau: float

    def force(self, t: float) -> float:
        return self.F0 - (self.F_inf - self.F0) * math.expm1(-t / self.tau)

    def rate(self, t: float) -> float:
        return (self.F_inf - self.F0) * math.exp(-t / self.tau) / self.tau

    def curvature(self, t: float) -> float:
        return -self.rate(t) / self.tau

    def is_constant(self) -> bool:
        return self.F_inf == self.F0


class Sigmoid(StaticLaw):
    """``F_S(t) = F0 + (F_inf - F0) t^n / (tau^n + t^n)``: non-convex aging for ``n > 1``.

    With ``r = (t/tau)^n``: the direct forms where ``t/tau`` and ``r`` are normal floats and ``r <= e^230`` (the
    powers of ``1 + r`` stay finite); elsewhere the same expressions in ``L = ln r = n (ln t - ln tau)`` and
    ``e = exp(-|L|)``, which neither overflow nor lose ``r`` to underflow.
    """

    CODE: ClassVar[int] = 4
    NAME: ClassVar[str] = "sigmoid"
    PARAMETERS: ClassVar[dict] = {
        "F0": (1.0, POSITIVE, "N"),
        "F_inf": (1.5, POSITIVE, "N"),
        "tau": (1.0, POSITIVE, "s"),
        "n": (2.0, Range(0.5, 20.0), "1"),
    }
    F0: float
    F_inf: float
    tau: float
    n: float

    def _ratio(self, t: float) -> float:
        """``r = (t/tau)^n`` for ``t > 0`` where the direct forms hold it to rounding, else NaN (then
        :meth:`_log_ratio` serves)."""
        s = t / self.tau
        if s > 1.0 and self.n * math.log(s) > _LARGEST_LOG_RATIO:
            return math.nan
        r = s ** self.n
        return r if r >= _SMALLEST_RATIO and s >= _SMALLEST_RATIO else math.nan

    def _log_ratio(self, t: float) -> float:
        """``ln r = n (ln t - ln tau)`` for ``t > 0``."""
        return self.n * (math.log(t) - math.log(self.tau))

    def force(self, t: float) -> float:
        if t <= 0.0:
            return self.F0
        r = self._ratio(t)
        if r == r:
            return self.F0 + (self.F_inf - self.F0) * r / (1.0 + r)
        log_r = self._log_ratio(t)  # r / (1 + r) = 1 / (1 + 1/r)
        if log_r > 0.0:
            return self.F0 + (self.F_inf - self.F0) / (1.0 + math.exp(-log_r))
        e = math.exp(log_r)
        return self.F0 + (self.F_inf - self.F0) * e / (1.0 + e)

    def rate(self, t: float) -> float:
        if t <= 0.0:
            if self.n > 1.0 or self.F_inf == self.F0:
                return 0.0
            return (self.F_inf - self.F0) / self.tau if self.n == 1.0 else math.copysign(math.inf, self.F_inf - self.F0)
        r = self._ratio(t)
        if r == r:
            return (self.F_inf - self.F0) * self.n * r / (t * (1.0 + r) ** 2)
        decay = -abs(self._log_ratio(t))  # r / (1 + r)^2 = e / (1 + e)^2, e = exp(-|ln r|)
        e = math.exp(decay)
        return (self.F_inf - self.F0) * self.n * _exp(decay - math.log(t)) / (1.0 + e) ** 2

    def curvature(self, t: float) -> float:
        if t <= 0.0:
            return math.copysign(math.inf, (self.F_inf - self.F0) * (self.n - 1.0)) if self.n != 1.0 else 0.0
        r = self._ratio(t)
        if r == r:
            shape = (self.n - 1.0) - (self.n + 1.0) * r
            return (self.F_inf - self.F0) * self.n * r * shape / t / t / (1.0 + r) ** 3
        log_r = self._log_ratio(t)  # r shape / (1 + r)^3 = e / (1 + e)^2 ((n - 1)(1 - q) - (n + 1) q), q = r/(1 + r)
        decay = -abs(log_r)
        e = math.exp(decay)
        q = 1.0 / (1.0 + e) if log_r > 0.0 else e / (1.0 + e)
        shape = (self.n - 1.0) * (1.0 - q) - (self.n + 1.0) * q
        return (self.F_inf - self.F0) * self.n * _exp(decay - 2.0 * math.log(t)) / (1.0 + e) ** 2 * shape

    def is_constant(self) -> bool:
        return self.F_inf == self.F0

    def convexity_breaks(self):
        if self.n <= 1.0:
            return ()
        return (self.tau * ((self.n - 1.0) / (self.n + 1.0)) ** (1.0 / self.n),)


class CallableStatic(StaticLaw):
    """Any Python callables ``force(t)``, ``rate(t)``, ``curvature(t)`` and the stick
    times where the curvature changes sign (Python API only)."""

    CODE: ClassVar[int] = 0
    NAME: ClassVar[str] = "callable"
    PARAMETERS: ClassVar[dict] = {}

    def __init__(self, force, rate, curvature, convexity_breaks=()):  # no parameters to set
        self._force = force
        self._rate = rate
        self._curvature = curvature
        self._breaks = tuple(float(b) for b in convexity_breaks)

    def __reduce__(self):
        return CallableStatic, (self._force, self._rate, self._curvature, self._breaks)

    def force(self, t: float) -> float:
        return float(self._force(t))

    def rate(self, t: float) -> float:
        return float(self._rate(t))

    def curvature(self, t: float) -> float:
        return float(self._curvature(t))

    def convexity_breaks(self):
        return self._breaks

    def check(self):
        value = self.force(0.0)
        if not math.isfinite(value) or value <= 0.0:
            raise ParameterError(f"static law callable gives F_S(0) = {value!r}; allowed is a finite value > 0")

    def __repr__(self):
        return f"CallableStatic({self._force!r})"


def _rebuild(law_class, parameters):
    """A law from its class and ``{name: value}`` (unpickling)."""
    return law_class(**parameters)


KINETIC_LAWS = {law.CODE: law for law in (Coulomb, Viscous, Stribeck, Lubricated, CarlsonLanger)}
STATIC_LAWS = {law.CODE: law for law in (Constant, Logarithmic, Saturating, Sigmoid)}


def _law_class(table, kind, code_or_name):
    for law in table.values():
        if code_or_name in (law.CODE, law.NAME):
            return law
    choices = ", ".join(f"{law.CODE} ({law.NAME})" for law in table.values())
    raise ParameterError(f"{kind}.law = {code_or_name!r} is not a known law: allowed are {choices}")


def kinetic_law(code_or_name, **parameters):
    """Build a kinetic law from its code (1..5) or name and its parameters."""
    return _law_class(KINETIC_LAWS, "kinetic", code_or_name)(**parameters)


def static_law(code_or_name, **parameters):
    """Build a static law from its code (1..4) or name and its parameters."""
    return _law_class(STATIC_LAWS, "static", code_or_name)(**parameters)


def check_pair(kinetic, static):
    """Check both laws and ``F_K(0+) <= F_S(0)``, the condition for a block to stick at all."""
    kinetic.check()
    static.check()
    fk0, fs0 = kinetic.at_rest(), static.force(0.0)
    if not fk0 <= fs0:
        raise ParameterError(
            f"kinetic friction at rest F_K(0+) = {fk0!r} N exceeds static friction F_S(0) = {fs0!r} N: "
            f"allowed is F_K(0+) <= F_S(0) (lower kinetic.F0 / kinetic.F_stribeck, raise kinetic.sigma or raise "
            f"static.F0)"
        )
