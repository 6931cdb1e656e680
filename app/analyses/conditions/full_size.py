"""Necessary condition (19) and sufficient condition (17)-(18) with SLEPc.

Small problems (``n <= dense_limit``) use SLEPc's LAPACK solver, which computes the whole
spectrum: the answer is then complete. Larger ones use Krylov-Schur with shift-and-invert about
0 and report how many eigenvalues nearest 0 were examined.
"""
from __future__ import annotations

from contextlib import ExitStack

import numpy as np
import scipy.linalg
from petsc4py import PETSc
from slepc4py import SLEPc

from app.analyses.mceip_lambda2.bounds import inertia_negative_or_zero
from app.analyses.outcomes import NecessaryOutcome, Solution, SufficientOutcome
from app.analyses.pencils.reduced import combine, dense, diag_scale, eliminate_static, gather_vec, serial_copy, sym_part
from app.linalg import configure_direct, eps_solve, from_options, mumps_null_pivots, owned, set_up, with_prefix
from app.scene.schema import EigSettings

#: from this size on, shift-and-invert factorises with MUMPS even on one rank: its factorisation is
#: 3-7x faster than PETSc's own at 25k-100k DOFs, its solves 2x slower (a Krylov-Schur solve does
#: tens of them), so below it PETSc's own is faster (app/analyses/mceip_lambda2/bounds.py uses
#: MUMPS from 5,000 rows for inertia counts, which factorise only)
MUMPS_MIN_DOFS = 20_000


def _shift_invert(eps: SLEPc.EPS, sigma: float) -> PETSc.KSP:
    """Shift-and-invert spectral transformation about ``sigma``, eigenvalues nearest it first;
    returns the ST's KSP (the caller makes it a direct solve)."""
    st = eps.getST()
    st.setType(SLEPc.ST.Type.SINVERT)
    eps.setTarget(sigma)
    eps.setWhichEigenpairs(SLEPc.EPS.Which.TARGET_MAGNITUDE)
    return st.getKSP()


def _eps(A: PETSc.Mat, B: PETSc.Mat | None, hermitian: bool, settings: EigSettings,
         prefix: str, pivoting: bool = False) -> tuple[SLEPc.EPS, str]:
    """A configured EPS for ``A x = theta B x`` (the caller owns it), options read under ``prefix``.

    A dense-size pencil (``n <= dense_limit``) distributed over several ranks is solved whole on
    every rank (:func:`serial_copy`): the dense solvers need the whole matrix anyway, and in
    parallel SLEPc builds the shift-and-invert operator column by column, one distributed
    solve each (210 DOFs on 2 ranks: 160 ms a solve against 2 ms). Every rank then computes the
    same numbers from the same data."""
    if A.getComm().getSize() > 1 and A.getSize()[0] <= settings.dense_limit:
        copies = [serial_copy(A)] + ([] if B is None else [serial_copy(B)])
        try:
            return _eps(copies[0], None if B is None else copies[1], hermitian, settings, prefix, pivoting)
        finally:
            for c in copies:       # the EPS holds its own references
                c.destroy()
    eps = with_prefix(SLEPc.EPS().create(A.getComm()), prefix)
    try:
        how = _configure(eps, A, B, hermitian, settings, pivoting)
        from_options(eps)
    except BaseException:
        eps.destroy()
        raise
    return eps, how


