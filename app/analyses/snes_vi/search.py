"""MCEIP-mu and MCEIP-lambda^2 through the MCPs of Propositions 1 and 2 (paper eqs. (27)-(34)).

Both eigenproblems have the form: find ``t >= 0`` and ``x = (x_f, x_c)``, ``x != 0``, with

    (A0 + t A1) x = y,   y_f = 0,   0 <= x_c ⊥ y_c >= 0,                     (12)-(14), (21)-(23)

(``t = mu`` with ``A0 = K0, A1 = K1``; ``t = lambda^2`` with ``A0 = K*(mu), A1 = M*(mu)``).
Adding the normalisation ``e^T x_c = c + gamma`` with ``t`` complementary to ``gamma`` gives a
non-monotone MCP in ``z = (x_f, x_c, t)``, solved here with PETSc's SNES VI solvers:
``vinewtonrsls`` (reduced-space active set, the production solver) and ``vinewtonssls``
(semismooth, a robust globaliser whose result is then polished by ``vinewtonrsls``).

A run finds at most one solution. The search combines several starting points with the shifted
problems of the paper's section 4 (``t = t_bar + zeta`` above, ``t = t_bar - zeta`` below a found
value), and reports every distinct solution with its evidence (residual, complementarity,
method, start, iterations) and the intervals searched. It never claims completeness: only the
enumeration (:mod:`app.analyses.enumerate`) proves it for small problems.
"""
from __future__ import annotations

from contextlib import ExitStack

import numpy as np
import scipy.linalg
from petsc4py import PETSc

from app.analyses.pencils.reduced import REPLICATE_MAX, dense, diag_scale, serial_copy
from app.analyses.snes_vi.bordered import RSLS, SSLS, BorderedMcp
from app.analyses.snes_vi.results import McpSolution, SearchReport
from app.linalg import owned
from app.scene.schema import McpSettings

__all__ = ["RSLS", "SSLS", "BorderedMcp", "McpSolution", "SearchReport", "search_mceip"]


def _same(a: McpSolution, b: McpSolution, tol: float) -> bool:
    return (abs(a.value - b.value) <= tol * max(1.0, abs(a.value), abs(b.value))
            and float(np.max(np.abs(a.x_c - b.x_c))) <= 1e-6)


def _pattern_eig_starts(D0: np.ndarray, D1: np.ndarray, comp: np.ndarray, slip: np.ndarray) -> list[tuple[float, np.ndarray]]:
    """Starts from the linear eigenproblem of one stick/slip pattern (eq. (25)): every real
    ``t >= 0`` whose eigenvector has ``x_P`` of one sign gives ``(t, x_c)``."""
    n = D0.shape[0]
    free = np.setdiff1d(np.arange(n), comp)
    R = np.concatenate([free, comp[slip]])
    w, V = scipy.linalg.eig(D0[np.ix_(R, R)], -D1[np.ix_(R, R)])
    out = []
    for t, v in zip(w, V.T):
        if not np.isfinite(t) or abs(t.imag) > 1e-9 * max(1.0, abs(t)) or t.real < 0:
            continue
        xp = v.real[len(free):]
        if np.sum(xp) < 0:
            xp = -xp
        if np.min(xp) < -1e-9 * np.max(np.abs(xp)):
            continue
        xc = np.zeros(len(comp))
        xc[slip] = np.maximum(xp, 0)
        out.append((float(t.real), xc))
    return out


