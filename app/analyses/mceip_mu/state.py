"""The MCEIP-mu result of one state: candidate search, then the proof (paper eqs. (21)-(23)).

The proof itself is :mod:`app.analyses.mceip_mu` (branch and bound with rigorous floating-point
tests, re-verified by an independent checker; docs/proofs.md). This module turns it into the
:class:`~app.analyses.outcomes.MceipMuOutcome` of the state, keeps the solutions the search found
above the cap (found, not proven), and builds the :class:`~app.analyses.outcomes.Certificate`
shared with MCEIP-lambda^2.
"""
from __future__ import annotations

import numpy as np

from app.analyses.mceip_mu.kernel import rounding as _rounding
from app.analyses.outcomes import STOPPED, Certificate, CompleteClaim, MceipMuOutcome, OnsetClaim, Solution
from app.linalg import one_blas_thread


def certificate(method: str, interval: tuple[float, float], status: str, seconds: float | None,
                detail: dict | None = None, gap: float | None = None, rigorous: bool = True) -> Certificate:
    """The :class:`~app.analyses.outcomes.Certificate` of an MCEIP outcome (mu or lambda^2).
    ``interval``: the range of the eigenvalue the status speaks about; ``status`` is ``"proven"``
    only when every solution in it is listed; ``seconds`` ``None`` when not timed (else rounded
    to 0.1 ms). ``rigorous``: every step of the argument carries a rigorous bound of its rounding
    error (or is exact); ``False`` for arguments that rest on floating-point eigenvalues or
    factorisations without such a bound (the summary then says "shown in floating point", not
    "proven")."""
    return Certificate(method=method, interval=(float(interval[0]), float(interval[1])), status=status, gap=gap,
                       seconds=None if seconds is None else round(float(seconds), 4), detail=detail or {},
                       rigorous=bool(rigorous))


def enumeration_certificate(sols: list[Solution]) -> Certificate:
    """The certificate of a finished exhaustive enumeration (every support was solved); marks
    every solution ``certified``."""
    for x in sols:
        x.mark(certified=True)
    return certificate("exhaustive enumeration (24)-(26), batched LAPACK", (0.0, np.inf), "proven", None,
                       {"solutions": len(sols)}, gap=0.0)


def in_pd_plus_nn(S: np.ndarray) -> bool:
    """Proven: the symmetric ``S`` is in ``PD + NN`` (so strictly copositive). Exact power-of-two
    diagonal scaling, splits ``N = theta * (positive off-diagonal part)``, ``theta`` in
    {0, 1, 1/2}, and the verified Cholesky of :func:`app.analyses.mceip_mu.kernel.rounding.verified_pd`."""
    S = np.asarray(S, dtype=float)
    if S.size == 0:
        return True
    d = np.diag(S)
    if not np.all(np.isfinite(S)) or np.any(d <= 0):
        return False
    e = np.frexp(np.sqrt(d))[1].astype(np.int64)
    Sn = np.ldexp(S, -(e[:, None] + e[None, :]))
    off = Sn - np.diag(np.diag(Sn))
    pos = np.maximum(off, 0.0)
    return any(_rounding.verified_pd(Sn - theta * pos) for theta in (0.0, 1.0, 0.5))


# --- the MCEIP-mu result of one state: search + certificate ----------------------------------------

def mu_cap(scene_mu: float, settings) -> float:
    """The cap below which every critical mu is proven: ``settings.mu_cap`` if set, else
    ``settings.mu_cap_factor`` times the scene's mu (times 1 when the scene's mu is 0)."""
    if settings.mu_cap is not None:
        return float(settings.mu_cap)
    return float(settings.mu_cap_factor) * (scene_mu if scene_mu > 0 else 1.0)


def time_limits(settings) -> str:
    """The wall-clock safety stops of the MCEIP-mu proofs in ``settings`` (an
    :class:`app.scene.sections.McpSettings`), for a status that one of them ended."""
    def one(key: str) -> str:
        v = getattr(settings, key)
        return f"{key} = {'off' if v is None else f'{v:g} s'}"
    return ", ".join(one(k) for k in ("certify_seconds", "certify_seconds_large", "certify_all_seconds"))


