"""Closing tests with witnesses: each proves that a family of supports has no MCEIP-mu solution
with mu in an interval (paper eqs. (21)-(23), condensed on the slip nodes).

A solution is ``mu >= 0``, ``v >= 0``, ``v != 0`` with ``y = A(mu) v >= 0`` and ``v_i y_i = 0``,
``A(mu) = A0 + mu A1``. Every test returns ``True`` only when its conclusion holds for the exact
pencil, every rounding error bounded by :mod:`.rounding`.

* **Sign argument** (:func:`copositive_at`): at a solution supported in ``U``,
  ``v_U^T D A_UU(mu) v_U = sum_i d_i v_i y_i = 0`` for any positive diagonal ``D``; so if
  ``sym(D A_UU(mu))`` is strictly copositive there is no such solution. Strict copositivity is
  proven by an exact split ``P + N`` (``N >= 0`` entrywise, ``P`` proven positive definite).
  ``A(mu)`` is affine in mu and the strictly copositive matrices form a convex cone, so the test
  at both ends of ``[a, b]`` closes the whole interval (:func:`closes_subsets`).
* **Nonsingularity on an interval** (:func:`nonsingular_on`): with ``R ~ A(m)^-1``, every
  ``A(mu)``, ``|mu - m| <= h``, is nonsingular when ``||I - R A(m)||_inf + h ||R A1||_inf < 1``
  (Banach lemma; both products bounded rigorously): then no support ``P`` solution has its mu
  in the interval.
* **Products of constraints** (:func:`rlt_closes`): ``x^T M y <= 0`` at a solution for a
  matrix ``M`` nonpositive off the diagonal (except on forced columns), so a strictly copositive
  ``sym(M A_UU)`` at both ends excludes the family (the sign argument is ``M = D``).
* **Farkas vectors** (:func:`farkas_closes`): a vector ``w``, nonpositive off a forced set ``F``,
  with ``(A(mu)^T w)_U > 0`` at both ends of ``[a, b]`` excludes every solution whose support
  lies between ``F`` and ``U`` there (the linear relaxation of that family is infeasible).
"""
from __future__ import annotations

import numpy as np

from app.analyses.mceip_mu.kernel.rounding import (
    U_ROUND,
    gamma,
    mr_mul,
    pencil_at,
    rounded_up,
    safe_inv,
    verified_pd,
)


def copositive_at(a0: np.ndarray, a1: np.ndarray, mu: float, d: np.ndarray, theta: float) -> bool:
    """``sym(D A(mu))`` is strictly copositive, by the split ``N = theta * (positive off-diagonal
    part)``, ``P = H - N`` (exact for ``theta`` in {0, 1/2, 1}), ``P`` proven positive definite."""
    if theta not in (0.0, 0.5, 1.0) or np.any(~(d > 0)) or not np.all(np.isfinite(d)):
        return False
    A = a0 + mu * a1
    DA = d[:, None] * A
    H = 0.5 * (DA + DA.T)
    aD = d[:, None] * (np.abs(a0) + abs(mu) * np.abs(a1))
    E = gamma(5) * 0.5 * (aD + aD.T)
    return pd_plus_nn(H, E, theta)


def pd_plus_nn(H: np.ndarray, E: np.ndarray, theta: float) -> bool:
    """Every symmetric matrix within entrywise ``E`` of ``H`` is strictly copositive: the exact
    split ``N = theta * (positive off-diagonal part of H)`` and ``H - N`` proven positive
    definite (within the Frobenius norm of ``E``)."""
    if theta > 0:
        off = H - np.diag(np.diag(H))
        H = H - theta * np.maximum(off, 0.0)
    return verified_pd(H, float(rounded_up(np.sqrt(np.sum(E * E)), E.size)))


def closes_subsets(a0, a1, U: np.ndarray, a: float, b: float, d: np.ndarray, theta: float) -> bool:
    """No solution with support in ``U`` and mu in ``[a, b]`` (sign argument at both ends)."""
    if not (a <= b) or len(d) != len(U):
        return False
    sub0, sub1 = a0[np.ix_(U, U)], a1[np.ix_(U, U)]
    return copositive_at(sub0, sub1, a, d, theta) and (a == b or copositive_at(sub0, sub1, b, d, theta))


