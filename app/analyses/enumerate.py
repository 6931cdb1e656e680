"""Exhaustive enumeration of an MCEIP (end of the paper's section 3, eqs. (24)-(26)).

Each of the ``2^s - 1`` non-empty stick/slip patterns (supports) ``P`` of the ``s``
complementarity unknowns gives a linear eigenproblem on the free DOFs plus ``x_P`` (25),

    (A0 + t A1)[R, R] x_R = 0,   R = free + P,

and its real eigenpairs with ``t >= 0``, ``x_P > 0`` and ``y_stick >= 0`` (26) are the solutions
with that pattern. Exact and complete, exponential in ``s``: the cross-check for small
problems, and the fastest certificate below a crossover size (see app/analyses/mceip_mu/state.py).

The work is batched: all supports of one size ``k`` are stacked into ``(m, n_R, n_R)`` arrays
and go through LAPACK together (``numpy.linalg.solve`` and ``eigvals`` on the stack). With
``A0[R, R]`` invertible the pencil's eigenvalues are ``t = -1/nu`` for the eigenvalues ``nu`` of
``A0[R, R]^{-1} A1[R, R]``; a support whose ``A0[R, R]`` is numerically singular falls back to
the generalised QZ solver (scipy.linalg.eig). Null vectors (through a batched SVD) are only
computed for the candidates with an admissible real eigenvalue, and the sign checks (26) use
tolerances relative to the pencil's scale.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from app.linalg import one_blas_thread


class TooManySlipNodes(Exception):
    """An enumeration refused as too large (more slip nodes than ``settings.enumerate_max_slip``,
    or a full-size pencil too large to be dense); the message says which, and the caller records
    the problem as not enumerated."""

    pass


#: Relative size below which a margin (min x_P / max x_P, min y_stick / scale) is not resolved by
#: double precision on these pencils: such solutions are reported with ``ill_conditioned: true``.
RESOLVE_TOL = 1e-9
#: Relative residual of the null vector above which a real eigenvalue is rejected.
RESIDUAL_TOL = 1e-8
#: Elements (m * n_R^2) per LAPACK batch (bounds memory at s = 20: about 40 MB per batch).
BATCH_ELEMENTS = 2_000_000


@dataclass
class PatternSolution:
    """One exact solution of (25)-(26): the eigenpair of one support with its sign margins."""

    value: float
    x: np.ndarray               # restricted-space vector (free + all complementarity), x_c sums to 1
    support: np.ndarray         # bool over the complementarity unknowns: True = slip (x > 0)
    residual: float             # ||(A0 + t A1)[R, R] x_R|| / (scale ||x_R||)
    min_x: float                # min x_P / max x_P  (> 0)
    min_y: float                # min y_stick / scale (>= -RESOLVE_TOL); +inf if no stick node
    ill_conditioned: bool       # a margin below RESOLVE_TOL: double precision cannot resolve it
    complementarity: float = 0.0  # max |x_i y_i| / scale over the complementarity unknowns
    min_y_all: float = 0.0        # min y_c / scale over all complementarity unknowns (evidence)

    def as_dict(self, comp: np.ndarray) -> dict:
        """The solution as reported in the results: value, ``x_Ts`` (the complementarity part of ``x``,
        positions ``comp``), the slip/stick pattern, residual, complementarity, the sign margins of
        (26) relative to the pencil's scale and ``ill_conditioned``."""
        xc = self.x[comp]
        return {"value": float(self.value), "x_Ts": [float(v) for v in xc],
                "pattern": ["slip" if b else "stick" for b in self.support],
                "residual": float(self.residual), "complementarity": float(self.complementarity),
                "min_x_Ts": float(self.min_x),
                "min_y_Ts": float(self.min_y_all),
                "margin_y_stick": float(self.min_y) if np.isfinite(self.min_y) else None,
                "ill_conditioned": bool(self.ill_conditioned)}


def pencil_scale(A0: np.ndarray) -> float:
    """The unit-free scale tolerances are relative to: the largest diagonal entry of ``A0``."""
    sc = float(np.max(np.abs(np.diag(A0)), initial=0.0))
    return sc if sc > 0 else max(float(np.max(np.abs(A0), initial=0.0)), 1e-300)


