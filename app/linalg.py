"""Direct solvers: the one place where LU/Cholesky and MUMPS options are set.

Every factorisation in the app (the stiffness K of the loading path, the bordered MCP Jacobians,
the shift-and-invert spectral transformations, the inertia counts) is configured here, so the
choice of factor package and its MUMPS controls exist once.

- :func:`configure_direct` turns an existing KSP (e.g. ``snes.getKSP()`` or
  ``eps.getST().getKSP()``) into a direct solve.
- :func:`lu_solver` creates, configures and sets up a KSP for a matrix; the caller owns it and
  calls ``destroy()`` (or uses :func:`lu` as a context manager, which does).

Also here: :func:`set_linesearch` (a SNES line search through a private options prefix, removed
at once) and :func:`one_blas_thread` (one BLAS thread around dense numpy/LAPACK work).

No option is left in PETSc's global options database.
"""
from __future__ import annotations

import contextlib
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Literal, Optional

from petsc4py import PETSc

Factor = Literal["lu", "cholesky"]


def configure_direct(ksp: PETSc.KSP, *, factor: Factor = "lu", mumps: Optional[bool] = None,
                     inertia: bool = False, shift: Optional[float] = None,
                     ordering: Optional[str] = None) -> PETSc.KSP:
    """Make ``ksp`` a direct solve (``preonly`` + ``factor``); returns ``ksp``.

    ``mumps``: use MUMPS; ``None`` (default) means "MUMPS when the KSP's communicator has more
    than one rank" (PETSc's own serial factorisation is faster on the small serial problems).
    ``inertia``: MUMPS controls for reporting the inertia of an LDL^T factorisation (ICNTL(13) = 1,
    no ScaLAPACK root; ICNTL(24) = 1, null pivot detection); sets the factor up, so the
    operators must already be set. ``shift``/``ordering`` apply to PETSc's own factorisation only
    (a NONZERO pivot shift, e.g. 1e-14; an ordering such as ``"qmd"``).
    """
    ksp.setType("preonly")
    pc = ksp.getPC()
    pc.setType(factor)
    use_mumps = ksp.getComm().getSize() > 1 if mumps is None else mumps
    if use_mumps:
        pc.setFactorSolverType("mumps")
        if inertia:
            pc.setFactorSetUpSolverType()
            F = pc.getFactorMatrix()
            F.setMumpsIcntl(13, 1)
            F.setMumpsIcntl(24, 1)
    else:
        if shift is not None:
            pc.setFactorShift(PETSc.Mat.FactorShiftType.NONZERO, shift)
        if ordering is not None:
            pc.setFactorOrdering(ordering)
    return ksp


def set_linesearch(snes: PETSc.SNES, kind: str, prefix: str) -> None:
    """Give ``snes`` the line search ``kind`` (e.g. ``"basic"``: full Newton steps). petsc4py 3.18
    has no SNESLineSearch object, so this goes through the options database under the SNES's own
    private ``prefix``, and the option is removed at once (nothing is left in the database)."""
    snes.setOptionsPrefix(prefix)
    opts = PETSc.Options()
    opts.setValue(f"{prefix}snes_linesearch_type", kind)
    try:
        snes.setFromOptions()
    finally:
        opts.delValue(f"{prefix}snes_linesearch_type")


def lu_solver(A: PETSc.Mat, *, factor: Factor = "lu", mumps: Optional[bool] = True,
              inertia: bool = False, ordering: Optional[str] = None) -> PETSc.KSP:
    """A KSP on ``A``'s communicator that solves with the factors of ``A`` (MPI collective).

    Defaults to a MUMPS LU factorisation (``mumps=None``: MUMPS only in parallel, see
    :func:`configure_direct`; ``inertia``, ``ordering`` likewise) and factorises it here. The
    caller owns the KSP and must ``destroy()`` it; :func:`lu` is the context-manager form.
    """
    ksp = PETSc.KSP().create(A.getComm())
    try:
        ksp.setOperators(A)
        configure_direct(ksp, factor=factor, mumps=mumps, inertia=inertia, ordering=ordering)
        ksp.setUp()
    except BaseException:
        ksp.destroy()
        raise
    return ksp


_CONTROLLER: list = []


def one_blas_thread():
    """Context: one BLAS thread around small batched dense work (OpenBLAS threads make stacks
    of 20 x 20 solves 10-20x slower on this kind of machine, and the contact increments' dense
    2n x 2n LU factorisations 2-3x slower); all threads again afterwards. The BLAS libraries are
    inspected once per process (``threadpool_limits`` scans every loaded library on each call:
    2-4 ms, issue 14)."""
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:              # pragma: no cover - threadpoolctl is a dependency
        return contextlib.nullcontext()
    if not _CONTROLLER:
        _CONTROLLER.append(ThreadpoolController())
    return _CONTROLLER[0].limit(limits=1, user_api="blas")


@contextmanager
def lu(A: PETSc.Mat, **kwargs) -> Iterator[PETSc.KSP]:
    """``with lu(A) as ksp:`` -- :func:`lu_solver` whose KSP is destroyed on leaving the block."""
    ksp = lu_solver(A, **kwargs)
    try:
        yield ksp
    finally:
        ksp.destroy()
