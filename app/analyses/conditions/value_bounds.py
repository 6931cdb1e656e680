"""Bounds on one value of the necessary condition (19) on the contact DOFs once the budget of exact
Schur complements is spent (docs/method.md section 2, "When the budget is spent"): from the exact
values of ``Y`` already computed, with the sign of the value decided by ``Y(0)``."""
from __future__ import annotations

import numpy as np
import scipy.linalg


def bracket(root) -> tuple[float, float]:
    """``(lo, hi)`` around the root of ``f`` of ``root`` (a
    :class:`~app.analyses.conditions.contact_spectrum.Root`) from the exact values of ``Y`` already computed and ``Y(0)``
    (docs/method.md section 2, "When the budget is spent"): ``f`` decreases with slope at most -1
    and is concave (``Y`` is convex in ``sigma`` below ``k_1``, so ``S`` is concave). With ``f(p) > 0``
    at ``p`` the largest such point and ``f(q) < 0`` at ``q`` the smallest such one, the root lies in
    ``(p, q)``, below ``p + f(p)`` (the slope) and ``k_1`` (interlacing), above ``q + f(q)`` (the
    slope), the root of the chord through both points (concavity: ``f`` lies above its chords) and
    the first root of a lower bound of ``f`` above ``p`` (from ``X_ii >= k_1 I``; not with static
    DOFs, whose interior is a pencil), and below the root of the line through two known points on
    one side (concavity: beyond them ``f`` lies below it). The sign of the value is that of ``f(0)``."""
    sc = root.sc
    sc.at_zero()
    pts = []
    for q in sorted(sc.known(), key=lambda q: q[0]):       # one of the points that coincide (end 0 and 0)
        if not pts or q[0] - pts[-1][0] > 1e-9 * abs(sc.k1):
            pts.append(q)

    def positive(i: int) -> bool:
        try:
            scipy.linalg.cholesky(root.exact(*pts[i])[0])
            return True
        except np.linalg.LinAlgError:
            return False

    # f decreases: the first point where it is not positive, by bisection on the sorted points
    # (Cholesky factorisations, not eigenvalues), then f itself at the two points either side
    a, b = 0, len(pts)
    while a < b:
        m = (a + b) // 2
        if positive(m):
            a = m + 1
        else:
            b = m
    def f(i: int) -> tuple[float, float, np.ndarray]:
        return pts[i][0], root.f_exact(*pts[i]), root.exact(*pts[i])[1]

    pos = [f(a - 1)] if a > 0 else []
    neg = [f(a)] if a < len(pts) else []
    # concavity: beyond two points on one side, f lies below the line through them, whose root is
    # then an upper bound on the root
    beyond = [(f(a - 2), pos[0])] if a > 1 else []
    beyond += [(neg[0], f(a + 1))] if a + 1 < len(pts) else []
    lo, hi = -np.inf, sc.k1
    if pos:
        p, fp, G = max(pos, key=lambda q: q[0])
        lo, hi = p, min(hi, p + fp)
        if not sc.static and p < sc.k1:
            # Y(sigma) - Y(p) <= (sigma - p) / (k_1 - sigma) Y(p) (functions of X_ii >= k_1 I), so
            # f(p + d) >= f(p) - d - d g / (k_1 - p - d), g >= ||P^T Y(p) P|| (its Frobenius norm): the
            # first root bounds d
            g = float(np.linalg.norm(G))
            k = sc.k1 - p
            b = fp + k + g
            lo = max(lo, p + 2.0 * fp * k / (b + np.sqrt(max(b * b - 4.0 * fp * k, 0.0))))
    if neg:
        q, fq, _ = min(neg, key=lambda r: r[0])
        hi = min(hi, q)
        lo = max(lo, q + fq)
        if pos:
            lo = max(lo, p + fp * (q - p) / (fp - fq))
    for (x1, f1, _), (x2, f2, _) in beyond:
        if f1 - f2 > 1e-6 * max(abs(f1), abs(f2)):         # a line resolved above the rounding of f
            hi = min(hi, x1 - f1 * (x2 - x1) / (f2 - f1))
    return float(min(lo, hi)), float(hi)     # min: rounding at a point where f ~ 0
