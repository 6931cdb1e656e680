"""Is a symmetric matrix positive definite? At any size, for the matrices a scene gives.

A singular or indefinite stiffness, or a mass with a negative or zero eigenvalue, gives numbers
that mean nothing (a "proven" critical mu of a floating body). The test scales the matrix to a
unit diagonal, ``S = D^-1/2 A D^-1/2`` (after checking the diagonal is positive), and then

* up to :data:`DENSE_MAX` rows: dense Cholesky of S (numpy);
* above: the inertia of S from a sparse symmetric LDL^T factorisation (MUMPS through
  petsc4py, serial on this process: ``ICNTL(13) = 1`` keeps the root node off ScaLAPACK so
  that ``INFOG(12)``, the number of negative pivots, is the number of negative eigenvalues
  (Sylvester); ``ICNTL(24) = 1`` with ``CNTL(3)`` detects null pivots, ``INFOG(28)``).

The PETSc objects carry their own option prefix and never read options: nothing a user's file
or environment sets changes this test.
"""
from __future__ import annotations

import numpy as np

DENSE_MAX = 2000
NULL_PIVOT = 1e-12          # a pivot below this (of the unit-diagonal S) counts as zero


def _scaled(A):
    """The unit-diagonal scaling of A (CSR), or a reason why A cannot be SPD."""
    import scipy.sparse as sp
    d = A.diagonal()
    if np.any(d <= 0):
        i = int(np.argmin(d))
        return None, f"diagonal entry [{i}, {i}] = {d[i]:.6g} <= 0"
    s = sp.diags(1.0 / np.sqrt(d))
    return sp.csr_matrix(s @ A @ s), None


def _inertia_mumps(S) -> tuple[int, int]:
    """(negative pivots, null pivots) of the sparse symmetric S by MUMPS (serial)."""
    from petsc4py import PETSc

    from app.linalg import from_options, set_up, with_prefix
    n = S.shape[0]
    mat = PETSc.Mat().createAIJ((n, n), csr=(S.indptr.astype(PETSc.IntType), S.indices.astype(PETSc.IntType),
                                             S.data), comm=PETSc.COMM_SELF)
    ksp = with_prefix(PETSc.KSP().create(comm=PETSc.COMM_SELF), "cd_spd_check_")
    try:
        ksp.setOperators(mat)
        ksp.setType("preonly")
        pc = ksp.getPC()
        pc.setType("cholesky")
        pc.setFactorSolverType("mumps")
        pc.setFactorSetUpSolverType()
        F = pc.getFactorMatrix()
        F.setMumpsIcntl(13, 1)          # no ScaLAPACK on the root node: exact inertia
        F.setMumpsIcntl(24, 1)          # null pivot detection
        F.setMumpsCntl(3, NULL_PIVOT)   # relative to max |S| (1: S has a unit diagonal)
        F.setMumpsIcntl(4, 0)           # quiet
        from_options(ksp)
        try:
            set_up(ksp)
        except PETSc.Error:
            return 0, 1                 # the factorisation broke down: a zero pivot
        return int(F.getMumpsInfog(12)), int(F.getMumpsInfog(28))
    finally:
        ksp.destroy()
        mat.destroy()


def not_spd(A) -> str | None:
    """None if the symmetric CSR matrix A is positive definite, else the reason (one phrase)."""
    S, why = _scaled(A)
    if why:
        return why
    n = S.shape[0]
    if n <= DENSE_MAX:
        try:
            np.linalg.cholesky(S.toarray())
        except np.linalg.LinAlgError:
            w = np.linalg.eigvalsh(S.toarray())
            neg, null = int(np.sum(w < -NULL_PIVOT)), int(np.sum(np.abs(w) <= NULL_PIVOT))
            return _describe(neg, max(null, 1 if neg == 0 else 0), "dense Cholesky fails")
        return None
    neg, null = _inertia_mumps(S)
    return _describe(neg, null, "inertia of a sparse LDL^T factorisation (MUMPS)") if neg or null else None


def _describe(neg: int, null: int, how: str) -> str:
    parts = ([f"{neg} negative eigenvalue(s)"] if neg else []) + ([f"{null} zero eigenvalue(s) (singular)"] if null else [])
    return f"{' and '.join(parts)} ({how})"
