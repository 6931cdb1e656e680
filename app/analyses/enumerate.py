"""Exhaustive enumeration of an MCEIP (end of the paper's section 3, eqs. (24)-(26)).

Each of the ``2^s - 1`` non-empty stick/slip patterns of the ``s`` slip nodes gives a linear
generalised eigenproblem on the free DOFs plus the slipping ``x_Ts`` (25); its real eigenpairs
with ``t >= 0``, ``x_slip > 0`` and ``y_stick >= 0`` (26) are the solutions with that pattern.
Exact and complete, exponential in ``s``: the cross-check for small problems, never the
production path.
"""
from __future__ import annotations

import itertools

import numpy as np
import scipy.linalg


class TooManySlipNodes(Exception):
    pass


def enumerate_mceip(A0: np.ndarray, A1: np.ndarray, comp: np.ndarray, max_slip: int,
                    tol: float = 1e-9, pairs: list[tuple[int, int]] | None = None) -> list[dict]:
    """All solutions of ``(A0 + t A1) x = y, y_f = 0, 0 <= x_c ⊥ y_c >= 0, t >= 0`` (dense).

    Returns dicts with ``value``, ``x_Ts`` (sum 1), ``pattern``, sorted by value. ``tol`` is
    relative to the largest diagonal entry of ``A0`` (and to ``max x`` for the sign checks).
    """
    comp = np.asarray(comp)
    s = len(comp)
    if s > max_slip:
        raise TooManySlipNodes(f"{s} slip nodes: enumeration of 2^{s} patterns refused "
                               f"(settings.enumerate_max_slip = {max_slip})")
    n = A0.shape[0]
    scale = float(np.max(np.abs(np.diag(A0)))) or 1.0
    free = np.setdiff1d(np.arange(n), comp)
    out: list[dict] = []
    cpos = {int(c): k for k, c in enumerate(comp)}
    cpairs = [(cpos[a], cpos[b]) for a, b in (pairs or [])]
    for k in range(1, s + 1):
        for P in itertools.combinations(range(s), k):
            if any(a in P and b in P for a, b in cpairs):
                continue   # both directions of one split tangential rate: degenerate (a = b)
            P = np.array(P)
            stick = np.setdiff1d(np.arange(s), P)
            R = np.concatenate([free, comp[P]])
            a0, a1 = A0[np.ix_(R, R)], A1[np.ix_(R, R)]
            w, V = scipy.linalg.eig(a0, -a1)
            for j, t in enumerate(w):
                if not np.isfinite(t) or abs(t.imag) > 1e-9 * max(1.0, abs(t)):
                    continue
                t = t.real
                if t < -tol:
                    continue
                v = V[:, j]
                v = v.real if np.max(np.abs(v.imag)) <= 1e-9 * np.max(np.abs(v)) else None
                if v is None:
                    continue
                xp = v[len(free):]
                if np.sum(xp) < 0:
                    v, xp = -v, -xp
                if np.min(xp) <= tol * np.max(np.abs(xp)) * 1e3:
                    continue
                x = np.zeros(n)
                x[R] = v
                x /= np.sum(xp)
                y = (A0 + t * A1) @ x
                if len(stick) and np.min(y[comp[stick]]) < -1e3 * tol * scale:
                    continue
                xc = x[comp]
                out.append({"value": float(max(t, 0.0)), "x_Ts": [float(v) for v in xc],
                            "pattern": ["slip" if i in set(P.tolist()) else "stick" for i in range(s)],
                            "residual": float(np.max(np.abs(np.delete(y, comp)), initial=0.0) / scale)})
    return sorted(out, key=lambda d: (d["value"], d["pattern"]))
