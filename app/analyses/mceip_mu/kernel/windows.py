"""Verified isolated eigenpairs of a support's pattern problem (paper eqs. (25)-(26)).

* **Isolated eigenpairs** (:func:`verify_window`): Krawczyk's operator for the bordered system
  ``F(x, mu) = [A_PP(mu) x ; x_k - 1]`` on a box ``X = [x~ +- r] x [mu~ +- h]``: ``K(X)`` inside
  the interior of ``X`` proves a unique zero in ``X`` (Krawczyk 1969; Rump, "Verification methods",
  Acta Numerica 2010, Theorem 8.1), enclosed by ``K(X)``. A perturbation bound then shows that
  every eigenpair of the support with mu in the window lies in ``X``, so the window holds
  exactly one eigenvalue of ``P``; the signs of ``x_P`` and of ``y`` off ``P`` over the enclosure
  decide whether it is a solution, not one, or cannot be decided in double precision
  (``ill_conditioned``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.analyses.mceip_mu.kernel.rounding import TINY, U_ROUND, mr_mul, norm_inf_up, pencil_at, rounded_up


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
    p = len(P)
    lo, hi = mu - h, mu + h
    fail = Window(False, lo, hi)
    if p == 0 or not (h > 0) or not np.all(np.isfinite(x)) or len(x) != p:
        return fail
    k = int(np.argmax(np.abs(x)))
    x = x / x[k]
    x[k] = 1.0
    box = _krawczyk(a0[np.ix_(P, P)], a1[np.ix_(P, P)], mu, x, k, h)
    if box is None:
        return fail
    Kc, Kr = box
    enc_mu = (mu + Kc[p], Kr[p])
    e_lo = float(enc_mu[0] - enc_mu[1] - U_ROUND * abs(enc_mu[0]) - TINY)
    e_hi = float(enc_mu[0] + enc_mu[1] + U_ROUND * abs(enc_mu[0]) + TINY)
    xc = x + Kc[:p]
    xr = rounded_up(Kr[:p] + U_ROUND * np.abs(xc), 2)
    verdict, min_x, min_y = _signs(a0, a1, P, pairs, cap, e_lo, e_hi, xc, xr)
    return Window(True, float(np.nextafter(lo, np.inf)), float(np.nextafter(hi, -np.inf)), e_lo, e_hi, verdict,
                  min_x, min_y)


def _krawczyk(s0: np.ndarray, s1: np.ndarray, mu: float, x: np.ndarray, k: int, h: float):
    """Krawczyk's test for ``[A_PP(mu) x ; x_k - 1] = 0`` on the box ``[x +- rx] x [mu +- h]``, and
    the uniqueness of the eigenpair in the window. Returns ``(Kc, Kr)`` (``K(X) - z~`` as centre
    and radius; ``z = (x, mu)``) or ``None`` when not proven."""
    p = len(x)
    # bordered Jacobian J(x, mu) = [[A_PP(mu), a1_PP x], [e_k^T, 0]] at the midpoint, R ~ J^-1
    A_mid, rA_mid = pencil_at(s0, s1, mu)
    Jm = np.zeros((p + 1, p + 1))
    Jm[:p, :p] = A_mid
    Jm[:p, p] = s1 @ x
    Jm[p, k] = 1.0
    try:
        R = np.linalg.inv(Jm)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(R)):
        return None
    f, rf = mr_mul(A_mid, rA_mid, x[:, None], None)      # F(z~) = A(mu~) x~ (last row exact 0)
    f, rf = f[:, 0], rf[:, 0]
    beta_num = norm_inf_up(R)
    a1n = norm_inf_up(s1)
    xn = float(np.max(np.abs(x)))
    fn = float(rounded_up(np.max(np.abs(f) + rf), 2))
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
        rG = rounded_up(rC + U_ROUND * np.abs(G), 2)
        g = norm_inf_up(np.abs(G) + rG)
        Fz = np.append(f, 0.0)
        rFz = np.append(rf, 0.0)
        RF, rRF = mr_mul(R, None, Fz[:, None], rFz[:, None])
        rz = np.append(np.full(p, rx), h)
        Kc = -RF[:, 0]                                  # K - z~ = -R F + G (X - z~)
        Kr = rounded_up(rRF[:, 0] + (np.abs(G) + rG) @ rz, p + 4)
        inside = np.all((np.abs(Kc) + Kr) * (1.0 + 4.0 * U_ROUND) < rz)
        if g < 1.0 and inside:
            break
        rx *= 8.0
    else:
        return None
    # uniqueness in the window: an eigenpair (x2, mu2), mu2 within h, has x2_k != 0 and, scaled to
    # x2_k = 1, ||x2 - x~|| <= beta (h ||a1|| ||x~|| + ||f||) / (1 - beta h ||a1||) with
    # beta >= ||J(x~, mu~)^-1|| <= ||R|| / (1 - g)  (J(x~, mu~) is in the box, so g bounds it too)
    beta = beta_num / (1.0 - g)
    q = beta * h * a1n * (1.0 + 1e-12)
    if not q < 1.0:
        return None
    delta = rounded_up(beta * (h * a1n * xn + fn) / (1.0 - q), 8)
    if not delta <= rx:
        return None
    return Kc, Kr


def _signs(a0, a1, P, pairs, cap, e_lo: float, e_hi: float, xc: np.ndarray, xr: np.ndarray):
    """The verdict on the enclosed eigenpair (mu in ``[e_lo, e_hi]``, x in ``[xc +- xr]``) and the
    proven margins ``min x_P / max x_P`` and ``min y`` off ``P`` (scaled by ``max |A0|``)."""
    s = a0.shape[0]
    xmin = float(np.min(xc - xr))
    xmax_up = float(np.max(np.abs(xc) + xr))
    # y off P over the enclosure: A(mu)[Q, P] x, mu in [e_lo, e_hi], x in [xc +- xr]; rows that
    # vanish by an exact identity of the pencil (structural_zeros) satisfy y >= 0 as y = 0
    Q = np.setdiff1d(np.setdiff1d(np.arange(s), P), structural_zeros(a0, a1, P, pairs))
    ymin = np.inf
    ymax_any_neg = False
    if len(Q):
        em = 0.5 * (e_lo + e_hi)
        eh = float(rounded_up(0.5 * (e_hi - e_lo), 2))
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
    return verdict, xmin / max(xmax_up, 1e-300), ymin / scale_y
