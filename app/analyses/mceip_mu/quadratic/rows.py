"""Exact row structure of the quadratic split pencil of zero-reaction nodes, for the enumeration of
app/analyses/mceip_mu/quadratic/problem.py (docs/method.md section 8).

A zero-reaction node's split rows satisfy ``row_a(mu) = A0[a] + mu A0[N]`` and
``row_N(mu) = A0[N]`` exactly (``a`` or ``b``, ``N`` its normal rate), so on a support holding
``a`` and ``N`` the ``mu`` of ``det A_JJ`` cancels exactly; and ``A2 = G`` vanishes on the zero
nodes' columns, so the companion linearisation has infinite eigenvalues. Left to rounding, both
give spurious finite roots near ``1 / eps``; the row operation ``row_a -= mu row_N`` (determinant
unchanged) and the degree bound of ``det A_JJ`` remove them before any eigenvalue is trusted.
"""
from __future__ import annotations

import numpy as np


def zero_node_rows(a0, a1, a2, pairs) -> list[tuple[int, int]]:
    """``(i, n)``: a half ``i`` of a pair and the normal row ``n`` of its zero-reaction node, where
    the split pencil's identities hold exactly: ``a1[i] = a0[n]``, ``a2[i] = 0``, ``a1[n] = a2[n] = 0``."""
    out = []
    for p in pairs:
        for i in p:
            i = int(i)
            if np.any(a2[i]):
                continue
            for n in range(a0.shape[0]):
                if n not in p and np.array_equal(a1[i], a0[n]) and not np.any(a1[n]) and not np.any(a2[n]):
                    out.append((i, n))
                    break
    return out


def lower_rows(B0, B1, B2, Rb, triples) -> tuple[np.ndarray, np.ndarray]:
    """``B1, B2`` after the row operation ``row_i -= mu row_n`` on every support holding both ``i``
    and ``n`` of :func:`zero_node_rows` (``det`` unchanged): the row of ``i`` becomes the constant
    ``a0[i]``, so its exact cancellation of ``mu`` is not left to rounding (which would give a
    spurious root of a constant determinant near ``1 / eps``). ``B1, B2`` themselves without ``triples``."""
    if not triples:
        return B1, B2
    C1, C2 = B1.copy(), B2.copy()
    for j, R in enumerate(Rb):
        where = {int(r): q for q, r in enumerate(R)}
        for i, n in triples:
            if i in where and n in where:
                qi, qn = where[i], where[n]
                C1[j, qi] = B1[j, qi] - B0[j, qn]
                C2[j, qi] = B2[j, qi] - B1[j, qn]
    return C1, C2


def drop_infinite(W: np.ndarray, B1: np.ndarray, B2: np.ndarray) -> np.ndarray:
    """``W`` with its largest ``2k - deg`` eigenvalues per support set infinite, ``deg`` the bound on
    the degree of ``det A_JJ(mu)`` from the rows (and columns) of ``A1``, ``A2`` that vanish:
    a row of degree 2, 1 or 0 in mu contributes that much. A singular ``A2`` (a zero-reaction
    node's columns carry no curvature term) has infinite eigenvalues that the companion
    linearisation perturbs to ``O(1 / sqrt(eps))``, not to infinity."""
    two = np.any(B2 != 0, axis=2)
    one = np.any(B1 != 0, axis=2) & ~two
    rows = 2 * two.sum(axis=1) + one.sum(axis=1)
    two_c = np.any(B2 != 0, axis=1)
    one_c = np.any(B1 != 0, axis=1) & ~two_c
    cols = 2 * two_c.sum(axis=1) + one_c.sum(axis=1)
    drop = W.shape[1] - np.minimum(rows, cols)
    if not np.any(drop > 0):
        return W
    W = W.copy()
    order = np.argsort(-np.where(np.isfinite(W), np.abs(W), np.inf), axis=1)
    for j in np.flatnonzero(drop > 0):
        W[j, order[j, :drop[j]]] = np.inf
    return W