def _configure(eps: SLEPc.EPS, A: PETSc.Mat, B: PETSc.Mat | None, hermitian: bool, settings: EigSettings,
               pivoting: bool = False) -> str:
    """The EPS's solver for ``A x = theta B x`` (LAPACK up to ``settings.dense_limit``, else
    Krylov-Schur); ``pivoting``: the shift-and-invert factorisation pivots (MUMPS), for a
    saddle-point ``A``."""
    n = A.getSize()[0]
    eps.setOperators(A, B)
    if hermitian:
        eps.setProblemType(SLEPc.EPS.ProblemType.HEP if B is None else SLEPc.EPS.ProblemType.GHEP)
    else:
        eps.setProblemType(SLEPc.EPS.ProblemType.NHEP if B is None else SLEPc.EPS.ProblemType.GNHEP)
    if n <= settings.dense_limit:
        eps.setType(SLEPc.EPS.Type.LAPACK)
        eps.setDimensions(nev=n)
        how = f"SLEPc lapack, all {n} eigenvalues"
        if B is not None and not hermitian:
            # LAPACK's generalised reordering (tgexc) fails on these pencils; work on the
            # standard problem of shift-and-invert about 0 instead: K*^-1 M* x = (1/theta) x.
            configure_direct(_shift_invert(eps, 0.0))
            how += " (shift-and-invert about 0)"
    else:
        eps.setType(SLEPc.EPS.Type.KRYLOVSCHUR)
        nev = min(settings.nev, n)
        eps.setDimensions(nev=nev)
        eps.setTolerances(tol=settings.tol, max_it=settings.max_it)
        if hermitian:
            eps.setWhichEigenpairs(SLEPc.EPS.Which.SMALLEST_REAL)
            how = f"SLEPc krylovschur, {nev} smallest"
        else:
            # large serial pencils: MUMPS factorises 2-4x faster than PETSc's own LU (100k DOFs:
            # 0.9-1.7 s against 3.3-3.7 s); small ones keep PETSc's (faster there)
            configure_direct(_shift_invert(eps, 0.0), mumps=True if n >= MUMPS_MIN_DOFS or pivoting else None)
            how = f"SLEPc krylovschur + sinvert at 0, {nev} eigenvalues nearest 0"
    return how


def _below(A: PETSc.Mat, sigma: float) -> int:
    """Number of eigenvalues of the symmetric ``A`` at or below ``sigma`` (LDL^T inertia count of
    ``A - sigma I``; Sylvester's law of inertia)."""
    C = A.copy()
    try:
        C.shift(-sigma)
        return inertia_negative_or_zero(C, _ordering(A))
    finally:
        C.destroy()


#: Krylov-Schur subspace of the shift-and-invert solve for one eigenvalue nearest a shift, and its
#: restarts: a 4-vector subspace converges an isolated eigenvalue in about half the work of SLEPc's
#: default 16; where the smallest eigenvalues cluster (the consistent mass matrix of a large mesh:
#: at 25k DOFs it ran its 1,000 restarts for 13 s and failed), a 32-vector one follows (1.1 s)
NEAREST_ATTEMPTS = ((4, 60), (32, None))
#: up to this size PETSc's own serial Cholesky uses the QMD ordering (0.9 against 1.3 ms per
#: factorisation at 800 DOFs); above it, PETSc's default (nested dissection)
QMD_MAX = 5000


def _ordering(A: PETSc.Mat) -> str | None:
    return "qmd" if A.getSize()[0] <= QMD_MAX else None


def _nearest_sym_eig(At: PETSc.Mat, sigma: float, settings: EigSettings,
                     shift_below: bool = False, vectors: list | None = None) -> float | None:
    """:func:`_nearest_sym_eig_once` with the subspaces and restart budgets of
    :data:`NEAREST_ATTEMPTS` in turn (``None``: ``settings.max_it``), until one converges.
    ``vectors``: ``[start]`` (this rank's part of a start vector, or None), replaced by the
    eigenvector's part when one converges."""
    for ncv, max_it in NEAREST_ATTEMPTS:
        lam = _nearest_sym_eig_once(At, sigma, settings, shift_below, ncv,
                                    settings.max_it if max_it is None else min(max_it, settings.max_it), vectors)
        if lam is not _NOT_BELOW and lam is not None:
            return lam
        if lam is _NOT_BELOW:           # a larger subspace would not help
            return None
    return None


def smallest_above(A: PETSc.Mat, sigma: float, settings: EigSettings) -> float | None:
    """The smallest eigenvalue of the symmetric sequential ``A`` when ``sigma`` lies below its
    spectrum, proven by the inertia of the shift-and-invert factorisation itself (the eigenvalue
    nearest ``sigma`` is then the smallest); None when it does not or the solve fails."""
    return _nearest_sym_eig(A, sigma, settings, shift_below=True)


#: what :func:`_nearest_sym_eig_once` returns when ``shift_below`` finds the shift not below the spectrum
_NOT_BELOW = object()


