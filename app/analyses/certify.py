"""Proven answers for the condensed MCEIP-mu (DESIGN.md section 7).

Problem: ``A(mu) = A0 + mu A1`` (s x s), find ``mu >= 0``, ``v >= 0``, ``e^T v = 1`` with
``y = A(mu) v >= 0`` and ``v_i y_i = 0`` (21)-(23). This module proves

(a) the onset: the smallest critical mu of the state, or that there is none below ``cap``;
(b) every critical mu in ``[0, cap]``, each with its mode,

and says exactly what it proved. The tools, cheapest first:

* **Sign argument** (lower bound): at a solution ``v^T A(mu) v = v^T y = 0``, so no solution has a
  mu at which ``sym A(mu)`` is strictly copositive. Membership of the convex cone
  ``PD + NN`` (``P`` positive definite plus ``N`` entrywise nonnegative) is a sufficient test,
  certified here by explicit splits and a Cholesky factorisation; ``A(mu)`` being affine in mu,
  a test passed at 0 and at ``b`` holds on all of ``[0, b]``, and bisection on ``b`` gives a
  proven lower bound ``mu_lb`` (the plain PD test, eq. (19) at the condensed level, is the
  split ``N = 0``).
* **Exhaustive enumeration** (:mod:`app.analyses.enumerate`, batched LAPACK) of all supports
  on ``[mu_lb, cap]``: exact and complete, the certificate for small ``s``.
* **Branch and bound** (SCIP through pyscipopt) for larger ``s``: binaries ``z_i`` (1 = slips),
  ``v_i <= z_i``, ``y_i <= Y_i (1 - z_i)`` with ``Y_i`` a proven bound of ``|y_i|`` on the simplex,
  ``w = m v`` as bilinear equalities, ``m = mu / cap`` in ``[mu_lb / cap, 1]``. Every support
  already known to hold solutions (search candidates, earlier SCIP points), after all its exact
  solutions in the interval have been listed, is excluded by a no-good cut on ``z``; SCIP then
  looks for anything else. "Infeasible" is the certificate that nothing else lies in the
  interval. The optimiser is never trusted for the answer: its pattern ``z`` is re-solved
  exactly (25) and checked (26); a pattern without an exact solution in the interval holds no
  solution at all and is cut as well.

The SCIP certificate is subject to SCIP's feasibility tolerance (1e-9 here, on a pencil scaled
to unit diagonal and ``m <= 1``): a relaxed tolerance can only add spurious points (which are
re-checked exactly and cut), not remove true ones, up to floating-point error in its LPs.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from app.analyses.enumerate import PatternSolution, enumerate_patterns, pencil_scale
from app.linalg import one_blas_thread


def certificate(method: str, interval: tuple[float, float], status: str, seconds: float | None,
                detail: dict | None = None, gap: float | None = None) -> dict:
    """The ``certificate`` block of an MCEIP result (mu or lambda^2; fields method, interval,
    status, gap, seconds, detail). ``interval``: the range of the eigenvalue the status speaks
    about; ``status`` is ``"proven"`` only when every solution in it is listed; ``seconds``
    ``None`` when not timed."""
    return {"method": method, "interval": [float(interval[0]), float(interval[1])], "status": status,
            "gap": gap, "seconds": None if seconds is None else round(float(seconds), 4), "detail": detail or {}}


@dataclass
class Certificate:
    """What was proven about the condensed MCEIP-mu of one state."""
    method: str                       # "copositivity", "enumeration", "branch-and-bound (SCIP)"
    interval: tuple[float, float]     # [a, b] proven: every solution in it is listed ([0, mu_lb] if unfinished)
    status: str                       # "proven", "not proven within N s", ...
    proven: bool
    solutions: list[PatternSolution]  # exact solutions in [0, cap] (complete if proven)
    lower_bound: float                # proven: no solution below it
    gap: float | None                 # relative gap between the interval's ends still open (0 if proven)
    seconds: float
    detail: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return certificate(self.method, self.interval, self.status, self.seconds, self.detail, self.gap)


# --- certified lower bound (sign argument) ------------------------------------------------------

def in_pd_plus_nn(S: np.ndarray, margin: float = 1e-10) -> bool:
    """Sufficient test of ``S`` in ``PD + NN``: some explicit split ``S = P + N``, ``N >= 0``
    entrywise, with ``P`` positive definite (Cholesky succeeds with the relative ``margin``)."""
    d = np.sqrt(np.maximum(np.abs(np.diag(S)), 1e-300))
    Sn = S / d[:, None] / d[None, :]
    off = Sn - np.diag(np.diag(Sn))
    pos = np.maximum(off, 0.0)
    for theta in (0.0, 1.0, 0.5):
        P = Sn - theta * pos
        try:
            L = np.linalg.cholesky(P - margin * np.eye(len(S)))
        except np.linalg.LinAlgError:
            continue
        if np.all(np.isfinite(L)):
            return True
    return False


def copositivity_bound(A0: np.ndarray, A1: np.ndarray, cap: float, pairs: list | None = None,
                       steps: int = 40) -> tuple[float, str]:
    """A proven ``mu_lb``: no MCEIP-mu solution has ``mu < mu_lb`` (sign argument above).

    Returns ``(mu_lb, how)``; ``mu_lb >= cap`` proves there is no solution below ``cap``.
    With split tangential rates (zero-reaction nodes) ``sym A0`` is only PSD (the null direction
    ``a = b``) and no bound is claimed (0)."""
    if pairs:
        return 0.0, "none (split tangential rates make sym A0 singular on the cone)"
    scale = pencil_scale(A0)
    S0 = 0.5 * (A0 + A0.T) / scale
    S1 = 0.5 * (A1 + A1.T) / scale
    if not in_pd_plus_nn(S0):
        return 0.0, "none (sym A0 not certified copositive)"
    # Plain PD bound: sym A(mu) = S0 + mu S1 is PD for mu < -1 / min eig(S0^{-1} S1).
    L = np.linalg.cholesky(S0)
    C = np.linalg.solve(L, np.linalg.solve(L, S1).T).T
    nu = np.linalg.eigvalsh(0.5 * (C + C.T))
    pd = np.inf if nu[0] >= 0 else -1.0 / nu[0]
    pd_safe = pd * (1 - 1e-8)
    if pd_safe >= cap:
        return cap, "sym A(mu) positive definite on [0, cap]"
    lo, hi = pd_safe, cap
    if in_pd_plus_nn(S0 + hi * S1):
        return cap, "sym A(mu) in PD + NN at 0 and at cap (convexity)"
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        if in_pd_plus_nn(S0 + mid * S1):
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-6 * hi:
            break
    how = "sym A(mu) positive definite below mu_lb" if lo <= pd_safe else "sym A(mu) in PD + NN on [0, mu_lb] (convexity)"
    return lo, how


# --- branch and bound with SCIP -------------------------------------------------------------------

def _support_solutions(A0, A1, sup: np.ndarray, a: float, b: float) -> list[PatternSolution]:
    return enumerate_patterns(A0, A1, np.arange(A0.shape[0]), t_min=a, t_max=b, supports=sup[None])


def _scip_round(a0: np.ndarray, a1: np.ndarray, m_lo: float, cuts: list[np.ndarray],
                pairs: list[tuple[int, int]], seconds: float):
    """One SCIP solve: the smallest ``m`` in ``[m_lo, 1]`` with a support not cut.
    Returns (status, m, v, z, nodes, gap). SCIP's "error in LP solver" (seen on random pencils
    with the tighter LP tolerance) is retried once with SCIP's default LP tolerance."""
    t0 = time.perf_counter()
    try:
        return _scip_solve(a0, a1, m_lo, cuts, pairs, seconds, 0.1)
    except Exception as err:          # pyscipopt raises a bare Exception for SCIP errors
        if "LP" not in str(err):
            return f"SCIP error: {err}", None, None, None, 0, None     # reported: not proven
    try:
        return _scip_solve(a0, a1, m_lo, cuts, pairs, seconds - (time.perf_counter() - t0), 1.0)
    except Exception as err:
        return f"SCIP error: {err}", None, None, None, 0, None


