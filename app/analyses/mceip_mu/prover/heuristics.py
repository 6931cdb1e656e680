"""Floating-point guesses that guide the MCEIP-mu prover: never part of a proof.

The diagonal scalings tried by the sign argument (:func:`perron_scaling`: ``z / x`` of the
eigenvalue with the smallest real part) and the Newton polish of an eigenpair before its
Krawczyk window (:func:`polish`). A bad guess only costs a test that then fails.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.linalg


def perron_scaling(A: np.ndarray) -> np.ndarray | None:
    """``z / x`` (geometric mean 1) for the eigenvalue of ``A`` with the smallest real part, when
    it is real and both eigenvectors are positive (full eigendecomposition)."""
    try:
        w, vl, vr = scipy.linalg.eig(A, left=True, right=True)
    except (np.linalg.LinAlgError, ValueError):
        return None
    if not np.all(np.isfinite(w)):
        return None
    j = int(np.argmin(w.real))
    if abs(w[j].imag) > 1e-12 * max(1.0, abs(w[j].real)):
        return None
    return _ratio(vr[:, j].real, vl[:, j].real)


def perron_scaling_large(A: np.ndarray, steps: int = 30) -> np.ndarray | None:
    """:func:`perron_scaling` by inverse iteration (one LU factorisation, ``steps`` solves with
    ``A`` and with ``A^T``): the eigenvalue nearest 0, which below an onset is the one with the
    smallest real part; a guess that fails only costs the sign argument one candidate."""
    try:
        lu = scipy.linalg.lu_factor(A, check_finite=False)
    except (np.linalg.LinAlgError, ValueError):
        return None
    n = A.shape[0]
    x = np.ones(n) / math.sqrt(n)
    z = x.copy()
    with np.errstate(all="ignore"):
        for _ in range(steps):
            x = scipy.linalg.lu_solve(lu, x, check_finite=False)
            z = scipy.linalg.lu_solve(lu, z, trans=1, check_finite=False)
            nx, nz = np.linalg.norm(x), np.linalg.norm(z)
            if not (np.isfinite(nx) and np.isfinite(nz) and nx > 0 and nz > 0):
                return None
            x, z = x / nx, z / nz
        lam = float(x @ (A @ x))
        if np.linalg.norm(A @ x - lam * x) > 1e-6 * max(np.linalg.norm(A, 1), 1e-300):
            return None          # not converged: no candidate
    return _ratio(x, z)


def _ratio(x: np.ndarray, z: np.ndarray) -> np.ndarray | None:
    x = x * np.sign(np.sum(x))
    z = z * np.sign(np.sum(z))
    if not (np.all(x > 0) and np.all(z > 0)):
        return None
    d = z / x
    d = d / math.exp(float(np.mean(np.log(d))))
    return d if np.all(np.isfinite(d)) and np.max(d) / np.min(d) < 1e12 else None


def polish(s0: np.ndarray, s1: np.ndarray, mu: float, x: np.ndarray, steps: int = 2) -> tuple[float, np.ndarray]:
    """Newton steps on ``[A(mu) x ; x_k - 1] = 0`` from an eigenpair of LAPACK (tighter windows)."""
    p = len(x)
    try:
        _, _, Vh = np.linalg.svd(s0 + mu * s1)
        x = Vh[-1]
    except np.linalg.LinAlgError:
        pass
    k = int(np.argmax(np.abs(x)))
    x = x / x[k]
    for _ in range(steps):
        J = np.zeros((p + 1, p + 1))
        J[:p, :p] = s0 + mu * s1
        J[:p, p] = s1 @ x
        J[p, k] = 1.0
        F = np.append((s0 + mu * s1) @ x, x[k] - 1.0)
        try:
            dz = np.linalg.solve(J, -F)
        except np.linalg.LinAlgError:
            break
        if not np.all(np.isfinite(dz)):
            break
        x, mu = x + dz[:p], mu + float(dz[p])
    return mu, x
