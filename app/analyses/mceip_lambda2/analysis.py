"""MCEIP-lambda^2 (12)-(14) of one classified state: proof of no solution where it can be had, else search.

Order: (19) at the scene's mu (no divergence when it fails), the exact slip-node reduction
(:mod:`app.analyses.mceip_lambda2.exact`, small systems), then the SNES VI search of
:func:`app.analyses.snes_vi.search.search_mceip` boxed by the inertia-proven bound of
:mod:`app.analyses.mceip_lambda2.bounds`. Every result carries ``certified`` and a ``certificate``.
"""
from __future__ import annotations

import time

import numpy as np

from app.analyses.conditions import eliminated, full_size
from app.analyses.mceip_lambda2 import bounds as l2b
from app.analyses.mceip_lambda2 import dynamic_contact as l2d
from app.analyses.mceip_lambda2 import exact as l2x
from app.analyses.mceip_lambda2 import reduced_search as l2rs
from app.analyses.mceip_mu.state import certificate
from app.analyses.outcomes import MceipLambda2Outcome, NecessaryOutcome, SufficientOutcome
from app.analyses.pencils.reduced import diag_scale
from app.analyses.pencils.state import StatePencils, keep_modes, no_slip, on_rank_zero, warm_hints
from app.analyses.snes_vi.search import search_mceip
from app.scene.schema import Scene
from app.systems.base import System


def mceip_lambda2(system: System, p: StatePencils, scene: Scene, s: int,
                  nec: NecessaryOutcome | None = None) -> MceipLambda2Outcome:
    """MCEIP-lambda^2 (12)-(14) at ``scene.lambda2_mu`` with what is proven (app/analyses/mceip_lambda2/bounds.py):
    no solution when (19) fails; otherwise no solution above an inertia-proven bound ``T``, and
    ``[0, T]`` searched by SNES VI (found, not proven). Every result has ``certified`` and a
    ``certificate``; solutions above the free-block spectrum or whose pattern does not solve its
    restricted eigenproblem are labelled ill-conditioned."""
    mu = scene.lambda2_mu
    t_start = time.perf_counter()
    if s == 0:
        result, search = no_slip()
        d = MceipLambda2Outcome(solutions=[], result=result, search=search, certified=True,
                                certificate=certificate("no slip nodes (x_Ts is empty)", (0.0, np.inf), l2b.PROVEN, 0.0))
    elif system.static_constraint:
        # an incompressible material: no elimination of the pressure, hence no values or signs of
        # (19) and no bound on lambda^2 (sym K* is unbounded below there, docs/method.md section 10)
        with system.stages("MCEIP-lambda2 (12)-(14)"):
            d = _lambda2_search(p, scene, None, mu, t_start)
    else:
        with system.stages("MCEIP-lambda2 (12)-(14)"):
            d = _on_contact_dofs(p, scene, mu, t_start) if nec is None else None
            if d is not None:
                d.mu = mu
                return d
        mixed = system.has_static_dofs
        if nec is None and mixed:  # the full-size pencils hold the pressure: (19) from the contact DOFs
            with system.stages("MCEIP-lambda2 (12)-(14)"):
                try:
                    nec = eliminated.eliminated_necessary(p, mu, scene.settings.eig,
                                                                warm_hints(system, mu))     # MPI collective
                except RuntimeError:   # the values declined, the system too large: searched without a bound
                    d = _lambda2_search(p, scene, None, mu, t_start)
                    d.mu = mu
                    return d
        if nec is None:           # the full-size pencils, only where the contact DOFs do not decide
            K0, K1 = p.K()
            M0, M1 = p.M()
            with system.stages("MCEIP-lambda2 (12)-(14)"):
                nec = full_size.necessary(K0, K1, M0, M1, mu, scene.settings.eig, warm_hints(system, mu), p.star(mu))
        if not nec.satisfied and not mixed:     # the verified sign argument factorises them
            K0, K1 = p.K()
            M0, M1 = p.M()
        with system.stages("MCEIP-lambda2 (12)-(14)"):
            if not nec.satisfied:
                # x^T y = 0 at a solution, so lambda^2 x^T M* x + x^T K* x = 0: impossible when
                # K*(mu) is PD and M*(mu) PSD. No search is needed: there is no solution.
                search = {"complete": True, "necessary_condition": nec.as_dict(),
                          "note": "no solution: the necessary condition (19) fails at this mu (K* PD, M* PSD), "
                                  "which proves that (12)-(14) has no solution"}
                # with the pressure (mixed element) the full-size symmetric parts are not (19)'s:
                # the signs are those of the contact DOFs' values, floating point
                rigorous = not mixed and l2b.verified_sign_argument(
                    K0, K1, M0, M1, mu, scene.settings.mcp.lambda2_exact_max_dofs)   # MPI collective
                cert = certificate(
                    "sign argument: x^T y = 0 at a solution, impossible with sym K*(mu) PD and sym M*(mu) PSD (19)"
                    + ("; both proven PD by verified dense Cholesky factorisations" if rigorous else
                       "; PD from floating-point eigenvalues of the system with the pressure eliminated (values "
                       "of (19) on the contact DOFs), not verified" if mixed else
                       "; PD from floating-point eigenvalues (SLEPc), not verified"),
                    (0.0, np.inf), l2b.PROVEN, time.perf_counter() - t_start,
                    {"min_eig_K_sym": nec.min_eig_K_sym, "min_eig_M_sym": nec.min_eig_M_sym}, gap=0.0,
                    rigorous=rigorous)
                d = MceipLambda2Outcome(solutions=[], result="no solution (proved by the necessary condition (19))",
                                        search=search, certified=True, certificate=cert)
            else:
                d = _lambda2_search(p, scene, nec, mu, t_start)
    d.mu = mu
    return d