def condensed_mu_result(A0: np.ndarray, A1: np.ndarray, cap: float, settings,
                        pairs: list[tuple[int, int]] | None = None,
                        warm: list[tuple[np.ndarray, float]] | None = None) -> MceipMuOutcome:
    """MCEIP-mu (21)-(23) on the condensed pencil: floating-point candidates (exhaustive
    enumeration up to ``settings.certify_enumerate_max`` slip nodes, the dense semismooth Newton
    search of :mod:`app.analyses.mceip_mu.candidates` above), then the proof of :mod:`app.analyses.mceip_mu`.

    Two claims: the onset (smallest critical mu, or none in ``[0, cap]``) and the complete list
    in ``[0, cap]`` (attempted up to ``settings.certify_all_max`` slip nodes). ``certified`` is
    true when the independent checker accepted both; ``onset.proven`` when it accepted the first.
    Candidates above the cap are listed as found (``certified: false``). The pencil and the proof
    log travel in the private ``_proof`` key (written to ``proofs/`` beside results.json)."""
    from app.analyses.mceip_mu import candidates
    from app.analyses.mceip_mu.proven import mceip_mu, mceip_mu_none_below_cap
    from app.analyses.mceip_mu.prover.live import LIVE

    s = A0.shape[0]
    comp = np.arange(s)
    pairs = list(pairs or [])
    large = s > settings.search_full_max
    with one_blas_thread():
        if s > settings.certify_enumerate_max and large and settings.certify and settings.prove_first and \
                (quick := mceip_mu_none_below_cap(A0, A1, cap, pairs=pairs)) is not None:
            # proven without a search: no critical mu in [0, cap] (values above the cap, which a
            # search might meet, are outside every claim and not searched for)
            rep = candidates.DenseSearchReport([], 0, 0, 0, 0.0, note=(
                f"no search: s = {s} > search_full_max and the sign argument alone proved that no critical mu "
                f"lies in [0, {cap:.6g}] (values above the cap are not searched for)"))
            return _outcome(A0, A1, cap, quick, [], {}, rep, comp, settings)
        if s > settings.certify_enumerate_max:
            LIVE.reset("search")
        cands, rep = candidates.policy(A0, A1, pairs, settings.certify_enumerate_max,
                                       mu0s=tuple(settings.starts) + (1000.0,),
                                       zero_one_max=settings.search_zero_one_max, full_max=settings.search_full_max,
                                       one_node=settings.search_one_node, warm=warm)
        found_by = {(round(c.exact.value, 9), tuple(c.exact.support)): c for c in rep.candidates}
        proof = None
        if settings.certify:
            guide = [(np.flatnonzero(p.support), p.value, p.x) for p in cands if p.value <= cap * (1 + 1e-9)]
            # the budgets count tree nodes; the *_seconds keys are a wall-clock safety stop (None: off)
            proof = mceip_mu(A0, A1, cap, pairs=pairs, candidates=guide,
                             seconds=settings.certify_seconds_large if large else settings.certify_seconds,
                             want_all=s <= settings.certify_all_max, all_seconds=settings.certify_all_seconds,
                             all_nodes=settings.certify_all_nodes,
                             onset_nodes=settings.certify_onset_nodes_large if large else settings.certify_onset_nodes)
    return _outcome(A0, A1, cap, proof, cands, found_by, rep, comp, settings)


def _solution_dict(value, x, support, comp, a0, a1, norms: tuple[float, float]) -> dict:
    """The results.json entry of one solution (paper axes: x on the slip nodes, sum 1);
    ``norms``: the 2-norms of ``a0`` and ``a1`` (the residual is relative to the pencil at mu)."""
    y = (a0 + value * a1) @ x
    stick = y[~support]
    return {"value": float(value), "x_Ts": [float(v) for v in x[comp]],
            "pattern": ["slip" if b else "stick" for b in support],
            # relative to the pencil's size at this mu (what rounding can resolve there)
            "residual": float(np.linalg.norm(y[support]) / max(np.linalg.norm(x) * (norms[0] + abs(value) * norms[1]),
                                                                1e-300)),
            "complementarity": float(np.max(np.abs(x * y), initial=0.0)),
            "min_x_Ts": float(np.min(x[support]) / max(np.max(x), 1e-300)) if support.any() else 0.0,
            "min_y_Ts": float(np.min(y)) if len(y) else 0.0,
            "margin_y_stick": float(np.min(stick)) if len(stick) else None}