def search_mceip(A0: PETSc.Mat, A1: PETSc.Mat, comp: np.ndarray, problem: str,
                 settings: McpSettings, value_scale: float | None = None,
                 t_upper: float = np.inf, pairs: list[tuple[int, int]] | None = None,
                 pivoting: bool = False) -> SearchReport:
    """Find the distinct solutions of the MCEIP ``(A0 + t A1) x = y`` reachable by the search.

    The problem is scaled first: ``A0 / alpha`` and ``A1 * tau / alpha`` with ``alpha`` the
    largest diagonal entry of ``A0`` and ``t = tau * t_scaled`` (``tau = 1`` for mu, a
    frequency-squared scale for lambda^2), so tolerances are unit-free. Phases:

    1. global starts: uniform ``x_Ts`` with the configured ``t0``; ``x_Ts`` on one slip node, and
       zero on one slip node, each with its least-squares ``t0``; ``vinewtonrsls`` and
       ``vinewtonssls`` (polished by ``vinewtonrsls``) from each;
    2. pattern neighbourhoods (problems of at most ``pattern_eig_limit`` unknowns): the
       eigenpairs of the pattern of every solution found, of the patterns with one node
       flipped and of those with one slip node swapped for a stick node are used as starts
       for ``vinewtonrsls``;
    3. gaps (the paper's section 4, systematic): the values found split ``[0, inf)`` into
       intervals; each is searched with ``t = lo + zeta``, ``0 <= zeta <= hi - lo``.
    Phases 2-3 repeat while they find something (at most ``shift_rounds`` times).
    ``t_upper`` is a proven bound on the values (every search is boxed by it). ``pivoting``:
    pivoted (MUMPS) linear solves, for pencils with a saddle-point block.
    """
    alpha = diag_scale(A0)
    tau = 1.0 if value_scale is None else value_scale
    # a small problem distributed over several ranks is searched whole on every rank: each
    # Newton step of the distributed search is a handful of collectives on a few hundred
    # unknowns; every rank computes the same solutions from the same data
    whole = A0.getComm().getSize() > 1 and A0.getSize()[0] <= REPLICATE_MAX
    with ExitStack() as owns:                      # every PETSc object destroyed, errors included
        S0, S1 = (owns.enter_context(owned(serial_copy(A) if whole else A.copy())) for A in (A0, A1))
        S0.scale(1.0 / alpha)
        S1.scale(tau / alpha)
        op = BorderedMcp(S0, S1, comp, pairs=pairs, pivoting=pivoting)
        owns.callback(op.destroy)
        op.stagnation = settings.stagnation_its
        return _search(op, S0, S1, comp, problem, settings, tau, t_upper, pairs)


def _search(op: BorderedMcp, S0: PETSc.Mat, S1: PETSc.Mat, comp: np.ndarray, problem: str,
            settings: McpSettings, tau: float, t_upper: float,
            pairs: list[tuple[int, int]] | None) -> SearchReport:
    """The phases of :func:`search_mceip` on the scaled problem ``op``."""
    s = len(comp)
    # positions of split pairs within x_c (a pattern with both a and b active is degenerate)
    cpos = {int(c): k for k, c in enumerate(comp)}
    cpairs = [(cpos[a], cpos[b]) for a, b in (pairs or [])]
    run = _Runs(op, comp, problem, settings, tau, t_upper)
    report = run.report
    dense_ops = None
    if op.n <= settings.pattern_eig_limit:
        dense_ops = (dense(S0), dense(S1))
    x0s = _global_starts(run, s, t_upper)
    expanded: set[tuple[bool, ...]] = set()
    searched: set[tuple[float, float]] = set()
    for _ in range(settings.shift_rounds):
        n_before = len(report.solutions)
        if dense_ops is not None:
            _pattern_neighbourhoods(run, dense_ops, s, cpairs, expanded)
        _gaps(run, x0s, dense_ops is not None, searched)
        if len(report.solutions) == n_before:
            break
    return report