def supports_of_size(s: int, k: int, pairs: list[tuple[int, int]] | None = None) -> np.ndarray:
    """All supports of size ``k`` (rows of indices into the ``s`` complementarity unknowns),
    without those that hold both halves ``(a, b)`` of a split tangential rate (degenerate)."""
    P = np.array(list(itertools.combinations(range(s), k)), dtype=np.int64).reshape(-1, k)
    if pairs and len(P):
        mask = np.zeros((len(P), s), dtype=bool)
        mask[np.arange(len(P))[:, None], P] = True
        bad = np.zeros(len(P), dtype=bool)
        for a, b in pairs:
            bad |= mask[:, a] & mask[:, b]
        P = P[~bad]
    return P


def _batch_eigenvalues(B0: np.ndarray, B1: np.ndarray) -> np.ndarray:
    """Eigenvalues ``t`` of the stacked pencils ``(B0 + t B1) x = 0`` (shape (m, n)); infinite
    eigenvalues are ``inf`` (complex where they are complex)."""
    m, n, _ = B0.shape
    out = np.full((m, n), np.inf, dtype=complex)
    # Conditioning of B0 through its 1-norm estimate: numerically singular ones go to QZ.
    try:
        C = np.linalg.solve(B0, B1)
        ok = np.all(np.isfinite(C), axis=(1, 2))
        ok &= np.linalg.norm(C, 1, axis=(1, 2)) < 1e12 * np.maximum(np.linalg.norm(B1, 1, axis=(1, 2)), 1e-300) \
            / np.maximum(np.linalg.norm(B0, 1, axis=(1, 2)), 1e-300)
    except np.linalg.LinAlgError:
        C, ok = None, np.zeros(m, dtype=bool)
    if C is not None and ok.any():
        nu = np.linalg.eigvals(C[ok])
        # eigenvalues of C at rounding level are infinite eigenvalues t (A1 rank deficient)
        zero = np.abs(nu) <= 1e-12 * np.linalg.norm(C[ok], 1, axis=(1, 2))[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(zero, np.inf, -1.0 / np.where(zero, 1.0, nu))
        out[ok] = t
    for j in np.flatnonzero(~ok):
        w = scipy.linalg.eig(B0[j], -B1[j], right=False)
        out[j] = np.where(np.isfinite(w), w, np.inf)
    return out


def enumerate_patterns(A0: np.ndarray, A1: np.ndarray, comp: np.ndarray, t_min: float = 0.0,
                       t_max: float = np.inf, pairs: list[tuple[int, int]] | None = None,
                       supports: np.ndarray | None = None) -> list[PatternSolution]:
    """Every solution of (25)-(26) with ``t_min <= t <= t_max`` over all supports (or the given
    ``supports``: a bool array (m, s)). Batched over supports of equal size. ``pairs`` are
    positions in ``comp`` of split tangential rates (zero-reaction nodes)."""
    comp = np.asarray(comp, dtype=np.int64)
    n, s = A0.shape[0], len(comp)
    free = np.setdiff1d(np.arange(n), comp)
    nf = len(free)
    scale = pencil_scale(A0)
    a0, a1 = A0 / scale, A1 / scale
    out: list[PatternSolution] = []
    if supports is None:
        groups = ((k, supports_of_size(s, k, pairs)) for k in range(1, s + 1))
    else:
        supports = np.asarray(supports, dtype=bool)
        sizes = supports.sum(axis=1)
        groups = ((k, np.array([np.flatnonzero(r) for r in supports[sizes == k]]).reshape(-1, k))
                  for k in sorted(set(sizes.tolist())) if k > 0)
    for k, P in groups:
        if not len(P):
            continue
        nr = nf + k
        step = max(1, BATCH_ELEMENTS // (nr * nr))
        for lo in range(0, len(P), step):
            Pb = P[lo:lo + step]
            R = np.concatenate([np.broadcast_to(free, (len(Pb), nf)), comp[Pb]], axis=1)
            B0 = a0[R[:, :, None], R[:, None, :]]
            B1 = a1[R[:, :, None], R[:, None, :]]
            T = _batch_eigenvalues(B0, B1)
            real = np.isfinite(T) & (np.abs(T.imag) <= 1e-6 * np.maximum(1.0, np.abs(T.real)))
            tr = np.where(real, T.real, np.nan)
            lo_t = t_min - 1e-12 * max(1.0, abs(t_min))
            hi_t = t_max * (1 + 1e-12) if np.isfinite(t_max) else np.inf
            cand = real & (tr >= lo_t) & (tr <= hi_t) & (tr >= -1e-12)
            ii, jj = np.nonzero(cand)
            if not len(ii):
                continue
            t = tr[ii, jj]
            At = B0[ii] + t[:, None, None] * B1[ii]
            _, sv, Vh = np.linalg.svd(At)
            v = Vh[:, -1, :]                                   # null vector of each candidate
            # smallest singular value relative to ||B0|| + |t| ||B1|| (the pencil's scale at t)
            res = sv[:, -1] / np.maximum(np.linalg.norm(B0[ii], 2, axis=(1, 2))
                                         + np.abs(t) * np.linalg.norm(B1[ii], 2, axis=(1, 2)), 1e-300)
            xp = v[:, nf:]
            sgn = np.where(xp.sum(axis=1) < 0, -1.0, 1.0)
            v = v * sgn[:, None]
            xp = v[:, nf:]
            big = np.max(np.abs(xp), axis=1)
            mx = np.min(xp, axis=1) / np.maximum(big, 1e-300)
            keep = (mx > 0) & (res <= RESIDUAL_TOL)
            for c in np.flatnonzero(keep):
                b, tc = ii[c], float(max(t[c], 0.0))
                x = np.zeros(n)
                x[R[b]] = v[c]
                x /= np.sum(x[comp])
                y = (a0 + tc * a1) @ x
                sup = np.zeros(s, dtype=bool)
                sup[Pb[b]] = True
                ystick = y[comp[~sup]]
                my = float(np.min(ystick)) if len(ystick) else np.inf
                if my < -RESOLVE_TOL:
                    continue
                resid = float(np.linalg.norm(y[R[b]]) / max(np.linalg.norm(x[R[b]]), 1e-300))
                out.append(PatternSolution(value=tc, x=x, support=sup, residual=resid, min_x=float(mx[c]),
                                           min_y=my, ill_conditioned=bool(mx[c] < RESOLVE_TOL or my < RESOLVE_TOL),
                                           complementarity=float(np.max(np.abs(x[comp] * y[comp]))),
                                           min_y_all=float(np.min(y[comp]))))
    return sorted(out, key=lambda d: (d.value, tuple(~d.support)))


def enumerate_mceip(A0: np.ndarray, A1: np.ndarray, comp: np.ndarray, max_slip: int,
                    pairs: list[tuple[int, int]] | None = None) -> list[dict]:
    """All solutions of ``(A0 + t A1) x = y, y_f = 0, 0 <= x_c ⊥ y_c >= 0, t >= 0`` (dense).

    Returns dicts with ``value``, ``x_Ts`` (sum 1), ``pattern`` (``slip`` exactly on the support
    whose restricted eigenproblem (25) the pair solves), the residual and sign margins of (26)
    relative to the pencil's scale and ``ill_conditioned``; sorted by value. ``pairs`` are the
    (a, b) positions (in the full numbering) of split tangential rates.
    """
    comp = np.asarray(comp)
    s = len(comp)
    if s > max_slip:
        raise TooManySlipNodes(f"{s} slip nodes: enumeration of 2^{s} patterns refused "
                               f"(settings.enumerate_max_slip = {max_slip})")
    cpos = {int(c): k for k, c in enumerate(comp)}
    cpairs = [(cpos[a], cpos[b]) for a, b in (pairs or [])]
    with one_blas_thread():
        sols = enumerate_patterns(A0, A1, comp, pairs=cpairs)
    return [d.as_dict(comp) for d in sols]