def _scip_solve(a0: np.ndarray, a1: np.ndarray, m_lo: float, cuts: list[np.ndarray],
                pairs: list[tuple[int, int]], seconds: float, lp_factor: float):
    import pyscipopt

    s = a0.shape[0]
    # SCIP's feasibility tolerances can declare the problem infeasible when a solution lies within
    # ~1e-8 of an end of the interval (seen with a solution 1e-8 above the copositivity bound), so
    # the interval given to SCIP is widened by 1e-6 at both ends: an infeasibility proof on the
    # wider interval proves the narrower one, and every point it returns is checked exactly.
    lo, hi = m_lo * (1 - 1e-6), 1.0 + 1e-6
    model = pyscipopt.Model()
    model.hideOutput()
    model.setParam("limits/time", max(seconds, 0.1))
    model.setParam("numerics/feastol", 1e-9)
    model.setParam("parallel/maxnthreads", 1)
    # no NLP relaxation/heuristics: SCIP's Ipopt resolves MUMPS to the MPI build PETSc loaded, whose
    # MPI_Bcast on COMM_WORLD deadlocks when one rank alone certifies (distributed MCEIP-mu); the
    # proof rests on LP relaxations and spatial branching only
    model.setParam("nlp/disable", True)
    model.setParam("numerics/lpfeastolfactor", lp_factor)   # 0.1: LP tolerance 1e-10 (1e-12 needs GMP)
    # speed (issue 14): the model is infeasible once the known supports are cut, so primal heuristics
    # find nothing, and cutting planes cost more than the nodes they save (paper states s = 15-17: 4
    # proofs 0.62 -> 0.07 s CPU). Presolving stays at its default: with "fast" presolving (and
    # separation off) SCIP declared infeasible a random pencil with a clean solution (seed 394604 of
    # tests/test_certify.py; 3 misses in 80 random pencils, none with these settings in 290 with s = 1-13).
    model.setHeuristics(pyscipopt.SCIP_PARAMSETTING.OFF)
    model.setSeparating(pyscipopt.SCIP_PARAMSETTING.OFF)
    # SCIP catches Ctrl-C and stops with "userinterrupt", turned into KeyboardInterrupt below so
    # that an interrupted run stops promptly and cleans up like any other
    v = [model.addVar(f"v{i}", lb=0.0, ub=1.0) for i in range(s)]
    w = [model.addVar(f"w{i}", lb=0.0, ub=hi) for i in range(s)]
    z = [model.addVar(f"z{i}", vtype="B") for i in range(s)]
    m = model.addVar("m", lb=lo, ub=hi)
    # |y_i| <= max_j |(a0 + m a1)_ij| on the simplex, and |a0 + m a1| is convex in m: its largest
    # value on [m_lo, 1] is at an end (a proven big-M, tighter than max|a0| + max|a1|)
    Y = np.maximum(np.max(np.abs(a0 + lo * a1), axis=1), np.max(np.abs(a0 + hi * a1), axis=1))
    model.addCons(pyscipopt.quicksum(v) == 1.0)
    model.addCons(pyscipopt.quicksum(w) == m)           # e^T w = m e^T v (valid, tightens)
    for i in range(s):
        model.addCons(w[i] == m * v[i])
        model.addCons(w[i] <= hi * v[i])
        model.addCons(w[i] >= lo * v[i])                  # McCormick with m >= m_lo
        y = pyscipopt.quicksum(float(a0[i, j]) * v[j] + float(a1[i, j]) * w[j] for j in range(s)
                               if a0[i, j] != 0 or a1[i, j] != 0)
        model.addCons(y >= 0)
        model.addCons(y <= float(Y[i]) * (1 - z[i]))
        model.addCons(v[i] <= z[i])
    for ia, ib in pairs:
        model.addCons(z[ia] + z[ib] <= 1)
    for c in cuts:
        model.addCons(pyscipopt.quicksum(1 - z[i] for i in np.flatnonzero(c)) +
                      pyscipopt.quicksum(z[i] for i in np.flatnonzero(~c)) >= 1)
    model.setObjective(m, "minimize")
    model.optimize()
    status = model.getStatus()
    if status == "userinterrupt":
        raise KeyboardInterrupt
    nodes = model.getNNodes()
    gap = model.getGap() if status not in ("infeasible",) else 0.0
    if model.getNSols() > 0 and status in ("optimal", "timelimit", "gaplimit", "sollimit"):
        sol = model.getBestSol()
        return (status, float(model.getSolVal(sol, m)), np.array([model.getSolVal(sol, x) for x in v]),
                np.array([model.getSolVal(sol, x) > 0.5 for x in z]), nodes, gap)
    return status, None, None, None, nodes, gap


