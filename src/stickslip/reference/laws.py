"""The reference's own friction laws and parameters, written from SPEC section 2 (not taken from ``core``).

Kinetic laws give ``F_K(u)`` (N) for the sliding speed ``u = |v_rel| >= 0`` (m/s)
and ``slope(u) = dF_K/du`` (N s/m); ``affine()`` is ``(F0, gamma)`` when
``F_K(u) = F0 + gamma u`` exactly (closed-form slips), else None. Static laws give
``F_S(t)`` (N) after sticking ``t >= 0`` s and ``rate(t) = dF_S/dt`` (N/s);
``convexity_breaks()`` are the stick times where ``F_S''`` changes sign.

Laws are built by SPEC name or code from FMU-named values
(:func:`parameters_from_values`), or directly; a Python user may pass any
callables through :class:`CustomKinetic` / :class:`CustomStatic`.
"""

import math

from .errors import ReferenceParameterError

INF = math.inf

# allowed ranges (low, high, low_open[, high_open]) by parameter name; the same name has the same range in every law
_NON_NEGATIVE = (0.0, INF, False)
_POSITIVE = (0.0, INF, True)
_RANGES = {
    "kinetic": {"F0": _NON_NEGATIVE, "gamma": _NON_NEGATIVE, "F_stribeck": _NON_NEGATIVE,
                "v_stribeck": _POSITIVE, "delta": (1.0, 10.0, False), "gamma1": _NON_NEGATIVE,
                "gamma2": _NON_NEGATIVE, "v_tilde": _NON_NEGATIVE, "dv": _POSITIVE, "sigma": (0.0, 1.0, False, True),
                "alpha": _NON_NEGATIVE},
    "static": {"F0": _POSITIVE, "A": _NON_NEGATIVE, "tau": _POSITIVE, "F_inf": _POSITIVE, "n": (0.5, 20.0, False)},
}


def _check_value(name, value, allowed):
    low, high, low_open, high_open = (*allowed, False)[:4]
    inside = (math.isfinite(value) and (value > low if low_open else value >= low)
              and (value < high if high_open else value <= high))
    if not inside:
        left, right = "(" if low_open else "[", ")" if high_open else "]"
        raise ReferenceParameterError(f"{name} = {value!r} is out of range: allowed is {left}{low:g}, {high:g}{right}")


class _CodedLaw:
    """A SPEC law: its parameters as attributes, validated by :meth:`check`."""

    KIND = ""
    NAME = ""
    CODE = 0
    NAMES = ()

    def __init__(self, **values):
        missing = [n for n in self.NAMES if n not in values]
        extra = sorted(set(values) - set(self.NAMES))
        if missing or extra:
            raise ReferenceParameterError(
                f"{self.KIND} law {self.NAME!r} takes exactly the parameters {list(self.NAMES)}"
                f" (missing {missing}, unknown {extra})")
        for name in self.NAMES:
            setattr(self, name, float(values[name]))

    def check(self):
        """Raise ReferenceParameterError naming the first parameter outside its range."""
        for name in self.NAMES:
            _check_value(f"{self.KIND}.{name}", getattr(self, name), _RANGES[self.KIND][name])

    def __repr__(self):
        args = ", ".join(f"{n}={getattr(self, n)!r}" for n in self.NAMES)
        return f"reference {self.KIND} {self.NAME}({args})"


# ----------------------------------------------------------------- kinetic laws (u in m/s, N)


class _Kinetic(_CodedLaw):
    KIND = "kinetic"

    def affine(self):
        return None


class Coulomb(_Kinetic):
    """``F_K(u) = F0``."""

    NAME, CODE, NAMES = "coulomb", 1, ("F0",)

    def force(self, u):
        return self.F0

    def slope(self, u):
        return 0.0

    def affine(self):
        return self.F0, 0.0


class Viscous(_Kinetic):
    """``F_K(u) = F0 + gamma u``."""

    NAME, CODE, NAMES = "viscous", 2, ("F0", "gamma")

    def force(self, u):
        return self.F0 + self.gamma * u

    def slope(self, u):
        return self.gamma

    def affine(self):
        return self.F0, self.gamma


class Stribeck(_Kinetic):
    """``F_K(u) = F0 + F_stribeck exp(-(u/v_stribeck)^delta) + gamma u``."""

    NAME, CODE, NAMES = "stribeck", 3, ("F0", "F_stribeck", "v_stribeck", "delta", "gamma")

    def force(self, u):
        return self.F0 + self.F_stribeck * math.exp(-math.pow(u / self.v_stribeck, self.delta)) + self.gamma * u

    def slope(self, u):
        # d/du exp(-(u/vs)^d) = -(d/vs) (u/vs)^(d-1) exp(-(u/vs)^d)
        ratio = u / self.v_stribeck
        return self.gamma - self.F_stribeck * (self.delta / self.v_stribeck) * math.pow(ratio, self.delta - 1.0) * (
            math.exp(-math.pow(ratio, self.delta)))

    def affine(self):
        return (self.F0 + self.F_stribeck, self.gamma) if self.F_stribeck == 0.0 else None


