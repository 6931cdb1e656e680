"""The trusted kernel: rigorous tests on a condensed MCEIP-mu pencil, and the proof-log checker.

Problem (paper eqs. (21)-(23), condensed on the ``s`` slip nodes): ``A(mu) = A0 + mu A1``;
a solution is ``mu >= 0``, ``v >= 0``, ``v != 0`` with ``y = A(mu) v >= 0`` and ``v_i y_i = 0``.
Its support ``P = {i : v_i > 0}`` must not hold both halves ``(a, b)`` of a ``pair`` (split
tangential rates of zero-reaction nodes). The pencil's floating-point entries are the data: the
proof is about them exactly.

This module does not import the prover (:mod:`app.analyses.mceip_mu.prover`); the prover uses
its tests. Every test below returns ``True`` only when its conclusion holds for the exact pencil,
with every rounding error of the floating-point arithmetic bounded:

* **Products** (:func:`mr_mul`): midpoint-radius matrix products. For ``C = fl(A B)`` with inner
  dimension ``n``, ``|C - A B| <= gamma_n |A| |B| + n eta`` (Higham, *Accuracy and Stability of
  Numerical Algorithms*, 2nd ed., sec. 3.5; any summation order, with FMA too; ``eta`` bounds
  underflow), plus the radii of the factors. Every computed bound is inflated by a relative
  ``1 + 4 gamma_(n+4)`` and an absolute ``eta`` so that its own rounding is covered.
* **Positive definiteness** (:func:`verified_pd`): a floating-point Cholesky of ``H - c I`` that
  runs to completion gives ``R^T R = H - c I + dH`` with ``|dH| <= gamma_(n+1) |R^T| |R|`` (Higham,
  Theorem 10.3; the bound holds for any evaluation order, blocked LAPACK included); so
  ``lambda_min(H) >= c - gamma_(n+1) ||R||_F^2 - (rounding of the shift) - (input radius)``, and
  positive definiteness is proven when that is positive (the idea of Rump, BIT 46 (2006) 433-452).
* **Sign argument** (:func:`copositive_at`): at a solution supported in ``U``,
  ``v_U^T D A_UU(mu) v_U = sum_i d_i v_i y_i = 0`` for any positive diagonal ``D``; so if
  ``sym(D A_UU(mu))`` is strictly copositive there is no such solution. Strict copositivity is
  proven by an exact split ``P + N`` (``N >= 0`` entrywise, ``P`` proven positive definite).
  ``A(mu)`` is affine in mu and the strictly copositive matrices form a convex cone, so the test
  at both ends of ``[a, b]`` closes the whole interval (:func:`closes_subsets`).
* **Nonsingularity on an interval** (:func:`nonsingular_on`): with ``R ~ A(m)^-1``, every
  ``A(mu)``, ``|mu - m| <= h``, is nonsingular when ``||I - R A(m)||_inf + h ||R A1||_inf < 1``
  (Banach lemma; both products bounded rigorously): then no support ``P`` solution has its mu
  in the interval.
* **Products of constraints** (:func:`rlt_closes`): ``x^T M y <= 0`` at a solution for a
  matrix ``M`` nonpositive off the diagonal (except on forced columns), so a strictly copositive
  ``sym(M A_UU)`` at both ends excludes the family (the sign argument is ``M = D``).
* **Farkas vectors** (:func:`farkas_closes`): a vector ``w``, nonpositive off a forced set ``F``,
  with ``(A(mu)^T w)_U > 0`` at both ends of ``[a, b]`` excludes every solution whose support
  lies between ``F`` and ``U`` there (the linear relaxation of that family is infeasible).
* **Isolated eigenpairs** (:func:`verify_window`): Krawczyk's operator for the bordered system
  ``F(x, mu) = [A_PP(mu) x ; x_k - 1]`` on a box ``X = [x~ +- r] x [mu~ +- h]``: ``K(X)`` inside
  the interior of ``X`` proves a unique zero in ``X`` (Krawczyk 1969; Rump, "Verification methods",
  Acta Numerica 2010, Theorem 8.1), enclosed by ``K(X)``. A perturbation bound then shows that
  every eigenpair of the support with mu in the window lies in ``X``, so the window holds
  exactly one eigenvalue of ``P``; the signs of ``x_P`` and of ``y`` off ``P`` over the enclosure
  decide whether it is a solution, not one, or cannot be decided in double precision
  (``ill_conditioned``).

The log (:class:`ProofLog`) is a tree of nodes ``(U, [a, b])`` ("no solution with support in ``U``
and mu in ``[a, b]`` other than the listed ones"); :func:`check_log` re-runs every node's test from
the pencil and checks that the children of each node cover it. The format is documented in
docs/proofs.md.
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass, field

import numpy as np

U_ROUND = 2.0 ** -53          # unit roundoff of IEEE double
ETA = 2.0 ** -1074            # smallest positive subnormal
TINY = 2.0 ** -1000           # absolute slack for underflow in a product sum (>> n * ETA for n < 2^70)

FORMAT = "mceip-mu-proof/2"
FORMATS_READ = ("mceip-mu-proof/1", FORMAT)   # version 1: no forced sets (a leaf is its own)


def gamma(n: int) -> float:
    """Higham's ``gamma_n = n u / (1 - n u)``."""
    nu = n * U_ROUND
    return nu / (1.0 - nu)


def _up(x, n: int):
    """A computed nonnegative bound inflated to cover its own rounding (``n`` operations deep)."""
    return x * (1.0 + 4.0 * gamma(n + 4)) + TINY


def rounded_up(x, n: int):
    """A computed nonnegative bound inflated to cover its own rounding (``n`` operations deep)."""
    return _up(x, n)


