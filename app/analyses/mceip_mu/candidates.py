"""Dense candidate search for the condensed MCEIP-mu (the paper's Propositions 1-2, eqs. (21)-(23)).

The condensed problem lives on the ``s`` complementarity unknowns only (no free DOFs):

    y = (A0 + mu A1) x,   0 <= x ⊥ y >= 0,   0 <= mu ⊥ e^T x - c >= 0.

With the min-function ``phi(a, b) = min(a, b)`` this is the square nonsmooth system
``Phi(x, mu) = (min(x, y), min(mu, e^T x - c)) = 0``, solved here by a semismooth Newton method
(generalised Jacobian row ``e_i`` where ``x_i <= y_i``, the pencil's row ``[A(mu)_i, (A1 x)_i]``
otherwise) with a monotone backtracking line search on ``|Phi|^2 / 2``, run for many starts at
once: the iterates are a ``(B, s + 1)`` array and every Newton step is one batched LAPACK solve.
No PETSc objects, no MPI: the condensed pencil is small and replicated.

A converged run gives a candidate. It is never reported as is: its support (``x > 0``) is
re-solved exactly (eq. (25), :func:`app.analyses.enumerate.enumerate_patterns`) and the
eigenpair of that support nearest the Newton value that passes the sign checks (26) is reported,
with the Newton evidence (iterations, residual, start) attached. This is a heuristic search:
completeness is the job of app/analyses/mceip_mu/state.py.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from app.analyses.enumerate import PatternSolution, enumerate_patterns, pencil_scale


@dataclass
class Candidate:
    """One exact solution found by the search, with the evidence of the run(s) that found it."""

    exact: PatternSolution
    newton_value: float
    newton_residual: float      # |Phi| at the end of the run (scaled pencil)
    iterations: int
    found_by: list[str] = field(default_factory=list)

    def as_dict(self, comp: np.ndarray) -> dict:
        """The exact solution's record (:meth:`app.analyses.enumerate.PatternSolution.as_dict`) with
        the Newton evidence: iterations, final residual, the labels of the first 8 starts that found
        it and their count."""
        d = self.exact.as_dict(comp)
        d.update({"iterations": int(self.iterations), "newton_residual": float(self.newton_residual),
                  "found_by": self.found_by[:8], "found_count": len(self.found_by)})
        return d


@dataclass
class DenseSearchReport:
    """What a dense search did: the candidates found (exact solutions, by value), the number of
    starts, of converged runs and of converged runs whose support gave no exact solution, the wall
    time in seconds and a note on the method (a search, not a proof)."""

    candidates: list[Candidate]
    starts: int
    converged: int
    rejected: int               # converged runs whose support did not give an exact solution
    seconds: float
    note: str = ("semismooth Newton (min-function) on the bordered MCP of Propositions 1-2, batched over "
                 "starts; every reported pair is the exact eigenpair (25) of the run's support, checked by (26); "
                 "a search, not a proof")


def _start_rows(xs: list[np.ndarray], labels: list[str], mu0s: list[float],
                pairs: list[tuple[int, int]]) -> tuple[list[np.ndarray], list[str]]:
    """The start vectors ``xs`` (one half of each split tangential rate only, normalised to
    ``e^T x = 1``) with every ``mu0``: one ``(len(xs), s + 1)`` block of rows ``(x, mu0)`` per
    ``mu0``, and their labels."""
    X = np.array(xs)
    for a, b in pairs:          # start with one half of each split tangential rate only
        X[:, b] = np.where(X[:, a] > 0, 0.0, X[:, b])
    X = X / np.maximum(X.sum(axis=1, keepdims=True), 1e-300)
    rows = [np.hstack([X, np.full((len(X), 1), m)]) for m in mu0s]
    return rows, [f"{l}, mu0={m:.6g}" for m in mu0s for l in labels]


def _starts(s: int, mu0s: list[float], pairs: list[tuple[int, int]],
            zero_one: bool = True) -> tuple[np.ndarray, list[str]]:
    """Start rows ``(x, mu)``, each with every ``mu0``: uniform ``x``, ``x`` on one unknown and
    (``zero_one``) ``x`` zero on one unknown."""
    xs, labels = [np.ones(s)], ["uniform x"]
    for i in range(s):
        xs.append(np.eye(s)[i])
        labels.append(f"x on unknown {i}")
    if s > 2 and zero_one:
        for i in range(s):
            xs.append(1.0 - np.eye(s)[i])
            labels.append(f"x zero on unknown {i}")
    rows, lab = _start_rows(xs, labels, mu0s, pairs)
    return np.concatenate(rows), lab


def _reduced_starts(a0: np.ndarray, a1: np.ndarray, mu0s: list[float], pairs: list[tuple[int, int]],
                    one_node: int) -> tuple[np.ndarray, list[str]]:
    """The start set of a large condensed problem (``s`` above ``search_full_max``): uniform ``x``
    and ``x`` on ``one_node`` evenly spaced unknowns (the first and last included), each with every
    ``mu0``, plus the eigenvectors (25) of the all-slip pattern with a real ``mu >= 0`` (positive
    part, started at their own ``mu``). About ``(one_node + 1) * len(mu0s)`` runs instead of
    ``(s + 1) * len(mu0s)``: each Newton step costs ``O(s^3)``, so the full set costs ``O(s^4)``."""
    s = a0.shape[0]
    picks = np.unique(np.round(np.linspace(0, s - 1, max(one_node, 2))).astype(int))
    xs, labels = [np.ones(s)], ["uniform x"]
    for i in picks:
        xs.append(np.eye(s)[i])
        labels.append(f"x on unknown {i}")
    rows, lab = _start_rows(xs, labels, mu0s, pairs)
    try:
        w, V = scipy.linalg.eig(a0, -a1)
    except (np.linalg.LinAlgError, ValueError):
        w, V = np.zeros(0), np.zeros((s, 0))
    real = np.isfinite(w) & (np.abs(w.imag) <= 1e-9 * np.maximum(1.0, np.abs(w))) & (w.real >= 0)
    for j in np.flatnonzero(real):
        v = V[:, j].real
        v = v if v.sum() >= 0 else -v
        x = np.maximum(v, 0.0)
        for a, b in pairs:
            x[b] = 0.0 if x[a] > 0 else x[b]
        if x.sum() <= 0:
            continue
        rows.append(np.append(x / x.sum(), w[j].real)[None])
        lab.append(f"positive part of the all-slip eigenvector (25) at mu={w[j].real:.6g}")
    return np.concatenate(rows), lab


def _lstsq_batched(J: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Minimum-norm least-squares solutions of the stack ``J[k] d = b[k]`` through one batched SVD
    (the cut-off of ``numpy.linalg.lstsq(rcond=None)``: ``eps * n * sigma_max``)."""
    U, sig, Vt = np.linalg.svd(J)
    cut = np.finfo(float).eps * J.shape[-1] * sig[:, :1]
    inv = np.where(sig > cut, 1.0 / np.where(sig > cut, sig, 1.0), 0.0)
    return np.einsum("kji,kj->ki", Vt, inv * np.einsum("kji,kj->ki", U, b))


