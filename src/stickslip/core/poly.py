"""Small polynomials in the step fraction ``theta`` in [0, 1], as coefficient lists (lowest first)."""

from __future__ import annotations  # annotations stay unevaluated: the FMU runs on CPython 3.8+

from .rootfind import brent


def evaluate(coeffs: list[float], theta: float) -> float:
    """``sum(c_k theta^k)`` by Horner's rule."""
    result = 0.0
    for c in reversed(coeffs):
        result = result * theta + c
    return result


def evaluate_pair(coeffs_a: list[float], coeffs_b: list[float], theta: float) -> tuple[float, float]:
    """Both polynomials (of equal length) at ``theta``, in one Horner pass."""
    a = 0.0
    b = 0.0
    for ca, cb in zip(reversed(coeffs_a), reversed(coeffs_b)):
        a = a * theta + ca
        b = b * theta + cb
    return a, b


def derivative(coeffs: list[float]) -> list[float]:
    """Coefficients of ``d/dtheta``."""
    return [k * c for k, c in enumerate(coeffs)][1:]


def monotone_breaks(coeffs: list[float], a: float = 0.0, b: float = 1.0) -> list[float]:
    """Sorted points ``a = p0 < p1 < ... = b`` between which the polynomial is monotonic.

    The interior points are the real roots of the derivative in ``(a, b)``,
    found recursively (each derivative is split where its own derivative
    vanishes, so every root is bracketed exactly: no sampling, no missed pair).
    """
    return [a] + _roots(derivative(coeffs), a, b) + [b]


def _roots(coeffs: list[float], a: float, b: float) -> list[float]:
    """Real roots of the polynomial strictly inside ``(a, b)`` where it changes sign."""
    while coeffs and coeffs[-1] == 0.0:
        coeffs = coeffs[:-1]
    if len(coeffs) < 2:
        return []
    if len(coeffs) == 2:
        root = -coeffs[0] / coeffs[1]
        return [root] if a < root < b else []
    points = [a] + _roots(derivative(coeffs), a, b) + [b]
    roots = []
    for left, right in zip(points, points[1:]):
        f_left, f_right = evaluate(coeffs, left), evaluate(coeffs, right)
        if (f_left < 0.0 < f_right) or (f_right < 0.0 < f_left):
            roots.append(brent(lambda th: evaluate(coeffs, th), left, right, f_left, f_right))
    return roots
