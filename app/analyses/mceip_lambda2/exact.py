"""A proof that MCEIP-lambda^2 (12)-(14) has no solution, on the exact slip-node reduction
(docs/method.md section 7).

With ``H(t) = K + t M`` (``t = lambda^2 >= 0``, SPD) every DOF except the slip nodes' ``x_Ts`` is
eliminated exactly: the interior through the eigen-decomposition ``K Phi = M Phi Omega``
(``Phi^T M Phi = I``), which gives the dynamic contact flexibility
``W(t) = B Phi (Omega + t)^-1 Phi^T B^T`` and its inverse, the dynamic contact Schur complement
``Z(t)`` (``Z(0)`` is the static one of the condensed MCEIP-mu); the free contact nodes as in
:func:`app.analyses.pencils.condensed_mu_pencil`. The result is the ``s x s`` matrix ``S(t)``
with ``y_Ts = S(t) x_Ts`` at every ``x`` with ``y_f = 0``, so (12)-(14) is
``x >= 0, S(t) x >= 0, x_i (S(t) x)_i = 0`` (``S(0)`` is the condensed MCEIP-mu pencil at mu).

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

Everything is dense and ``O(n^3)`` once per system (the eigen-decomposition), then ``O(n s^2)``
per ``t``; it is used up to ``McpSettings.lambda2_exact_max_dofs`` DOFs. A failed proof proves
nothing: the caller then searches with SNES VI.
"""
from __future__ import annotations

import time
import weakref
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from app.analyses.certify import in_pd_plus_nn
from app.analyses.pencils import dense
from app.analyses.state_pencils import per_system
from app.loading.classify import FREE, Classification

#: relative margin of the PD + NN tests (rounding of the eliminations, pencil scaled to unit diagonal)
MARGIN = 1e-8


@dataclass
class DynamicContact:
    """The eigen-decomposition of ``(K, M)`` seen from the contact DOFs (paper axes, order
    ``T_0, N_0, T_1, ...``), shared by every classification of one system."""

    omega2: np.ndarray            # eigenvalues of K Phi = M Phi Omega
    BP: np.ndarray                # contact rows of Phi, paper-axis signs
    Kcc: np.ndarray               # K and M on the contact DOFs, paper axes
    Mcc: np.ndarray
    seconds: float
    _cache: dict = field(default_factory=dict, repr=False)

    @classmethod
    def from_dense(cls, K: np.ndarray, M: np.ndarray, dofs: np.ndarray, signs: np.ndarray) -> "DynamicContact":
        """The decomposition from dense ``K`` and ``M`` (``scipy.linalg.eigh``: ``K`` symmetric, ``M`` SPD):
        ``dofs`` the contact DOFs in the order ``T_0, N_0, T_1, ...`` and ``signs`` their paper-axis
        signs; the time it took is kept in ``seconds``."""
        t0 = time.perf_counter()
        w, Phi = scipy.linalg.eigh(K, M)
        BP = signs[:, None] * Phi[dofs, :]
        sK = signs[:, None] * K[np.ix_(dofs, dofs)] * signs[None, :]
        sM = signs[:, None] * M[np.ix_(dofs, dofs)] * signs[None, :]
        return cls(w, BP, sK, sM, time.perf_counter() - t0)

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``Z(t)`` (dynamic contact Schur complement of ``K + t M``) and ``H_cc(t)``."""
        hit = self._cache.get(t)
        if hit is None:
            W = (self.BP / (self.omega2 + t)) @ self.BP.T
            Z = np.linalg.inv(0.5 * (W + W.T))
            hit = (0.5 * (Z + Z.T), self.Kcc + t * self.Mcc)
            if len(self._cache) > 4096:
                self._cache.clear()
            self._cache[t] = hit
        return hit


_SYSTEMS: dict[int, tuple[weakref.ref, DynamicContact | None]] = {}


def dynamic_contact(system, max_dofs: int) -> DynamicContact | None:
    """The system's :class:`DynamicContact`, built on first use (MPI collective: dense copies of
    K and M on every rank); None above ``max_dofs`` or when ``(K, M)`` is not SPD."""
    return per_system(_SYSTEMS, system, lambda: _build(system, max_dofs))


def _build(system, max_dofs: int) -> DynamicContact | None:
    if system.n_dofs > max_dofs:
        return None
    K, M = dense(system.K), dense(system.mass())                  # MPI collective
    dofs = np.array([[nd.dof_T, nd.dof_N] for nd in system.nodes]).ravel()
    signs = np.array([[nd.sign_T, nd.sign_N] for nd in system.nodes], dtype=float).ravel()
    try:
        return DynamicContact.from_dense(K, M, dofs, signs)
    except (np.linalg.LinAlgError, ValueError):
        return None


class _Reduction:
    """``sym S(t)`` and ``Sh(t)`` of one classification at mu (cached per t)."""

    def __init__(self, dc: DynamicContact, cls: Classification, mu: float):
        self.dc, self.mu = dc, mu
        slip, free = cls.slip, cls.indices(FREE)
        s = len(slip)
        nC = dc.Kcc.shape[0]
        F = np.sort(np.concatenate([2 * free, 2 * free + 1])).astype(int)
        self.nF = nF = len(F)
        # kept contact unknowns (F..., Ts...): columns Q (x = Q u), rows R (y = R w), paper axes
        Q = np.zeros((nC, nF + s))
        R = np.zeros((nF + s, nC))
        Q[F, np.arange(nF)] = 1.0
        R[np.arange(nF), F] = 1.0
        S = cls.slip_signs
        Q[2 * slip, nF + np.arange(s)] = S
        R[nF + np.arange(s), 2 * slip] = S
        R[nF + np.arange(s), 2 * slip + 1] = mu
        self.Q, self.R, self.D = Q, R, Q - R.T
        self._cache: dict[float, tuple[np.ndarray, np.ndarray]] = {}

    def _schur(self, X: np.ndarray) -> np.ndarray:
        n = self.nF
        if n == 0:
            return X
        return X[n:, n:] - X[n:, :n] @ np.linalg.solve(X[:n, :n], X[:n, n:])

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``(Sh(t), Q(t))`` with ``sym S(t) = Sh(t) + Q(t)``."""
        hit = self._cache.get(t)
        if hit is None:
            Z, H = self.dc.at(t)
            A = self.R @ Z @ self.Q
            G = 0.5 * (A + A.T) - 0.25 * self.D.T @ (H - Z) @ self.D
            Sx, Sh = self._schur(A), self._schur(G)
            Sh = 0.5 * (Sh + Sh.T)
            hit = (Sh, 0.5 * (Sx + Sx.T) - Sh)
            self._cache[t] = hit
        return hit


