"""Batched bracketing: sign changes of a function sampled on a grid, refined all at once.

The functions of the analysis (grazing margins, classifications) are costly
to evaluate one point at a time but cheap in batches (:mod:`.flow` integrates a
whole batch in about the time of one member). :func:`refine` therefore
refines every bracket at once by k-section: each round evaluates ``k``
interior points of every bracket in one call and keeps the sub-bracket with
the first sign change, so the width shrinks by ``k + 1`` per round whether the
function is smooth there or jumps. A smooth sign change then gets its final
estimate by linear interpolation inside the last bracket.
"""

import numpy as np


def sign_changes(x, f):
    """Brackets ``[(x_i, x_{i+1}, f_i, f_{i+1}), ...]`` where finite samples change sign (zeros count)."""
    x, f = np.asarray(x, float), np.asarray(f, float)
    out = []
    good = np.flatnonzero(np.isfinite(f))
    for i, j in zip(good, good[1:]):
        if (f[i] < 0.0) != (f[j] < 0.0):
            out.append((x[i], x[j], f[i], f[j]))
    return out


def refine(fun, brackets, tol=1e-7, k=8, max_rounds=40):
    """Refine sign changes of ``fun`` (array -> array) inside ``[(a, b, fa, fb), ...]``.

    Returns ``[(root, a, b, fa, fb), ...]`` with ``b - a <= tol``; ``root`` is the
    linear interpolation of the last bracket (exact for a smooth sign change to
    second order in ``tol``; inside the bracket for a jump).
    """
    return refine_labels(None, brackets, tol, k, max_rounds, values=lambda x: np.asarray(fun(x), float))


def refine_labels(label_fun, brackets, tol=1e-7, k=8, max_rounds=40, values=None):
    """Refine changes of a discrete label (``label_fun``: array -> sequence of labels) by k-section.

    Each bracket ``(a, b, la, lb)`` keeps the first sub-interval where the label
    differs from ``la``. With ``values`` (the continuous function behind a sign
    label), the final brackets carry its values and the root is interpolated.
    """
    work = [list(b) for b in brackets]
    if not work:
        return []
    first_label = [bool(b[2] < 0.0) if values is not None else b[2] for b in work]
    if values is not None:
        vals = [[b[2], b[3]] for b in work]
    for _ in range(max_rounds):
        active = [i for i, b in enumerate(work) if b[1] - b[0] > tol]
        if not active:
            break
        points = np.concatenate([np.linspace(work[i][0], work[i][1], k + 2)[1:-1] for i in active])
        raw = values(points) if values is not None else None
        labels = list(np.asarray(raw) < 0.0) if values is not None else list(label_fun(points))
        for n, i in enumerate(active):
            a, b = work[i][0], work[i][1]
            xs = np.linspace(a, b, k + 2)
            ls = list(labels[n * k:(n + 1) * k])
            for m in range(k):
                if ls[m] != first_label[i]:
                    work[i][0], work[i][1] = xs[m], xs[m + 1]
                    if values is not None:
                        vals[i] = [vals[i][0] if m == 0 else raw[n * k + m - 1], raw[n * k + m]]
                    break
            else:
                work[i][0] = xs[k]
                if values is not None:
                    vals[i][0] = raw[n * k + k - 1]
    out = []
    for i, b in enumerate(work):
        a, c = b[0], b[1]
        if values is not None:
            fa, fc = vals[i]
            root = a - fa * (c - a) / (fc - fa) if fc != fa and np.isfinite(fa) and np.isfinite(fc) else 0.5 * (a + c)
            root = min(max(root, a), c)
            out.append((float(root), a, c, float(fa), float(fc)))
        else:
            out.append((0.5 * (a + c), a, c, b[2], b[3]))
    return out