def rlt_closes(a0: np.ndarray, a1: np.ndarray, U: np.ndarray, F, a: float, b: float, M, theta: float) -> bool:
    r"""No solution whose support ``P`` satisfies ``F <= P <= U`` has mu in ``[a, b]``, by a
    product-of-constraints argument (reformulation-linearisation): a ``|U| x |U|`` matrix ``M``
    with ``M_ij <= 0`` for ``i != j`` and ``U[j]`` not in ``F`` (diagonal and forced columns of any
    sign), and ``sym(M A_UU(mu))`` strictly copositive at ``a`` and ``b`` (exact split
    ``P + N``, ``P`` proven positive definite, as :func:`copositive_at`).

    At such a solution ``x_U^T M A_UU x_U = x^T M y = sum_{i in P, j in U \ P} x_i M_ij y_j <= 0``
    (``x_i = 0`` off ``P``, ``y_j = 0`` on ``P``, ``j`` off ``P`` is not in ``F``, ``y_j >= 0``), which
    strict copositivity forbids. ``M = D`` positive diagonal is the sign argument. Affine in mu,
    so both ends cover the interval."""
    U = np.asarray(U, dtype=np.int64)
    p = len(U)
    M = np.asarray(M, dtype=float)
    if M.shape != (p, p) or p == 0 or not np.all(np.isfinite(M)) or theta not in (0.0, 0.5, 1.0) \
            or not (a <= b):
        return False
    forced = np.isin(U, np.asarray(list(F), dtype=np.int64))
    sign_free = np.eye(p, dtype=bool) | forced[None, :]
    if np.any(M[~sign_free] > 0):
        return False
    sub0, sub1 = a0[np.ix_(U, U)], a1[np.ix_(U, U)]
    for mu in ((a, b) if a != b else (a,)):
        A, rA = pencil_at(sub0, sub1, mu)
        C, rC = mr_mul(M, None, A, rA)
        H = 0.5 * (C + C.T)
        R = rounded_up(0.5 * (rC + rC.T) + U_ROUND * np.abs(H), 2)
        if not pd_plus_nn(H, R, theta):
            return False
    return True


def farkas_closes(a0: np.ndarray, a1: np.ndarray, U: np.ndarray, F, a: float, b: float, w) -> bool:
    """No solution whose support ``P`` satisfies ``F <= P <= U`` has mu in ``[a, b]``, by a Farkas
    (Gordan) vector ``w`` (length ``s``) with ``w_i <= 0`` for every ``i`` not in ``F`` and
    ``(A(mu)^T w)_U > 0`` at ``a`` and at ``b``.

    At such a solution ``w^T y = sum_{i not in P} w_i y_i <= 0`` (``y_P = 0``, ``y >= 0`` and
    ``w_i <= 0`` off ``P``, as ``F <= P``), while ``w^T y = (A(mu)^T w)^T x = sum_{j in P} g_j x_j > 0``.
    ``g = A(mu)^T w`` is affine in mu, so both ends cover the interval. The linear relaxation of
    the family (complementarity fixed on ``F``, dropped elsewhere) is infeasible exactly when such
    a vector exists; it is found by an LP in the prover and re-checked here with a rigorous bound
    on the rounding of ``g``, never taken from the LP's status."""
    U = np.asarray(U, dtype=np.int64)
    if len(U) == 0 or not (a <= b):
        return False
    return farkas_at((pencil_at(a0[:, U], a1[:, U], mu) for mu in ((a, b) if a != b else (a,))), w, F, a0.shape[0])


def farkas_at(enclosures, w, F, s: int) -> bool:
    """The Farkas test of :func:`farkas_closes` on pencils given by ``enclosures``: pairs
    ``(C, rC)`` (midpoint, radius) enclosing the columns ``U`` of each pencil the family's mu
    range is a convex combination of (the ends of ``[a, b]`` for ``A0 + mu A1``; the corners of
    the lifting for the quadratic pencil, app/analyses/mceip_mu/quadratic/check.py). ``w``: the
    vector (length ``s``), nonpositive off the forced set ``F``, with ``(C^T w)_j > 0`` for every
    enclosed ``C`` (rigorously, with the radii)."""
    w = np.asarray(w, dtype=float)
    if w.shape != (s,) or not np.all(np.isfinite(w)):
        return False
    free = np.zeros(s, dtype=bool)
    free[[int(i) for i in F if 0 <= int(i) < s]] = True
    if np.any(w[~free] > 0):
        return False
    for C, rC in enclosures:
        g, rg = mr_mul(C.T, rC.T, w[:, None], None)
        if not np.all(g[:, 0] - rg[:, 0] > 0):
            return False
    return True