def _rayleigh_bound(nec: NecessaryOutcome) -> float | None:
    """``-min eig sym K* / min eig sym M*`` (widened by 1e-6): ``x^T (lambda^2 M* + K*) x = x^T y = 0``
    at a solution bounds lambda^2 by it when sym M*(mu) is PD (and sym K*(mu) is not); else None."""
    m_rel = (nec.min_eig_M_sym_relative if nec.min_eig_M_sym_relative is not None
             else nec.min_eig_M_sym_relative_bounds[0])
    if m_rel > 1e-12 and nec.lower("K") < 0:     # lower bounds where only bounds are known: a bound still
        return -nec.lower("K") / nec.lower("M") * (1 + 1e-6)
    return None


def _on_rank_zero(p: StatePencils, scene: Scene, work):
    """``work(dc)`` on rank 0, which alone holds the system's exact reduction (dense, or K and M
    gathered there; on a curved obstacle with its contact frames and curvature term,
    :class:`app.analyses.pencils.kept_contact.KeptContact`), broadcast to every rank; None where
    it could not be built. MPI collective."""
    dc = l2d.dynamic_contact(p.system, scene.settings.mcp.lambda2_exact_max_dofs)    # MPI collective (first call)

    def alone():
        if dc is None:
            return None
        evaluations = dc.evaluations
        with p.system.stages("MCEIP-lambda2 exact reduction"):
            got = work(dc)
        return got, dc.evaluations - evaluations, dc.method, dc.seconds

    return on_rank_zero(p.system, alone)                                              # MPI collective