def _outcome(A0, A1, cap, proof, cands, found_by, rep, comp, settings) -> MceipMuOutcome:
    """The MCEIP-mu outcome: the solutions, the proof's claims, the search."""
    sols = [Solution.from_fields(d) for d in _solutions(A0, A1, cap, proof, cands, found_by, comp)]
    if proof is None:
        result, cert, onset, complete, certified = _unproven(sols)
    else:
        result, cert, onset, complete, certified = _proven(proof, sols, cap, settings)
    search = {"method": "dense semismooth Newton (min-function), batched over starts",
              "attempts": rep.starts, "converged": rep.converged,
              "rejected_by_exact_check": rep.rejected, "seconds": round(rep.seconds, 4),
              "found": len(cands), "intervals": ["[0, inf)"], "complete": certified, "note": rep.note}
    stored = None
    if proof is not None:
        stored = {"A0": np.asarray(A0, dtype=float), "A1": np.asarray(A1, dtype=float),
                  "log": proof.log.to_json(), "pairs": [list(p) for p in proof.log.pairs]}
    return MceipMuOutcome(solutions=sols, result=result, search=search, certified=certified, certificate=cert,
                          onset=onset, complete=complete, proof=stored)


def _solutions(A0, A1, cap, proof, cands, found_by, comp) -> list[dict]:
    """The solutions in the proof (with their enclosures) and the search's candidates it did not
    rule out, sorted by value and pattern."""
    from app.analyses.enumerate import pencil_scale
    sc = pencil_scale(A0)
    a0, a1 = A0 / sc, A1 / sc
    norms = (float(np.linalg.norm(a0, 2)), float(np.linalg.norm(a1, 2)))     # once: an SVD each
    sols: list[dict] = []
    keys: list[tuple] = []
    if proof is not None:
        enclosures: list[tuple[float, float]] = []
        for p in proof.solutions:
            # the same eigenvalue of the same support, reached from two leaves of the proof (their
            # verified windows overlap, and each holds one eigenvalue of that support): listed once,
            # as proven if either leaf proved it
            same = next((i for i, ((_, sup), (lo, hi)) in enumerate(zip(keys, enclosures))
                         if sup == tuple(p.support) and lo <= p.enclosure[1] and p.enclosure[0] <= hi), None)
            if same is not None and (sols[same]["certified"] or not p.proven):
                continue
            d = _solution_dict(p.value, p.x, p.support, comp, a0, a1, norms)
            d.update({"enclosure": [float(p.enclosure[0]), float(p.enclosure[1])],
                      "proven_min_x_Ts": float(p.min_x),
                      "proven_margin_y_stick": float(p.min_y) if np.isfinite(p.min_y) else None,
                      "ill_conditioned": bool(p.ill_conditioned), "certified": bool(p.proven),
                      "found_by": ["proof (verified window)"], "found_count": 1, "iterations": 0})
            c = found_by.get((round(p.value, 9), tuple(p.support)))
            if c is not None:
                d.update({"iterations": c.iterations, "found_by": c.found_by[:8], "found_count": len(c.found_by)})
            if same is not None:
                sols[same], keys[same], enclosures[same] = d, (p.value, tuple(p.support)), tuple(p.enclosure)
                continue
            sols.append(d)
            keys.append((p.value, tuple(p.support)))
            enclosures.append((float(p.enclosure[0]), float(p.enclosure[1])))
    for p in cands:
        if any(abs(p.value - v) <= 1e-8 * max(1.0, abs(v)) and sup == tuple(p.support) for v, sup in keys):
            continue
        if proof is not None and p.value <= cap and (proof.all.proven or p.value <= proof.lower_bound):
            continue          # not confirmed by the proof: below a proven bound it is no solution
        d = p.as_dict(comp)
        # the residual as for the proven ones: relative to the pencil's size at this mu
        d["residual"] = _solution_dict(p.value, p.x, p.support, comp, a0, a1, norms)["residual"]
        c = found_by.get((round(p.value, 9), tuple(p.support)))
        d.update({"certified": False, "iterations": c.iterations if c else 0,
                  "found_by": c.found_by[:8] if c else ["floating-point enumeration (24)-(26)"],
                  "found_count": len(c.found_by) if c else 1})
        sols.append(d)
    sols.sort(key=lambda d: (d["value"], d["pattern"]))
    return sols