def certify_mu(A0: np.ndarray, A1: np.ndarray, cap: float, seconds: float = 30.0,
               enumerate_max: int = 14, pairs: list[tuple[int, int]] | None = None,
               candidates: list[PatternSolution] | None = None) -> Certificate:
    """Prove every solution of the condensed MCEIP-mu in ``[0, cap]`` (and so the onset).

    ``candidates`` (exact solutions from the search) only speed up the proof: their supports are
    listed and cut first. ``seconds`` is the budget: an unfinished proof is reported as such."""
    t0 = time.perf_counter()
    pairs = list(pairs or [])
    s = A0.shape[0]
    comp = np.arange(s)
    lb, how = copositivity_bound(A0, A1, cap, pairs)
    detail: dict = {"lower_bound": float(lb), "lower_bound_by": how, "s": s, "cap": float(cap)}
    if lb >= cap:
        return Certificate("copositivity (sign argument)", (0.0, cap), "proven", True, [], cap, 0.0,
                           time.perf_counter() - t0, detail)
    if s <= enumerate_max:
        sols = enumerate_patterns(A0, A1, comp, t_min=lb, t_max=cap, pairs=pairs)
        detail["supports"] = int(2 ** s - 1)
        return Certificate("exhaustive enumeration (24)-(26), batched LAPACK", (0.0, cap), "proven", True, sols,
                           lb, 0.0, time.perf_counter() - t0, detail)

    scale = pencil_scale(A0)
    a0, a1 = A0 / scale, A1 * cap / scale
    found: dict[tuple, PatternSolution] = {}
    cuts: list[np.ndarray] = []
    cut_keys: set[tuple] = set()

    def take(sup: np.ndarray) -> int:
        key = tuple(bool(b) for b in sup)
        if key in cut_keys:
            return 0
        sols = _support_solutions(A0, A1, np.asarray(key), lb, cap)
        for p in sols:
            found[(round(p.value, 10), key)] = p
        cut_keys.add(key)
        cuts.append(np.asarray(key))
        return len(sols)

    for p in candidates or []:
        if p.value <= cap * (1 + 1e-12):
            take(p.support)
    rounds, spurious, nodes = 0, 0, 0
    m_lo = lb / cap
    status = "not started"
    while True:
        left = seconds - (time.perf_counter() - t0)
        if left <= 0:
            status = "timelimit"
            break
        st, m, v, z, nn, gap = _scip_round(a0, a1, m_lo, cuts, pairs, left)
        rounds += 1
        nodes += nn
        if st == "infeasible":
            status = "infeasible"
            break
        if m is None:
            status = st
            break
        # The optimiser's point is only a hint: list the exact solutions of its pattern and cut it.
        got = take(z)
        if not got:
            sup_v = v > 1e-9 * np.max(v)
            got = take(sup_v) if not np.array_equal(sup_v, z) else 0
            spurious += 1
        if st != "optimal":
            status = st
            break
    sols = sorted(found.values(), key=lambda p: (p.value, tuple(~p.support)))
    detail.update({"scip_rounds": rounds, "scip_nodes": int(nodes), "patterns_cut": len(cuts),
                   "scip_points_without_exact_solution": spurious,
                   "candidates_given": len(candidates or [])})
    el = time.perf_counter() - t0
    if status == "infeasible":
        return Certificate("branch-and-bound (SCIP) with no-good cuts", (0.0, cap), "proven", True, sols, lb, 0.0,
                           el, detail)
    done_to = lb
    detail["scip_status"] = status
    return Certificate("branch-and-bound (SCIP) with no-good cuts", (0.0, lb),
                       f"not proven within {seconds:g} s", False, sols, done_to,
                       (cap - lb) / cap, el, detail)   # gap: share of [0, cap] left unproven