class Lubricated(_Kinetic):
    """``F_K(u) = u (g1 + g2 + (g2 - g1)(u - vt)/sqrt(dv^2 + (u - vt)^2)) / 2`` (Elmer 1997, fig. 3)."""

    NAME, CODE, NAMES = "lubricated", 4, ("gamma1", "gamma2", "v_tilde", "dv")

    def _switch(self, u):
        """``(w/r, r)`` with ``w = u - v_tilde``, ``r = sqrt(dv^2 + w^2)``: the smooth step from -1 to 1."""
        w = u - self.v_tilde
        r = math.sqrt(self.dv * self.dv + w * w)
        return w / r, r

    def force(self, u):
        step, _ = self._switch(u)
        return 0.5 * u * ((self.gamma1 + self.gamma2) + (self.gamma2 - self.gamma1) * step)

    def slope(self, u):
        # d/du [u s(u)] = s + u s', s' = dv^2 / r^3
        step, r = self._switch(u)
        step_slope = self.dv * self.dv / (r * r * r)
        return 0.5 * ((self.gamma1 + self.gamma2) + (self.gamma2 - self.gamma1) * (step + u * step_slope))

    def affine(self):
        return (0.0, self.gamma1) if self.gamma1 == self.gamma2 else None


class CarlsonLanger(_Kinetic):
    """``F_K(u) = F0 (1 - sigma) / (1 + 2 alpha u / (1 - sigma))`` (Carlson and Langer 1989): velocity weakening."""

    NAME, CODE, NAMES = "carlson-langer", 5, ("F0", "sigma", "alpha")

    def force(self, u):
        drop = 1.0 - self.sigma
        return self.F0 * drop / (1.0 + 2.0 * self.alpha * u / drop)

    def slope(self, u):
        # d/du c/(1 + b u) = -c b/(1 + b u)^2 with c = F0 (1 - sigma), b = 2 alpha/(1 - sigma): c b = 2 alpha F0
        drop = 1.0 - self.sigma
        denominator = 1.0 + 2.0 * self.alpha * u / drop
        return -2.0 * self.alpha * self.F0 / (denominator * denominator)

    def affine(self):
        return (self.F0 * (1.0 - self.sigma), 0.0) if self.alpha == 0.0 or self.F0 == 0.0 else None


# ----------------------------------------------------------------- static laws (t in s, N)


class _Static(_CodedLaw):
    KIND = "static"

    def is_constant(self):
        return False

    def convexity_breaks(self):
        return ()


class Constant(_Static):
    """``F_S(t) = F0``."""

    NAME, CODE, NAMES = "constant", 1, ("F0",)

    def force(self, t):
        return self.F0

    def rate(self, t):
        return 0.0

    def is_constant(self):
        return True


class Logarithmic(_Static):
    """``F_S(t) = F0 + A ln(1 + t/tau)``."""

    NAME, CODE, NAMES = "logarithmic", 2, ("F0", "A", "tau")

    def force(self, t):
        return self.F0 + self.A * math.log1p(t / self.tau)

    def rate(self, t):
        return (self.A / self.tau) / (1.0 + t / self.tau)

    def is_constant(self):
        return self.A == 0.0


class Saturating(_Static):
    """``F_S(t) = F0 + (F_inf - F0)(1 - exp(-t/tau))``."""

    NAME, CODE, NAMES = "saturating", 3, ("F0", "F_inf", "tau")

    def force(self, t):
        return self.F0 + (self.F_inf - self.F0) * -math.expm1(-t / self.tau)

    def rate(self, t):
        return (self.F_inf - self.F0) / self.tau * math.exp(-t / self.tau)

    def is_constant(self):
        return self.F_inf == self.F0


class Sigmoid(_Static):
    """``F_S(t) = F0 + (F_inf - F0) t^n / (tau^n + t^n)``; ``F_S''`` changes sign once for ``n > 1``."""

    NAME, CODE, NAMES = "sigmoid", 4, ("F0", "F_inf", "tau", "n")

    def force(self, t):
        s = t / self.tau
        if s > 1.0:  # t^n/(tau^n + t^n) = 1/(1 + s^-n), no overflow for large s
            return self.F0 + (self.F_inf - self.F0) / (1.0 + math.pow(s, -self.n))
        p = math.pow(s, self.n)
        return self.F0 + (self.F_inf - self.F0) * p / (1.0 + p)

    def rate(self, t):
        # d/dt s^n/(1 + s^n) = (n/tau) s^(n-1) / (1 + s^n)^2 with s = t/tau
        jump, n = self.F_inf - self.F0, self.n
        if jump == 0.0:
            return 0.0
        s = t / self.tau
        if s == 0.0:
            return 0.0 if n > 1.0 else jump / self.tau if n == 1.0 else math.copysign(INF, jump)
        if s > 1.0:  # s^(n-1)/(1+s^n)^2 = s^(-n-1)/(1+s^-n)^2
            q = math.pow(s, -n)
            return jump * (n / self.tau) * (q / s) / (1.0 + q) ** 2
        return jump * (n / self.tau) * math.pow(s, n - 1.0) / (1.0 + math.pow(s, n)) ** 2

    def is_constant(self):
        return self.F_inf == self.F0

    def convexity_breaks(self):
        # F_S'' ~ s^(n-2) ((n - 1) - (n + 1) s^n) / (1 + s^n)^3: one sign change where s^n = (n-1)/(n+1)
        if self.n <= 1.0 or self.F_inf == self.F0:
            return ()
        return (self.tau * math.pow((self.n - 1.0) / (self.n + 1.0), 1.0 / self.n),)


