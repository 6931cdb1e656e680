"""The values of the necessary condition (19), the smallest eigenvalues of sym K*(mu) and
sym M*(mu), from the contact DOFs (docs/method.md section 2, "The values of (19) on the contact
DOFs").

Let ``X`` be ``K`` or ``M`` and ``A = sym X*(mu)`` one classification's matrix. Every DOF that is
not a contact DOF (the interior ``i``) is kept by every classification, and ``A`` couples it
through ``X_ic P`` (``P = (Q + R^T) / 2``, the maps of the paper's change of variables on the
kept contact DOFs, :class:`app.analyses.pencils.kept_contact.KeptContact`). For a shift
``sigma`` below ``k_1``, the smallest eigenvalue of ``X_ii``, the block ``X_ii - sigma I`` is
positive definite and by Haynsworth's inertia additivity ``A - sigma I`` has as many negative
eigenvalues as the Schur complement onto the kept contact DOFs

    S(sigma) = sym(R X_cc Q) - sigma I - P^T Y(sigma) P,   Y(sigma) = X_ci (X_ii - sigma I)^-1 X_ic.

``Y`` does not depend on the classification. ``dS/dsigma = -I - P^T Y' P <= -I``, so
``f(sigma) = lambda_min(S(sigma))`` decreases with slope at most -1 and its root is the smallest
eigenvalue of ``A`` (Cauchy interlacing puts it at or below ``k_1``; with no root below ``k_1``
it is ``k_1``). An error ``E`` in ``Y`` moves the root by at most ``||P||^2 ||E||`` (slope <= -1).

``Y`` is computed exactly (MUMPS's Schur complement of ``X - sigma I`` onto the contact DOFs,
one partial factorisation: ``Y = X_cc - sigma I - Z``) at the nodes of a piecewise Chebyshev
interpolant in ``u = log(kappa - sigma)``: ``Y`` is analytic off the interior spectrum
``[k_1, inf)``, which the map sends to the lines ``Im u = +-pi``, so each piece of length
:data:`PIECE` converges geometrically. When the interior's second eigenvalue lies :data:`GAP`
above the first, the first pole is removed exactly (its eigenpair, from SLEPc) and ``kappa`` is
the second eigenvalue; otherwise ``kappa = k_1``. Pieces are built when a root needs them, and the
classifications of a path share them, so the whole path costs a few dozen factorisations per
matrix where the full-size eigenvalue costs two per classification.

A classification whose root lies outside :data:`MAX_PIECES` pieces, or in a piece whose
interpolation error estimate (its last Chebyshev coefficients) exceeds :data:`TOL` of the
matrix's scale, is left to the full-size computation (:func:`value` returns None).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.linalg
import scipy.optimize
from petsc4py import PETSc

from app.analyses.conditions.interior_modes import interior_modes
from app.analyses.conditions.value_bounds import bracket
from app.analyses.pencils.kept_contact import KeptContact
from app.analyses.pencils.state import on_rank_zero, sequential_km, system_cache
from app.loading.classify import Classification
from app.loading.mumps_schur import SchurComplements, static_schur, without_static

#: length of one interpolation piece in u = log(kappa - sigma) (a factor e^2 in kappa - sigma)
PIECE = 2.0
#: Chebyshev nodes (first kind) per piece: exact values of Y, one factorisation each
NODES = 16
#: pieces on either side of the first one before a classification is left to the full-size solve
MAX_PIECES = 6
#: interpolation error (estimated) and root tolerance, relative to the matrix's largest diagonal entry
TOL = 1e-12
#: the first interior eigenvalue's pole is removed exactly when the second lies at least GAP (relative)
#: above it; MODE_TOL is SLEPc's tolerance for the two (the eigenvalues converge as its square)
GAP = 0.25
MODE_TOL = 1e-10


@dataclass
class ShiftedContact:
    """One symmetric matrix ``X`` (``K`` or ``M``) of a system seen from its contact DOFs (paper
    axes, order ``T_0, N_0, T_1, ...``) as a function of a shift ``sigma < k_1``, shared by every
    classification of the path."""

    exact: Callable[[float], np.ndarray]     # Y(sigma), exactly (one factorisation)
    Xcc: np.ndarray
    k1: float                                # smallest eigenvalue of X_ii
    poles: np.ndarray                        # removed interior eigenvalues k_1..k_p (p >= 0)
    residues: np.ndarray                     # n_c x p: X_ci phi_j (paper axes)
    kappa: float                             # first pole of the interpolated remainder
    scale: float                             # largest diagonal entry of X
    interior_scale: float                    # largest diagonal entry of X_ii
    evaluations: int = 0                     # exact values of Y computed
    pieces: dict = field(default_factory=dict)   # index -> (coefficients, error estimate)
    ends: dict = field(default_factory=dict)     # index -> Y at the piece's upper end in sigma
    budget: int | None = None                # most exact values of Y (None: no limit); Y(0) is always had
    static: bool = False                     # X's static DOFs eliminated (the interior a pencil X_ii - sigma D_ii)
    zero: np.ndarray | None = None           # Y(0), computed on first use

    def affordable(self, n: int) -> bool:
        """``n`` more exact values of ``Y`` fit in the budget."""
        return self.budget is None or self.evaluations + n <= self.budget

    def at_zero(self) -> np.ndarray:
        """``Y(0)`` exactly (computed once, whatever the budget: the sign of (19) rests on it)."""
        if self.zero is None:
            self.zero = self.exact(0.0)
            self.evaluations += 1
        return self.zero

    def known(self) -> list[tuple[float, np.ndarray]]:
        """Every exact value of ``Y`` computed so far outside the pieces' nodes: ``(sigma, Y)``."""
        pts = [(self.end(j), Y) for j, Y in self.ends.items()]
        return pts + ([(0.0, self.zero)] if self.zero is not None else [])

    @property
    def anchor(self) -> float:
        """``u`` of the first piece's lower end: ``sigma = k_1`` when poles were removed,
        ``sigma = 0`` otherwise."""
        return float(np.log(self.kappa - self.k1)) if len(self.poles) else float(np.log(self.kappa))

    def _remainder_exact(self, sigma: float) -> np.ndarray:
        Y = self.exact(sigma)
        self.evaluations += 1
        if len(self.poles):
            Y = Y - (self.residues / (self.poles - sigma)) @ self.residues.T
        return Y

    def piece(self, j: int) -> tuple[np.ndarray, float]:
        """Chebyshev coefficients ``(NODES, n_c, n_c)`` of the remainder on piece ``j`` (built on
        first use) and their error estimate (the largest entry of the last two coefficients)."""
        hit = self.pieces.get(j)
        if hit is None:
            theta = (2 * np.arange(NODES) + 1) * np.pi / (2 * NODES)
            u = self.anchor + PIECE * (j + 0.5 * (1.0 + np.cos(theta)))
            values = np.array([self._remainder_exact(self.kappa - np.exp(x)) for x in u])
            T = np.cos(np.outer(np.arange(NODES), theta)) * (2.0 / NODES)
            T[0] *= 0.5
            coef = np.tensordot(T, values, axes=(1, 0))
            err = float(np.abs(coef[-2:]).max())
            hit = self.pieces[j] = (coef, err)
        return hit

    def end(self, j: int) -> float:
        """``sigma`` at the upper end of piece ``j`` (its lower end in ``u``)."""
        return float(self.kappa - np.exp(self.anchor + PIECE * j))

    def exact_at_end(self, j: int) -> np.ndarray:
        """``Y`` exactly at :meth:`end` of piece ``j`` (cached: the classifications bracket their
        roots with these, so only the pieces holding roots are interpolated)."""
        hit = self.ends.get(j)
        if hit is None:
            hit = self.ends[j] = self.exact(self.end(j))
            self.evaluations += 1
        return hit

    def coordinate(self, sigma: float, j: int | None = None) -> tuple[int, float]:
        """The piece of ``sigma`` (or the given piece ``j``, ``sigma`` at its ends) and the local
        coordinate ``x`` in [-1, 1] there."""
        u = np.log(self.kappa - sigma)
        if j is None:
            j = int(np.floor((u - self.anchor) / PIECE))
        x = 2.0 * (u - self.anchor - PIECE * j) / PIECE - 1.0
        return j, float(np.clip(x, -1.0, 1.0))