def mr_mul(A: np.ndarray, rA, B: np.ndarray, rB) -> tuple[np.ndarray, np.ndarray]:
    """Midpoint-radius product: ``(C, rC)`` with ``|A~ B~ - C| <= rC`` for every ``A~`` within
    ``rA`` of ``A`` and ``B~`` within ``rB`` of ``B`` (entrywise; ``None`` means exact)."""
    C = A @ B
    n = A.shape[-1]
    aA, aB = np.abs(A), np.abs(B)
    rad = gamma(n + 2) * (aA @ aB)
    if rB is not None:
        rad = rad + aA @ rB
    if rA is not None:
        rad = rad + rA @ (aB if rB is None else aB + rB)
    return C, _up(rad, n + 4)


def pencil_at(a0: np.ndarray, a1: np.ndarray, mu: float, h: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """``A(mu')`` for every ``|mu' - mu| <= h`` as midpoint and radius (``fl(a0 + mu a1)``)."""
    A = a0 + mu * a1
    rad = gamma(2) * (np.abs(a0) + abs(mu) * np.abs(a1))
    if h > 0:
        rad = rad + h * np.abs(a1)
    return A, _up(rad, 4)


def _norm_inf(M: np.ndarray) -> float:
    return float(_up(np.max(np.sum(np.abs(M), axis=-1), initial=0.0), M.shape[-1]))


def verified_pd(H: np.ndarray, radius: float = 0.0) -> bool:
    """Every symmetric matrix within 2-norm ``radius`` of the symmetric float matrix ``H`` is
    positive definite (shifted Cholesky with the a-posteriori bound above)."""
    n = H.shape[0]
    if n == 0:
        return True
    if not np.all(np.isfinite(H)) or not np.isfinite(radius):
        return False
    d = np.diag(H)
    if np.any(d <= 0):
        return False
    g = gamma(n + 1)
    tr = float(np.sum(d)) * (1.0 + 2.0 * gamma(n))
    shift = 2.0 * (radius + g * tr + U_ROUND * float(np.max(d))) + 8.0 * n * (n + 2) * TINY
    Hs = H - shift * np.eye(n)
    try:
        L = np.linalg.cholesky(Hs)
    except np.linalg.LinAlgError:
        return False
    if not np.all(np.isfinite(L)):
        return False
    frob2 = float(_up(np.sum(L * L), n * n))
    bound = radius + g * frob2 + U_ROUND * float(np.max(np.abs(np.diag(Hs)))) + 8.0 * n * (n + 2) * TINY
    return shift > _up(bound, 8)


def copositive_at(a0: np.ndarray, a1: np.ndarray, mu: float, d: np.ndarray, theta: float) -> bool:
    """``sym(D A(mu))`` is strictly copositive, by the split ``N = theta * (positive off-diagonal
    part)``, ``P = H - N`` (exact for ``theta`` in {0, 1/2, 1}), ``P`` proven positive definite."""
    if theta not in (0.0, 0.5, 1.0) or np.any(~(d > 0)) or not np.all(np.isfinite(d)):
        return False
    A = a0 + mu * a1
    DA = d[:, None] * A
    H = 0.5 * (DA + DA.T)
    aD = d[:, None] * (np.abs(a0) + abs(mu) * np.abs(a1))
    E = gamma(5) * 0.5 * (aD + aD.T)
    return _pd_plus_nn(H, E, theta)


def _pd_plus_nn(H: np.ndarray, E: np.ndarray, theta: float) -> bool:
    """Every symmetric matrix within entrywise ``E`` of ``H`` is strictly copositive: the exact
    split ``N = theta * (positive off-diagonal part of H)`` and ``H - N`` proven positive
    definite (within the Frobenius norm of ``E``)."""
    if theta > 0:
        off = H - np.diag(np.diag(H))
        H = H - theta * np.maximum(off, 0.0)
    return verified_pd(H, float(_up(np.sqrt(np.sum(E * E)), E.size)))


def closes_subsets(a0, a1, U: np.ndarray, a: float, b: float, d: np.ndarray, theta: float) -> bool:
    """No solution with support in ``U`` and mu in ``[a, b]`` (sign argument at both ends)."""
    if not (a <= b) or len(d) != len(U):
        return False
    sub0, sub1 = a0[np.ix_(U, U)], a1[np.ix_(U, U)]
    return copositive_at(sub0, sub1, a, d, theta) and (a == b or copositive_at(sub0, sub1, b, d, theta))


def rlt_closes(a0: np.ndarray, a1: np.ndarray, U: np.ndarray, F, a: float, b: float, M, theta: float) -> bool:
    """No solution whose support ``P`` satisfies ``F <= P <= U`` has mu in ``[a, b]``, by a
    product-of-constraints argument (reformulation-linearisation): a ``|U| x |U|`` matrix ``M``
    with ``M_ij <= 0`` for ``i != j`` and ``U[j]`` not in ``F`` (diagonal and forced columns of any
    sign), and ``sym(M A_UU(mu))`` strictly copositive at ``a`` and ``b`` (exact split
    ``P + N``, ``P`` proven positive definite, as :func:`copositive_at`).

    At such a solution ``x_U^T M A_UU x_U = x^T M y = sum_{i in P, j in U \\ P} x_i M_ij y_j <= 0``
    (``x_i = 0`` off ``P``, ``y_j = 0`` on ``P``, ``j`` off ``P`` is not in ``F``, ``y_j >= 0``), which
    strict copositivity forbids. ``M = D`` positive diagonal is the sign argument. Affine in mu,
    so both ends cover the interval."""
    U = np.asarray(U, dtype=np.int64)
    p = len(U)
    M = np.asarray(M, dtype=float)
    if M.shape != (p, p) or p == 0 or not np.all(np.isfinite(M)) or theta not in (0.0, 0.5, 1.0) \
            or not (a <= b):
        return False
    forced = np.isin(U, np.asarray(list(F), dtype=np.int64))
    sign_free = np.eye(p, dtype=bool) | forced[None, :]
    if np.any(M[~sign_free] > 0):
        return False
    sub0, sub1 = a0[np.ix_(U, U)], a1[np.ix_(U, U)]
    for mu in ((a, b) if a != b else (a,)):
        A, rA = pencil_at(sub0, sub1, mu)
        C, rC = mr_mul(M, None, A, rA)
        H = 0.5 * (C + C.T)
        R = _up(0.5 * (rC + rC.T) + U_ROUND * np.abs(H), 2)
        if not _pd_plus_nn(H, R, theta):
            return False
    return True


def farkas_closes(a0: np.ndarray, a1: np.ndarray, U: np.ndarray, F, a: float, b: float, w) -> bool:
    """No solution whose support ``P`` satisfies ``F <= P <= U`` has mu in ``[a, b]``, by a Farkas
    (Gordan) vector ``w`` (length ``s``) with ``w_i <= 0`` for every ``i`` not in ``F`` and
    ``(A(mu)^T w)_U > 0`` at ``a`` and at ``b``.

    At such a solution ``w^T y = sum_{i not in P} w_i y_i <= 0`` (``y_P = 0``, ``y >= 0`` and
    ``w_i <= 0`` off ``P``, as ``F <= P``), while ``w^T y = (A(mu)^T w)^T x = sum_{j in P} g_j x_j > 0``.
    ``g = A(mu)^T w`` is affine in mu, so both ends cover the interval. The linear relaxation of
    the family (complementarity fixed on ``F``, dropped elsewhere) is infeasible exactly when such
    a vector exists; it is found by an LP in the prover and re-checked here with a rigorous bound
    on the rounding of ``g``, never taken from the LP's status."""
    s = a0.shape[0]
    w = np.asarray(w, dtype=float)
    U = np.asarray(U, dtype=np.int64)
    if w.shape != (s,) or len(U) == 0 or not np.all(np.isfinite(w)) or not (a <= b):
        return False
    free = np.zeros(s, dtype=bool)
    free[[int(i) for i in F if 0 <= int(i) < s]] = True
    if np.any(w[~free] > 0):
        return False
    for mu in ((a, b) if a != b else (a,)):
        A, rA = pencil_at(a0[:, U], a1[:, U], mu)
        g, rg = mr_mul(A.T, rA.T, w[:, None], None)
        if not np.all(g[:, 0] - rg[:, 0] > 0):
            return False
    return True


def nonsingular_on(a0: np.ndarray, a1: np.ndarray, P: np.ndarray, a: float, b: float) -> bool:
    """Every ``A_PP(mu)``, ``mu`` in ``[a, b]``, is nonsingular (so support ``P`` has no eigenvalue there)."""
    return bool(nonsingular_batch(a0, a1, P, np.array([a]), np.array([b]))[0])


def nonsingular_batch(a0: np.ndarray, a1: np.ndarray, P: np.ndarray, los: np.ndarray, his: np.ndarray) -> np.ndarray:
    """:func:`nonsingular_on` for many intervals ``[los[k], his[k]]`` at once (stacked LAPACK)."""
    los = np.asarray(los, dtype=float)
    his = np.asarray(his, dtype=float)
    out = np.zeros(len(los), dtype=bool)
    if len(P) == 0 or len(los) == 0:
        return out
    good = (los <= his) & np.isfinite(los) & np.isfinite(his)
    s0, s1 = a0[np.ix_(P, P)], a1[np.ix_(P, P)]
    p = len(P)
    m = 0.5 * (los + his)
    h = _up(np.maximum(his - m, m - los), 2)
    # A(mu) = A(m) + (mu - m) A1: ||I - R A(mu)|| <= ||I - R A(m)|| + h ||R A1||, each product
    # with its rigorous radius (far tighter than |R| |A1| near an eigenvalue)
    A = s0[None] + m[:, None, None] * s1[None]
    rA = _up(gamma(2) * (np.abs(s0)[None] + np.abs(m)[:, None, None] * np.abs(s1)[None]), 4)
    with np.errstate(all="ignore"):
        try:
            R = np.linalg.inv(A)
        except np.linalg.LinAlgError:
            R = np.stack([_safe_inv(Ak) for Ak in A])
        fin = np.all(np.isfinite(R), axis=(1, 2))
        R = np.where(fin[:, None, None], R, 0.0)
        aR = np.abs(R)
        C = R @ A
        rC = _up(gamma(p + 2) * (aR @ np.abs(A)) + aR @ rA, p + 4)
        C1 = R @ s1[None]
        rC1 = _up(gamma(p + 2) * (aR @ np.abs(s1)[None]), p + 4)
        G = np.eye(p)[None] - C
        rG = _up(rC + U_ROUND * np.abs(G) + h[:, None, None] * (np.abs(C1) + rC1), 4)
        nrm = _up(np.max(np.sum(np.abs(G) + rG, axis=2), axis=1), p)
    out = good & fin & (nrm < 1.0)
    return out


def _safe_inv(A: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return np.full_like(A, np.nan)


@dataclass
class Window:
    """The result of :func:`verify_window`: the enclosure of the only eigenpair of support ``P``
    with mu in ``[mu_lo, mu_hi]`` (the window) and what its signs say."""
    ok: bool                    # Krawczyk inclusion and uniqueness proven
    mu_lo: float                # the window (every eigenvalue of P in it is the enclosed one)
    mu_hi: float
    enc_lo: float = np.nan      # the enclosure of that eigenvalue
    enc_hi: float = np.nan
    verdict: str = "unproven"   # "solution", "not a solution", "ill-conditioned", "unproven"
    min_x: float = np.nan       # proven lower bound of min x_P / max x_P
    min_y: float = np.nan       # proven lower bound of min y off P (inf if P is everything)


def structural_zeros(a0: np.ndarray, a1: np.ndarray, P: np.ndarray, pairs) -> np.ndarray:
    """Rows ``j`` off ``P`` whose ``y_j`` vanishes at every eigenpair of ``P``, by an exact identity
    of the split pencil of a zero-reaction node (pair ``(a, b)``, normal rate ``N``): when
    ``A0[b] = -A0[a]``, ``A1[b] = A1[a] = A0[N]`` and ``A1[N] = 0`` entrywise (exact float
    equality), ``y_b = -y_a + 2 mu y_N``, zero when ``a`` and ``N`` are in ``P``."""
    inP = set(int(i) for i in P)
    out = []
    for a, b in pairs:
        for i, j in ((a, b), (b, a)):
            if i not in inP or j in inP:
                continue
            if not (np.array_equal(a0[j], -a0[i]) and np.array_equal(a1[j], a1[i])):
                continue
            for n in inP:
                if n != i and np.array_equal(a1[i], a0[n]) and not np.any(a1[n]):
                    out.append(j)
                    break
    return np.array(sorted(set(out)), dtype=np.int64)


def verify_window(a0: np.ndarray, a1: np.ndarray, P: np.ndarray, mu: float, x: np.ndarray, h: float,
                  cap: float | None = None, pairs=()) -> Window:
    """Prove that support ``P`` has exactly one eigenvalue in ``[mu - h, mu + h]`` and decide its
    signs. ``x``: approximate eigenvector on ``P`` (any scaling); ``cap``: the claim's upper end
    (an enclosure straddling 0 or ``cap`` is ``ill-conditioned``)."""
    s = a0.shape[0]
    p = len(P)
    lo, hi = mu - h, mu + h
    fail = Window(False, lo, hi)
    if p == 0 or not (h > 0) or not np.all(np.isfinite(x)) or len(x) != p:
        return fail
    k = int(np.argmax(np.abs(x)))
    x = x / x[k]
    x[k] = 1.0
    s0, s1 = a0[np.ix_(P, P)], a1[np.ix_(P, P)]
    # bordered Jacobian J(x, mu) = [[A_PP(mu), a1_PP x], [e_k^T, 0]] at the midpoint, R ~ J^-1
    A_mid, rA_mid = pencil_at(s0, s1, mu)
    Jm = np.zeros((p + 1, p + 1))
    Jm[:p, :p] = A_mid
    Jm[:p, p] = s1 @ x
    Jm[p, k] = 1.0
    try:
        R = np.linalg.inv(Jm)
    except np.linalg.LinAlgError:
        return fail
    if not np.all(np.isfinite(R)):
        return fail
    f, rf = mr_mul(A_mid, rA_mid, x[:, None], None)      # F(z~) = A(mu~) x~ (last row exact 0)
    f, rf = f[:, 0], rf[:, 0]
    beta_num = _norm_inf(R)
    a1n = _norm_inf(s1)
    xn = float(np.max(np.abs(x)))
    fn = float(_up(np.max(np.abs(f) + rf), 2))
    # box radius for x from the perturbation bound below (twice it, so Krawczyk has room)
    rx = 4.0 * beta_num * (h * a1n * xn + fn) + 1e-13 * xn
    for _ in range(2):
        # J over the box: A_PP(mu), |mu - mu~| <= h, and a1_PP x, |x - x~| <= rx
        A_box, rA_box = pencil_at(s0, s1, mu, h)
        ax, rax = mr_mul(s1, None, x[:, None], np.full((p, 1), rx))
        JX = np.zeros((p + 1, p + 1))
        rJ = np.zeros((p + 1, p + 1))
        JX[:p, :p], rJ[:p, :p] = A_box, rA_box
        JX[:p, p], rJ[:p, p] = ax[:, 0], rax[:, 0]
        JX[p, k] = 1.0
        C, rC = mr_mul(R, None, JX, rJ)
        G = np.eye(p + 1) - C
        rG = _up(rC + U_ROUND * np.abs(G), 2)
        g = _norm_inf(np.abs(G) + rG)
        Fz = np.append(f, 0.0)
        rFz = np.append(rf, 0.0)
        RF, rRF = mr_mul(R, None, Fz[:, None], rFz[:, None])
        rz = np.append(np.full(p, rx), h)
        Kc = -RF[:, 0]                                  # K - z~ = -R F + G (X - z~)
        Kr = _up(rRF[:, 0] + (np.abs(G) + rG) @ rz, p + 4)
        inside = np.all((np.abs(Kc) + Kr) * (1.0 + 4.0 * U_ROUND) < rz)
        if g < 1.0 and inside:
            break
        rx *= 8.0
    else:
        return fail
    # uniqueness in the window: an eigenpair (x2, mu2), mu2 within h, has x2_k != 0 and, scaled to
    # x2_k = 1, ||x2 - x~|| <= beta (h ||a1|| ||x~|| + ||f||) / (1 - beta h ||a1||) with
    # beta >= ||J(x~, mu~)^-1|| <= ||R|| / (1 - g)  (J(x~, mu~) is in the box, so g bounds it too)
    beta = beta_num / (1.0 - g)
    q = beta * h * a1n * (1.0 + 1e-12)
    if not q < 1.0:
        return fail
    delta = _up(beta * (h * a1n * xn + fn) / (1.0 - q), 8)
    if not delta <= rx:
        return fail
    enc_mu = (mu + Kc[p], Kr[p])
    e_lo = float(enc_mu[0] - enc_mu[1] - U_ROUND * abs(enc_mu[0]) - TINY)
    e_hi = float(enc_mu[0] + enc_mu[1] + U_ROUND * abs(enc_mu[0]) + TINY)
    xc = x + Kc[:p]
    xr = _up(Kr[:p] + U_ROUND * np.abs(xc), 2)
    xmin = float(np.min(xc - xr))
    xmax_up = float(np.max(np.abs(xc) + xr))
    # y off P over the enclosure: A(mu)[Q, P] x, mu in [e_lo, e_hi], x in [xc +- xr]; rows that
    # vanish by an exact identity of the pencil (structural_zeros) satisfy y >= 0 as y = 0
    Q = np.setdiff1d(np.setdiff1d(np.arange(s), P), structural_zeros(a0, a1, P, pairs))
    ymin = np.inf
    ymax_any_neg = False
    if len(Q):
        em = 0.5 * (e_lo + e_hi)
        eh = float(_up(0.5 * (e_hi - e_lo), 2))
        AQ, rAQ = pencil_at(a0[np.ix_(Q, P)], a1[np.ix_(Q, P)], em, eh)
        y, ry = mr_mul(AQ, rAQ, xc[:, None], xr[:, None])
        ylo, yhi = y[:, 0] - ry[:, 0], y[:, 0] + ry[:, 0]
        ymin = float(np.min(ylo))
        ymax_any_neg = bool(np.any(yhi < 0))
    scale_y = float(max(np.max(np.abs(a0)), 1e-300))
    outside = e_hi < 0 or (cap is not None and e_lo > cap)
    inside = e_lo >= 0 and (cap is None or e_hi <= cap)
    if outside or np.any(xc + xr < 0):
        verdict = "not a solution"          # mu outside [0, cap], or x_P surely has both signs (x_k = 1)
    elif np.all(xc - xr > 0):
        if ymax_any_neg:
            verdict = "not a solution"      # a stuck node would need y < 0
        elif ymin > 0 and inside:
            verdict = "solution"
        else:
            verdict = "ill-conditioned"     # a zero stick margin, or the enclosure straddles 0 or cap
    else:
        verdict = "ill-conditioned"         # a component of x_P not resolved from 0
    return Window(True, float(np.nextafter(lo, np.inf)), float(np.nextafter(hi, -np.inf)), e_lo, e_hi, verdict,
                  xmin / max(xmax_up, 1e-300), ymin / scale_y)


# --- the proof log ------------------------------------------------------------------------------

@dataclass
class Node:
    """One node of the proof tree: the family of supports ``P`` with ``F <= P <= U`` (indices into
    the slip nodes; ``F``, the forced set, is empty for "every support in ``U``") and mu in ``[a, b]``.

    ``kind``: ``"cop"`` (sign argument on ``U``, witness ``d``, ``theta``), ``"rlt"`` (products
    of constraints, witness ``M``, ``theta``: :func:`rlt_closes`), ``"farkas"`` (a Farkas
    vector ``w``, :func:`farkas_closes`), ``"bisect"`` (children on ``[a, m]`` and ``[m, b]``),
    ``"branch"`` (on an index ``i`` of ``U \\ F``: ``i`` not in the support, child ``(U \\ {i}, F)``,
    or in it, child ``(U \\ partners(i), F + {i})``), ``"pairsplit"`` (children ``U \\ {a}`` and
    ``U \\ {b}`` for a pair ``(a, b)`` inside ``U``), ``"drop"`` (children ``U \\ {i}`` for every
    ``i`` plus the exact-support leaf of ``U``), ``"leaf"`` (``F = U``, the exact support ``U``:
    ``windows`` each with one verified eigenpair, ``pieces`` of ``[a, b]`` each closed by a Farkas
    vector, and the checker's own nonsingularity cover of the rest), ``"pair"`` (``F`` holds both halves
    of a pair: no allowed support), ``"empty"`` (``U`` empty or ``F`` not inside ``U``: no
    support at all), ``"open"`` (not closed: the proof is unfinished)."""
    id: int
    U: list[int]
    a: float
    b: float
    kind: str
    children: list[int] = field(default_factory=list)
    d: list[float] | None = None
    theta: float | None = None
    windows: list[dict] = field(default_factory=list)     # {"mu", "h", "x"} (x on U)
    F: list[int] = field(default_factory=list)
    w: list[float] | None = None
    pieces: list[dict] = field(default_factory=list)      # leaf: {"a", "b", "w"} Farkas pieces
    M: list[list[float]] | None = None                     # rlt: the multiplier matrix (on U)

    def as_dict(self) -> dict:
        out = {"id": self.id, "U": self.U, "a": self.a, "b": self.b, "kind": self.kind}
        if self.F:
            out["F"] = self.F
        if self.children:
            out["children"] = self.children
        if self.d is not None:
            out["d"] = self.d
            out["theta"] = self.theta
        if self.windows:
            out["windows"] = self.windows
        if self.w is not None:
            out["w"] = self.w
        if self.pieces:
            out["pieces"] = self.pieces
        if self.M is not None:
            out["M"] = self.M
            out["theta"] = self.theta
        return out

    @classmethod
    def from_dict(cls, d: dict, version: int = 2) -> "Node":
        U = [int(i) for i in d["U"]]
        kind = str(d["kind"])
        F = [int(i) for i in d.get("F", [])]
        if version == 1 and kind in ("leaf", "pair"):
            F = list(U)                 # version 1: a leaf is the exact support U
        return cls(int(d["id"]), U, float(d["a"]), float(d["b"]), kind,
                   [int(c) for c in d.get("children", [])], d.get("d"), d.get("theta"),
                   list(d.get("windows", [])), F, d.get("w"), list(d.get("pieces", [])), d.get("M"))


@dataclass
class ProofLog:
    """The witnesses of one pencil's proof: the node tree, its roots (``onset`` and ``all``) and
    the exact power-of-two scale the pencil was divided by (``A / 2^k``: exact, no rounding)."""
    s: int
    cap: float
    scale_exp: int
    pairs: list[tuple[int, int]]
    nodes: list[Node]
    onset_root: int | None           # root of "no solution in [0, onset_below]"
    onset_below: float | None
    all_roots: list[int]             # roots tiling [0, cap] for "every solution in [0, cap] listed"
    onset_witness: dict | None = None   # {"U", "mu", "h", "x"}: a verified solution just above onset_below
    bound_root: int | None = None       # when the onset is not proven: root of "no solution in [0, bound]"
    bound: float | None = None

    def prune(self) -> None:
        """Keep only the nodes reachable from the roots (restarts leave unused ones)."""
        byid = {n.id: n for n in self.nodes}
        keep, stack = set(), [r for r in [self.onset_root, self.bound_root, *self.all_roots] if r is not None]
        while stack:
            j = stack.pop()
            if j in keep or j not in byid:
                continue
            keep.add(j)
            stack.extend(byid[j].children)
        self.nodes = [n for n in self.nodes if n.id in keep]

    def to_json(self) -> dict:
        return {"format": FORMAT, "s": self.s, "cap": self.cap, "scale_exp": self.scale_exp,
                "pairs": [list(p) for p in self.pairs], "onset_root": self.onset_root,
                "onset_below": self.onset_below, "all_roots": self.all_roots,
                "onset_witness": self.onset_witness, "bound_root": self.bound_root, "bound": self.bound,
                "nodes": [n.as_dict() for n in self.nodes]}

    @classmethod
    def from_json(cls, d: dict) -> "ProofLog":
        if d.get("format") not in FORMATS_READ:
            raise ValueError(f"proof log format {d.get('format')!r}, expected one of {FORMATS_READ}")
        version = FORMATS_READ.index(d["format"]) + 1
        return cls(int(d["s"]), float(d["cap"]), int(d["scale_exp"]), [tuple(p) for p in d["pairs"]],
                   [Node.from_dict(n, version) for n in d["nodes"]], d.get("onset_root"), d.get("onset_below"),
                   [int(r) for r in d.get("all_roots", [])], d.get("onset_witness"), d.get("bound_root"),
                   d.get("bound"))

    def dumps(self) -> str:
        return json.dumps(self.to_json(), separators=(",", ":"))


@dataclass
class CheckReport:
    """What :func:`check_log` accepted: the onset claim, the complete-list claim, the solutions."""
    onset_ok: bool
    all_ok: bool
    onset: tuple[float, float] | None                 # proven enclosure of the onset (None: none below cap)
    lower_bound: float                                # proven: no solution in [0, lower_bound]
    solutions: list[tuple[list[int], float, float]]   # (support, enclosure lo, hi) of verified solutions
    ill_conditioned: int
    errors: list[str]


def scaled(A0: np.ndarray, A1: np.ndarray, scale_exp: int) -> tuple[np.ndarray, np.ndarray]:
    """The pencil divided by ``2^scale_exp`` (exact)."""
    return np.ldexp(np.asarray(A0, dtype=float), -scale_exp), np.ldexp(np.asarray(A1, dtype=float), -scale_exp)


def _allowed(U: list[int], pairs) -> bool:
    su = set(U)
    return not any(a in su and b in su for a, b in pairs)


def check_node(a0, a1, node: Node, pairs, cap: float) -> tuple[bool, list, int, str]:
    """Re-run one node's own test. Returns ``(ok, solutions, ill, why)``."""
    U = np.asarray(node.U, dtype=np.int64)
    if node.kind == "cop":
        ok = node.d is not None and closes_subsets(a0, a1, U, node.a, node.b, np.asarray(node.d, float),
                                                   float(node.theta))
        return ok, [], 0, "" if ok else "sign argument fails"
    if node.kind == "rlt":
        ok = node.M is not None and rlt_closes(a0, a1, U, node.F, node.a, node.b, node.M, float(node.theta))
        return ok, [], 0, "" if ok else "product argument fails"
    if node.kind == "farkas":
        ok = node.w is not None and farkas_closes(a0, a1, U, node.F, node.a, node.b, node.w)
        return ok, [], 0, "" if ok else "Farkas vector fails"
    if node.kind == "empty":
        ok = not node.U or not set(node.F) <= set(node.U)
        return ok, [], 0, "" if ok else "the family is not empty"
    if node.kind == "pair":
        ok = not _allowed(node.F, pairs)
        return ok, [], 0, "" if ok else "F holds no pair"
    if node.kind == "leaf":
        if sorted(set(node.F)) != sorted(set(node.U)):
            return False, [], 0, "a leaf proves its exact support only (F must equal U)"
        if not _allowed(node.U, pairs):
            return True, [], 0, ""
        pieces, sols, ill = [], [], 0
        for w in node.windows:
            res = verify_window(a0, a1, U, float(w["mu"]), np.asarray(w["x"], float), float(w["h"]), cap, pairs)
            if not res.ok:
                return False, [], 0, f"window at mu = {w['mu']} not verified"
            pieces.append((res.mu_lo, res.mu_hi))
            if res.verdict == "solution":
                sols.append((list(node.U), res.enc_lo, res.enc_hi))
            elif res.verdict != "not a solution":
                ill += 1
                sols.append((list(node.U), res.enc_lo, res.enc_hi, res.verdict))
        for pc in node.pieces:
            lo, hi = float(pc["a"]), float(pc["b"])
            if not farkas_closes(a0, a1, U, node.U, lo, hi, pc["w"]):
                return False, [], 0, f"Farkas piece [{lo}, {hi}] fails"
        gaps = pieces + [(float(pc["a"]), float(pc["b"])) for pc in node.pieces]
        if not cover_nonsingular(a0, a1, U, node.a, node.b, gaps):
            return False, [], 0, "the rest of [a, b] not proven free of eigenvalues"
        return True, sols, ill, ""
    return False, [], 0, f"node kind {node.kind!r} proves nothing by itself"


def cover_nonsingular(a0, a1, U: np.ndarray, a: float, b: float, windows: list[tuple[float, float]],
                      rounds: int = 60, deadline: float | None = None) -> bool:
    """``[a, b]`` minus the ``windows`` is covered by intervals on which ``A_UU(mu)`` is proven
    nonsingular (batched tests, failed pieces halved, at most ``rounds`` times)."""
    todo = []
    reach = a
    for lo, hi in sorted(windows):
        if lo > reach:
            todo.append((reach, min(lo, b)))
        reach = max(reach, hi)
        if reach >= b:
            break
    if reach < b:
        todo.append((reach, b))
    for _ in range(rounds):
        if not todo:
            return True
        if deadline is not None and time.perf_counter() > deadline:
            return False
        lo = np.array([g[0] for g in todo])
        hi = np.array([g[1] for g in todo])
        ok = nonsingular_batch(a0, a1, U, lo, hi)
        mid = 0.5 * (lo + hi)
        bad = ~ok
        if np.any(bad & ~((lo < mid) & (mid < hi) & (hi - lo > 1e-15 * np.maximum(1.0, np.abs(hi))))):
            return False
        todo = [(float(x), float(m)) for x, m in zip(lo[bad], mid[bad])] + \
               [(float(m), float(y)) for m, y in zip(mid[bad], hi[bad])]
    return not todo


def _covers(pieces: list[tuple[float, float]], a: float, b: float) -> bool:
    """The union of the closed intervals ``pieces`` contains ``[a, b]``."""
    reach = a
    for lo, hi in sorted(pieces):
        if lo > reach:
            return False
        reach = max(reach, hi)
        if reach >= b:
            return True
    return reach >= b


def check_log(A0: np.ndarray, A1: np.ndarray, log: ProofLog) -> CheckReport:
    """Re-verify a proof log from the pencil alone (:func:`_check_log`, with one BLAS thread:
    the tests are stacks of small matrices)."""
    from app.linalg import one_blas_thread
    with one_blas_thread():
        return _check_log(A0, A1, log)


def _check_log(A0: np.ndarray, A1: np.ndarray, log: ProofLog) -> CheckReport:
    """Re-verify a proof log from the pencil alone.

    Every node reachable from the roots is checked: its own test (``cop``, ``leaf``, ``pair``),
    or, for ``bisect`` and ``drop``, that its children exist and cover it (same ``U`` on
    ``[a, m]`` and ``[m, b]``; ``U \\ {i}`` for every ``i`` on an interval containing ``[a, b]``,
    plus the exact-support leaf of ``U``). A reachable ``open`` node fails the claim."""
    errors: list[str] = []
    A0 = np.asarray(A0, dtype=float)
    A1 = np.asarray(A1, dtype=float)
    if A0.shape != (log.s, log.s) or A1.shape != (log.s, log.s):
        return CheckReport(False, False, None, 0.0, [], 0, [f"pencil is {A0.shape}, log is for s = {log.s}"])
    a0, a1 = scaled(A0, A1, log.scale_exp)
    pairs = [tuple(int(i) for i in p) for p in log.pairs]
    byid = {n.id: n for n in log.nodes}
    memo: dict[int, tuple[bool, list, int]] = {}

    def visit(i: int) -> tuple[bool, list, int]:
        order = []                         # post-order without recursion (trees can be deep; nodes shared)
        stack = [(i, False)]
        placed = set()
        while stack:
            j, expanded = stack.pop()
            if j in memo or (not expanded and j in placed):
                continue
            if expanded:
                order.append(j)
                continue
            placed.add(j)
            stack.append((j, True))
            n = byid.get(j)
            if n is not None:
                stack.extend((c, False) for c in n.children if c not in memo and c not in placed)
        for j in order:
            n = byid.get(j)
            if n is None:
                memo[j] = (False, [], 0)
                errors.append(f"node {j} missing")
                continue
            if n.kind in ("bisect", "branch", "drop", "pairsplit"):
                ok, why = _children_cover(n, byid, pairs)
                sols, ill = [], 0
                for c in n.children:
                    cok, cs, ci = memo.get(c, (False, [], 0))
                    ok = ok and cok
                    sols += cs
                    ill += ci
                if why:
                    errors.append(f"node {j}: {why}")
                memo[j] = (ok, sols, ill)
            elif n.kind == "open":
                memo[j] = (False, [], 0)
                errors.append(f"node {j} is open (unfinished)")
            else:
                ok, sols, ill, why = check_node(a0, a1, n, pairs, log.cap)
                if not ok:
                    errors.append(f"node {j}: {why}")
                memo[j] = (ok, sols, ill)
        return memo[i]

    onset_ok, onset = False, None
    if log.onset_root is not None and log.onset_below is not None:
        n = byid.get(log.onset_root)
        ok, sols, ill = visit(log.onset_root)
        full = n is not None and sorted(n.U) == list(range(log.s)) and not n.F and n.a <= 0.0 and n.b >= log.onset_below
        if not full:
            errors.append("onset root does not cover every support on [0, onset_below]")
        # the tree must list nothing (and nothing undecided) at or below onset_below
        empty = ill == 0 and not any(sl[1] <= log.onset_below for sl in sols)
        if ok and full and empty:
            if log.onset_below >= log.cap:
                onset_ok = True
            elif log.onset_witness is not None:
                w = log.onset_witness
                U = np.asarray(sorted(int(i) for i in w["U"]), dtype=np.int64)
                res = verify_window(a0, a1, U, float(w["mu"]), np.asarray(w["x"], float), float(w["h"]), log.cap,
                                    pairs)
                if res.ok and res.verdict == "solution" and _allowed(list(U), pairs) \
                        and res.enc_lo > log.onset_below:
                    onset_ok, onset = True, (float(log.onset_below), float(res.enc_hi))
                else:
                    errors.append("onset witness is not a verified solution above onset_below")
            else:
                errors.append("no onset witness")
    lower_bound = 0.0
    if onset_ok:
        lower_bound = float(log.onset_below)
    elif log.bound_root is not None and log.bound is not None:
        n = byid.get(log.bound_root)
        ok, sols, ill = visit(log.bound_root)
        if ok and ill == 0 and not sols and n is not None and sorted(n.U) == list(range(log.s)) and not n.F and n.a <= 0.0 \
                and n.b >= log.bound:
            lower_bound = float(log.bound)
        else:
            errors.append("bound tree not verified")
    all_ok = False
    found: dict[tuple, tuple] = {}
    ill_all = 0
    if log.all_roots:
        pieces = []
        ok_all = True
        for r in log.all_roots:
            n = byid.get(r)
            ok, sols, ill = visit(r)
            if n is None or sorted(n.U) != list(range(log.s)) or n.F:
                ok = False
                errors.append(f"root {r} does not hold every support")
            else:
                pieces.append((n.a, n.b))
            ok_all = ok_all and ok
            ill_all += ill
            for sl in sols:
                found[(tuple(sl[0]), round(sl[1], 12))] = sl
        all_ok = ok_all and _covers(pieces, 0.0, log.cap) and ill_all == 0
    sols = [sl for sl in found.values() if len(sl) == 3]
    return CheckReport(onset_ok, all_ok, onset, lower_bound, sorted(sols, key=lambda t: t[1]), ill_all, errors)


def _contains(k: Node, U, F, a: float, b: float) -> bool:
    """Child ``k``'s family holds every support ``P`` with ``F <= P <= U`` on ``[a, b]``: a larger
    ``U``, a smaller ``F`` and a longer interval only make its claim stronger."""
    return set(k.U) >= set(U) and set(k.F) <= set(F) and k.a <= a and k.b >= b


def _partners(i: int, pairs) -> set[int]:
    return {b for a, b in pairs if a == i} | {a for a, b in pairs if b == i}


def _children_cover(n: Node, byid: dict, pairs) -> tuple[bool, str]:
    """The children of a split node hold, together, every allowed support of its family."""
    kids = [byid.get(c) for c in n.children]
    if any(k is None for k in kids):
        return False, "a child is missing"
    U, F = set(n.U), set(n.F)
    if n.kind == "bisect":
        if len(kids) != 2:
            return False, "bisect needs two children"
        k1, k2 = kids
        ok = _contains(k1, U, F, k1.a, k1.b) and _contains(k2, U, F, k2.a, k2.b) and k1.a <= n.a \
            and k2.b >= n.b and k1.b >= k2.a
        return ok, "" if ok else "bisection children do not cover the node"
    if n.kind == "branch":
        # index i of U \ F: either i is not in the support (U \ {i}, F), or it is, and then no
        # partner of i is (U \ partners(i), F + {i})
        if len(kids) != 2:
            return False, "branch needs two children"
        k0, k1 = kids
        for i in U - F:
            if _contains(k0, U - {i}, F, n.a, n.b) and _contains(k1, U - _partners(i, pairs), F | {i}, n.a, n.b):
                return True, ""
        return False, "branch children do not split the family on an index"
    if n.kind == "pairsplit":
        # (a, b) a pair inside U: the allowed supports in U lie in U \ {a} or in U \ {b}
        if len(kids) != 2:
            return False, "pair split needs two children"
        for a, b in pairs:
            if a in U and b in U and _contains(kids[0], U - {a}, F, n.a, n.b) \
                    and _contains(kids[1], U - {b}, F, n.a, n.b):
                return True, ""
        return False, "pair split children are not U minus either half of a pair"
    if n.kind == "drop":
        # every U \ {i} on an interval containing [a, b], and the exact-support leaf of U
        need = set(U) if len(U) > 1 else set()     # U \ {i} is empty for |U| = 1: nothing to cover
        leaf = False
        for k in kids:
            if not (k.a <= n.a and k.b >= n.b):
                continue
            if set(k.U) == U and set(k.F) == U and k.kind in ("leaf", "pair"):
                leaf = True
                continue
            for i in list(need):
                if _contains(k, U - {i}, F, n.a, n.b):
                    need.discard(i)
        ok = leaf and not need
        return ok, "" if ok else "drop children do not cover the node"
    return False, f"node kind {n.kind!r} has no children rule"
