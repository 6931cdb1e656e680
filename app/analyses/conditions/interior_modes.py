"""The smallest eigenvalues of a system's interior block ``X_ii`` (``X`` = ``K`` or ``M``, every DOF
but the contact DOFs), where the values of the necessary condition (19) on the contact DOFs have
their first pole (app/analyses/conditions/contact_spectrum.py). SLEPc on the sequential matrix."""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc
from slepc4py import SLEPc

from app.analyses.conditions import full_size
from app.linalg import configure_direct, eps_solve, flush_subnormals, owned, set_up, with_prefix
from app.scene.schema import EigSettings


def interior_modes(Xii: PETSc.Mat, gap: float, tol: float, B: PETSc.Mat | None = None,
                   bounded: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
    """The two smallest eigenvalues of the SPD ``X_ii`` and, where the first is separated from
    the second by ``gap`` (relative), their eigenvectors (columns; else None, and only the first
    eigenvalue is accurate), to the SLEPc tolerance ``tol``. ``B``: of the generalised
    ``X_ii x = k B x`` (:func:`smallest_pairs`), both pairs to ``tol``.

    First a rough pair (tolerance 1e-2: one Krylov-Schur restart). Separated (a stiffness matrix):
    both pairs to ``tol``, which the rough pairs' residuals often show already; else the same
    factorisation solves again from them. Clustered (the consistent mass matrix, whose smallest
    eigenvalues differ by 1e-4 at 100k DOFs and took 6-7 s to converge from 0): the smallest
    alone, by shift-and-invert about a shift just below the rough value that the factorisation's
    own inertia proves below the spectrum (:func:`app.analyses.conditions.full_size.smallest_above`), where
    it converges in a few iterations. Subnormals are flushed in the factorisations
    (:func:`app.linalg.flush_subnormals`: the mass matrix's factor underflows at 10^6 DOFs).

    ``bounded``: ``X_ii``'s condition number does not grow with the mesh (a consistent mass
    matrix: a few dozen at most on a graded mesh of P1 or P2 elements), and it is taken as
    clustered: only its smallest eigenvalue is computed, and no pole is removed (which is always
    valid: the interpolation of (19) then has its first pole at ``k_1``). Its rough value comes
    from Krylov-Schur on ``X_ii`` itself, products with it only, no factorisation (at 10^6 DOFs
    2 s where the shift-and-invert rough solve took 14 s); where that does not converge within
    :data:`UNSHIFTED_RESTARTS` restarts, from the shift-and-invert one as without ``bounded``."""
    if B is not None:    # the pressure eliminated (generalised, B = diag(1, 0)): both pairs to tol
        with flush_subnormals():
            k, vecs = smallest_pairs(Xii, 2, tol, B)
        return k, (vecs if len(k) > 1 and (k[1] - k[0]) / k[1] >= gap else None)
    with flush_subnormals():
        return _interior_modes(Xii, gap, tol, bounded)


#: Krylov-Schur without a spectral transformation for the rough smallest eigenvalues of a
#: ``bounded`` interior block: its subspace, restarts and tolerance. The rough value need only lie
#: within the first shift's step (1e-4, relative) of the smallest eigenvalue: at 10^6 DOFs the
#: mass matrix's came to 2.4e-5 of it in 14 restarts
UNSHIFTED_NCV = 16
UNSHIFTED_RESTARTS = 60
UNSHIFTED_TOL = 1e-3


def _interior_modes(Xii: PETSc.Mat, gap: float, tol: float, bounded: bool = False
                    ) -> tuple[np.ndarray, np.ndarray | None]:
    rough = _unshifted(Xii) if bounded else None
    if rough is not None:                  # taken as clustered: the smallest alone, from below
        return _smallest_above_rough(Xii, np.array([rough]), tol)
    with owned(_eps(Xii, 2, None)) as eps:
        k, vecs, errors = _solve(eps, Xii, 1e-2)
        if len(k) > 1 and (k[1] - k[0]) / k[1] >= gap:
            # one restart builds 32 Krylov vectors, so the rough solve's pairs often hold to tol
            # already, or to the rounding of their residuals, below which no solve can show them:
            # their true residuals decide; else the same factorisation solves again
            if np.any(errors[:2] > np.maximum(tol, residual_floor(Xii, k[:2]))):
                k, vecs, _ = _solve(eps, Xii, tol, start=vecs)
            return k, vecs
    return _smallest_above_rough(Xii, k, tol)


def residual_floor(Xii: PETSc.Mat, k: np.ndarray) -> np.ndarray:
    """The rounding of the relative residuals ``||X x - k x|| / k`` of unit vectors ``x``:
    ``sqrt(m) u ||X||_1 / k`` with at most ``m`` entries per row of ``X`` (the probabilistic bound
    of Higham and Mary, ``sqrt(m) u`` for the ``m u`` of the worst case, on each entry of the
    product). A solve cannot show a pair's residual below it. At 10^6 DOFs the stiffness
    matrix's two smallest pairs came to 9e-11 and 4e-11 from every solve of one process (in the
    two-rank runs one of them above 1e-10, which solved again), against floors of 4e-10 and
    2e-10: a second solve to ``tol = 1e-10`` only drew again, for 11 s."""
    rows, _ = Xii.getRowIJ()
    m = int(np.diff(rows).max(initial=1))
    return np.sqrt(m) * np.finfo(float).eps / 2 * Xii.norm(PETSc.NormType.NORM_1) / np.asarray(k)


def _unshifted(Xii: PETSc.Mat) -> float | None:
    """The smallest eigenvalue of ``X_ii`` roughly (a Ritz value: from above), from Krylov-Schur
    without a spectral transformation (:data:`UNSHIFTED_NCV`, ...); None where it did not
    converge."""
    eps = with_prefix(SLEPc.EPS().create(PETSc.COMM_SELF), "cd_necessary_")
    with owned(eps):
        eps.setOperators(Xii)
        eps.setProblemType(SLEPc.EPS.ProblemType.HEP)
        eps.setType(SLEPc.EPS.Type.KRYLOVSCHUR)
        eps.setDimensions(nev=1, ncv=min(Xii.getSize()[0], UNSHIFTED_NCV))
        eps.setWhichEigenpairs(SLEPc.EPS.Which.SMALLEST_REAL)
        eps.setTolerances(tol=UNSHIFTED_TOL, max_it=UNSHIFTED_RESTARTS)
        eps_solve(eps)
        if eps.getConverged() < 1:
            return None
        k = float(min(eps.getEigenvalue(i).real for i in range(eps.getConverged())))
    return k if k > 0 else None


def _smallest_above_rough(Xii: PETSc.Mat, k: np.ndarray, tol: float) -> tuple[np.ndarray, None]:
    """The smallest eigenvalue of ``X_ii`` to ``tol`` (and ``k[1:]`` unchanged) from the rough
    ``k`` (at least its first entry): shift-and-invert about shifts below ``k[0]``, each proven
    below the spectrum by its factorisation's inertia
    (:func:`app.analyses.conditions.full_size.smallest_above`)."""
    step = 1e-4 * k[0]
    for _ in range(12):
        lam = full_size.smallest_above(Xii, float(k[0] - step), EigSettings(tol=tol))
        if lam is not None:
            return np.array([lam, *k[1:]]), None
        step *= 4.0
    k, _ = smallest_pairs(Xii, 2, tol)
    return k, None


def _solve(eps, Xii: PETSc.Mat, tol: float, start: np.ndarray | None = None
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``eps`` (:func:`_eps`) solved to ``tol`` from the columns of ``start`` (the factorisation
    made once, at the first solve): eigenvalues ascending, orthonormal eigenvectors (columns) and
    each pair's relative residual ``||X x - k x|| / k``, which bounds its relative error (``X``
    symmetric, ``x`` a unit vector)."""
    eps.setTolerances(tol=tol, max_it=1000)
    if start is not None:
        space = [Xii.createVecRight() for _ in range(start.shape[1])]
        for v, x in zip(space, start.T):
            v.setArray(x)
        eps.setInitialSpace(space)
        for v in space:
            v.destroy()
    set_up(eps)                   # the factorisation, with the interpreter released
    eps_solve(eps)
    return _pairs(eps, Xii, eps.getDimensions()[0])


def _eps(Xii: PETSc.Mat, nev: int, B: PETSc.Mat | None):
    """Shift-and-invert Krylov-Schur about 0 for the ``nev`` smallest eigenpairs of ``X_ii``
    (``B``: of ``X_ii x = k B x``), prefix ``cd_necessary_``."""
    n = Xii.getSize()[0]
    eps = with_prefix(SLEPc.EPS().create(PETSc.COMM_SELF), "cd_necessary_")
    eps.setOperators(Xii, B)
    eps.setProblemType(SLEPc.EPS.ProblemType.HEP if B is None else SLEPc.EPS.ProblemType.GHEP)
    eps.setType(SLEPc.EPS.Type.KRYLOVSCHUR)
    eps.setDimensions(nev=nev, ncv=min(n, 32))
    st = eps.getST()
    st.setType(SLEPc.ST.Type.SINVERT)
    eps.setTarget(0.0)
    eps.setWhichEigenpairs(SLEPc.EPS.Which.TARGET_MAGNITUDE)
    configure_direct(st.getKSP(), factor="cholesky", mumps=True)
    return eps


def _pairs(eps, Xii: PETSc.Mat, nev: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    got = eps.getConverged()
    if got < 1:
        raise RuntimeError("SLEPc found no eigenvalue of the interior block")
    vals, vecs, errors = [], [], []
    v = Xii.createVecRight()
    for i in range(min(got, nev)):
        vals.append(eps.getEigenpair(i, v).real)
        vecs.append(v.getArray().copy())
        errors.append(eps.computeError(i, SLEPc.EPS.ErrorType.RELATIVE))
    v.destroy()
    order = np.argsort(vals)
    return np.asarray(vals)[order], np.array(vecs).T[:, order], np.asarray(errors)[order]


def smallest_pairs(Xii: PETSc.Mat, nev: int, tol: float, B: PETSc.Mat | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The ``nev`` smallest eigenpairs of the SPD ``X_ii`` to ``tol`` (shift-and-invert
    Krylov-Schur at 0, MUMPS Cholesky), eigenvalues ascending, orthonormal eigenvectors as columns.
    ``B``: the generalised ``X_ii x = k B x`` with ``B`` positive semidefinite (1 on the massive
    DOFs, 0 on the mixed element's pressure: the eigenvalues of the interior with the pressure
    eliminated, docs/method.md section 10), ``B``-orthonormal eigenvectors; ``X_ii`` is then
    indefinite and factorised as such (MUMPS LDL^T with pivoting)."""
    with owned(_eps(Xii, min(nev, Xii.getSize()[0]), B)) as eps:
        vals, vecs, _ = _solve(eps, Xii, tol)
    return vals, vecs