def _on_contact_dofs(p: StatePencils, scene: Scene, mu: float, t_start: float) -> MceipLambda2Outcome | None:
    """MCEIP-lambda^2 decided on the contact DOFs alone, without the full-size eigenvalues of (19)
    (the scene did not ask for the necessary condition): its signs from the Schur complements of
    ``sym K*``, ``sym M*`` onto the kept contact DOFs (no solution when ``sym K*`` is PD and
    ``sym M*`` PSD), else the proof on the exact reduction from a power-of-two start bound. None
    when neither decides (the caller then computes (19) on the full pencils and searches)."""
    reduced = _search_reduced(p, scene)

    def work(dc):
        signs = l2x.contact_signs(dc, p.cls, mu)
        if (signs.k_pd and signs.m_psd) or not signs.m_pd:
            return signs, None, None
        start = l2x.start_bound(dc, p.cls, mu)
        if start is None:
            return signs, None, None
        proof = l2x.prove_no_solution(dc, p.cls, mu, start, max_failed=MAX_FAILED if reduced else 0)
        return signs, (start, *proof), _search_failed(dc, p.cls, mu, proof, scene) if reduced else None

    got = _on_rank_zero(p, scene, work)
    if got is None:
        return None
    (signs, proof, found), factorisations, method, setup_seconds = got
    detail = {"sym_K_star_pd": signs.k_pd, "sym_M_star_psd": signs.m_psd, "sym_M_star_pd": signs.m_pd,
              "new_factorisations": factorisations, "set_up_seconds": round(setup_seconds, 4)}
    if signs.k_pd and signs.m_psd:
        how = ("sign argument: x^T y = 0 at a solution, impossible with sym K*(mu) PD and sym M*(mu) PSD (19), "
               f"both decided on their Schur complements onto the kept contact DOFs (through the {method}; "
               "floating point, not verified)")
        search = {"complete": True, "note": "no solution: " + how}
        cert = certificate(how, (0.0, np.inf), l2b.PROVEN, time.perf_counter() - t_start, detail, gap=0.0,
                           rigorous=False)
        return MceipLambda2Outcome(solutions=[], result="no solution (proved by the necessary condition (19))",
                                   search=search, certified=True, certificate=cert)
    bound = None if proof is None else {
        "method": "Schur complement of sym K* + T sym M* onto the slip nodes PD (bisected from the "
                  "power of two found by doubling from tr K_cc / tr M_cc)",
        "start_bound": proof[0], "proven_bound": proof[2]}
    if reduced and (proof is None or not proof[1]):
        why = None if proof is not None else (
            "sym M*(mu) not PD: no bound on lambda^2" if not signs.m_pd else
            "no power of two T with the Schur complement of sym K* + T sym M* onto the slip nodes PD")
        return _reduced_outcome(method, bound, proof, found, {"contact_signs": detail}, t_start, why)
    if proof is None or not proof[1]:
        return None
    start, _, T, pdetail = proof
    return _shown_outcome(method, T, bound, {**pdetail, **detail}, t_start, {"contact_signs": detail})


#: intervals of t the proof may set aside for the search on the reduction (beyond: not decided)
MAX_FAILED = 16


def _search_reduced(p: StatePencils, scene: Scene) -> bool:
    """Where the proof fails, search on the exact reduction rather than by SNES VI on the full system."""
    return p.system.n_dofs > scene.settings.mcp.lambda2_full_search_max_dofs


def _search_failed(dc, cls, mu: float, proof: tuple[bool, float, dict], scene: Scene):
    """The search on the reduction in the intervals the proof set aside (None when the proof
    succeeded or did not end with such a list: a budget spent, no bound ``T``)."""
    proven, _, detail = proof
    if proven or not detail.get("covered"):
        return None
    return l2rs.search(dc, cls, mu, detail["failed"], scene.settings.mcp.search_full_max,
                       scene.settings.mcp.search_one_node)


def _reduced_outcome(method: str, bound: dict | None, proof, found, extra: dict, t_start: float,
                     why: str | None = None) -> MceipLambda2Outcome:
    """The outcome where the proof on the exact reduction failed above ``lambda2_full_search_max_dofs``:
    no solution outside the intervals it set aside (floating point), those intervals searched on the
    reduction (:mod:`app.analyses.mceip_lambda2.reduced_search`); or, where it set none aside (a
    budget spent, no bound: ``why``), not decided and not searched."""
    seconds = time.perf_counter() - t_start
    pdetail = {} if proof is None else proof[3]
    if found is None:
        why = pdetail.get("reason", why)
        search = {"complete": False, "upper_bound": bound, **extra,
                  "note": f"not decided: the proof on the exact slip-node reduction stopped ({why}), and the system is "
                          "above mcp.lambda2_full_search_max_dofs, where the full system is not searched"}
        cert = certificate("none", (0.0, 0.0), "not proven: not searched (the system is above "
                           "mcp.lambda2_full_search_max_dofs and the proof on the reduction stopped)", seconds,
                           {**pdetail, **extra}, rigorous=False)
        return MceipLambda2Outcome(solutions=[], result="not decided (proof stopped; not searched)", search=search,
                                   certified=False, certificate=cert)
    T = proof[2]
    for sol in found.solutions:
        sol.mark(certified=False)
    gaps = [list(ab) for ab in found.intervals]
    how = (f"sign argument on the exact slip-node reduction S(t) (free DOFs eliminated through the {method}): "
           "sym S(t) certified copositive on [0, T] outside the listed intervals, and the Schur complement of "
           "sym(K* + T M*) PD with sym M* PD for t >= T; the listed intervals searched on the reduction")
    search = {"complete": False, "upper_bound": bound, "lambda2_upper_bound": T, **extra,
              "searched_on_reduction": {"intervals": gaps, "candidates": found.candidates, "rejected": found.rejected,
                                        "exact_values": found.evaluations, "seconds": round(found.seconds, 4)},
              "note": "no solution outside the listed intervals (shown in floating point); solutions in them "
                      "searched on the exact reduction, not proven complete"}
    cert = certificate(how, (0.0, np.inf), "not proven: no solution with lambda^2 >= 0 outside "
                       f"{len(gaps)} interval(s) of total length {sum(b - a for a, b in gaps):.6g}, searched there",
                       seconds, {**pdetail, "proven_empty_except": gaps, "T": T}, gap=None, rigorous=False)
    n = len(found.solutions)
    result = (f"{n} solution(s) found on the exact reduction (not proven)" if n else
              "no solution found (not proven): none outside the listed intervals, none found in them")
    return MceipLambda2Outcome(solutions=found.solutions, result=result, search=search, certified=False,
                               certificate=cert)