def enumerate_all(A0: np.ndarray, A1: np.ndarray, cap: float, pairs: list[tuple[int, int]] | None = None) -> Certificate:
    """Every solution with ``mu >= 0`` by exhaustive enumeration (small ``s``). The certificate's
    interval stays ``[0, cap]`` (the product question); the solutions above the cap are listed
    too, and are complete as well (``detail.complete_above_cap``)."""
    t0 = time.perf_counter()
    s = A0.shape[0]
    sols = enumerate_patterns(A0, A1, np.arange(s), t_min=0.0, t_max=np.inf, pairs=list(pairs or []))
    return Certificate("exhaustive enumeration (24)-(26), batched LAPACK", (0.0, cap), "proven", True,
                       sols, cap, 0.0, time.perf_counter() - t0,
                       {"s": s, "supports": int(2 ** s - 1), "cap": float(cap), "complete_above_cap": True})


# --- the MCEIP-mu result of one state: search + certificate ----------------------------------------

def mu_cap(scene_mu: float, settings) -> float:
    """The cap below which every critical mu is proven: ``settings.mu_cap`` if set, else
    ``settings.mu_cap_factor`` times the scene's mu (times 1 when the scene's mu is 0)."""
    if settings.mu_cap is not None:
        return float(settings.mu_cap)
    return float(settings.mu_cap_factor) * (scene_mu if scene_mu > 0 else 1.0)


