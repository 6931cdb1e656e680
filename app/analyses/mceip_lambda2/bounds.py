"""What can be proven cheaply about MCEIP-lambda^2 (12)-(14) on the full-size pencil (its
``certificate`` block is built by :func:`app.analyses.mceip_mu.state.certificate`, as MCEIP-mu's).

Sign argument (the paper's (19), generalised): at a solution ``x^T y = x_Ts^T y_Ts = 0``, so
``x^T (K* + t M*) x = 0`` with ``t = lambda^2``. Hence no solution has a ``t`` at which the
symmetric part ``sym K* + t sym M*`` is positive definite:

- ``t = 0`` (PD ``sym K*``) with ``sym M*`` PSD: no solution at all, the necessary condition (19);
- when ``sym M*`` is PD, ``sym K* + T sym M*`` PD at one ``T`` makes it PD for every ``t >= T``
  (adding ``(t - T) sym M*``), so every solution has ``t < T``. ``T`` is proven by an LDL^T
  inertia count (no negative and no zero pivot, with a relative safety shift) and tightened by
  bisection from the Rayleigh-quotient bound ``-min eig sym K* / min eig sym M*``.

Nothing here proves the absence of solutions inside ``[0, T]`` (``sym K*(mu) + t sym M*`` is
indefinite there and its Schur complement onto the slip nodes is not copositive on the paper's
states): that interval is searched by SNES VI and reported "not proven".

Values above the free-block spectrum (the largest ``omega^2`` of ``K_ff x = omega^2 M_ff x``)
have free-DOF modes ``x_f = -(K_ff + t M_ff)^-1 A_fc x_c`` that are mass-dominated and decay
node to node by orders of magnitude: double precision cannot resolve their patterns, and such
solutions are labelled ill-conditioned instead of clean patterns.
"""
from __future__ import annotations

import time
from contextlib import ExitStack

import numpy as np
import scipy.linalg
from petsc4py import PETSc
from slepc4py import SLEPc

from app.analyses.pencils.reduced import (
    REPLICATE_MAX,
    axpy_structure,
    dense,
    diag_scale,
    eliminate_static,
    serial_copy,
    sym_part,
)
from app.linalg import eps_solve, from_options, lu, owned, with_prefix

PROVEN = "proven"


def _verified_pd_pencil(a0: np.ndarray, a1: np.ndarray, mu: float) -> bool:
    """``sym(a0 + mu a1)`` proven positive definite (the dense verified Cholesky of
    :func:`app.analyses.mceip_mu.kernel.rounding.verified_pd`, after an exact power-of-two diagonal
    scaling ``S``; the rounding of ``a0 + mu a1`` and of the symmetric part is in the radius).

    The rounding of ``H = sym fl(a0 + mu a1)`` is at most ``gamma_4 sym(|a0| + |mu| |a1|) +
    gamma_1 |H|`` entrywise; its 2-norm after the scaling is bounded by the Frobenius norms
    ``gamma_4 (||S a0 S||_F + |mu| ||S a1 S||_F) + gamma_1 ||S H S||_F`` (the absolute value and
    the symmetric part do not increase a Frobenius norm), each ``sqrt(s2^T (X o X) s2)`` with
    ``s2`` the squared scaling, rounded up."""
    from app.analyses.mceip_mu.kernel.rounding import gamma, rounded_up, verified_pd
    n = a0.shape[0]
    H = a0 + mu * a1
    H += H.T.copy()
    H *= 0.5
    d = np.diag(H)
    if not np.all(np.isfinite(H)) or np.any(d <= 0):
        return False
    scale = np.ldexp(1.0, -np.frexp(np.sqrt(d))[1])          # exact powers of two
    Hs = H * scale[:, None]
    Hs *= scale[None, :]
    s2 = scale * scale

    def frobenius(X: np.ndarray) -> float:
        return float(np.sqrt((X * X) @ s2 @ s2))

    radius = gamma(4) * (frobenius(a0) + abs(mu) * frobenius(a1)) + gamma(1) * float(np.sqrt(np.sum(Hs * Hs)))
    return verified_pd(Hs, float(rounded_up(radius, 3 * n)))