def _shown_outcome(method: str, T: float, bound: dict, detail: dict, t_start: float,
                   extra: dict) -> MceipLambda2Outcome:
    """The outcome "no solution" shown on the exact slip-node reduction on [0, T] and above ``T``."""
    how = (f"sign argument on the exact slip-node reduction S(t) (free DOFs eliminated through the {method}): "
           "sym S(t) certified copositive on [0, T] by intervals (concave + convex "
           "split, PD + NN at the ends), and the Schur complement of sym(K* + T M*) PD with sym M* PD for t >= T")
    search = {"attempts": 0, "converged": 0, "accepted": 0, "by_method": {}, "intervals": [],
              "starts": [], "identical_runs_skipped": 0, "complete": True,
              "note": "no search needed: " + how, **extra, "lambda2_upper_bound": T, "upper_bound": bound}
    # the reduction rests on a floating-point eigen-decomposition of (K, M) or factorisation of
    # K + t M without a rigorous error bound: its PD + NN tests are verified, the reduction is not
    cert = certificate(how, (0.0, np.inf), l2b.PROVEN, time.perf_counter() - t_start, {**detail, "T": T}, gap=0.0,
                       rigorous=False)
    return MceipLambda2Outcome(solutions=[], result="proven: no solution with lambda^2 >= 0", search=search,
                               certified=True, certificate=cert)


def _lambda2_proof(p: StatePencils, scene: Scene, nec: NecessaryOutcome, mu: float,
                   t_start: float) -> MceipLambda2Outcome | None:
    """MCEIP-lambda^2 proven to have no solution on the exact slip-node reduction
    (app/analyses/mceip_lambda2/exact.py), or None when that proof does not apply or does not succeed."""
    rayleigh = _rayleigh_bound(nec)
    if rayleigh is None:
        return None
    reduced = _search_reduced(p, scene)

    def work(dc):
        # on large systems the bisection starts from the power of two found by doubling, as without
        # (19): the same for most classifications of a path, so their values of t are shared (the
        # Rayleigh bounds differ from one classification to the next, and so would the grids)
        start = l2x.start_bound(dc, p.cls, mu) if reduced else None
        proof = l2x.prove_no_solution(dc, p.cls, mu, rayleigh if start is None else start,
                                      max_failed=MAX_FAILED if reduced else 0)
        return start, proof, _search_failed(dc, p.cls, mu, proof, scene) if reduced else None

    got = _on_rank_zero(p, scene, work)
    if got is None:
        return None
    (start, (proven, T, detail), found), factorisations, method, setup_seconds = got
    bound = {"method": "Schur complement of sym K* + T sym M* onto the slip nodes PD (bisected from the "
                       + ("Rayleigh-quotient bound -min eig sym K* / min eig sym M*)" if start is None else
                          "power of two found by doubling from tr K_cc / tr M_cc)"),
             "rayleigh_bound": rayleigh, "proven_bound": T, **({} if start is None else {"start_bound": start})}
    if not proven and reduced:
        return _reduced_outcome(method, bound, (rayleigh, proven, T, detail), found,
                                {"necessary_condition": nec.as_dict(), "new_factorisations": factorisations}, t_start)
    if not proven:
        return None
    return _shown_outcome(method, T, bound,
                          {**detail, "new_factorisations": factorisations, "set_up_seconds": round(setup_seconds, 4)},
                          t_start, {"necessary_condition": nec.as_dict()})