def _nearest_sym_eig_once(At: PETSc.Mat, sigma: float, settings: EigSettings, shift_below: bool,
                          ncv: int, max_it: int, vectors: list | None = None) -> float | None:
    """The eigenvalue of the symmetric ``At`` nearest ``sigma`` by shift-and-invert Krylov-Schur
    (LDL^T of ``At - sigma I``); None when the solve fails or converges nothing.

    ``shift_below``: first prove ``sigma`` below the spectrum from the solve's own factorisation
    (no negative and no zero pivot, serial only), else return None without solving. Without this
    proof the shift must already be known to lie below the spectrum: Cholesky without pivoting of
    an indefinite ``At - sigma I`` can be unstable, and the value would then be unreliable."""
    if shift_below and At.getComm().getSize() > 1:
        return _NOT_BELOW               # MUMPS LU in parallel: no inertia from the solve's factor
    eps = with_prefix(SLEPc.EPS().create(At.getComm()), "cd_necessary_")
    try:
        eps.setOperators(At)
        eps.setProblemType(SLEPc.EPS.ProblemType.HEP)
        eps.setType(SLEPc.EPS.Type.KRYLOVSCHUR)
        eps.setDimensions(nev=1, ncv=min(ncv, At.getSize()[0]))   # the answer is checked by inertia
        eps.setTolerances(tol=settings.tol, max_it=max_it)
        ksp = configure_direct(_shift_invert(eps, sigma),
                               factor="cholesky" if At.getComm().getSize() == 1 else "lu", ordering=_ordering(At),
                               mumps=True if At.getSize()[0] >= MUMPS_MIN_DOFS else None)
        from_options(eps)
        start = None if vectors is None else vectors[0]
        if start is not None and len(start) == At.getLocalSize()[0]:
            # the previous classification's eigenvector: the Krylov-Schur solve then converges in
            # about one restart (measured at 100k DOFs: 0.46 s -> 0.14 s); only the iterations change
            v0 = At.createVecRight()
            v0.setArray(start)
            eps.setInitialSpace([v0])
            v0.destroy()
        if shift_below:
            with mumps_null_pivots("cd_necessary_st_"):      # the inertia of MUMPS's factor
                set_up(eps)
            set_up(ksp)
            neg, zero, _ = ksp.getPC().getFactorMatrix().getInertia()
            if neg + zero > 0:
                return _NOT_BELOW
        set_up(eps)                   # the factorisation, with the interpreter released
        eps_solve(eps)
        vals = [eps.getEigenvalue(i).real for i in range(eps.getConverged())]
        if vals and vectors is not None:
            v = At.createVecRight()
            eps.getEigenvector(int(np.argmin(vals)), v)
            vectors[0] = v.getArray().copy()
            v.destroy()
    except PETSc.Error:
        return None
    finally:
        eps.destroy()
    return float(min(vals)) if vals else None


def _proven_smallest(At: PETSc.Mat, lam: float, scale: float) -> bool:
    """``lam`` is the smallest eigenvalue up to ``delta``: no eigenvalue below ``lam - delta``
    (LDL^T inertia count)."""
    delta = 1e-9 * max(abs(lam), scale)
    return _below(At, lam - delta) == 0


def _min_sym_eig_sinvert(At: PETSc.Mat, settings: EigSettings, hint: float | None,
                         vectors: list | None = None) -> float | None:
    """Smallest eigenvalue of the symmetric ``At`` by shift-and-invert Krylov-Schur about a shift
    ``sigma`` proven (inertia count) to lie below the whole spectrum, so the eigenvalue nearest
    ``sigma`` is the smallest one; ``sigma`` starts just below ``hint`` (the previous
    classification's value). The answer is checked by a second inertia count. None when a step
    fails (the caller falls back to plain Krylov-Schur).

    With a ``hint`` the first shift is tried directly (one factorisation fewer): the
    solve's own LDL^T must show it below the spectrum, and its nearest eigenvalue is kept only
    when the second inertia count proves it the smallest; otherwise the shift is moved below the
    spectrum as without a hint."""
    scale = diag_scale(At)
    step = 1e-3 * scale
    sigma = (hint if hint is not None else 0.0) - step
    if hint is not None:
        lam = _nearest_sym_eig(At, sigma, settings, shift_below=True, vectors=vectors)
        if lam is not None and _proven_smallest(At, lam, scale):
            return lam
    for _ in range(60):
        if _below(At, sigma) == 0:
            break
        step *= 4.0
        sigma -= step
    else:
        return None
    lam = _nearest_sym_eig(At, sigma, settings, vectors=vectors)
    if lam is None or not _proven_smallest(At, lam, scale):
        return None
    return lam