def _unproven(sols: list[Solution]):
    """(result, certificate, onset, complete, certified) when certification is switched off."""
    result = (f"{len(sols)} distinct solution(s) found" if sols else "no solution found") + \
             " (not proven: certification switched off, settings.mcp.certify = false)"
    cert = certificate("none", (0.0, 0.0), "not attempted", 0.0)
    onset = OnsetClaim(proven=False, status="not attempted")
    complete = CompleteClaim(proven=False, status="not attempted", interval=[0.0, 0.0])
    certified = False
    return result, cert, onset, complete, certified


def _proven(proof, sols: list[Solution], cap: float, settings):
    """(result, certificate, onset, complete, certified) of a proof (:mod:`app.analyses.mceip_mu`)."""
    above = sum(1 for d in sols if d.value > cap)
    o, a = proof.onset, proof.all
    if o.proven and o.value is not None:
        pat = next((d.pattern for d in sols if abs(d.value - o.value) <= 1e-9 * max(1.0, o.value)), [])
        result = (f"proven onset: mu = {o.value:.10g} (pattern {''.join('S' if q == 'slip' else '-' for q in pat)}, "
                  f"enclosure [{o.enclosure[0]:.10g}, {o.enclosure[1]:.10g}])")
    elif o.proven:
        result = f"proven: no critical mu in [0, {cap:.6g}]"
    else:
        result = f"onset {o.status}"
    if a.proven:
        result += f"; proven complete: {len(a.values)} critical value(s) in [0, {cap:.6g}]"
    elif proof.s <= settings.certify_all_max:
        result += f"; list {a.status} (budget certify_all_nodes = {settings.certify_all_nodes} tree nodes"
        result += f"; time limit {time_limits(settings)})" if proof.timed_out else ")"
    else:
        result += f"; list not attempted (s = {proof.s} > certify_all_max = {settings.certify_all_max})"
    if above:
        result += f"; {above} more found above the cap (not proven)"
    if proof.timed_out and not o.proven:
        result += f" (time limit {time_limits(settings)})"
    certified = bool(proof.certified)
    if certified:
        status = "proven"
    elif o.proven:
        status = "onset proven; list " + ("ill-conditioned" if proof.ill_conditioned else
                                          STOPPED if proof.timed_out else "not proven")
    elif proof.ill_conditioned:
        status = "ill-conditioned"
    else:
        status = f"not proven: {STOPPED}" if proof.timed_out else "not proven within budget"
    cert = certificate(proof.method, (0.0, cap) if certified else a.interval, status, proof.seconds,
                       {"s": proof.s, "cap": float(cap), "nodes": proof.nodes, "lower_bound": proof.lower_bound,
                        "check_seconds": round(proof.check_seconds, 4), "candidates": proof.candidates,
                        # what the independent checker re-verified: both claims, the onset, or (the
                        # prover's budget spent first) the lower bound alone
                        "checker": "accepted" if certified else ("onset accepted" if o.proven else
                                                                  "lower bound accepted"),
                        **({"stopped_by_time_limit": True} if proof.timed_out else {})},
                       gap=0.0 if certified else (cap - a.interval[1]) / cap)
    cert.cap = float(cap)
    cert.onset = o.value if o.proven else None
    cert.ill_conditioned = [d.value for d in sols if d.evidence.get("ill_conditioned")] or None
    onset = OnsetClaim(proven=o.proven, status=o.status, value=o.value,
                       enclosure=list(o.enclosure) if o.enclosure else None)
    complete = CompleteClaim(proven=a.proven, status=a.status, interval=list(a.interval),
                             count=len(a.values) if a.proven else None)
    return result, cert, onset, complete, certified