def _pd(X: np.ndarray) -> bool:
    d = np.sqrt(np.maximum(np.abs(np.diag(X)), 1e-300))
    try:
        np.linalg.cholesky(X / d[:, None] / d[None, :] - MARGIN * np.eye(len(X)))
        return True
    except np.linalg.LinAlgError:
        return False


def prove_no_solution(dc: DynamicContact, cls: Classification, mu: float, t_start: float,
                      intervals: int = 8, depth: int = 10) -> tuple[bool, float, dict]:
    """Try to prove that (12)-(14) has no solution with ``lambda^2 >= 0`` (caller: ``sym M*(mu)``
    PSD, ``t_start`` a bound with ``sym K* + t_start sym M*`` PD, e.g. the Rayleigh quotient bound).

    Returns ``(proven, T, detail)``: ``T`` the smallest of a bisection where ``Sh(T)`` is PD (no
    solution above it), and whether ``[0, T]`` was covered by certified intervals."""
    t0 = time.perf_counter()
    red = _Reduction(dc, cls, mu)
    # tail: smallest T (bisection, 8 steps) with Sh(T) PD
    lo, hi = 0.0, float(t_start)
    if not np.isfinite(hi) or not _pd(red.at(hi)[0]):
        return False, float(t_start), {"reason": "Sh(T) not PD at the start bound", "seconds": time.perf_counter() - t0}
    for _ in range(8):
        mid = 0.5 * (lo + hi)
        if _pd(red.at(mid)[0]):
            hi = mid
        else:
            lo = mid
    T = hi
    grid = np.linspace(0.0, T, intervals + 1)
    todo = [(float(grid[i]), float(grid[i + 1]), 0) for i in range(intervals)]
    proven_count = 0
    while todo:
        a, b, level = todo.pop()
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
        elif level < depth:
            m = 0.5 * (a + b)
            todo += [(a, m, level + 1), (m, b, level + 1)]
        else:
            return False, T, {"reason": f"sym S(t) not certified copositive on [{a:.6g}, {b:.6g}]",
                              "evaluations": len(red._cache), "seconds": time.perf_counter() - t0}
    return True, T, {"intervals": proven_count, "evaluations": len(red._cache),
                     "seconds": time.perf_counter() - t0}