def condensed_mu_result(A0: np.ndarray, A1: np.ndarray, cap: float, settings,
                        pairs: list[tuple[int, int]] | None = None,
                        warm: list[tuple[np.ndarray, float]] | None = None) -> dict:
    """MCEIP-mu (21)-(23) on the condensed pencil: candidates from the dense semismooth Newton
    search (:mod:`app.analyses.dense_mcp`), then the certificate for ``[0, cap]``.

    The ``solutions`` are the exact pairs (25)-(26): every one in ``[0, cap]`` (each with
    ``certified: true`` when the proof finished) and those the search found above the cap
    (``certified: false``). The state-level ``certified`` flag says whether the onset and every
    value up to the cap are proven; ``certificate`` says how.

    Above ``settings.search_full_max`` unknowns (issue 14: s up to ~180 at 100k DOFs) the search
    uses its reduced start set plus the ``warm`` starts ``(x, mu)`` (the previous classification's
    solutions mapped onto these unknowns), and SCIP gets ``settings.certify_seconds_large``."""
    from app.analyses import dense_mcp

    s = A0.shape[0]
    comp = np.arange(s)
    with one_blas_thread():
        if settings.certify and s <= settings.certify_enumerate_max and not pairs:
            # small s: exhaustive enumeration of every support is cheaper than the search and
            # proves the whole set, every critical mu >= 0 (not only those below the cap); with
            # zero-reaction nodes (pairs) the search + certificate below the cap stays
            rep, cert = dense_mcp.DenseSearchReport([], 0, 0, 0, 0.0, note=(
                f"no search: s = {s} <= certify_enumerate_max, every support enumerated")), enumerate_all(A0, A1, cap, pairs)
            by_key = {}
        else:
            rep = dense_mcp.search(A0, A1, pairs=pairs, mu0s=tuple(settings.starts) + (1000.0,),
                                   zero_one_max=settings.search_zero_one_max, full_max=settings.search_full_max,
                                   one_node=settings.search_one_node, warm=warm)
            by_key = {(round(c.exact.value, 9), tuple(c.exact.support)): c for c in rep.candidates}
            cert = None
        if settings.certify and cert is None:
            large = s > settings.search_full_max
            cert = certify_mu(A0, A1, cap, seconds=settings.certify_seconds_large if large else settings.certify_seconds,
                              enumerate_max=settings.certify_enumerate_max, pairs=pairs,
                              candidates=[c.exact for c in rep.candidates])
    proven = bool(cert is not None and cert.proven)
    sols: list[dict] = []
    seen: set = set()
    for p in (cert.solutions if cert is not None else []):
        key = (round(p.value, 9), tuple(p.support))
        seen.add(key)
        d = p.as_dict(comp)
        c = by_key.get(key)
        d.update({"iterations": c.iterations if c else 0,
                  "found_by": (c.found_by[:8] if c else []) + ([] if c else [f"certificate: {cert.method}"]),
                  "found_count": len(c.found_by) if c else 0, "certified": proven and p.value <= cap})
        sols.append(d)
    for key, c in by_key.items():
        if key in seen or (proven and c.exact.value <= cap):
            continue
        d = c.as_dict(comp)
        d["certified"] = False
        sols.append(d)
    sols.sort(key=lambda d: (d["value"], d["pattern"]))
    below = [d for d in sols if d["value"] <= cap]
    above = len(sols) - len(below)
    if cert is None:
        result = (f"{len(sols)} distinct solution(s) found" if sols else "no solution found") + \
                 " (not proven: certification switched off, settings.mcp.certify = false)"
    elif proven:
        if below:
            o = below[0]
            result = (f"proven: onset mu = {o['value']:.10g} (pattern "
                      f"{''.join('S' if q == 'slip' else '-' for q in o['pattern'])}), {len(below)} critical value(s) "
                      f"in [0, {cap:.6g}]")
        else:
            result = f"proven: no critical mu in [0, {cap:.6g}]"
        if above:
            result += (f"; {above} more above the cap (listed by the complete enumeration)"
                       if cert.detail.get("complete_above_cap") else f"; {above} more found above the cap (not proven complete)")
    else:
        result = (f"{cert.status}: {len(sols)} solution(s) found" if sols else f"{cert.status}: no solution found") + \
                 f"; proven only that none lies below {cert.lower_bound:.6g}"
    d: dict = {"solutions": sols, "result": result, "certified": proven,
               "certificate": (cert.as_dict() if cert is not None else
                               certificate("none", (0.0, 0.0), "not attempted", 0.0)),
               "search": {"method": "dense semismooth Newton (min-function), batched over starts",
                          "attempts": rep.starts, "converged": rep.converged,
                          "rejected_by_exact_check": rep.rejected, "seconds": round(rep.seconds, 4),
                          "found": len(rep.candidates), "intervals": ["[0, inf)"],
                          "complete": proven, "note": rep.note}}
    if cert is not None:
        d["certificate"]["cap"] = float(cap)
        d["certificate"]["onset"] = below[0]["value"] if (proven and below) else None
        ill = [x["value"] for x in below if x.get("ill_conditioned")]
        if ill:
            d["certificate"]["ill_conditioned"] = ill
    return d