# ----------------------------------------------------------------- user callables (Python API)


class CustomKinetic:
    """Any callables ``force(u)`` (N) and ``slope(u)`` (N s/m); integrated numerically."""

    KIND, NAME = "kinetic", "custom"

    def __init__(self, force, slope):
        self._force, self._slope = force, slope

    def force(self, u):
        return float(self._force(u))

    def slope(self, u):
        return float(self._slope(u))

    def affine(self):
        return None

    def check(self):
        value = self.force(0.0)
        if not (math.isfinite(value) and value >= 0.0):
            raise ReferenceParameterError(f"custom kinetic law: F_K(0) = {value!r}; allowed is a finite value >= 0")


class CustomStatic:
    """Any callables ``force(t)`` (N), ``rate(t)`` (N/s) and the stick times where ``F_S''`` changes sign."""

    KIND, NAME = "static", "custom"

    def __init__(self, force, rate, convexity_breaks=()):
        self._force, self._rate, self._breaks = force, rate, tuple(float(b) for b in convexity_breaks)

    def force(self, t):
        return float(self._force(t))

    def rate(self, t):
        return float(self._rate(t))

    def is_constant(self):
        return False

    def convexity_breaks(self):
        return self._breaks

    def check(self):
        value = self.force(0.0)
        if not (math.isfinite(value) and value > 0.0):
            raise ReferenceParameterError(f"custom static law: F_S(0) = {value!r}; allowed is a finite value > 0")


KINETIC = {law.NAME: law for law in (Coulomb, Viscous, Stribeck, Lubricated, CarlsonLanger)}
STATIC = {law.NAME: law for law in (Constant, Logarithmic, Saturating, Sigmoid)}


def law_class(kind, name_or_code):
    """The coded law class of ``kind`` ("kinetic" or "static") by its SPEC name or code."""
    table = KINETIC if kind == "kinetic" else STATIC
    for cls in table.values():
        if name_or_code in (cls.NAME, cls.CODE) and not isinstance(name_or_code, bool):
            return cls
    allowed = ", ".join(f"{cls.CODE} ({cls.NAME})" for cls in table.values())
    raise ReferenceParameterError(f"{kind}.law = {name_or_code!r} is not a known law: allowed are {allowed}")


def law(kind, name_or_code, **values):
    """A coded law of ``kind`` by its SPEC name or code, with its parameters."""
    return law_class(kind, name_or_code)(**values)


class ReferenceParameters:
    """Mass ``M`` (kg), stiffness ``kappa`` (N/m) and the reference's two laws."""

    __slots__ = ("M", "kappa", "kinetic", "static")

    def __init__(self, M, kappa, kinetic, static):
        self.M, self.kappa, self.kinetic, self.static = float(M), float(kappa), kinetic, static

    def check(self):
        """Raise ReferenceParameterError for a value out of range or ``F_K(0+) > F_S(0)``."""
        _check_value("M", self.M, _POSITIVE)
        _check_value("kappa", self.kappa, _POSITIVE)
        self.kinetic.check()
        self.static.check()
        fk0, fs0 = self.kinetic.force(0.0), self.static.force(0.0)
        if not fk0 <= fs0:
            raise ReferenceParameterError(
                f"F_K(0+) = {fk0!r} N exceeds F_S(0) = {fs0!r} N: allowed is F_K(0+) <= F_S(0)")

    def __repr__(self):
        return f"ReferenceParameters(M={self.M!r}, kappa={self.kappa!r}, {self.kinetic!r}, {self.static!r})"


def parameters_from_values(values):
    """:class:`ReferenceParameters` from FMU-named values: ``M``, ``kappa``, ``kinetic.law`` (code or
    name), ``kinetic.<p>`` and ``static.law``, ``static.<p>`` for every parameter of the two laws.
    Other keys (initial state, inputs, solver settings) are ignored; a missing one is an error."""
    laws = []
    for kind in ("kinetic", "static"):
        prefix = f"{kind}."
        given = {k[len(prefix):]: v for k, v in values.items() if k.startswith(prefix) and k != f"{kind}.law"}
        if f"{kind}.law" not in values:
            raise ReferenceParameterError(f"{kind}.law is missing")
        cls = law_class(kind, values[f"{kind}.law"])
        laws.append(cls(**{n: given[n] for n in cls.NAMES if n in given}))
    for name in ("M", "kappa"):
        if name not in values:
            raise ReferenceParameterError(f"{name} is missing")
    return ReferenceParameters(values["M"], values["kappa"], *laws)