def min_sym_eig(A: PETSc.Mat, settings: EigSettings, hint: float | None = None,
                vectors: list | None = None) -> float:
    """Smallest eigenvalue of the symmetric part (A + A^T)/2 (for the necessary condition (19)).

    Small problems: LAPACK (all eigenvalues). Larger ones: shift-and-invert about a shift proven
    below the spectrum by an LDL^T inertia count, warm-started from ``hint`` (2-3x
    fewer operations than Krylov-Schur on the smallest eigenvalue, same value); plain
    Krylov-Schur if that fails. ``vectors``: see :func:`_nearest_sym_eig` (shift-and-invert only)."""
    At = sym_part(A)
    try:
        if At.getSize()[0] > settings.dense_limit:
            lam = _min_sym_eig_sinvert(At, settings, hint, vectors)
            if lam is not None:
                return lam
        with owned(_eps(At, None, True, settings, "cd_necessary_")[0]) as eps:
            eps_solve(eps)
            vals = [eps.getEigenvalue(i).real for i in range(eps.getConverged())]
    finally:
        At.destroy()
    if not vals:
        raise RuntimeError("SLEPc did not converge the smallest eigenvalue of the symmetric part "
                           f"(settings.eig: tol={settings.tol}, max_it={settings.max_it})")
    return float(min(vals))


def necessary(K0: PETSc.Mat, K1: PETSc.Mat, M0: PETSc.Mat, M1: PETSc.Mat, mu: float,
              settings: EigSettings, hints: dict | None = None,
              stars: tuple[PETSc.Mat, PETSc.Mat] | None = None,
              space: tuple | None = None, known: dict | None = None) -> NecessaryOutcome:
    """Necessary condition (19): M*(mu) not PSD or K*(mu) not PD, from the symmetric parts.

    ``stars``: ``(K*(mu), M*(mu))`` already combined (kept; otherwise built and destroyed here).
    ``hints`` (name -> value, updated): the previous classification's eigenvalues, used as
    shifts (neighbouring classifications differ by one node). Both eigenvalues are also reported relative to the largest diagonal entry of the matrix, the
    scale used for the decision (so it does not depend on units). ``space``: ``(ReducedSpace,
    (r0, r1))``, the kept DOFs and the system's owned rows: the eigenvectors then go into
    ``hints`` too, in the system's numbering, as start vectors for the next classification.
    ``known``: name -> ``(value, scale, bounds)`` already computed on the contact DOFs
    (:func:`app.analyses.conditions.contact_spectrum.values`; ``value`` None and ``bounds`` where
    its budget was spent); only the others are solved here (their pencils may then be None).
    """
    out: dict = {"mu": mu}
    bounds: dict = {}
    for k, (name, A0, A1) in enumerate((("K", K0, K1), ("M", M0, M1))):
        if known is not None and known.get(name) is not None:
            lam, scale, within = known[name]
            if lam is None:       # the contact DOFs' budget spent: bounds, the sign decided
                bounds[name] = within
                out[f"min_eig_{name}_sym"] = out[f"min_eig_{name}_sym_relative"] = None
                out[f"min_eig_{name}_sym_bounds"] = (float(within[0]), float(within[1]))
                out[f"min_eig_{name}_sym_relative_bounds"] = (float(within[0] / scale), float(within[1] / scale))
                continue
            out[f"min_eig_{name}_sym"] = lam
            out[f"min_eig_{name}_sym_relative"] = lam / scale
            continue
        A = combine(A0, A1, mu) if (stars is None or stars[k] is None) else stars[k]
        try:
            scale = diag_scale(A)
            warm = hints is not None and space is not None and hints.get(f"{name}_vector") is not None
            vectors = [space[0].from_system(hints[f"{name}_vector"], space[1]) if warm else None]
            lam = min_sym_eig(A, settings, None if hints is None else hints.get(name), vectors)
        finally:
            if stars is None or stars[k] is None:
                A.destroy()
        if hints is not None:
            hints[name] = lam     # warm start for the next classification along the path
            if space is not None and vectors[0] is not None:
                hints[f"{name}_vector"] = space[0].to_system(vectors[0], space[1])
        out[f"min_eig_{name}_sym"] = lam
        out[f"min_eig_{name}_sym_relative"] = lam / scale
    rtol = 1e3 * np.finfo(float).eps
    # with bounds only, the sign is that of f(0) from the exact Y(0) (contact_spectrum._bracket): the
    # bounds never straddle 0, and a value within rtol of 0 counts as its sign says
    k_holds = (bounds["K"][1] <= 0 if "K" in bounds else out["min_eig_K_sym_relative"] <= rtol)
    m_holds = (bounds["M"][1] < 0 if "M" in bounds else out["min_eig_M_sym_relative"] < -rtol)
    out["satisfied"] = bool(k_holds or m_holds)
    return NecessaryOutcome(**out)