def verified_sign_argument(K0: PETSc.Mat, K1: PETSc.Mat, M0: PETSc.Mat, M1: PETSc.Mat, mu: float,
                           max_dofs: int) -> bool:
    """The necessary condition's "no solution" (19) with rigorous bounds: ``sym K*(mu)`` and
    ``sym M*(mu)`` proven positive definite by dense verified Cholesky factorisations, for
    pencils of at most ``max_dofs`` rows (``False`` above: not attempted). MPI collective (the
    dense copies); rank 0 decides."""
    from app.analyses.pencils.reduced import dense
    if K0.getSize()[0] > max_dofs:
        return False
    k0, k1, m0, m1 = (dense(X) for X in (K0, K1, M0, M1))          # MPI collective
    comm = K0.getComm().tompi4py()
    ok = _verified_pd_pencil(k0, k1, mu) and _verified_pd_pencil(m0, m1, mu) if comm.rank == 0 else None
    return bool(comm.bcast(ok, root=0))                              # MPI collective


#: from this many rows on, serial LDL^T factorisations use MUMPS (with pivoting, its inertia is the
#: true one): 3x faster than PETSc's own Cholesky at 25k DOFs and 8x at 100k; below, PETSc's own
#: (faster on small matrices)
MUMPS_LDLT_MIN = 5000


def ldlt_mumps(C: PETSc.Mat) -> bool | None:
    """The ``mumps`` argument of :func:`app.linalg.configure_direct` for an LDL^T of ``C``: True
    from :data:`MUMPS_LDLT_MIN` rows on, else None (MUMPS only in parallel)."""
    return True if C.getSize()[0] >= MUMPS_LDLT_MIN else None


def inertia_negative_or_zero(C: PETSc.Mat, ordering: str | None = None) -> int:
    """Number of negative plus zero pivots of an LDL^T factorisation of the symmetric ``C``; a
    failed factorisation counts as 1 (nothing proven). Only "0" is evidence (``C`` positive
    definite): for an indefinite ``C`` PETSc's own serial factorisation (Cholesky without pivoting,
    used below :data:`MUMPS_LDLT_MIN` rows) reports counts that depend on the ordering (not the
    true inertia). ``ordering``: for PETSc's own factorisation (e.g. ``"qmd"``), default its own."""
    try:
        # MUMPS (in parallel, and on large matrices) reports the inertia
        with lu(C, prefix="cd_inertia_", factor="cholesky", mumps=ldlt_mumps(C), inertia=True,
                ordering=ordering) as ksp:
            neg, zero, _ = ksp.getPC().getFactorMatrix().getInertia()
        return int(neg) + int(zero)
    except PETSc.Error:
        return 1


def proven_upper_bound(Ks: PETSc.Mat, Ms: PETSc.Mat, start: float, steps: int = 6,
                       guess: float | None = None) -> tuple[float, dict]:
    """Small ``T`` proven by an inertia count to make ``sym K* + T sym M*`` PD (caller: ``sym M*``
    PD, ``start`` a valid bound): bisection of ``steps`` steps on ``[0, start]``, or on
    ``[0, guess]`` when ``guess`` (e.g. 1.05 x the previous classification's bound) is proven
    first. Returns ``(T, detail)``; ``T = start`` when no smaller one is proven."""
    t0 = time.perf_counter()
    SK, SM = sym_part(Ks), sym_part(Ms)
    structure = axpy_structure(SK, SM)
    shift = 1e-10 * diag_scale(SK)      # relative safety margin for rounding in the factorisation
    counts = 0

    def pd(T: float) -> bool:
        nonlocal counts
        C = SK.copy()
        try:
            C.axpy(T, SM, structure=structure)
            C.shift(-shift)
            counts += 1
            return inertia_negative_or_zero(C) == 0
        finally:
            C.destroy()

    try:
        lo, hi = 0.0, float(start)
        if not np.isfinite(hi) or not pd(hi):
            return float(start), {"inertia_counts": counts, "seconds": time.perf_counter() - t0}
        if guess is not None and 0 < guess < hi and pd(guess):
            hi = guess
            steps = min(steps, 3)
        for _ in range(steps):
            mid = 0.5 * (lo + hi)
            if pd(mid):
                hi = mid
            else:
                lo = mid
        return hi, {"inertia_counts": counts, "bracket": [lo, hi], "seconds": time.perf_counter() - t0}
    finally:
        SK.destroy()
        SM.destroy()


