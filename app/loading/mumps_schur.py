"""Schur complements onto a few rows from MUMPS's partial factorisation (ICNTL(19)).

``A = [[A_ii, A_ic], [A_ci, A_cc]]`` with ``c`` a few hundred contact DOFs of a mesh of
10^5-10^6: MUMPS eliminates the interior ``i`` (ordered first) and returns the dense
``S = A_cc - A_ci A_ii^-1 A_ic`` without factorising it, so ``S`` needs only the interior block to
be nonsingular, costs about one factorisation (no solves, where the contact block of ``A^-1``
costs MUMPS's selected inverse on top, and ``S`` then one dense inversion), and is as accurate as
the elimination. petsc4py 3.18 does not wrap ``MatFactorSetSchurIS`` and
``MatFactorCreateSchurComplement``: they are called through ctypes in the PETSc library
petsc4py itself is linked to, as in :mod:`app.loading.mumps_inverse`. Sequential matrices only.
"""
from __future__ import annotations

import ctypes
import functools

import numpy as np
from petsc4py import PETSc

from app.linalg import flush_subnormals, from_options, set_up, with_prefix


@functools.lru_cache(maxsize=1)
def _api():
    """The C functions used here, or None when petsc4py's library lacks them."""
    try:
        lib = ctypes.CDLL(PETSc.__file__)
        fns = (lib.MatFactorSetSchurIS, lib.MatFactorCreateSchurComplement, lib.MatDenseGetArrayRead,
               lib.MatDenseRestoreArrayRead, lib.MatDestroy)
    except (OSError, AttributeError):
        return None
    vp, dp = ctypes.c_void_p, ctypes.POINTER(ctypes.POINTER(ctypes.c_double))
    for fn, args in zip(fns, ([vp, vp], [vp, ctypes.POINTER(vp), vp], [vp, dp], [vp, dp], [ctypes.POINTER(vp)])):
        fn.argtypes = args
        fn.restype = ctypes.c_int
    return fns


class SchurComplements:
    """Schur complements onto ``rows`` of sequential symmetric matrices that share one nonzero
    pattern (``A`` itself, whose values the caller changes between calls) and whose interior
    block (the other rows) is positive definite (``spd=False``: nonsingular): one MUMPS partial
    Cholesky (LDL^T) factorisation each, the ordering and symbolic analysis done once. Options prefix ``prefix``. :meth:`destroy` (or
    ``with``) frees the factorisation."""

    def __init__(self, A: PETSc.Mat, rows: np.ndarray, prefix: str, spd: bool = True):
        self.A = A
        # only the interior (every row but ``rows``) is factorised, and the callers keep it SPD
        # (a shift below its smallest eigenvalue, K + t M with t >= 0): flagged so, MUMPS factorises
        # it without pivoting (SYM = 1), 13 % faster at 100k DOFs, the same Schur complement to 1e-15.
        # ``spd=False``: an interior with a saddle-point block (the mixed element's pressure), which
        # MUMPS factorises as a symmetric indefinite matrix with pivoting (SYM = 2)
        A.setOption(PETSc.Mat.Option.SPD, spd)
        self.order = np.argsort(rows)                     # MUMPS returns S in ascending row order
        self.m = len(rows)
        self.ksp = with_prefix(PETSc.KSP().create(A.getComm()), prefix)
        self.rows = PETSc.IS().createGeneral(np.asarray(rows)[self.order].astype(PETSc.IntType),
                                             comm=PETSc.COMM_SELF)
        self._set = False

    def __call__(self) -> np.ndarray | None:
        """The Schur complement of the current values of ``A`` onto ``rows`` (in their order), or
        None when MUMPS cannot give it."""
        if self.m == self.A.getSize()[0]:        # nothing to eliminate (MUMPS needs an interior)
            rows = self.rows.getIndices()
            out = np.empty((self.m, self.m))
            out[np.ix_(self.order, self.order)] = self.A.getValues(rows, rows)
            return 0.5 * (out + out.T)
        api = _api()
        if api is None:
            return None
        set_is, create, get, restore, destroy = api
        ksp = self.ksp
        try:
            ksp.setOperators(self.A)
            if not self._set:
                ksp.setType("preonly")
                pc = ksp.getPC()
                pc.setType("cholesky")
                pc.setFactorSolverType("mumps")
                from_options(ksp)
                pc.setFactorSetUpSolverType()
                F = pc.getFactorMatrix()
                if F.getType() != "mumps" or set_is(F.handle, self.rows.handle) != 0:
                    return None
                self._set = True
            with flush_subnormals():             # a mass-like A's far fill underflows (see there)
                set_up(ksp)              # the interpreter released: progress and signals go on
            F = ksp.getPC().getFactorMatrix()
        except PETSc.Error:
            return None
        S = ctypes.c_void_p()
        if create(F.handle, ctypes.byref(S), None) != 0:
            return None
        ptr = ctypes.POINTER(ctypes.c_double)()
        try:
            if get(S, ctypes.byref(ptr)) != 0:
                return None
            dense = np.ctypeslib.as_array(ptr, shape=(self.m, self.m)).T.copy()     # column-major
            restore(S, ctypes.byref(ptr))
        finally:
            destroy(ctypes.byref(S))
        out = np.empty_like(dense)
        out[np.ix_(self.order, self.order)] = dense
        return 0.5 * (out + out.T)

    def destroy(self) -> None:
        """Free the factorisation and the index set (not ``A``)."""
        self.ksp.destroy()
        self.rows.destroy()

    def __enter__(self) -> "SchurComplements":
        return self

    def __exit__(self, *exc) -> None:
        self.destroy()


def static_schur(X: PETSc.Mat, dofs: np.ndarray, static: np.ndarray) -> np.ndarray:
    """``X_cc - X_cs X_ss^-1 X_sc`` (contact DOFs ``dofs`` in their order): the contact block with
    the static DOFs eliminated, from the submatrix of those rows (one MUMPS LDL^T)."""
    both = np.concatenate([np.asarray(dofs), np.asarray(static)]).astype(PETSc.IntType)
    rows = PETSc.IS().createGeneral(both, comm=PETSc.COMM_SELF)
    try:
        (sub,) = X.createSubMatrices(rows, rows)
    finally:
        rows.destroy()
    try:
        with SchurComplements(sub, np.arange(len(dofs)), "cd_static_", spd=False) as schur:
            S = schur()
    finally:
        sub.destroy()
    if S is None:
        raise RuntimeError("MUMPS gave no Schur complement of the static DOFs (is their block singular, nu = 1/2?)")
    return S


def without_static(M: PETSc.Mat, static: np.ndarray, dofs: np.ndarray) -> tuple[PETSc.Mat, np.ndarray]:
    """``(M_kk, dofs_k)``: the sequential ``M`` without the rows and columns ``static`` (a mass
    matrix, which holds nothing on the mixed element's pressure; the caller owns the submatrix) and
    the DOFs ``dofs`` renumbered in it."""
    keep = np.setdiff1d(np.arange(M.getSize()[0]), static).astype(PETSc.IntType)
    rows = PETSc.IS().createGeneral(keep, comm=PETSc.COMM_SELF)
    try:
        (Mk,) = M.createSubMatrices(rows, rows)
    finally:
        rows.destroy()
    return Mk, np.searchsorted(keep, dofs)
