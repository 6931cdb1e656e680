"""A proof that MCEIP-lambda^2 (12)-(14) has no solution, on the exact slip-node reduction
(docs/method.md section 7).

With ``H(t) = K + t M`` (``t = lambda^2 >= 0``, SPD) every DOF except the slip nodes' ``x_Ts`` is
eliminated exactly. The interior goes through the dynamic contact flexibility
``W(t) = B (K + t M)^-1 B^T`` and its inverse, the dynamic contact Schur complement ``Z(t)``
(``Z(0)`` is the static one of the condensed MCEIP-mu), which do not depend on the
classification: :class:`DynamicContact` computes them once per ``t`` for the whole path, from the
dense eigen-decomposition ``K Phi = M Phi Omega`` on small systems
(``W(t) = B Phi (Omega + t)^-1 Phi^T B^T``) and from a sparse Cholesky factorisation of ``K + t M``
with MUMPS's selected entries of its inverse above ``McpSettings.lambda2_exact_max_dofs``. The
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

import functools
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.linalg
import scipy.sparse
from petsc4py import PETSc

from app.analyses.mceip_mu.state import in_pd_plus_nn
from app.analyses.pencils.kept_contact import KeptContact
from app.analyses.pencils.reduced import axpy_structure, dense, eliminate_static
from app.analyses.pencils.state import sequential_km, system_cache
from app.linalg import lu_solver
from app.loading.classify import Classification
from app.loading.mumps_schur import SchurComplements, static_schur, without_static

#: relative margin of the PD + NN tests (rounding of the eliminations, pencil scaled to unit diagonal)
MARGIN = 1e-8


#: bytes of the dynamic Schur complements ``Z(t)`` kept per system (least recently used dropped first),
#: and the fewest kept whatever their size: one proof uses some 25 values of ``t`` and the next
#: classification mostly the same ones, so a cache smaller than that recomputes them in turn (at
#: 10^6 DOFs, 1,418 contact DOFs, 16 MB each, 512 MB hold only 32)
CACHE_BYTES = 512 * 2**20
CACHE_ENTRIES = 48


@dataclass
class DynamicContact:
    """``(K, M)`` seen from the contact DOFs (paper axes, order ``T_0, N_0, T_1, ...``), shared by
    every classification of one system: ``flexibility(t)`` is the dynamic contact flexibility
    ``W(t) = B (K + t M)^-1 B^T``; :meth:`at` inverts it to the dynamic contact Schur complement
    ``Z(t)``, kept for the next classifications (the proofs evaluate ``t`` on one dyadic grid per
    system, so neighbouring classifications mostly reuse them)."""

    flexibility: Callable[[float], np.ndarray]
    mass_flexibility: Callable[[], np.ndarray]    # B M^-1 B^T
    Kcc: np.ndarray               # K and M on the contact DOFs, paper axes
    Mcc: np.ndarray
    seconds: float                # time of the set-up (eigen-decomposition or gathering)
    method: str
    evaluations: int = 0          # Z(t) computed (cache misses)
    schur: Callable[[float], np.ndarray | None] | None = None   # Z(t) directly, where available
    _cache: OrderedDict = field(default_factory=OrderedDict, repr=False)
    _mass_schur: np.ndarray | None = field(default=None, repr=False)

    @classmethod
    def from_dense(cls, K: np.ndarray, M: np.ndarray, dofs: np.ndarray, signs: np.ndarray) -> "DynamicContact":
        """From dense ``K`` and ``M`` through the eigen-decomposition ``K Phi = M Phi Omega``
        (``scipy.linalg.eigh``: ``K`` symmetric, ``M`` SPD): ``W(t) = B Phi (Omega + t)^-1 Phi^T B^T``.
        ``dofs`` the contact DOFs in the order ``T_0, N_0, T_1, ...`` and ``signs`` their paper-axis
        signs; the time it took is kept in ``seconds``."""
        t0 = time.perf_counter()
        w, Phi = scipy.linalg.eigh(K, M)
        BP = signs[:, None] * Phi[dofs, :]
        sK = signs[:, None] * K[np.ix_(dofs, dofs)] * signs[None, :]
        sM = signs[:, None] * M[np.ix_(dofs, dofs)] * signs[None, :]
        # Phi^T M Phi = I, so M^-1 = Phi Phi^T
        return cls(lambda t: (BP / (w + t)) @ BP.T, lambda: BP @ BP.T, sK, sM, time.perf_counter() - t0,
                   "dense (K, M) eigen-decomposition")

    @classmethod
    def from_sparse(cls, K: PETSc.Mat, M: PETSc.Mat, dofs: np.ndarray, signs: np.ndarray,
                    own: Callable[..., None] | None = None, static: np.ndarray | None = None) -> "DynamicContact":
        """From sequential sparse ``K`` and ``M`` (the caller keeps them alive while this is used):
        each ``Z(t)`` is MUMPS's Schur complement of ``K + t M`` onto the contact DOFs
        (:class:`app.loading.mumps_schur.SchurComplements`, one partial factorisation; its PETSc
        objects handed to ``own``); where MUMPS cannot give it, ``W(t)`` is the signed contact
        block of ``(K + t M)^-1`` from one sparse Cholesky factorisation and MUMPS's selected
        entries of the inverse (:func:`app.loading.flexibility.flexibility_inverse`; block solves
        with the contact columns when the factor cannot give them).

        ``static``: DOFs without mass (the mixed element's pressure, ``K`` a saddle-point matrix
        with an invertible pressure block) that the result eliminates (docs/method.md section 10):
        ``Z(t)`` is unchanged (the quotient property of Schur complements: the pressure is among
        the eliminated DOFs; the interior is factorised as symmetric indefinite), the contact block
        ``K_cc`` is that of ``K_e = K / K_pp`` and the mass's Schur complement is that of ``M``
        without the pressure rows."""
        from app.loading.flexibility import flexibility_inverse, flexibility_matsolve
        t0 = time.perf_counter()
        structure = axpy_structure(K, M)
        mixed = static is not None and len(static) > 0

        def contact_block_of_inverse(A: PETSc.Mat, at: np.ndarray = dofs) -> np.ndarray:
            ksp = lu_solver(A, prefix="cd_dynamic_", factor="cholesky", mumps=True)
            try:
                W = flexibility_inverse(ksp, at, signs)
                if W is None:
                    W = flexibility_matsolve(ksp, A, at, signs)
                if W is None:
                    raise RuntimeError("the factorisation of K + t M gave no contact flexibility")
                return W
            finally:
                ksp.destroy()

        def flexibility(t: float) -> np.ndarray:
            A = K.copy()
            try:
                A.axpy(t, M, structure=structure)
                return contact_block_of_inverse(A)
            finally:
                A.destroy()

        # Z(t) directly from MUMPS's partial factorisation of K + t M, on one matrix whose values
        # change with t (ordering and symbolic analysis once): 0.2 s per t at 100k DOFs where the
        # factorisation and the contact block of its inverse took 0.44 s
        held: dict = {}
        into = (structure if structure == PETSc.Mat.Structure.SAME_NONZERO_PATTERN
                else PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)

        def schur(t: float) -> np.ndarray | None:
            if "A" not in held:
                held["A"] = K.copy()
                held["A"].axpy(1.0, M, structure=structure)     # the union pattern (values reset below)
                held["schur"] = SchurComplements(held["A"], dofs, "cd_dynamic_", spd=not mixed)
                if own is not None:
                    own(held["schur"], held["A"])
            held["A"].zeroEntries()
            held["A"].axpy(1.0, K, structure=into)
            held["A"].axpy(t, M, structure=into)
            Z = held["schur"]()
            return None if Z is None else signs[:, None] * Z * signs[None, :]

        rows = PETSc.IS().createGeneral(dofs.astype(PETSc.IntType), comm=PETSc.COMM_SELF)
        try:
            Kcc, Mcc = (X.createSubMatrices(rows, rows)[0] for X in (K, M))
            sK, sM = (signs[:, None] * Y.getValues(range(len(dofs)), range(len(dofs))) * signs[None, :]
                      for Y in (Kcc, Mcc))
            Kcc.destroy()
            Mcc.destroy()
        finally:
            rows.destroy()
        mass_flexibility = functools.partial(contact_block_of_inverse, M)
        if mixed:
            sK = signs[:, None] * static_schur(K, dofs, static) * signs[None, :]
            mass_flexibility = functools.partial(_without, M, static, contact_block_of_inverse, dofs)
        return cls(flexibility, mass_flexibility, sK, sM, time.perf_counter() - t0,
                   "MUMPS's Schur complement of K + t M onto the contact DOFs per t"
                   + (" (the pressure eliminated with the interior)" if mixed else ""), schur=schur)

    def mass_schur(self) -> np.ndarray:
        """The Schur complement of ``M`` onto the contact DOFs (paper axes), computed once."""
        if self._mass_schur is None:
            W = self.mass_flexibility()
            Z = np.linalg.inv(0.5 * (W + W.T))
            self._mass_schur = 0.5 * (Z + Z.T)
        return self._mass_schur

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``Z(t)`` (dynamic contact Schur complement of ``K + t M``) and ``H_cc(t)``."""
        return self.schur_at(t), self.Kcc + t * self.Mcc

    def schur_at(self, t: float) -> np.ndarray:
        """``Z(t)``, the dynamic contact Schur complement of ``K + t M``."""
        Z = self._cache.get(t)
        if Z is None:
            Z = None if self.schur is None else self.schur(t)
            if Z is None:
                W = self.flexibility(t)
                Z = np.linalg.inv(0.5 * (W + W.T))
                Z = 0.5 * (Z + Z.T)
            self.evaluations += 1
            while self._cache and (len(self._cache) + 1) * Z.nbytes > max(CACHE_BYTES, CACHE_ENTRIES * Z.nbytes):
                self._cache.popitem(last=False)
            self._cache[t] = Z
        else:
            self._cache.move_to_end(t)
        return Z