def free_block_max_omega2(Ks: PETSc.Mat, Ms: PETSc.Mat, comp: np.ndarray, tol: float = 1e-8) -> float | None:
    """Largest ``omega^2`` of the free block ``K_ff x = omega^2 M_ff x`` (``K*`` and ``M*`` have
    the free rows of ``K`` and ``M``: their ``f`` rows do not depend on mu). None if SLEPc fails."""
    r0, r1 = Ks.getOwnershipRange()
    free = np.setdiff1d(np.arange(r0, r1), comp).astype(PETSc.IntType)
    with ExitStack() as owns:
        isf = owns.enter_context(owned(PETSc.IS().createGeneral(free, comm=Ks.getComm())))
        Kf = owns.enter_context(owned(Ks.createSubMatrix(isf, isf)))
        Mf = owns.enter_context(owned(Ms.createSubMatrix(isf, isf)))
        if Kf.getComm().getSize() > 1 and 0 < Kf.getSize()[0] <= REPLICATE_MAX:    # MPI collective
            Kf, Mf = (owns.enter_context(owned(serial_copy(A))) for A in (Kf, Mf))
        eps = owns.enter_context(owned(with_prefix(SLEPc.EPS().create(Kf.getComm()), "cd_lambda2_")))
        if Kf.getSize()[0] == 0:
            return None
        try:
            eps.setOperators(Kf, Mf)
            eps.setProblemType(SLEPc.EPS.ProblemType.GHEP)
            eps.setWhichEigenpairs(SLEPc.EPS.Which.LARGEST_MAGNITUDE)
            eps.setDimensions(nev=1)
            eps.setTolerances(tol=tol, max_it=2000)
            from_options(eps)
            eps_solve(eps)
            if eps.getConverged() < 1:
                return None
            return float(eps.getEigenvalue(0).real)
        except PETSc.Error:
            return None


#: largest reduced pencil whose free block :func:`free_block_max_omega2_eliminated` solves (dense)
ELIMINATED_MAX_DOFS = 4000


def free_block_max_omega2_eliminated(Ks: PETSc.Mat, Ms: PETSc.Mat, comp: np.ndarray,
                                     static: np.ndarray) -> float | None:
    """:func:`free_block_max_omega2` of a pencil with static DOFs ``static`` (kept numbering; the
    mixed element's pressure, no mass): their rows make the free block's pencil singular, so its
    largest finite ``omega^2`` is that of the free block with them eliminated, dense (LAPACK, the
    largest eigenvalue only) up to :data:`ELIMINATED_MAX_DOFS`, else None. MPI collective."""
    if Ks.getSize()[0] > ELIMINATED_MAX_DOFS:
        return None
    K, M = dense(Ks), dense(Ms)                                       # MPI collective
    free = np.setdiff1d(np.arange(K.shape[0]), comp)
    Ke, Me, _ = eliminate_static(K[np.ix_(free, free)], M[np.ix_(free, free)], np.searchsorted(free, static))
    Ke = 0.5 * (Ke + Ke.T)                       # the free rows are K's own: symmetric up to rounding
    m = Ke.shape[0]
    if m == 0:
        return None
    try:
        return float(scipy.linalg.eigh(Ke, Me, eigvals_only=True, subset_by_index=[m - 1, m - 1])[0])
    except (np.linalg.LinAlgError, ValueError):
        return None