def _chebyshev(x: float, n: int) -> np.ndarray:
    return np.cos(np.arange(n) * np.arccos(x))


class Root:
    """``f(sigma) = lambda_min(S(sigma))`` of one classification at ``mu`` on the interpolant.

    On a curved obstacle the maps hold the contact frames and ``bend`` adds, for ``K``, the
    curvature term on the slip nodes' ``x_Ts`` (:class:`~app.analyses.pencils.kept_contact.KeptContact`)."""

    def __init__(self, sc: ShiftedContact, cls: Classification, mu: float, bend: bool = False):
        kc = KeptContact(sc.Xcc.shape[0], cls, mu)
        self.sc, self.n = sc, kc.n
        self.P = (0.5 * (kc.Q + kc.R)).tocsc()
        A0 = kc.reduced(sc.Xcc, bend)
        self.A0 = 0.5 * (A0 + A0.T)
        self.Pw = np.asarray(self.P.T @ sc.residues) if len(sc.poles) else np.zeros((kc.n, 0))
        self._projected: dict[int, np.ndarray] = {}
        self._exact: dict[float, list] = {}      # sigma -> [S, P^T Y P, f or None] from an exact Y

    def projected(self, j: int) -> np.ndarray:
        """``P^T C_m P`` for the coefficients ``C_m`` of piece ``j``."""
        hit = self._projected.get(j)
        if hit is None:
            coef, _ = self.sc.piece(j)
            m, nc, _ = coef.shape
            left = np.asarray(self.P.T @ coef.reshape(m * nc, nc).T).T          # rows of C_m P
            left = left.reshape(m, nc, self.n).transpose(1, 0, 2).reshape(nc, m * self.n)
            hit = np.asarray(self.P.T @ left).reshape(self.n, m, self.n).transpose(1, 0, 2)
            self._projected[j] = np.ascontiguousarray(hit)
            hit = self._projected[j]
        return hit

    def S(self, sigma: float, j: int) -> np.ndarray:
        """``S(sigma)`` with the remainder interpolated on piece ``j`` (``sigma`` in it or at its ends)."""
        _, x = self.sc.coordinate(sigma, j)
        C = self.projected(j)
        S = self.A0 - np.tensordot(_chebyshev(x, C.shape[0]), C, axes=(0, 0))
        S[np.diag_indices_from(S)] -= sigma
        if self.Pw.shape[1]:
            S -= (self.Pw / (self.sc.poles - sigma)) @ self.Pw.T
        return 0.5 * (S + S.T)

    def f(self, sigma: float, j: int) -> float:
        """``f(sigma)``, the smallest eigenvalue of ``S(sigma)`` on the interpolant of piece ``j``."""
        return float(scipy.linalg.eigvalsh(self.S(sigma, j), subset_by_index=[0, 0])[0])

    def f_end(self, j: int) -> float:
        """``f`` at the upper end of piece ``j`` in sigma, from the exact ``Y`` there; just below
        ``k_1`` for the first piece when its pole is removed (minus infinity when the pole couples
        to the kept DOFs)."""
        sc = self.sc
        if len(sc.poles) and j == 0:
            if np.linalg.norm(self.Pw) > 1e-8 * np.linalg.norm(sc.residues):
                return -np.inf
            return self.f(sc.k1 - TOL * sc.scale, 0)
        return self.f_exact(sc.end(j), sc.exact_at_end(j))

    def exact(self, sigma: float, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``S(sigma)`` and ``P^T Y P`` (both symmetrised) from the exact ``Y = Y(sigma)``, kept per
        ``sigma``: the walk of :func:`value` and the bounds of
        :func:`app.analyses.conditions.value_bounds.bracket` read the same points."""
        hit = self._exact.get(sigma)
        if hit is None:
            PY = np.asarray(self.P.T @ np.asarray(self.P.T @ Y).T)
            PY = 0.5 * (PY + PY.T)
            S = self.A0 - PY
            S[np.diag_indices_from(S)] -= sigma
            hit = self._exact[sigma] = [0.5 * (S + S.T), PY, None]
        return hit[0], hit[1]

    def f_exact(self, sigma: float, Y: np.ndarray) -> float:
        """``f(sigma)`` from the exact ``Y = Y(sigma)`` (kept, as :meth:`exact`)."""
        S, _ = self.exact(sigma, Y)
        hit = self._exact[sigma]
        if hit[2] is None:
            hit[2] = float(scipy.linalg.eigvalsh(S, subset_by_index=[0, 0])[0])
        return hit[2]


@dataclass(frozen=True)
class Value:
    """The smallest eigenvalue of one ``sym X*(mu)`` from the contact DOFs: ``value``, or where the
    budget of exact values of ``Y`` is spent, ``None`` and ``bounds = (lo, hi)`` with
    ``lo <= value <= hi``, its sign decided (:func:`_bracket`)."""

    value: float | None
    scale: float          # the largest diagonal entry of sym X*(mu), which the value is reported against
    bounds: tuple[float, float] | None = None


def value(sc: ShiftedContact, cls: Classification, mu: float, hint: float | None = None,
          bend: bool = False) -> Value | None:
    """The smallest eigenvalue of ``sym X*(mu)`` of classification ``cls`` (see the module's
    docstring), or None when it is left to the full-size solve. ``hint``: the previous
    classification's value (where to look first); ``bend``: ``X`` is ``K``, which carries a curved
    obstacle's curvature term (:class:`Root`)."""
    root = Root(sc, cls, mu, bend)
    if root.n == 0:                           # every contact DOF removed: sym X* is X_ii
        return Value(sc.k1, sc.interior_scale)
    scale = max(sc.interior_scale, float(np.abs(np.diag(root.A0)).max()))
    tol = TOL * sc.scale

    def ends(j: int) -> tuple[float, float]:
        """Piece j's ends in sigma, upper first (just below k_1 for the first piece with its pole
        removed: the pole term is infinite at k_1)."""
        hi = sc.end(j)
        if len(sc.poles) and j == 0:
            hi = sc.k1 - tol
        return hi, sc.end(j + 1)

    lowest_j = 0 if len(sc.poles) else -MAX_PIECES
    j = sc.coordinate(hint)[0] if hint is not None and hint < sc.k1 else 0
    j = int(np.clip(j, lowest_j, MAX_PIECES))
    visited = []
    # f decreases with sigma: the root lies in piece j when f < 0 at its upper end and f > 0 at its
    # lower one (exact values there)
    while True:
        visited.append(j)
        if not _affords_ends(sc, j):
            return Value(None, scale, bracket(root))
        if root.f_end(j) >= 0:                # the root is closer to k_1
            if j == lowest_j:
                if len(sc.poles):             # f >= 0 up to just below k_1: the value is k_1
                    return Value(sc.k1, scale)
                return None
            j -= 1
        elif root.f_end(j + 1) <= 0:          # further below
            if j == MAX_PIECES:
                return None
            j += 1
        else:
            break
        if j in visited:                      # not monotone (rounding): leave it to the full-size solve
            return None
    hi, lo = ends(j)
    if j not in sc.pieces and not sc.affordable(NODES):
        return Value(None, scale, bracket(root))
    _, err = sc.piece(j)
    if err > tol:
        return None
    try:
        sigma = scipy.optimize.brentq(root.f, lo, hi, args=(j,), xtol=tol, rtol=4 * np.finfo(float).eps,
                                      maxiter=200)
    except (ValueError, RuntimeError):         # the interpolant's signs at the ends differ from the exact ones
        return None
    return Value(float(sigma), scale)


def _affords_ends(sc: ShiftedContact, j: int) -> bool:
    """The exact values of ``Y`` at piece ``j``'s ends (those the walk reads) are had or fit the budget
    (the first piece's upper end with its pole removed is interpolated: a whole piece)."""
    need = 0
    for i in (j, j + 1):
        if len(sc.poles) and i == 0:
            need += 0 if 0 in sc.pieces else NODES
        elif i not in sc.ends:
            need += 1
    return sc.affordable(need)


def build(X: PETSc.Mat, dofs: np.ndarray, signs: np.ndarray,
          own: Callable[..., None] | None = None, static: np.ndarray | None = None,
          mass: bool = False) -> ShiftedContact:
    """:class:`ShiftedContact` of the sequential symmetric positive definite ``X`` (kept alive by
    the caller): its interior eigenpairs (SLEPc), and a function giving ``Y(sigma)`` exactly from
    a factorisation of ``X - sigma I`` that keeps its symbolic analysis between shifts. The PETSc
    objects it creates are handed to ``own`` (:meth:`app.systems.base.System.own`: destroyed with
    the system), else left to the garbage collector. ``mass``: ``X`` is a consistent mass matrix,
    whose interior's condition number does not grow with the mesh (``bounded`` of
    :func:`app.analyses.conditions.interior_modes.interior_modes`).

    ``static``: DOFs without mass (the mixed element's pressure, ``X`` then a saddle-point matrix
    with an invertible pressure block) that are eliminated first: the result is that of
    ``X_e = X / X_ss`` (docs/method.md section 10). Its contact block ``X_e,cc`` is the Schur
    complement of the contact and static rows onto the contact DOFs, and ``Y`` comes from the
    Schur complements of ``X - sigma D``, ``D = diag(1, 0 on static)`` (the quotient property:
    eliminating the static DOFs first gives ``X_e - sigma I``), the interior eigenpairs from
    ``X_ii x = k D_ii x``."""
    N = X.getSize()[0]
    interior = np.setdiff1d(np.arange(N), dofs).astype(PETSc.IntType)
    diag = X.getDiagonal()
    d = np.abs(diag.getArray())
    diag.destroy()
    scale = float(d.max())
    interior_scale = float(d[interior].max()) if len(interior) else 0.0
    rows = PETSc.IS().createGeneral(np.asarray(dofs, dtype=PETSc.IntType), comm=PETSc.COMM_SELF)
    inner = PETSc.IS().createGeneral(interior, comm=PETSc.COMM_SELF)
    try:
        (Xcc,) = X.createSubMatrices(rows, rows)
        (Xii,) = X.createSubMatrices(inner, inner)
        (Xci,) = X.createSubMatrices(rows, inner)
    finally:
        rows.destroy()
        inner.destroy()
    Dii = _mass_indicator(Xii, interior, static) if static is not None and len(static) else None
    try:
        cc = signs[:, None] * Xcc.getValues(range(len(dofs)), range(len(dofs))) * signs[None, :]
        if Dii is not None:           # X_e,cc: the static DOFs eliminated from the contact block
            cc, scale, interior_scale = _eliminated_contact(X, dofs, signs, static, interior, d)
        k, Phi = interior_modes(Xii, GAP, MODE_TOL, Dii, bounded=mass)
        p = 1 if Phi is not None and len(k) > 1 and (k[1] - k[0]) / k[1] >= GAP else 0
        W = _residues(Xci, Phi[:, :p] if p else None, signs)
    finally:
        for Y in (Xcc, Xii, Xci, Dii):
            if Y is not None:
                Y.destroy()
    if not k[0] > TOL * scale:
        raise RuntimeError("the interior block is not positive definite (a body held only at its contact DOFs)")
    kappa = float(k[p]) if p else float(k[0])
    A = X.copy()
    schur = SchurComplements(A, dofs, "cd_shifted_", spd=Dii is None)
    massive = None
    if Dii is not None:                          # -sigma D: nothing on the static DOFs' diagonal
        massive = A.createVecLeft()
        massive.setArray(np.where(np.isin(np.arange(N), static), 0.0, 1.0))

    def exact(sigma: float) -> np.ndarray:
        X.copy(A, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        if massive is None:
            A.shift(-sigma)
        else:
            step = massive.copy()
            step.scale(-sigma)
            A.setDiagonal(step, addv=PETSc.InsertMode.ADD_VALUES)
            step.destroy()
        Z = schur()
        if Z is None:
            raise RuntimeError("MUMPS gave no Schur complement of X - sigma I onto the contact DOFs")
        Y = cc - signs[:, None] * Z * signs[None, :]
        Y[np.diag_indices_from(Y)] -= sigma
        return 0.5 * (Y + Y.T)

    if own is not None:
        own(schur, A, *([massive] if massive is not None else []))
    return ShiftedContact(exact, cc, float(k[0]), k[:p].copy(), W[:, :p].copy(), kappa, scale, interior_scale,
                          static=Dii is not None)


def _residues(Xci: PETSc.Mat, Phi: np.ndarray | None, signs: np.ndarray) -> np.ndarray:
    """``X_ci phi_j`` in paper axes for the removed poles' eigenvectors ``phi_j`` (the columns of
    ``Phi``; None: no pole removed, an ``n_c x 0`` array)."""
    W = np.zeros((len(signs), 0 if Phi is None else Phi.shape[1]))
    v, x = Xci.createVecLeft(), Xci.createVecRight()
    for j in range(W.shape[1]):
        x.setArray(Phi[:, j])
        Xci.mult(x, v)
        W[:, j] = signs * v.getArray()
    v.destroy()
    x.destroy()
    return W


def _mass_indicator(Xii: PETSc.Mat, interior: np.ndarray, static: np.ndarray) -> PETSc.Mat:
    """``D_ii``: the diagonal matrix with 1 on the interior's massive DOFs, 0 on its static ones."""
    on = np.ones(len(interior))
    on[np.isin(interior, static)] = 0.0
    d = Xii.createVecLeft()
    d.setArray(on)
    D = PETSc.Mat().createAIJ(Xii.getSizes(), nnz=1, comm=PETSc.COMM_SELF)
    D.setUp()
    D.setDiagonal(d)
    D.assemble()
    d.destroy()
    return D


def _eliminated_contact(X: PETSc.Mat, dofs: np.ndarray, signs: np.ndarray, static: np.ndarray,
                       interior: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, float, float]:
    """``(X_e,cc, scale, interior scale)`` with the static DOFs eliminated (paper axes): the scales
    the tolerances use are X's diagonal ``d`` on the interior's massive DOFs (the static DOFs' own
    diagonal is no entry of X_e) and X_e,cc's."""
    cc = signs[:, None] * static_schur(X, dofs, static) * signs[None, :]
    has_mass = ~np.isin(interior, static)
    interior_scale = float(d[interior[has_mass]].max()) if has_mass.any() else 0.0
    return cc, max(interior_scale, float(np.abs(np.diag(cc)).max())), interior_scale


def contact_spectra(system, work: float | None = None) -> tuple[ShiftedContact, ShiftedContact] | None:
    """``K`` and ``M`` of ``system`` seen from its contact DOFs, built on first use on rank 0
    (None on the other ranks, and on rank 0 when they cannot be built). ``work``: the budget of
    each matrix in DOF-factorisations (``eig.necessary_value_work``: exact values of ``Y`` times
    the system's DOFs), set at the first call. MPI collective on the first call (``K`` and ``M``
    gathered on rank 0 when distributed) unless :func:`sequential_km` has run: then rank 0 may
    call it alone."""
    def made():
        got = _build_both(system)
        if got is not None and work is not None:
            for sc in got:
                sc.budget = max(1, int(work // max(system.n_dofs, 1)))
        return got
    return system_cache(system).once("spectra", made)


def _build_both(system) -> tuple[ShiftedContact, ShiftedContact] | None:
    pair = sequential_km(system)                                      # MPI collective (first call)
    if pair is None:
        return None
    dofs = np.array([[nd.dof_T, nd.dof_N] for nd in system.nodes]).ravel()
    signs = np.array([[nd.sign_T, nd.sign_N] for nd in system.nodes], dtype=float).ravel()
    static = system.static_dofs
    try:
        if static is None or not len(static):
            return (build(pair[0], dofs, signs, system.own), build(pair[1], dofs, signs, system.own, mass=True))
        # the static DOFs eliminated: K through them; M (nothing on them) without them
        K, M = pair
        Mu, at = without_static(M, static, dofs)
        system.own(Mu)
        return (build(K, dofs, signs, system.own, static), build(Mu, at, signs, system.own, mass=True))
    except (PETSc.Error, RuntimeError, np.linalg.LinAlgError):
        return None


def values(system, cls: Classification, mu: float, hints: dict,
           work: float | None = None) -> dict[str, tuple[float | None, float, tuple | None] | None]:
    """The smallest eigenvalues of ``sym K*(mu)`` and ``sym M*(mu)`` of ``cls`` and the scale each
    is reported relative to (the largest diagonal entry of that matrix), as ``{"K": (value, scale,
    bounds) or None, "M": ...}``: None where it is left to the full-size solve (:func:`value`
    declined); ``value`` None and ``bounds`` ``(lo, hi)`` where the budget ``work``
    (:func:`contact_spectra`) is spent. ``hints`` (name -> the previous classification's value)
    is read and updated. MPI collective: rank 0 computes, every rank gets the answer."""
    sequential_km(system)                                             # MPI collective (first call)

    def alone():
        got = {"K": None, "M": None}
        spectra = contact_spectra(system, work)       # built on first use (K and M gathered above)
        for name, sc in zip(("K", "M"), spectra or ()):
            try:     # on a curved obstacle K* carries the curvature term (app/analyses/pencils/kept_contact.py)
                v = value(sc, cls, mu, hints.get(name), bend=name == "K")
            except (RuntimeError, PETSc.Error, np.linalg.LinAlgError):
                v = None
            if v is not None:
                got[name] = (v.value, v.scale, v.bounds)
        return got

    got = on_rank_zero(system, alone)                                 # MPI collective
    for name, v in got.items():
        if v is not None and v[0] is not None:
            hints[name] = v[0]
    return got