def sufficient(Ks: PETSc.Mat, Ms: PETSc.Mat, comp: np.ndarray, settings: EigSettings,
               keep_modes: bool = False, static: np.ndarray | None = None) -> SufficientOutcome:
    """Sufficient condition (17)-(18): real eigenpairs of (lambda^2 M* + K*) x = 0, lambda^2 > 0, x_Ts >= 0.

    Solved as ``K* x = theta M* x`` (``lambda^2 = -theta``); every real eigenpair with
    ``lambda^2 > 0`` is checked for ``x_Ts >= 0`` (up to the sign of the eigenvector).

    ``static``: DOFs without mass (the mixed element's pressure; the reduction leaves their rows
    as they are, ``K*_ss = K_ss``). The pencil then has infinite eigenvalues, whose rounded images
    LAPACK would return among the finite ones: a dense-size pencil is solved with the static DOFs
    eliminated (``K*_e = K*_kk - K*_ks K_ss^-1 K*_sk``, the same finite eigenvalues, docs/method.md
    section 10) or, where ``K_ss = 0`` (nu = 1/2), on the constraint's kernel; a larger one by
    shift-and-invert about 0, which returns the eigenvalues nearest 0 and never the infinite ones.
    """
    mixed = static is not None and len(static) > 0
    if mixed and Ks.getSize()[0] <= settings.dense_limit:
        pairs, nconv, how = _eliminated_pairs(Ks, Ms, static)
        return admissible(pairs, nconv, how, comp, keep_modes)
    eps, how = _eps(Ks, Ms, False, settings, "cd_sufficient_", pivoting=mixed)
    with ExitStack() as owns:
        owns.enter_context(owned(eps))
        op = eps.getOperators()[0]          # Ks, or its serial copy (:func:`_eps`)
        vr, vi = (owns.enter_context(owned(op.createVecRight())) for _ in range(2))
        eps_solve(eps)
        nconv = eps.getConverged()
        pairs = []
        for i in range(nconv):
            theta = eps.getEigenpair(i, vr, vi)
            if not _growing(theta):
                continue
            pairs.append((-theta.real, gather_vec(vr), float(eps.computeError(i, SLEPc.EPS.ErrorType.RELATIVE))))
    return admissible(pairs, nconv, how, comp, keep_modes)


def _growing(theta: complex) -> bool:
    """Whether the eigenvalue ``theta`` of ``K* x = theta M* x`` is real (to 1e-8), finite and
    negative: a ``lambda^2 = -theta > 0``."""
    return bool(abs(theta.imag) <= 1e-8 * max(abs(theta), 1e-300) and np.isfinite(theta.real) and theta.real < 0)