def _newton_steps(J: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Newton steps ``J[k] d = b[k]`` of the stack by one batched LAPACK solve; when LAPACK finds
    a singular Jacobian, only the singular ones (zero determinant, i.e. a zero pivot) get the
    minimum-norm least-squares step (:func:`_lstsq_batched`), the others still the solve."""
    try:
        return np.linalg.solve(J, b[:, :, None])[:, :, 0]
    except np.linalg.LinAlgError:
        pass
    # an exactly zero pivot of the LU factorisation makes the determinant's sign exactly zero
    # (slogdet: the same test without the overflow of det on large stacks)
    sing = np.linalg.slogdet(J)[0] == 0
    d = np.empty(b.shape)
    if sing.all() or len(J) == 1:
        return _lstsq_batched(J, b)
    d[sing] = _lstsq_batched(J[sing], b[sing])
    ok = ~sing
    try:
        d[ok] = np.linalg.solve(J[ok], b[ok][:, :, None])[:, :, 0]
    except np.linalg.LinAlgError:     # not isolated by the determinant (underflow): halve the stack
        h = len(J) // 2
        return np.concatenate([_newton_steps(J[:h], b[:h]), _newton_steps(J[h:], b[h:])])
    return d


def _jacobian(a0: np.ndarray, a1: np.ndarray, Zi: np.ndarray, y: np.ndarray, g: np.ndarray, xa1: np.ndarray,
              eye: np.ndarray, ones_row: np.ndarray) -> np.ndarray:
    """Generalised Jacobians of ``Phi`` at the rows ``Zi = (x, mu)`` (``y = A(mu) x``,
    ``g = e^T x - 1``, ``xa1 = A1 x`` there): the pencil's row where ``x_i > y_i``, ``e_i`` else."""
    m, n1 = Zi.shape
    s = n1 - 1
    x, mu = Zi[:, :s], Zi[:, s]
    J = np.empty((m, n1, n1))
    # rows of the pencil: d y / d (x, mu) = [A(mu), A1 x]; rows e_i where x_i <= y_i
    np.multiply(mu[:, None, None], a1[None], out=J[:, :s, :s])
    J[:, :s, :s] += a0[None]
    J[:, :s, s] = xa1
    use_x = x <= y
    ri, ci = np.nonzero(use_x)
    J[ri, ci, :] = eye[ci]
    use_mu = mu <= g
    J[:, s, :] = np.where(use_mu[:, None], eye[s][None], ones_row[None])
    return J


def _backtrack(phi, Zi: np.ndarray, d: np.ndarray, base: np.ndarray, moved: np.ndarray, new: tuple, nm: np.ndarray):
    """The halvings 1/2 ... 1/2^11 of the Newton step ``d`` for the rows that rejected the full
    step (``~moved``), all at once; the first accepted one is taken. Updates ``moved``, the new
    iterates and their ``phi`` values (``new = (Z, F, y, g, xa1)``) and norms ``nm`` in place."""
    todo = np.flatnonzero(~moved)
    if not len(todo):
        return
    n1 = Zi.shape[1]
    steps = 0.5 ** np.arange(1, 12)
    Zt = (Zi[todo, None, :] + steps[None, :, None] * d[todo, None, :]).reshape(-1, n1)
    Ft, yt, gt, xt = phi(Zt)
    nt = np.linalg.norm(Ft, axis=1).reshape(len(todo), len(steps))
    okt = np.isfinite(nt) & (nt <= (1 - 1e-4 * steps[None, :]) * base[todo, None])
    hit = okt.any(axis=1)
    first = np.argmax(okt, axis=1)[hit]
    rows, pick = todo[hit], np.flatnonzero(hit) * len(steps) + first
    moved[rows] = True
    for arr, trial in zip(new, (Zt, Ft, yt, gt, xt)):
        arr[rows] = trial[pick]
    nm[rows] = nt[hit, first]


def semismooth_newton(a0: np.ndarray, a1: np.ndarray, Z: np.ndarray, max_it: int = 60,
                      tol: float = 1e-13, stagnation_its: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Batched semismooth Newton on ``min(x, A(mu) x) = 0, min(mu, e^T x - 1) = 0`` from the rows
    of ``Z = (x, mu)``. Returns final iterates, ``|Phi|`` and iteration counts.

    ``stagnation_its`` > 0: a run whose ``|Phi|`` has not halved within that many iterations is
    stopped (it is reported as not converged, like a run that ran out of iterations)."""
    B, n1 = Z.shape
    s = n1 - 1
    Z = Z.copy()
    its = np.zeros(B, dtype=int)
    # Only the rows still iterating are evaluated (Newton step, each backtracking halving, the new
    # residual): a row stops when it converges (|Phi| <= tol) or when no step of the monotone
    # backtracking decreases |Phi| (stagnation). Issue 14: 2x less time than whole-batch evaluation.
    a0t, a1t = np.ascontiguousarray(a0.T), np.ascontiguousarray(a1.T)
    ones_row = np.concatenate([np.ones(s), [0.0]])

    def phi(Z):
        x, mu = Z[:, :s], Z[:, s]
        xa1 = x @ a1t
        y = x @ a0t + mu[:, None] * xa1
        g = x.sum(axis=1) - 1.0
        F = np.empty_like(Z)
        np.minimum(x, y, out=F[:, :s])
        np.minimum(mu, g, out=F[:, s])
        return F, y, g, xa1

    F, y, g, xa1 = phi(Z)
    nrm = np.linalg.norm(F, axis=1)
    active = np.isfinite(nrm) & (nrm > tol)
    eye = np.eye(n1)
    ref, ref_it = nrm.copy(), np.zeros(B, dtype=int)     # stagnation test: |Phi| to halve from ref
    for it in range(max_it):
        idx = np.flatnonzero(active)
        if not len(idx):
            break
        Zi = Z[idx]
        J = _jacobian(a0, a1, Zi, y[idx], g[idx], xa1[idx], eye, ones_row)
        d = _newton_steps(J, -F[idx])
        # monotone backtracking on |Phi|: the full step for every row, then the halvings
        # 1/2 ... 1/2^11 of the rows that rejected it, all at once (the first accepted one is taken)
        base = nrm[idx]
        newZ = Zi + d
        Fm, ym, gm, xm = phi(newZ)
        nm = np.linalg.norm(Fm, axis=1)
        moved = np.isfinite(nm) & (nm <= (1 - 1e-4) * base)
        _backtrack(phi, Zi, d, base, moved, (newZ, Fm, ym, gm, xm), nm)
        im = idx[moved]
        Z[im] = newZ[moved]
        F[im], y[im], g[im], xa1[im], nrm[im] = Fm[moved], ym[moved], gm[moved], xm[moved], nm[moved]
        its[idx] += 1
        active[idx[~moved]] = False              # stagnation: stop early
        active &= np.isfinite(nrm) & (nrm > tol)
        if stagnation_its > 0:
            halved = nrm <= 0.5 * ref
            ref = np.where(halved, nrm, ref)
            ref_it = np.where(halved, it + 1, ref_it)
            active &= (it + 1 - ref_it) < stagnation_its
    return Z, nrm, its


def search(A0: np.ndarray, A1: np.ndarray, pairs: list[tuple[int, int]] | None = None,
           mu0s: tuple[float, ...] = (0.5, 2.0, 10.0, 100.0, 1000.0), max_it: int = 60,
           zero_one_max: int | None = None,
           t_max: float = np.inf, neighbour_rounds: int = 0, full_max: int | None = None,
           one_node: int = 8, stagnation_its: int = 10,
           warm: list[tuple[np.ndarray, float]] | None = None) -> DenseSearchReport:
    """Candidate solutions of the condensed MCEIP-mu (``A0``, ``A1``: s x s) from many starts.

    Up to ``full_max`` unknowns (``None``: always) every one-unknown start is run; above it the
    reduced start set of :func:`_reduced_starts` (``one_node`` one-unknown starts), and runs that
    stagnate for ``stagnation_its`` iterations are stopped, and ``warm`` starts ``(x, mu)`` (the
    previous classification's solutions along the path, mapped onto these unknowns) are added."""
    t0 = time.perf_counter()
    pairs = list(pairs or [])
    s = A0.shape[0]
    scale = pencil_scale(A0)
    a0, a1 = A0 / scale, A1 / scale
    large = full_max is not None and s > full_max
    if large:
        Z0, labels = _large_starts(a0, a1, mu0s, pairs, one_node, warm)
        note = (f"reduced start set (s = {s} > search_full_max = {full_max}): uniform x and x on {one_node} "
                "evenly spaced unknowns with every mu0, and the all-slip eigenvectors (25); "
                f"runs stagnating for {stagnation_its} iterations stopped")
    else:
        # above ``zero_one_max`` unknowns the "x zero on one unknown" starts (nearly uniform there) are left out
        Z0, labels = _starts(s, list(mu0s), pairs, zero_one=zero_one_max is None or s <= zero_one_max)
        note = None
    Z, nrm, its = semismooth_newton(a0, a1, Z0, max_it=max_it, stagnation_its=stagnation_its if large else 0)
    conv = np.flatnonzero(np.isfinite(nrm) & (nrm <= 1e-9) & (Z[:, s] >= 0))
    cache: dict[tuple, list[PatternSolution]] = {}
    found, rejected = _exact_candidates(A0, A1, Z, nrm, its, conv, labels, pairs, t_max, cache)
    _neighbours(A0, A1, found, set(cache), pairs, t_max, neighbour_rounds)
    cands = sorted(found.values(), key=lambda c: c.exact.value)
    rep = DenseSearchReport(candidates=cands, starts=len(Z0), converged=len(conv), rejected=rejected,
                            seconds=time.perf_counter() - t0)
    if note:
        rep.note = f"{rep.note}; {note}"
    return rep


def _large_starts(a0: np.ndarray, a1: np.ndarray, mu0s, pairs: list[tuple[int, int]], one_node: int,
                  warm: list[tuple[np.ndarray, float]] | None) -> tuple[np.ndarray, list[str]]:
    """The reduced start set of a large problem, the ``warm`` starts first (so that the evidence,
    ``found_by[:8]``, shows them)."""
    s = a0.shape[0]
    Z0, labels = _reduced_starts(a0, a1, list(mu0s), pairs, one_node)
    rows, wl = [], []
    for x, mu in warm or []:
        x = np.maximum(np.asarray(x, dtype=float), 0.0)
        if x.shape == (s,) and x.sum() > 0 and np.isfinite(mu) and mu >= 0:
            rows.append(np.append(x / x.sum(), mu))
            wl.append(f"previous classification's solution (mu={mu:.6g})")
    if rows:
        Z0, labels = np.vstack([np.array(rows), Z0]), wl + labels
    return Z0, labels


def _exact_candidates(A0: np.ndarray, A1: np.ndarray, Z: np.ndarray, nrm: np.ndarray, its: np.ndarray,
                      conv: np.ndarray, labels: list[str], pairs: list[tuple[int, int]], t_max: float,
                      cache: dict) -> tuple[dict[tuple, Candidate], int]:
    """The converged runs ``conv`` re-solved exactly on their supports (eq. (25), checks (26)):
    ``(candidates by (value, support), number of runs rejected)``; ``cache`` keeps every support's
    exact solutions."""
    s = A0.shape[0]
    found: dict[tuple, Candidate] = {}
    rejected = 0
    for b in conv:
        x = Z[b, :s].copy()
        for ia, ib in pairs:
            m = min(x[ia], x[ib])
            if m > 0:
                x[ia] -= m
                x[ib] -= m
        mu = float(Z[b, s])
        # The run's support is x > 0; entries at round-off level (a node the run left at 1e-17
        # instead of 0) make that support's restricted eigenproblem (25) fail the checks (26),
        # so supports without them are tried next. Only an exact, checked pair is kept.
        ex = None
        for rel in (0.0, 1e-12, 1e-9):
            sup = x > rel * x.max()
            if not sup.any() or any(sup[ia] and sup[ib] for ia, ib in pairs):
                continue
            key = tuple(sup)
            if key not in cache:
                cache[key] = enumerate_patterns(A0, A1, np.arange(s), t_max=t_max, supports=sup[None])
            if cache[key]:
                near = min(cache[key], key=lambda p: abs(p.value - mu))
                if abs(near.value - mu) <= 1e-6 * max(1.0, mu):
                    ex = near
                    break
        if ex is None:
            rejected += 1
            continue
        k = (round(ex.value, 9), key)
        c = found.get(k)
        if c is None:
            c = found[k] = Candidate(exact=ex, newton_value=mu, newton_residual=float(nrm[b]), iterations=int(its[b]))
        c.found_by.append(f"semismooth Newton from {labels[b]} ({its[b]} it.)")
    return found, rejected


def _neighbours(A0: np.ndarray, A1: np.ndarray, found: dict[tuple, Candidate], tried: set,
                pairs: list[tuple[int, int]], t_max: float, rounds: int) -> None:
    """Pattern neighbourhoods: the exact eigenpairs (25) of every support one flip away from a
    found one (batched), repeated while they give new solutions (added to ``found``)."""
    s = A0.shape[0]
    frontier = [k for _, k in found]
    for _ in range(rounds):
        nxt = []
        for key in frontier:
            base = np.array(key)
            for j in range(s):
                sup = base.copy()
                sup[j] = not sup[j]
                k2 = tuple(sup)
                if k2 in tried or not sup.any() or any(sup[ia] and sup[ib] for ia, ib in pairs):
                    continue
                tried.add(k2)
                nxt.append(k2)
        if not nxt:
            break
        new = enumerate_patterns(A0, A1, np.arange(s), t_max=t_max, supports=np.array(nxt))
        frontier = []
        for ex in new:
            k = (round(ex.value, 9), tuple(ex.support))
            if k not in found:
                found[k] = Candidate(exact=ex, newton_value=float("nan"), newton_residual=float("nan"), iterations=0,
                                     found_by=["exact eigenpair (25) of a pattern one flip from a found one"])
                frontier.append(k[1])


def policy(A0: np.ndarray, A1: np.ndarray, pairs: list[tuple[int, int]], enumerate_max: int,
           t_max: float = np.inf, **search_kw) -> tuple[list[PatternSolution], DenseSearchReport]:
    """The floating-point candidates of the condensed MCEIP-mu that guide its proof (they never
    decide it): every support enumerated (eqs. (24)-(26), :func:`enumerate_patterns`) up to
    ``enumerate_max`` slip nodes, the dense search (:func:`search`, keywords ``search_kw``) above;
    the exact solutions found and the report of what was done. The one policy of the studies
    (app/analyses/mceip_mu/state.py) and of ``app.mceip_mu`` (app/analyses/mceip_mu/proven.py)."""
    s = A0.shape[0]
    if s <= enumerate_max:
        sols = enumerate_patterns(A0, A1, np.arange(s), t_max=t_max, pairs=list(pairs))
        return sols, DenseSearchReport([], 0, 0, 0, 0.0, note=(
            f"no search: s = {s} <= certify_enumerate_max, every support enumerated in floating point "
            "(candidates for the proof)"))
    rep = search(A0, A1, pairs=list(pairs), t_max=t_max, **search_kw)
    return [c.exact for c in rep.candidates], rep
