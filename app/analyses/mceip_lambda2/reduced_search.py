"""MCEIP-lambda^2 (12)-(14) searched on the exact slip-node reduction, in the intervals of ``t``
where its proof fails (docs/method.md section 7, "Where the proof fails").

:func:`app.analyses.mceip_lambda2.exact.prove_no_solution` certifies intervals of
``t = lambda^2``; with ``max_failed`` it sets aside those it cannot certify and shows that the rest
of ``[0, inf)`` holds no solution. A solution ``(t, x)`` of ``x >= 0, S(t) x >= 0,
x^T S(t) x = 0`` (``S(t)`` the ``s x s`` reduction onto the slip nodes' ``x_Ts``) then lies in
one of those intervals. On each ``[a, b]``, with ``S`` exact at both ends (one sparse
factorisation of ``K + t M`` each above the dense size), ``S`` is replaced by its chord
``S(a) + tau (S(b) - S(a))``, ``tau`` in ``[0, 1]``, which is a linear pencil as in MCEIP-mu:
the batched semismooth Newton search of :func:`app.analyses.mceip_mu.candidates.search` finds its
solutions, each the exact eigenpair (25) of its support ``J``. Each is then taken to the exact
``S``: the support's pencil is the chord through the two latest exact values of ``S`` (the
secant method in matrix form, one factorisation per step) until ``t`` settles, and at that ``t``
the null vector of the exact ``S_JJ(t)`` must be positive and ``(S(t) x)`` nonnegative off ``J``
(the sign checks (26), tolerances of :mod:`app.analyses.enumerate`).

A search, not a proof: solutions found are "found (not proven)", and the intervals searched are
reported with them. Used where the SNES VI search on the full system would factorise the whole
system at every Newton step (minutes to hours per state at 10^6 DOFs): on the reduction it costs
a few factorisations per interval.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from app.analyses.enumerate import RESIDUAL_TOL, RESOLVE_TOL, enumerate_patterns, pencil_scale
from app.analyses.mceip_lambda2.dynamic_contact import DynamicContact
from app.analyses.mceip_lambda2.exact import Reduction
from app.analyses.mceip_mu import candidates
from app.analyses.outcomes import Solution
from app.loading.classify import Classification

#: most secant steps (exact values of S, one factorisation each) taking one candidate to the exact S
SECANT_STEPS = 8
#: the secant steps stop when t moves by less than this, relative to the interval's length
T_TOL = 1e-10


@dataclass
class ReducedSearch:
    """What :func:`search` did: the solutions found (``lambda^2`` ascending), the intervals
    searched, the candidates of the chord pencils and how many the exact ``S`` kept, the exact
    values of ``S`` computed (new factorisations are counted by the caller) and the time."""

    solutions: list[Solution]
    intervals: list[tuple[float, float]]
    candidates: int = 0
    rejected: int = 0
    evaluations: int = 0
    seconds: float = 0.0
    notes: list[str] = field(default_factory=list)


def _support_roots(S1: np.ndarray, t1: float, S2: np.ndarray, t2: float, J: np.ndarray) -> list[float]:
    """The ``t`` where the chord of ``S`` through ``(t1, S1)``, ``(t2, S2)`` is singular on the
    support ``J`` with a positive null vector, on either side of ``t1`` (the pencil's parameter is
    nonnegative: one pencil towards ``t2``, one away from it)."""
    s = S1.shape[0]
    sup = np.zeros(s, dtype=bool)
    sup[J] = True
    h = t2 - t1
    roots = []
    for D, sign in ((S2 - S1, 1.0), (S1 - S2, -1.0)):
        for p in enumerate_patterns(S1, D, np.arange(s), supports=sup[None]):
            roots.append(t1 + sign * p.value * h)
    return roots


def _exact_solution(red: Reduction, J: np.ndarray, t: float, scale: float) -> Solution | None:
    """The solution with support ``J`` at ``t`` on the exact ``S(t)``, or None when its sign checks
    (26) or its residual (relative to ``scale``, the interval's ``S(a)``: at a solution ``S_JJ``
    itself may be as small as its residual) fail."""
    S = red.S(t)
    s = S.shape[0]
    _, sv, Vh = np.linalg.svd(S[np.ix_(J, J)] / scale)
    v = Vh[-1]
    v = v if v.sum() >= 0 else -v
    res = float(sv[-1])
    min_x = float(v.min() / max(np.abs(v).max(), 1e-300))
    if min_x <= 0 or res > RESIDUAL_TOL:
        return None
    x = np.zeros(s)
    x[J] = v / v.sum()
    y = S @ x / scale
    off = np.setdiff1d(np.arange(s), J)
    min_y = float(y[off].min()) if len(off) else np.inf
    if min_y < -RESOLVE_TOL:
        return None
    support = np.zeros(s, dtype=bool)
    support[J] = True
    return Solution(value=float(t), x_Ts=[float(v) for v in x],
                    pattern=["slip" if b else "stick" for b in support],
                    evidence={"residual": res, "complementarity": float(np.max(np.abs(x * y))),
                              "min_x_Ts": min_x, "min_y_Ts": float(y.min()),
                              "margin_y_stick": min_y if np.isfinite(min_y) else None,
                              "ill_conditioned": bool(min_x < RESOLVE_TOL or min_y < RESOLVE_TOL),
                              "found_by": ["search on the exact slip-node reduction (chord pencil, then secant "
                                           "steps on the exact S(t))"],
                              "found_count": 1, "iterations": 0, "pattern_residual": res,
                              "pattern_verified": True})


def _to_exact(red: Reduction, a: float, b: float, t0: float, roots_of) -> float:
    """``t`` on the exact ``S`` from a chord pencil's ``t0`` in ``[a, b]``: secant steps, each the root
    (``roots_of(S1, t1, S2, t2)``: those of the chord through two exact values of ``S``) nearest the
    latest ``t`` of the chord through the two latest exact values, until ``t`` moves by less than
    :data:`T_TOL` of ``b - a`` (at most :data:`SECANT_STEPS` exact values)."""
    t, other = t0, min((a, b), key=lambda e: abs(e - t0))
    for _ in range(SECANT_STEPS):
        if abs(t - other) <= T_TOL * (b - a):
            break
        roots = [r for r in roots_of(red.S(t), t, red.S(other), other)
                 if max(0.0, a - (b - a)) <= r <= b + (b - a)]
        if not roots:
            break
        t, other = float(min(roots, key=lambda r: abs(r - t))), t
        if abs(t - other) <= T_TOL * (b - a):
            t = other          # S is exact at other; t differs by less than the tolerance
            break
    return t


def search(dc: DynamicContact, cls: Classification, mu: float, intervals: list[tuple[float, float]],
           full_max: int = 40, one_node: int = 4) -> ReducedSearch:
    """The solutions of (12)-(14) in the ``intervals`` of ``t`` (those
    :func:`app.analyses.mceip_lambda2.exact.prove_no_solution` could not certify), found on the
    exact reduction (see the module's docstring). Dense work on ``s x s`` matrices and a few exact
    values of ``S`` per candidate. ``full_max``, ``one_node``: above ``full_max`` slip nodes the
    chord pencils' search runs MCEIP-mu's reduced start set (``mcp.search_full_max``,
    ``mcp.search_one_node``)."""
    t0 = time.perf_counter()
    red = Reduction(dc, cls, mu)
    out = ReducedSearch(solutions=[], intervals=[(float(a), float(b)) for a, b in intervals])
    before = dc.evaluations
    seen: list[tuple[tuple, float]] = []
    for a, b in intervals:
        Sa, Sb = red.S(a), red.S(b)
        rep = candidates.search(Sa, Sb - Sa, mu0s=(0.25, 0.5, 0.75), t_max=1.0, full_max=full_max,
                                one_node=one_node)
        for c in rep.candidates:
            out.candidates += 1
            J = np.flatnonzero(c.exact.support)
            t = _to_exact(red, a, b, a + c.exact.value * (b - a),
                          lambda S1, t1, S2, t2, J=J: _support_roots(S1, t1, S2, t2, J))
            key = tuple(J.tolist())
            if any(k == key and abs(t - u) <= 1e-8 * max(abs(u), b - a) for k, u in seen):
                continue
            sol = _exact_solution(red, J, t, pencil_scale(Sa))
            if sol is None:
                out.rejected += 1
                continue
            seen.append((key, t))
            out.solutions.append(sol)
    out.solutions.sort(key=lambda q: q.value)
    out.evaluations = dc.evaluations - before
    out.seconds = time.perf_counter() - t0
    return out


def _chord_roots(S1: np.ndarray, t1: float, S2: np.ndarray, t2: float) -> np.ndarray:
    """The real ``t`` where the chord of ``S`` through ``(t1, S1)``, ``(t2, S2)`` is singular (all of
    ``S``: the generalised eigenvalues of ``(S1, S1 - S2)`` in ``tau = (t - t1) / (t2 - t1)``)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = scipy.linalg.eigvals(S1, S1 - S2)
    real = np.isfinite(tau) & (np.abs(tau.imag) <= 1e-8 * np.maximum(1.0, np.abs(tau.real)))
    return t1 + tau.real[real] * (t2 - t1)


def eigenpairs(dc: DynamicContact, cls: Classification, mu: float,
               intervals: list[tuple[float, float]]) -> list[tuple[float, np.ndarray, float]]:
    """The real eigenpairs of (17)-(18) with ``lambda^2 = t`` in the ``intervals`` on the exact
    reduction: ``S(t) x = 0`` (``y = 0`` on the slip nodes, the free DOFs eliminated), as ``(t, x
    (s values on the slip nodes' x_Ts, unit norm), relative residual)``. Outside the intervals
    ``sym S(t)`` is copositive (the proof), so no eigenvector there has ``x >= 0``. Each real root
    of the chord pencil on an interval is taken to the exact ``S`` by the secant steps of
    :func:`search` (on every slip node); a search, not a proof."""
    red = Reduction(dc, cls, mu)
    out: list[tuple[float, np.ndarray, float]] = []
    for a, b in intervals:
        h = b - a
        Sa = red.S(a)
        scale = pencil_scale(Sa)
        for t0 in _chord_roots(Sa, a, red.S(b), b):
            if not a - 1e-9 * h <= t0 <= b + 1e-9 * h:
                continue
            t = _to_exact(red, a, b, float(t0), lambda *q: list(_chord_roots(*q)))
            _, sv, Vh = np.linalg.svd(red.S(t) / scale)
            res = float(sv[-1])              # relative to the interval's S(a): at a root S itself may be small
            if res <= RESIDUAL_TOL and t > 0 and not any(abs(t - u) <= 1e-8 * max(t, h) for u, _, _ in out):
                out.append((t, Vh[-1], res))
    return sorted(out, key=lambda q: q[0])