class _Runs:
    """The SNES VI runs of one search on the scaled problem ``op``, and its report: a run is a
    deterministic function of its start, bounds and method, so an identical run is not repeated."""

    def __init__(self, op: BorderedMcp, comp: np.ndarray, problem: str, settings: McpSettings, tau: float,
                 t_upper: float):
        self.op, self.comp, self.settings, self.tau = op, comp, settings, tau
        self.report = SearchReport(problem=problem, solutions=[])
        self.done: set = set()
        self.tol = settings.accept_tol
        self.top = t_upper / tau if np.isfinite(t_upper) else PETSc.INFINITY

    def attempt(self, method: str, x0: np.ndarray, label: str, t0: float, tbar: float = 0.0,
                sigma: float = 1.0, zeta_max: float | None = None,
                x_start: np.ndarray | None = None) -> McpSolution | None:
        """One run from ``x0`` (or the lifted ``x_start``) and ``t0`` on ``t = tbar + sigma zeta``,
        ``0 <= zeta <= zeta_max``; the new solution it found, if any (added to the report)."""
        op, top, report = self.op, self.top, self.report
        if zeta_max is None:
            zeta_max = top - tbar if sigma > 0 else tbar
        t0 = min(t0, 0.5 * (tbar + top)) if np.isfinite(top) else t0
        zeta0 = min(max((t0 - tbar) * sigma, 0.0), zeta_max)
        # A run is a deterministic function of its start, bounds and method: an identical run
        # (e.g. several configured t0 clipped to the same value by t_upper) is not repeated.
        key = (method, zeta0, tbar, sigma, zeta_max,
               (x0 / max(np.sum(x0), 1e-300)).tobytes() + np.float64(t0).tobytes() if x_start is None
               else x_start.tobytes())
        if key in self.done:
            report.skipped_identical += 1
            return None
        self.done.add(key)
        if x_start is None:
            x_start = op.lift(x0 / max(np.sum(x0), 1e-300), t0)
        x, t, reason, its, tag = self._solve(method, x0, zeta0, tbar, sigma, zeta_max, x_start)
        report.attempts += 1
        stats = report.by_method.setdefault(tag, {"attempts": 0, "converged": 0, "accepted": 0})
        stats["attempts"] += 1
        if reason > 0:
            report.converged += 1
            stats["converged"] += 1
        zeta = (t - tbar) * sigma
        if (tbar > 0 and zeta <= 1e-12 * max(tbar, 1.0)) or (np.isfinite(zeta_max) and zeta >= zeta_max * (1 - 1e-12)):
            return None  # stopped on an artificial bound of a shifted search: not a solution
        sol = op.check(x, t, self.tol)
        if sol is None:
            return None
        return self._accept(sol, t, its, f"{tag} from {label}, t0={t0 * self.tau:.6g}", stats)

    def _solve(self, method: str, x0: np.ndarray, zeta0: float, tbar: float, sigma: float, zeta_max: float,
               x_start: np.ndarray):
        """``(x, t, reason, its, tag)`` of one run; a semismooth result is polished by the
        reduced-space solver (``tag``: the method or methods)."""
        op, settings, comp = self.op, self.settings, self.comp
        x, t, reason, its = op.solve(method, x0, zeta0, tbar, sigma, zeta_max, settings,
                                     x_full=x_start * op.c)
        tag = method
        if method == SSLS:  # polish the semismooth result with the reduced-space solver
            xs = x[comp]
            if np.all(np.isfinite(x)) and np.isfinite(t) and np.sum(np.maximum(xs, 0)) > 0:
                xp = x.copy()
                xp[comp] = np.maximum(xs, 0)
                zeta = min(max((t - tbar) * sigma, 0.0), zeta_max)
                x, t, reason, its2 = op.solve(RSLS, xs, zeta, tbar, sigma, zeta_max, settings, x_full=xp)
                its += its2
                tag = f"{SSLS}+{RSLS}"
        return x, t, reason, its, tag

    def _accept(self, sol: McpSolution, t: float, its: int, found_by: str, stats: dict) -> McpSolution | None:
        """A checked solution, polished on the unshifted problem; None if it was already found."""
        op, comp, report = self.op, self.comp, self.report
        # Final polish on the unshifted problem: a true solution is a fixed point of it.
        x2, t2, reason2, its2 = op.solve(RSLS, sol.x[comp], t, 0.0, 1.0, PETSc.INFINITY, self.settings,
                                         x_full=sol.x * op.c)
        sol2 = op.check(x2, t2, self.tol) if reason2 > 0 else None
        if sol2 is not None and abs(sol2.value - sol.value) <= 1e-6 * max(1.0, sol.value):
            sol, its = sol2, its + its2
        report.accepted += 1
        stats["accepted"] += 1
        sol.value *= self.tau
        sol.iterations = its
        sol.found_by.append(found_by)
        for old in report.solutions:
            if _same(old, sol, 1e-7):
                old.found_by.extend(sol.found_by)
                return None
        report.solutions.append(sol)
        return sol


def _global_starts(run: _Runs, s: int, t_upper: float) -> list[tuple[str, np.ndarray]]:
    """Phase 1: uniform ``x_Ts`` with the configured ``t0``, then the one-node starts with their
    least-squares ``t0``, both methods each; returns the starts ``(label, x0)``."""
    op, settings, report = run.op, run.settings, run.report
    uniform = np.ones(s)
    x0s = [("uniform x_Ts", uniform)]
    if settings.pattern_starts and s > 1:
        x0s += [(f"x_Ts on slip node {i}", np.eye(s)[i]) for i in range(s)]
        if s > 2:
            x0s += [(f"x_Ts zero on slip node {i}", 1.0 - np.eye(s)[i]) for i in range(s)]
    report.starts = [label for label, _ in x0s]
    report.intervals.append(f"[0, {t_upper:.10g}]" if np.isfinite(t_upper) else "[0, inf)")
    for t0 in settings.starts:
        for method in (RSLS, SSLS):
            run.attempt(method, uniform, "uniform x_Ts", t0)
    for label, x0 in x0s:
        t0, xs = op.consistent_t(x0 / np.sum(x0))
        if t0 is not None:
            for method in (RSLS, SSLS):
                run.attempt(method, x0, label + " (least-squares t0)", t0, x_start=xs)
    return x0s