def _eigenpair_solutions(p: StatePencils, scene: Scene, mu: float, sols: list) -> int:
    """Add to ``sols`` the admissible eigenpairs of (17)-(18) at ``mu`` (``lambda^2 > 0``,
    ``x_Ts >= 0``, ``y = 0``: solutions of (12)-(14) with every slip node slipping or at rest) that
    the search did not find; returns how many. For the incompressible material, whose search has no
    bound on lambda^2 to box it. MPI collective."""
    Ks, Ms = p.star(mu)
    static = p.space.positions(p.system.static_dofs) if p.system.has_static_dofs else None     # MPI collective
    suff = full_size.sufficient(Ks, Ms, p.space.comp, scene.settings.eig, keep_modes=keep_modes(scene),
                                static=static)                                         # MPI collective
    added = 0
    for m in suff.modes:
        if any(abs(m.value - s.value) <= 1e-8 * m.value for s in sols):
            continue
        err = m.evidence.get("relative_error")
        m.evidence = {"residual": err, "complementarity": 0.0, "min_x_Ts": float(min(m.x_Ts)), "min_y_Ts": 0.0,
                      "iterations": 0, "found_by": ["admissible eigenpair of (17)-(18) (y = 0)"], "found_count": 1,
                      "pattern_residual": err, "pattern_verified": True}
        sols.append(m)
        added += 1
    sols.sort(key=lambda s: s.value)
    return added


def _search_bound(p: StatePencils, scene: Scene, nec: NecessaryOutcome | None, mu: float,
                  Ks, Ms) -> tuple[float, dict]:
    """The bound ``T`` on lambda^2 that boxes the search, and how it was had."""
    # x^T (lambda^2 M* + K*) x = x^T y = 0 bounds lambda^2 by the Rayleigh quotients:
    # lambda^2 <= -min eig sym(K*) / min eig sym(M*) when sym(M*) is PD; an LDL^T inertia
    # count of sym K* + T sym M* proves a smaller bound T (app/analyses/mceip_lambda2/bounds.py).
    upper, bound = np.inf, {"method": "none (sym M*(mu) not PD: no upper bound on lambda^2)" if nec is not None else
                                      "none (an incompressible material: sym K*(mu) is unbounded below and gives no "
                                      "bound on lambda^2)" if p.system.static_constraint else
                                      "none (no values of (19) with the pressure eliminated for this classification)"}
    rayleigh = None if nec is None else _rayleigh_bound(nec)
    if rayleigh is not None and p.system.has_static_dofs:
        # the pencils hold the pressure, whose inertia is not the eliminated system's: the bound from
        # the Schur complement onto the slip nodes instead (exact.tail_bound)
        got = _on_rank_zero(p, scene, lambda dc: l2x.tail_bound(dc, p.cls, mu, rayleigh))   # MPI collective
        if got is not None and got[0] is not None:
            upper = got[0]
            bound = {"method": "Schur complement of sym K* + T sym M* onto the slip nodes PD (bisected from "
                               "the Rayleigh-quotient bound -min eig sym K* / min eig sym M*; floating point)",
                     "rayleigh_bound": rayleigh, "proven_bound": upper}
        else:
            upper, bound = rayleigh, {"method": "the Rayleigh-quotient bound -min eig sym K* / min eig sym M* "
                                                "(values of (19), floating point)",
                                      "rayleigh_bound": rayleigh, "proven_bound": rayleigh}
    elif rayleigh is not None:
        hints = warm_hints(p.system, mu)
        prev = hints.get("lambda2_bound")
        upper, detail = l2b.proven_upper_bound(Ks, Ms, rayleigh, guess=None if prev is None else 1.05 * prev)
        hints["lambda2_bound"] = upper       # warm start for the next classification
        bound = {"method": "sym K* + T sym M* PD by an LDL^T inertia count, bisected from the "
                           "Rayleigh-quotient bound -min eig sym K* / min eig sym M*",
                 "rayleigh_bound": rayleigh, "proven_bound": upper, **detail}
    return upper, bound