def _eliminated_pairs(Ks: PETSc.Mat, Ms: PETSc.Mat, static: np.ndarray) -> tuple[list, int, str]:
    """The real eigenpairs ``(lambda^2 > 0, x, relative residual)`` of a dense-size pencil with the
    static DOFs eliminated (LAPACK on ``(K*_e, M*_kk)``), ``x`` lifted back to every DOF by the
    static rows ``K*_sk x_k + K_ss x_s = 0``. MPI collective (the pencil gathered on every rank)."""
    K, M = dense(Ks), dense(Ms)                               # MPI collective
    keep = np.setdiff1d(np.arange(K.shape[0]), static)
    Kks, Ksk, Kss = K[np.ix_(keep, static)], K[np.ix_(static, keep)], K[np.ix_(static, static)]
    constrained = np.abs(Kss).max(initial=0.0) == 0.0
    if constrained:
        # nu = 1/2: the static rows are a constraint K_sk x_k = 0 and x_s its multiplier. On
        # x_k = Z z (Z a basis of ker K_sk), tested with W (a basis of the left kernel of K_ks), the
        # finite eigenvalues are those of (W^T K_kk Z, W^T M_kk Z); x_s from the kept rows
        Z, W = scipy.linalg.null_space(Ksk), scipy.linalg.null_space(Kks.T)
        if Z.shape[1] != W.shape[1] or Z.shape[1] == 0:
            raise np.linalg.LinAlgError("the incompressibility constraint does not have full rank")
        theta, V = scipy.linalg.eig(W.T @ K[np.ix_(keep, keep)] @ Z, W.T @ M[np.ix_(keep, keep)] @ Z)
        V = Z @ V
        how = f"LAPACK, all {Z.shape[1]} eigenvalues of the pencil on its {len(static)} incompressibility constraints"
    else:
        Ke, Mk, _ = eliminate_static(K, M, static)
        theta, V = scipy.linalg.eig(Ke, Mk)
        how = f"LAPACK, all {len(keep)} eigenvalues of the pencil with its {len(static)} pressure DOFs eliminated"
    norm_k, norm_m = np.linalg.norm(K, 1), np.linalg.norm(M, 1)
    pairs = []
    for th, v in zip(theta, V.T):
        if not _growing(th):
            continue
        x = np.zeros(K.shape[0])
        x[keep] = v.real
        if constrained:         # the multiplier from the kept rows (least squares: K_ks has full column rank)
            rhs = th.real * (M[np.ix_(keep, keep)] @ v.real) - K[np.ix_(keep, keep)] @ v.real
            x[static] = np.linalg.lstsq(Kks, rhs, rcond=None)[0]
        else:
            x[static] = -np.linalg.solve(Kss, Ksk @ v.real)
        res = np.linalg.norm(K @ x - th.real * (M @ x), 1) / ((norm_k + abs(th.real) * norm_m) * np.linalg.norm(x, 1))
        pairs.append((-th.real, x, float(res)))
    return pairs, len(theta), how


def admissible(pairs: list, nconv: int, how: str, comp: np.ndarray, keep_modes: bool) -> SufficientOutcome:
    """(17)-(18) from the real eigenpairs ``(lambda^2 > 0, x, relative error)``: those with
    ``x_Ts >= 0`` (up to the sign of ``x``; ``x_Ts`` at the positions ``comp`` of ``x``)."""
    candidates, admissible, modes = [], [], []
    for lam2, x, res in pairs:
        xc = x[comp]
        big = float(np.max(np.abs(xc))) if len(xc) else 0.0
        if big > 0 and np.sum(xc) < 0:
            x, xc = -x, -xc
        ok = bool(big > 0 and np.min(xc) >= -1e-8 * big)
        candidates.append({"lambda2": float(lam2), "admissible": ok, "min_x_Ts_rel": float(np.min(xc) / big) if big else 0.0,
                           "relative_error": float(res)})
        if ok:
            admissible.append(float(lam2))
            xn = np.maximum(xc, 0) / np.sum(np.maximum(xc, 0))
            modes.append(Solution(value=float(lam2), x_Ts=[float(v) for v in xn],
                                  pattern=["slip" if v > 1e-8 else "stick" for v in xn],
                                  evidence={"relative_error": float(res)},
                                  x=x / np.sum(xc) if keep_modes else None))
    order = np.argsort(admissible)[::-1]
    return SufficientOutcome(satisfied=bool(admissible), lambda2=[admissible[i] for i in order],
                             modes=[modes[i] for i in order],
                             real_candidates=sorted(candidates, key=lambda c: -c["lambda2"]),
                             eigensolver=how, converged=nconv)