def _without(M: PETSc.Mat, static: np.ndarray, block_of_inverse: Callable, dofs: np.ndarray) -> np.ndarray:
    """``block_of_inverse`` of ``M`` without the rows and columns ``static`` (which hold nothing),
    at the contact DOFs ``dofs`` renumbered accordingly."""
    Mu, at = without_static(M, static, dofs)
    try:
        return block_of_inverse(Mu, at)
    finally:
        Mu.destroy()


def dynamic_contact(system, max_dense_dofs: int) -> DynamicContact | None:
    """The system's :class:`DynamicContact` on rank 0 (None on the other ranks), built on first use:
    dense up to ``max_dense_dofs`` DOFs, sparse factorisations above (MPI collective: K and M
    gathered on rank 0 when distributed). None on rank 0 too when ``(K, M)`` is not SPD."""
    return system_cache(system).once("dynamic", lambda: _build(system, max_dense_dofs))


def _build(system, max_dense_dofs: int) -> DynamicContact | None:
    comm = system.comm
    dofs = np.array([[nd.dof_T, nd.dof_N] for nd in system.nodes]).ravel()
    signs = np.array([[nd.sign_T, nd.sign_N] for nd in system.nodes], dtype=float).ravel()
    static = system.static_dofs
    mixed = static is not None and len(static) > 0
    K, M = system.K, system.mass()
    if system.n_dofs <= max_dense_dofs:
        Kd, Md = dense(K), dense(M)                                  # MPI collective
        if comm.rank != 0:
            return None
        try:
            if mixed:         # the pressure eliminated first (its block is invertible: nu < 1/2)
                Kd, Md, keep = eliminate_static(Kd, Md, static)
                Kd = 0.5 * (Kd + Kd.T)
                dofs = np.searchsorted(keep, dofs)
            return DynamicContact.from_dense(Kd, Md, dofs, signs)
        except (np.linalg.LinAlgError, ValueError):
            return None
    pair = sequential_km(system)                                    # MPI collective (first call)
    if pair is None:
        return None
    K, M = pair
    return DynamicContact.from_sparse(K, M, dofs, signs, system.own, static if mixed else None)


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