def _lambda2_search(p: StatePencils, scene: Scene, nec: NecessaryOutcome | None, mu: float,
                    t_start: float) -> MceipLambda2Outcome:
    """The proof on the exact reduction where it succeeds, else the SNES VI search boxed by the
    best bound available (``nec`` None: the pressure is a constraint, no bound)."""
    proof = None if nec is None else _lambda2_proof(p, scene, nec, mu, t_start)
    if proof is not None:
        return proof
    Ks, Ms = p.star(mu)        # shared with the conditions (19), (17)-(18); destroyed with p
    tau = diag_scale(Ks) / diag_scale(Ms)
    upper, bound = _search_bound(p, scene, nec, mu, Ks, Ms)
    rep = search_mceip(Ks, Ms, p.space.comp, "lambda2", scene.settings.mcp, value_scale=tau,
                       t_upper=upper, pivoting=p.system.has_static_dofs)
    sols = rep.typed_solutions(keep_vectors=keep_modes(scene))
    search = rep.search()
    search.update(necessary_condition=None if nec is None else nec.as_dict(), lambda2_upper_bound=upper,
                  upper_bound=bound)
    added = _eigenpair_solutions(p, scene, mu, sols) if nec is None else 0       # MPI collective (not bounded)
    if added:
        search["from_sufficient_condition"] = added
    omega2 = None
    if sols and p.system.static_constraint:
        pass                             # no elimination of the pressure: not computed
    elif sols and p.system.has_static_dofs:     # the pressure rows carry no mass: eliminated first
        omega2 = l2b.free_block_max_omega2_eliminated(Ks, Ms, p.space.comp,
                                                      p.space.positions(p.system.static_dofs))   # MPI collective
    elif sols:
        omega2 = l2b.free_block_max_omega2(Ks, Ms, p.space.comp)
    for sol in sols:
        sol.mark(certified=False)
        why = []
        if omega2 is not None and sol.value > omega2:
            why.append(f"lambda^2 above the free-block spectrum (max omega^2 = {omega2:.6g}): the mode "
                       "decays by orders of magnitude between nodes, unresolvable in double precision")
        if not sol.evidence.get("pattern_verified", True):
            why.append("the pattern does not solve its restricted eigenproblem (25)-(26) to the tolerance")
        sol.mark(ill_conditioned=bool(why))
        if why:
            sol.mark(conditioning="; ".join(why))
    if omega2 is not None:
        search["free_block_max_omega2"] = omega2
    result = rep.result() if not added else (
        f"{len(sols)} distinct solution(s) found ({added} from the admissible eigenpairs of (17)-(18))")
    clean = [x for x in sols if not x.evidence["ill_conditioned"]]
    if len(clean) < len(sols):
        result = (f"{len(clean)} clean solution(s) and {len(sols) - len(clean)} "
                  "ill-conditioned one(s) found (not proven)")
    hi = upper if np.isfinite(upper) else np.inf
    cert = certificate(
        bound["method"] if np.isfinite(upper) else "none",
        (hi, np.inf) if np.isfinite(hi) else (0.0, 0.0),
        ("proven: no solution with lambda^2 in the interval; " if np.isfinite(hi) else "") +
        f"not proven: [0, {hi:.6g}] searched by SNES VI (solutions found there are not proven complete)",
        time.perf_counter() - t_start,
        {"proven_empty": [hi, np.inf] if np.isfinite(hi) else None, "searched_not_proven": [0.0, hi]})
    return MceipLambda2Outcome(solutions=sols, result=result, search=search, certified=False, certificate=cert)


def sufficient_on_reduction(p: StatePencils, scene: Scene, lambda2: MceipLambda2Outcome) -> SufficientOutcome | None:
    """(17)-(18) at the scene's mu where MCEIP-lambda^2 at that mu was searched on the exact
    reduction (above ``mcp.lambda2_full_search_max_dofs``), without an eigensolver on the full
    system: an admissible eigenpair solves (12)-(14) with ``y = 0``, so none lies outside the
    intervals of ``t`` the proof set aside, and inside them the real eigenpairs come from the
    reduction (:func:`app.analyses.mceip_lambda2.reduced_search.eigenpairs`; their modes on the
    slip nodes only). None when ``lambda2`` was not searched so. MPI collective."""
    gaps = (lambda2.search or {}).get("searched_on_reduction", {}).get("intervals")
    if gaps is None:
        return None
    got = _on_rank_zero(p, scene, lambda dc: l2rs.eigenpairs(dc, p.cls, scene.mu, [tuple(g) for g in gaps]))
    if got is None:
        return None
    pairs, factorisations, method, _ = got
    s = len(p.cls.slip)
    out = full_size.admissible(pairs, len(pairs),
                               f"the exact slip-node reduction S(t) (through the {method}): real roots of det S(t) in "
                               f"the {len(gaps)} interval(s) of lambda^2 where MCEIP-lambda^2's proof set aside "
                               "copositivity (none outside them), chord pencils then secant steps; a search, not a "
                               "proof", np.arange(s), False)
    out.mu = scene.mu
    return out