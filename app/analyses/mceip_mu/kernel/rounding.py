"""Rigorous floating-point bounds: the rounding-error model the proofs of MCEIP-mu rest on.

Every test of the trusted kernel (:mod:`.closing`, :mod:`.windows`, :mod:`.checker`) is built
from these bounds; none of these modules imports the prover.

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
"""
from __future__ import annotations

import numpy as np

U_ROUND = 2.0 ** -53          # unit roundoff of IEEE double
ETA = 2.0 ** -1074            # smallest positive subnormal
TINY = 2.0 ** -1000           # absolute slack for underflow in a product sum (>> n * ETA for n < 2^70)


def gamma(n: int) -> float:
    """Higham's ``gamma_n = n u / (1 - n u)``."""
    nu = n * U_ROUND
    return nu / (1.0 - nu)


def rounded_up(x, n: int):
    """A computed nonnegative bound inflated to cover its own rounding (``n`` operations deep)."""
    return x * (1.0 + 4.0 * gamma(n + 4)) + TINY


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
    return C, rounded_up(rad, n + 4)


def pencil_at(a0: np.ndarray, a1: np.ndarray, mu: float, h: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """``A(mu')`` for every ``|mu' - mu| <= h`` as midpoint and radius (``fl(a0 + mu a1)``)."""
    A = a0 + mu * a1
    rad = gamma(2) * (np.abs(a0) + abs(mu) * np.abs(a1))
    if h > 0:
        rad = rad + h * np.abs(a1)
    return A, rounded_up(rad, 4)


def norm_inf_up(M: np.ndarray) -> float:
    """An upper bound of the infinity norm of ``M`` (of each matrix of a stack)."""
    return float(rounded_up(np.max(np.sum(np.abs(M), axis=-1), initial=0.0), M.shape[-1]))


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
    Hs = H.copy()
    Hs[np.diag_indices(n)] -= shift
    try:
        L = np.linalg.cholesky(Hs)
    except np.linalg.LinAlgError:
        return False
    if not np.all(np.isfinite(L)):
        return False
    frob2 = float(rounded_up(np.sum(L * L), n * n))
    bound = radius + g * frob2 + U_ROUND * float(np.max(np.abs(np.diag(Hs)))) + 8.0 * n * (n + 2) * TINY
    return shift > rounded_up(bound, 8)


def safe_inv(A: np.ndarray) -> np.ndarray:
    """``A^-1``, or NaNs where LAPACK finds ``A`` singular (the caller's test then fails)."""
    try:
        return np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return np.full_like(A, np.nan)
