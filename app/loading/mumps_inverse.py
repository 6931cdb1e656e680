"""Selected entries of K^-1 from MUMPS's factors (``MatMumpsGetInverse``, MUMPS ICNTL(30)).

MUMPS computes requested entries of the inverse with both triangular solves pruned to the
parts of the elimination tree they need, which for the contact block of K^-1 (a few hundred
boundary DOFs of a mesh of 10^5-10^6) costs a small fraction of full solves with the same
right-hand sides. petsc4py 3.18 does not wrap ``MatMumpsGetInverse``; it is called here through
ctypes in the PETSc library petsc4py itself is linked to, on the factor's C handle. One rank
only (see :func:`inverse_block`); app/loading/flexibility.py falls back to block solves.
"""
from __future__ import annotations

import ctypes
import functools

import numpy as np
from petsc4py import PETSc

#: MUMPS controls the inverse computation changes (right-hand side and solution format, ICNTL(30))
KEPT_CONTROLS = (20, 21, 30)


@functools.lru_cache(maxsize=1)
def _get_inverse():
    """The C function ``PetscErrorCode MatMumpsGetInverse(Mat F, Mat spRHS)``, or None."""
    try:
        # dlsym on petsc4py's extension module also searches the libraries it was linked with
        fn = ctypes.CDLL(PETSc.__file__).MatMumpsGetInverse
    except (OSError, AttributeError):
        return None
    fn.argtypes = [ctypes.c_void_p, ctypes.c_void_p]
    fn.restype = ctypes.c_int
    return fn


def inverse_block(F: PETSc.Mat, rows: np.ndarray) -> np.ndarray | None:
    """``K^-1[rows][:, rows]`` from the MUMPS factor ``F`` of K on one rank, or None when the
    factor cannot give it (not MUMPS, the function not found, a MUMPS error, more than one rank:
    in parallel a solve with the factor after PETSc 3.18's ``MatMumpsGetInverse`` fails or hangs,
    even with the controls below restored).

    MUMPS reads the requested pattern as the transpose of an N x N sparse matrix: row j of it lists
    the wanted entries of column j of K^-1, and the values come back in place. ``rows`` must be
    distinct."""
    fn = _get_inverse()
    if F.getComm().getSize() > 1 or fn is None or F.getType() != "mumps":
        return None
    N = F.getSize()[0]
    m = len(rows)
    order = np.argsort(rows)
    wanted = np.asarray(rows)[order]
    counts = np.zeros(N, dtype=np.int64)
    counts[wanted] = m
    csr = (np.concatenate([[0], np.cumsum(counts)]).astype(PETSc.IntType),
           np.tile(wanted, m).astype(PETSc.IntType), np.zeros(m * m))
    pattern = PETSc.Mat().createAIJ((N, N), csr=csr, comm=PETSc.COMM_SELF)
    spRHS = PETSc.Mat().createTranspose(pattern)
    saved = {k: F.getMumpsIcntl(k) for k in KEPT_CONTROLS}
    try:
        err = fn(ctypes.c_void_p(F.handle), ctypes.c_void_p(spRHS.handle))
        if err != 0:
            return None
        values = pattern.getValuesCSR()[2].reshape(m, m)          # [j, i] = K^-1[wanted[i], wanted[j]]
        block = np.empty((m, m))
        block[np.ix_(order, order)] = values.T
        return block
    finally:
        for k, v in saved.items():        # the factor's later solves are ordinary solves again
            F.setMumpsIcntl(k, v)
        spRHS.destroy()
        pattern.destroy()
