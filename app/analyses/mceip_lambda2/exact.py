"""A proof that MCEIP-lambda^2 (12)-(14) has no solution, on the exact slip-node reduction
(docs/method.md section 7).

With ``H(t) = K + t M`` (``t = lambda^2 >= 0``, SPD) every DOF except the slip nodes' ``x_Ts`` is
eliminated exactly. The interior goes through the dynamic contact flexibility
``W(t) = B (K + t M)^-1 B^T`` and its inverse, the dynamic contact Schur complement ``Z(t)``
(``Z(0)`` is the static one of the condensed MCEIP-mu), which do not depend on the
classification: :class:`app.analyses.mceip_lambda2.dynamic_contact.DynamicContact` computes them
once per ``t`` for the whole path. The
free contact nodes are eliminated as in :func:`app.analyses.pencils.reduced.condensed_mu_pencil`. The
result is the ``s x s`` matrix ``S(t)`` with ``y_Ts = S(t) x_Ts`` at every ``x`` with ``y_f = 0``,
so (12)-(14) is ``x >= 0, S(t) x >= 0, x_i (S(t) x)_i = 0`` (``S(0)`` is the condensed MCEIP-mu
pencil at mu).

Sign argument: at a solution ``x^T S(t) x = 0``, so no solution has a ``t`` at which
``sym S(t)`` is strictly copositive. To prove it on an interval, split (exactly)

    x^T S(t) x = x^T Sh(t) x + x^T Q(t) x,

``Sh(t)`` the Schur complement of ``sym A(t)`` (``A(t) = K*(mu) + t M*(mu)``) onto the slip
nodes, concave in ``t`` (a minimum over the eliminated DOFs of forms affine in ``t``), and
``Q(t) = N^T A_ff(t)^-1 N / 4`` with ``N = A_fc - A_cf^T`` affine in ``t``, convex in ``t``
(matrix-fractional function). On ``[a, b]``, ``Sh`` lies above its chord and ``Q`` above a
secant line through a neighbouring grid point (convexity), so ``x^T S(t) x`` is bounded below by
a matrix affine in ``t``; if that lies in ``PD + NN`` at both ends it does on all of ``[a, b]``
(convex cone), which proves no solution there. Intervals that fail are bisected. For
``t >= T``: when ``sym M*`` is PSD, ``Sh`` increases with ``t`` (Loewner order), so ``Sh(T)`` PD
proves no solution above ``T`` (the same ``T`` as an LDL^T inertia count of ``sym K* + T sym M*``,
by Haynsworth's inertia additivity).

Cost: the dense set-up is ``O(n^3)`` once per system, then ``O(n_c^3)`` per ``t`` (``n_c`` the
contact DOFs); the sparse one is one factorisation per ``t``. The proof evaluates ``t`` on a dyadic
grid, so the classifications along a path share most factorisations (the 100k-DOF block: 36 for
104 classifications). A failed proof proves nothing: the caller then searches with SNES VI.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from app.analyses.mceip_lambda2.dynamic_contact import DynamicContact
from app.analyses.mceip_mu.state import in_pd_plus_nn
from app.analyses.pencils.kept_contact import KeptContact
from app.loading.classify import Classification

#: relative margin of the PD + NN tests (rounding of the eliminations, pencil scaled to unit diagonal)
MARGIN = 1e-8


class Reduction(KeptContact):
    """``S(t)``, ``sym S(t)`` and ``Sh(t)`` of one classification at mu (cached per t).

    The maps are the identity on the free nodes' DOFs (the first ``nF`` kept unknowns) and ``D =
    Q - R^T`` is zero there, so ``A(t) = R Z(t) Q`` and ``G(t) = sym A(t) - D^T (H(t) - Z(t)) D / 4``
    (:meth:`KeptContact.kept`, ``H = K_cc + t M_cc``) share their free block ``Z_FF(t)``, SPD: one
    Cholesky factorisation gives both Schur complements onto the slip nodes, ``S = A_SS - A_SF
    Z_FF^-1 A_FS`` and ``Sh = G_SS - G_SF Z_FF^-1 G_FS`` with ``G_FS = (A_FS + A_SF^T) / 2``, and
    ``D^T H D`` is ``D^T K_cc D + t D^T M_cc D``, formed once. :meth:`sh` gives ``Sh(t)`` alone (the
    bisections for the bound ``T`` read nothing else); :meth:`at` completes ``S(t)`` from the same
    elimination."""

    def __init__(self, dc: DynamicContact, cls: Classification, mu: float):
        super().__init__(dc.Kcc.shape[0], cls, mu)
        self.dc, self.mu = dc, mu
        self._cache: dict[float, tuple] = {}
        self._q: dict[float, np.ndarray] = {}
        Ds = self.D[:, self.nF:].tocsc()               # the slip nodes' columns (the others are zero)
        Ds.sort_indices()
        # D's columns as (rows, values) slots, one per entry (one on a flat obstacle, up to two in a
        # contact frame; unused slots hold value 0): D^T X D is then a sum of gathered s x s blocks
        count = np.diff(Ds.indptr)
        slots = max(1, int(count.max(initial=0)))
        self._d_rows = np.zeros((slots, Ds.shape[1]), dtype=np.intp)
        self._d_vals = np.zeros((slots, Ds.shape[1]))
        for k in range(slots):
            has = count > k
            self._d_rows[k, has] = Ds.indices[Ds.indptr[:-1][has] + k]
            self._d_vals[k, has] = Ds.data[Ds.indptr[:-1][has] + k]
        self._DKD, self._DMD = self._dxd(dc.Kcc), self._dxd(dc.Mcc)

    def _dxd(self, X: np.ndarray) -> np.ndarray:
        """``D_S^T X D_S`` (``D`` on the slip nodes' columns) by gathers of ``X``."""
        out = np.zeros((self._d_rows.shape[1],) * 2)
        for ra, va in zip(self._d_rows, self._d_vals):
            for rb, vb in zip(self._d_rows, self._d_vals):
                out += X[np.ix_(ra, rb)] * va[:, None] * vb[None, :]
        return out

    def _schur(self, X: np.ndarray) -> np.ndarray:
        n = self.nF
        if n == 0:
            return X
        return X[n:, n:] - X[n:, :n] @ np.linalg.solve(X[:n, :n], X[:n, n:])

    def S(self, t: float) -> np.ndarray:
        """``S(t)`` itself (``s x s``, slip nodes in the classification's order): ``y_Ts = S(t) x_Ts``
        at every ``x`` with ``y_f = 0``."""
        return self._schur(self.reduced(self.dc.schur_at(t), bend=True))

    def sh(self, t: float) -> np.ndarray:
        """``Sh(t)`` alone (the bisections for the bound ``T`` read only it)."""
        return self._parts(t)[0]

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``(Sh(t), Q(t))`` with ``sym S(t) = Sh(t) + Q(t)``."""
        Sh, ASS, U, V = self._parts(t)
        Q = self._q.get(t)
        if Q is None:
            Sx = ASS if U is None else ASS - V.T @ U
            Q = self._q[t] = 0.5 * (Sx + Sx.T) - Sh
            self._cache[t] = (Sh, None, None, None)      # what made S(t) is no longer needed
        return Sh, Q

    def _parts(self, t: float) -> tuple:
        """``Sh(t)`` and what ``S(t)`` takes from the same elimination: ``A_SS`` and ``L^-1 A_FS``,
        ``L^-T A_SF^T`` (``Z_FF = L L^T``; None without free nodes), kept per ``t`` (their number is
        the values of ``t`` a proof used)."""
        hit = self._cache.get(t)
        if hit is None:
            Z = self.dc.schur_at(t)
            A = self.reduced(Z, bend=True)         # K* + t M*: a curved obstacle's term is K*'s
            n = self.nF
            ASS = A[n:, n:].copy()                 # not a view: A is not kept
            Sh = 0.5 * (ASS + ASS.T) - 0.25 * (self._DKD + t * self._DMD - self._dxd(Z))
            U = V = None
            if n:
                try:
                    L = scipy.linalg.cholesky(A[:n, :n], lower=True)
                    U = scipy.linalg.solve_triangular(L, A[:n, n:], lower=True)
                    V = scipy.linalg.solve_triangular(L, np.ascontiguousarray(A[n:, :n].T), lower=True)
                    W = 0.5 * (U + V)             # L^-1 G_FS
                    Sh = Sh - W.T @ W
                except np.linalg.LinAlgError:    # Z_FF not PD in floating point: LU factorisations
                    GFS = 0.5 * (A[:n, n:] + A[n:, :n].T)
                    Sh = Sh - GFS.T @ np.linalg.solve(A[:n, :n], GFS)
                    ASS, U, V = self._schur(A), None, None
            hit = self._cache[t] = (0.5 * (Sh + Sh.T), ASS, U, V)
        return hit


def _pd(X: np.ndarray) -> bool:
    d = np.sqrt(np.maximum(np.abs(np.diag(X)), 1e-300))
    try:
        np.linalg.cholesky(X / d[:, None] / d[None, :] - MARGIN * np.eye(len(X)))
        return True
    except np.linalg.LinAlgError:
        return False


#: most values of t one proof may use (its work budget: counted, never timed); beyond it the proof
#: gives up and the caller searches
MAX_EVALUATIONS = 400


def _not_copositive(S: np.ndarray) -> bool:
    """A witness that the symmetric ``S`` is not copositive: a negative diagonal entry, or a negative
    smallest eigenvalue whose eigenvector has one sign (``x >= 0`` with ``x^T S x < 0``). No interval
    with such an end can be certified (its lower bound at that end is at most ``S``), however halved;
    without a witness nothing is claimed (the PD + NN test is a sufficient one)."""
    d = np.diag(S)
    if (d < 0).any():
        return True
    w, v = scipy.linalg.eigh(S, subset_by_index=[0, 0])
    x = v[:, 0]
    return bool(w[0] < 0 and (np.all(x >= 0) or np.all(x <= 0)))


def _dyadic_above(x: float) -> float:
    """The smallest power of two at or above ``x > 0``."""
    m, e = np.frexp(x)
    return float(np.ldexp(1.0, int(e) - (1 if m == 0.5 else 0)))


@dataclass(frozen=True)
class Signs:
    """The signs of the necessary condition (19) on the contact DOFs: ``sym K*(mu)`` positive
    definite, ``sym M*(mu)`` positive semi-definite and definite, each decided on its Schur
    complement onto the kept contact DOFs (the interior blocks ``K_ii``, ``M_ii`` are SPD, so by
    Haynsworth's inertia additivity the whole matrix has the sign of that Schur complement),
    with the relative margin :data:`MARGIN` (floating point)."""

    k_pd: bool
    m_psd: bool
    m_pd: bool


def contact_signs(dc: DynamicContact, cls: Classification, mu: float) -> Signs:
    """:class:`Signs` of one classification: dense work on the kept contact DOFs only."""
    red = Reduction(dc, cls, mu)
    GK = red.kept(*dc.at(0.0), bend=True)
    GM = red.kept(dc.mass_schur(), dc.Mcc)
    m_pd = _pd(GM)
    m_psd = m_pd or _pd(GM + 2 * MARGIN * np.diag(np.abs(np.diag(GM))))
    return Signs(k_pd=_pd(GK), m_psd=m_psd, m_pd=m_pd)


def start_bound(dc: DynamicContact, cls: Classification, mu: float, doublings: int = 80) -> float | None:
    """A power of two ``T`` with ``Sh(T)`` positive definite (caller: ``sym M*(mu)`` PD, so every
    larger ``t`` has it too): doublings from the power of two nearest ``tr K_cc / tr M_cc``, each a
    value of ``t`` on the dyadic grid; None if none of ``doublings`` is."""
    red = Reduction(dc, cls, mu)
    ratio = float(np.trace(dc.Kcc) / np.trace(dc.Mcc))
    if not np.isfinite(ratio) or ratio <= 0:
        return None
    t = float(np.ldexp(1.0, int(np.round(np.log2(ratio)))))
    for _ in range(doublings):
        if _pd(red.sh(t)):
            return t
        t *= 2.0
    return None


def _tail(red: Reduction, t_start: float, steps: int = 8) -> float | None:
    """The smallest ``T`` of a bisection (``steps`` halvings from the power of two above
    ``t_start``, on the dyadic grid) with ``Sh(T)`` PD, or None when ``Sh`` is not PD there."""
    lo, hi = 0.0, _dyadic_above(float(t_start))
    if not _pd(red.sh(hi)):
        return None
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        if _pd(red.sh(mid)):
            hi = mid
        else:
            lo = mid
    return hi


def tail_bound(dc: DynamicContact, cls: Classification, mu: float, t_start: float) -> float | None:
    """An upper bound ``T`` on every solution's ``lambda^2`` (caller: ``sym M*(mu)`` PD and
    ``t_start > 0`` a bound, e.g. the Rayleigh quotient's): ``Sh(T)``, the Schur complement of
    ``sym(K* + T M*)`` onto the slip nodes, PD makes ``sym(K* + t M*)`` PD for every ``t >= T``
    (Haynsworth; ``Sh`` increases with ``t``), and ``x^T (K* + t M*) x = 0`` at a solution.
    Floating point; None when no such ``T`` is found at the power of two above ``t_start``."""
    if not np.isfinite(t_start) or t_start <= 0:
        return None
    return _tail(Reduction(dc, cls, mu), t_start)


def prove_no_solution(dc: DynamicContact, cls: Classification, mu: float, t_start: float,
                      pieces: int = 8, depth: int = 10,
                      max_evaluations: int = MAX_EVALUATIONS, max_failed: int = 0) -> tuple[bool, float, dict]:
    """Try to prove that (12)-(14) has no solution with ``lambda^2 >= 0`` (caller: ``sym M*(mu)``
    PSD, ``t_start`` a bound with ``sym K* + t_start sym M*`` PD, e.g. the Rayleigh quotient bound).

    Returns ``(proven, T, detail)``: ``T`` the smallest of a bisection where ``Sh(T)`` is PD (no
    solution above it), and whether ``[0, T]`` was covered by certified intervals.

    Every ``t`` it evaluates is a dyadic multiple of a power of two (the bisection starts at the
    power of two above ``t_start``, which is a bound too as ``Sh`` increases with ``t``; ``[0, T]``
    is covered by pieces of the power-of-two width about ``T / pieces``), so the classifications of
    one system evaluate ``W(t)`` on one grid and mostly reuse each other's. At most
    ``max_evaluations`` distinct ``t`` (the proof's budget); ``False`` when it runs out.

    An interval still not certified at ``depth`` halvings ends the proof, or with ``max_failed > 0``
    is set aside and the others go on (as is at once, then, one where ``sym S(t)`` is shown not
    copositive at both ends, as near a solution: :func:`_not_copositive`): ``detail["failed"]`` then lists up to ``max_failed`` such
    intervals (exact ``S`` at their ends) and ``detail["covered"]`` is True when ``[0, inf)`` holds
    no solution outside them (every other interval certified; a proof stopped by ``max_failed``
    or the budget has no ``covered``). The search of
    :mod:`app.analyses.mceip_lambda2.reduced_search` looks in them."""
    t0 = time.perf_counter()
    red = Reduction(dc, cls, mu)

    def used() -> int:
        return len(red._cache)

    def out_of_budget(a: float, b: float) -> tuple[bool, float, dict]:
        return False, T, {"reason": f"budget of {max_evaluations} values of t spent at [{a:.6g}, {b:.6g}]",
                          "evaluations": used(), "seconds": time.perf_counter() - t0}

    if not np.isfinite(t_start) or t_start <= 0:
        return False, float(t_start), {"reason": "no finite positive start bound", "seconds": time.perf_counter() - t0}
    T = _tail(red, t_start)
    if T is None:
        return False, _dyadic_above(float(t_start)), {"reason": "Sh(T) not PD at the start bound",
                                                       "seconds": time.perf_counter() - t0}
    failed: list[tuple[float, float]] = []
    width = _dyadic_above(T / pieces)
    todo = [(i * width, (i + 1) * width, 0) for i in range(int(np.ceil(T / width)))][::-1]
    proven_count = 0
    while todo:
        a, b, level = todo.pop()
        if used() + 4 > max_evaluations:
            return out_of_budget(a, b)
        Sa, Qa = red.at(a)
        Sb, Qb = red.at(b)
        h = b - a
        if a > 0:     # Q(t) >= Q(a) + (t - a) (Q(a) - Q(z)) / (a - z) on [a, b] (left secant)
            z = max(0.0, a - h)
            slope = (Qa - red.at(z)[1]) / (a - z)
            La, Lb = Sa + Qa, Sb + Qa + h * slope
        else:         # Q(t) >= Q(b) + (t - b) (Q(c) - Q(b)) / (c - b) on [a, b] (right secant)
            c = b + h
            slope = (red.at(c)[1] - Qb) / (c - b)
            La, Lb = Sa + Qb - h * slope, Sb + Qb
        if in_pd_plus_nn(La) and in_pd_plus_nn(Lb):
            proven_count += 1
        elif max_failed and len(failed) < max_failed and _not_copositive(Sa + Qa) and _not_copositive(Sb + Qb):
            failed.append((a, b))     # sym S(t) is not copositive at either end: no halving certifies them
        elif level < depth:
            m = 0.5 * (a + b)
            todo += [(m, b, level + 1), (a, m, level + 1)]
        elif len(failed) < max_failed:
            failed.append((a, b))
        else:
            return False, T, {"reason": f"sym S(t) not certified copositive on [{a:.6g}, {b:.6g}]",
                              "evaluations": used(), "seconds": time.perf_counter() - t0,
                              **({"failed": failed} if max_failed else {})}
    done = {"intervals": proven_count, "evaluations": used(), "seconds": time.perf_counter() - t0}
    if failed:
        return False, T, {**done, "failed": failed, "covered": True,
                          "reason": f"sym S(t) not certified copositive on {len(failed)} interval(s) of t"}
    return True, T, done