def nonsingular_on(a0: np.ndarray, a1: np.ndarray, P: np.ndarray, a: float, b: float) -> bool:
    """Every ``A_PP(mu)``, ``mu`` in ``[a, b]``, is nonsingular (so support ``P`` has no eigenvalue there)."""
    return bool(nonsingular_batch(a0, a1, P, np.array([a]), np.array([b]))[0])


def nonsingular_batch(a0: np.ndarray, a1: np.ndarray, P: np.ndarray, los: np.ndarray, his: np.ndarray) -> np.ndarray:
    """:func:`nonsingular_on` for many intervals ``[los[k], his[k]]`` at once (stacked LAPACK)."""
    los = np.asarray(los, dtype=float)
    his = np.asarray(his, dtype=float)
    out = np.zeros(len(los), dtype=bool)
    if len(P) == 0 or len(los) == 0:
        return out
    good = (los <= his) & np.isfinite(los) & np.isfinite(his)
    s0, s1 = a0[np.ix_(P, P)], a1[np.ix_(P, P)]
    p = len(P)
    m = 0.5 * (los + his)
    h = rounded_up(np.maximum(his - m, m - los), 2)
    # A(mu) = A(m) + (mu - m) A1: ||I - R A(mu)|| <= ||I - R A(m)|| + h ||R A1||, each product
    # with its rigorous radius (far tighter than |R| |A1| near an eigenvalue)
    A = s0[None] + m[:, None, None] * s1[None]
    rA = rounded_up(gamma(2) * (np.abs(s0)[None] + np.abs(m)[:, None, None] * np.abs(s1)[None]), 4)
    with np.errstate(all="ignore"):
        try:
            R = np.linalg.inv(A)
        except np.linalg.LinAlgError:
            R = np.stack([safe_inv(Ak) for Ak in A])
        fin = np.all(np.isfinite(R), axis=(1, 2))
        R = np.where(fin[:, None, None], R, 0.0)
        aR = np.abs(R)
        C = R @ A
        rC = rounded_up(gamma(p + 2) * (aR @ np.abs(A)) + aR @ rA, p + 4)
        C1 = R @ s1[None]
        rC1 = rounded_up(gamma(p + 2) * (aR @ np.abs(s1)[None]), p + 4)
        G = np.eye(p)[None] - C
        rG = rounded_up(rC + U_ROUND * np.abs(G) + h[:, None, None] * (np.abs(C1) + rC1), 4)
        nrm = rounded_up(np.max(np.sum(np.abs(G) + rG, axis=2), axis=1), p)
    out = good & fin & (nrm < 1.0)
    return out


def cover_nonsingular(a0, a1, U: np.ndarray, a: float, b: float, windows: list[tuple[float, float]],
                      rounds: int = 60, max_pieces: int = 4096) -> bool:
    """``[a, b]`` minus the ``windows`` is covered by intervals on which ``A_UU(mu)`` is proven
    nonsingular (batched tests, failed pieces halved, at most ``rounds`` times and at most
    ``max_pieces`` pieces in one batch: a budget in work, so the answer does not depend on the
    machine's speed)."""
    todo = []
    reach = a
    for lo, hi in sorted(windows):
        if lo > reach:
            todo.append((reach, min(lo, b)))
        reach = max(reach, hi)
        if reach >= b:
            break
    if reach < b:
        todo.append((reach, b))
    for _ in range(rounds):
        if not todo:
            return True
        if len(todo) > max_pieces:
            return False
        lo = np.array([g[0] for g in todo])
        hi = np.array([g[1] for g in todo])
        ok = nonsingular_batch(a0, a1, U, lo, hi)
        mid = 0.5 * (lo + hi)
        bad = ~ok
        if np.any(bad & ~((lo < mid) & (mid < hi) & (hi - lo > 1e-15 * np.maximum(1.0, np.abs(hi))))):
            return False
        todo = [(float(x), float(m)) for x, m in zip(lo[bad], mid[bad])] + \
               [(float(m), float(y)) for m, y in zip(mid[bad], hi[bad])]
    return not todo


def covers(pieces: list[tuple[float, float]], a: float, b: float) -> bool:
    """The union of the closed intervals ``pieces`` contains ``[a, b]``."""
    reach = a
    for lo, hi in sorted(pieces):
        if lo > reach:
            return False
        reach = max(reach, hi)
        if reach >= b:
            return True
    return reach >= b