def _pattern_neighbourhoods(run: _Runs, dense_ops, s: int, cpairs: list[tuple[int, int]],
                            expanded: set[tuple[bool, ...]]) -> None:
    """Phase 2: the eigenvectors of the patterns of the solutions found (the all-slip pattern
    when none is), of those with one node flipped and one slip node swapped with a stick node."""
    report = run.report
    if "pattern eigenvector starts" not in report.starts:
        report.starts.append("pattern eigenvector starts")
    # Nothing found yet: expand around the all-slip pattern instead (phases 2-3 must
    # run even when the first starts found nothing).
    bases = ([tuple(p == "slip" for p in sol.pattern) for sol in report.solutions]
             or [tuple(True for _ in range(s))])
    for base in bases:
        on = [i for i in range(s) if base[i]]
        off = [i for i in range(s) if not base[i]]
        # the pattern itself, one node flipped, and one slip node swapped with a stick node
        moves = [()] + [(j,) for j in range(s)] + [(i, j) for i in on for j in off]
        for move in moves:
            pat = list(base)
            for j in move:
                pat[j] = not pat[j]
            pat = tuple(pat)
            if pat in expanded or not any(pat) or any(pat[a] and pat[b] for a, b in cpairs):
                continue
            expanded.add(pat)
            slip = np.flatnonzero(pat)
            for t0, xc in _pattern_eig_starts(*dense_ops, run.op.comp, slip):
                run.attempt(RSLS, xc, "eigenvector of pattern " + "".join("S" if q else "-" for q in pat), t0)


def _gaps(run: _Runs, x0s: list[tuple[str, np.ndarray]], one_node_starts: bool,
          searched: set[tuple[float, float]]) -> None:
    """Phase 3 (the paper's section 4): every interval between the values found, searched with
    ``t = lo + zeta``, ``0 <= zeta <= hi - lo``."""
    op, tau, top, report = run.op, run.tau, run.top, run.report
    uniform = x0s[0][1]
    values = sorted({round(sol.value / tau, 12) for sol in report.solutions})
    edges = [0.0] + [v for v in values for _ in (0, 1)] + [top if np.isfinite(top) else np.inf]
    for lo, hi in zip(edges[0::2], edges[1::2]):
        lo = lo * (1 + 1e-6)
        hi = hi * (1 - 1e-6) if np.isfinite(hi) else hi
        key = (round(lo, 12), round(hi, 12))
        if hi <= lo or key in searched:
            continue
        searched.add(key)
        report.intervals.append(f"[{lo * tau:.10g}, {hi * tau:.10g}]" if np.isfinite(hi)
                                else f"[{lo * tau:.10g}, inf)")
        zmax = hi - lo if np.isfinite(hi) else PETSc.INFINITY
        guesses = [0.5 * (lo + hi)] if np.isfinite(hi) else [2.0 * lo + 1.0, 10.0 * lo + 10.0]
        for t0 in guesses:
            for method in (RSLS, SSLS):
                run.attempt(method, uniform, "uniform x_Ts, t in gap", t0, tbar=lo, sigma=1.0, zeta_max=zmax)
        gap_starts = [(label, x0) for label, x0 in x0s[1:] if label.startswith("x_Ts on")]
        for label, x0 in (gap_starts if one_node_starts else []):  # one-node starts again, boxed in the gap
            t_ls, xs = op.consistent_t(x0 / np.sum(x0), t_guess=guesses[0])
            t0 = t_ls if t_ls is not None and lo <= t_ls <= hi else guesses[0]
            run.attempt(RSLS, x0, f"{label}, t in gap", t0, tbar=lo, sigma=1.0, zeta_max=zmax,
                        x_start=xs if t_ls is not None and lo <= t_ls <= hi else None)
