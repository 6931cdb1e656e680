"""MCEIP-mu on a curved obstacle: the quadratic complementarity eigenproblem (docs/method.md section 8).

On a curved obstacle the condensed pencil of the transition problem is quadratic in mu,

    A(mu) x = y,   A(mu) = A0 + mu A1 + mu^2 A2,   mu >= 0,   0 <= x ⊥ y >= 0,   x != 0,

with ``A2 = G = diag(kappa_i P_i)`` on the slip nodes. Solutions are found by enumeration of the
``2^s - 1`` supports ``J`` (the slip nodes that keep slipping in the mode): each support is the
quadratic eigenproblem ``A(mu)[J, J] x_J = 0``, solved through its first companion
linearisation

    [[0, I], [-A0_JJ, -A1_JJ]] z = mu [[I, 0], [0, A2_JJ]] z,    z = (x_J, mu x_J),

(QZ, scipy.linalg.eig: a singular ``A2`` gives infinite eigenvalues, which are dropped), and
(batched: with ``A0_JJ`` invertible, the eigenvalues ``1/mu`` of the reversed companion matrix
``[[0, I], [-A0_JJ^-1 A2_JJ, -A0_JJ^-1 A1_JJ]]`` through LAPACK on the whole stack of supports of
one size), and each real ``mu >= 0`` with a null vector ``x_J > 0`` and ``y = A(mu)[J^c, J] x_J >= 0`` is a
solution (the sign checks (26)). With ``A2 = 0`` this is the flat enumeration (24)-(26).

What this proves: by itself nothing. The enumeration is exhaustive over supports, but each
eigenproblem and each sign check is decided in floating point, so its results are *found by
exhaustive enumeration, not proven*; margins below ``RESOLVE_TOL`` are flagged
``ill_conditioned``. Refused above ``max_slip`` slip nodes (``settings.enumerate_max_slip``).
:func:`quadratic_mu_result` adds a proof: up to ``PROOF_MAX_S`` slip nodes the exact proof of
:mod:`app.analyses.mceip_mu.quadratic.proof` (rational determinants, isolated real roots, ball
arithmetic, every support), above it the branch and bound of
:mod:`app.analyses.mceip_mu.quadratic.bb` (families of supports closed with rigorous bounds, single
supports decided by the same exact proof, the log re-verified by
:mod:`app.analyses.mceip_mu.quadratic.check`). When it is complete the list in ``[0, cap]`` is
proven and each solution carries a rigorous ``enclosure``; a branch and bound out of time may
prove the onset alone; otherwise everything stays *found, not proven*.
"""
from __future__ import annotations

import math
import time

import numpy as np
import scipy.linalg

from app.analyses.enumerate import (
    BATCH_ELEMENTS,
    RESIDUAL_TOL,
    RESOLVE_TOL,
    TooManySlipNodes,
    pencil_scale,
    supports_of_size,
)
from app.analyses.mceip_mu.quadratic.rows import drop_infinite, lower_rows, zero_node_rows
from app.analyses.outcomes import STOPPED, CompleteClaim, MceipMuOutcome, OnsetClaim, Solution
from app.linalg import one_blas_thread


def quadratic_eigenvalues(a0: np.ndarray, a1: np.ndarray, a2: np.ndarray) -> np.ndarray:
    """Finite eigenvalues of ``(a0 + mu a1 + mu^2 a2) x = 0`` (complex array), by QZ on the
    first companion linearisation."""
    k = a0.shape[0]
    Z, I = np.zeros((k, k)), np.eye(k)
    L = np.block([[Z, I], [-a0, -a1]])
    B = np.block([[I, Z], [Z, a2]])
    w = scipy.linalg.eig(L, B, right=False)
    return w[np.isfinite(w)]


def _batch_eigenvalues(B0: np.ndarray, B1: np.ndarray, B2: np.ndarray) -> np.ndarray:
    """Eigenvalues mu of the stacked quadratic pencils (shape (m, 2k), complex; inf where infinite).

    With ``B0`` invertible, ``nu = 1/mu`` are the eigenvalues of the companion matrix of the
    reversed polynomial ``nu^2 B0 + nu B1 + B2``, ``[[0, I], [-B0^-1 B2, -B0^-1 B1]]`` (batched
    LAPACK); a numerically singular ``B0`` goes to QZ (:func:`quadratic_eigenvalues`)."""
    m, k, _ = B0.shape
    out = np.full((m, 2 * k), np.inf, dtype=complex)
    try:
        C1 = np.linalg.solve(B0, B1)
        C2 = np.linalg.solve(B0, B2)
        n0 = np.linalg.norm(B0, 1, axis=(1, 2))
        ok = np.all(np.isfinite(C1), axis=(1, 2)) & np.all(np.isfinite(C2), axis=(1, 2))
        ok &= (np.linalg.norm(C1, 1, axis=(1, 2)) < 1e12 * np.maximum(np.linalg.norm(B1, 1, axis=(1, 2)), 1e-300) / np.maximum(n0, 1e-300))
        ok &= (np.linalg.norm(C2, 1, axis=(1, 2)) < 1e12 * np.maximum(np.linalg.norm(B2, 1, axis=(1, 2)), 1e-300) / np.maximum(n0, 1e-300))
    except np.linalg.LinAlgError:
        ok = np.zeros(m, dtype=bool)
    if ok.any():
        j = np.flatnonzero(ok)
        L = np.zeros((len(j), 2 * k, 2 * k))
        L[:, :k, k:] = np.eye(k)
        L[:, k:, :k] = -C2[j]
        L[:, k:, k:] = -C1[j]
        nu = np.linalg.eigvals(L)
        zero = np.abs(nu) <= 1e-12 * np.maximum(np.linalg.norm(L, 1, axis=(1, 2)), 1e-300)[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            out[j] = np.where(zero, np.inf, 1.0 / np.where(zero, 1.0, nu))
    for j in np.flatnonzero(~ok):
        w = quadratic_eigenvalues(B0[j], B1[j], B2[j])
        out[j, :len(w)] = w
    return out


def enumerate_quadratic(A0: np.ndarray, A1: np.ndarray, A2: np.ndarray, max_slip: int,
                        mu_max: float = np.inf, comp: np.ndarray | None = None,
                        pairs: list[tuple[int, int]] | None = None) -> list[dict]:
    """Every solution of the quadratic MCEIP-mu with ``0 <= mu <= mu_max``, by supports (batched
    over the supports of one size, as app/analyses/enumerate.py does for the linear pencil).

    ``comp``: positions of the complementarity unknowns ``x_c`` (default: all; the others are
    ``x_f`` with ``y_f = 0``, kept in every support as in (25)); ``pairs``: the ``(a, b)``
    positions (full numbering) of the split tangential rates of zero-reaction nodes, which no
    support holds both of (:func:`app.analyses.enumerate.supports_of_size`), and whose stick margin
    vanishing by the exact identity ``y_b = -y_a + 2 mu y_N`` counts as ``y = 0``
    (:func:`app.analyses.mceip_mu.quadratic.proof.structural_zeros`).

    Returns dicts with ``value``, ``x_Ts`` (``x_c``, sum 1), ``pattern``, ``residual`` (smallest
    singular value of ``A(mu)[R, R]`` relative to ``||a0|| + mu ||a1|| + mu^2 ||a2||``),
    ``complementarity``, ``min_x_Ts``, ``min_y_Ts``, ``margin_y_stick`` and ``ill_conditioned``;
    sorted by value.
    """
    n = A0.shape[0]
    comp = np.arange(n, dtype=np.int64) if comp is None else np.asarray(comp, dtype=np.int64)
    s = len(comp)
    if s > max_slip:
        raise TooManySlipNodes(f"{s} slip nodes: enumeration of the 2^{s} supports of the quadratic MCEIP-mu "
                               f"refused (settings.enumerate_max_slip = {max_slip})")
    free = np.setdiff1d(np.arange(n), comp)
    nf = len(free)
    cpos = {int(c): k for k, c in enumerate(comp)}
    cpairs = [(cpos[int(a)], cpos[int(b)]) for a, b in (pairs or [])]
    sc = pencil_scale(A0)
    a0, a1, a2 = A0 / sc, A1 / sc, A2 / sc
    triples = zero_node_rows(a0, a1, a2, pairs or [])
    out: list[dict] = []
    seen: list[tuple[float, tuple]] = []
    with one_blas_thread():
        for k in range(1, s + 1):
            P = supports_of_size(s, k, cpairs)
            nr = nf + k
            step = max(1, BATCH_ELEMENTS // (4 * nr * nr))
            for lo in range(0, len(P), step):
                Pb = P[lo:lo + step]
                Rb = np.concatenate([np.broadcast_to(free, (len(Pb), nf)), comp[Pb]], axis=1)
                B0 = a0[Rb[:, :, None], Rb[:, None, :]]
                B1 = a1[Rb[:, :, None], Rb[:, None, :]]
                B2 = a2[Rb[:, :, None], Rb[:, None, :]]
                C1, C2 = lower_rows(B0, B1, B2, Rb, triples)
                W = drop_infinite(_batch_eigenvalues(B0, C1, C2), C1, C2)
                real = np.isfinite(W) & (np.abs(W.imag) <= 1e-6 * np.maximum(1.0, np.abs(W.real)))
                wr = np.where(real, W.real, np.nan)
                cand = real & (wr >= -1e-12) & (wr <= (mu_max * (1 + 1e-12) if np.isfinite(mu_max) else np.inf))
                ii, jj = np.nonzero(cand)
                if not len(ii):
                    continue
                mu = np.maximum(wr[ii, jj], 0.0)
                At = B0[ii] + mu[:, None, None] * B1[ii] + (mu * mu)[:, None, None] * B2[ii]
                _, sv, Vh = np.linalg.svd(At)
                norms = (np.linalg.norm(B0[ii], 2, axis=(1, 2)) + mu * np.linalg.norm(B1[ii], 2, axis=(1, 2))
                         + mu * mu * np.linalg.norm(B2[ii], 2, axis=(1, 2)))
                res = sv[:, -1] / np.maximum(norms, 1e-300)
                v = Vh[:, -1, :]
                v = v * np.where(v[:, nf:].sum(axis=1) < 0, -1.0, 1.0)[:, None]
                xp = v[:, nf:]
                mx = np.min(xp, axis=1) / np.maximum(np.max(np.abs(xp), axis=1), 1e-300)
                for c in np.flatnonzero((mx > 0) & (res <= RESIDUAL_TOL)):
                    J, m_c = Pb[ii[c]], float(mu[c])
                    if any(abs(val - m_c) <= 1e-10 * max(1.0, m_c) and sup == tuple(J) for val, sup in seen):
                        continue        # a double eigenvalue: one solution
                    x = np.zeros(n)
                    x[Rb[ii[c]]] = v[c] / xp[c].sum()
                    d = _record((a0, a1, a2), x, m_c, J, comp, pairs or [], float(res[c]), float(mx[c]))
                    if d is not None:
                        seen.append((m_c, tuple(J)))
                        out.append(d)
    return sorted(out, key=lambda d: (d["value"], d["pattern"]))


def _record(a, x: np.ndarray, mu: float, J, comp, pairs, res: float, mx: float) -> dict | None:
    """The solution record of the null vector ``x`` of support ``J`` at ``mu``, or None when a
    stick margin is negative (the rows of ``structural_zeros`` are ``y = 0`` exactly)."""
    from app.analyses.mceip_mu.quadratic.proof import structural_zeros
    a0, a1, a2 = a
    y = (a0 + mu * a1 + mu * mu * a2) @ x
    sup = np.zeros(len(comp), dtype=bool)
    sup[J] = True
    exact0 = set(structural_zeros(a0, a1, a2, comp[J], pairs).tolist())
    stick = np.array([y[comp[i]] for i in np.flatnonzero(~sup) if int(comp[i]) not in exact0])
    my = float(np.min(stick)) if len(stick) else np.inf
    if my < -RESOLVE_TOL:
        return None
    xc, yc = x[comp], y[comp]
    return {"value": mu, "x_Ts": [float(t) for t in xc], "pattern": ["slip" if b else "stick" for b in sup],
            "residual": res, "complementarity": float(np.max(np.abs(xc * yc))),
            "min_x_Ts": mx, "min_y_Ts": float(np.min(yc)), "margin_y_stick": my if np.isfinite(my) else None,
            "ill_conditioned": bool(mx < RESOLVE_TOL or my < RESOLVE_TOL)}


#: up to this many slip nodes the exact per-support proof of app/analyses/mceip_mu/quadratic/proof.py
#: (every support, 0.3 s at s = 8); above it the branch and bound of
#: app/analyses/mceip_mu/quadratic/bb.py, whose leaves are the same exact per-support decisions
PROOF_MAX_S = 8
#: the proofs/ record of a per-support proof: the pencil and the claim's cap; the exact proof is
#: deterministic, so re-checking it is proving it again from the stored pencil
QUADRATIC_FORMAT = "mceip-mu-quadratic/1"
#: the proofs/ record of a branch and bound: the pencil and its log, re-verified by the checker
#: of app/analyses/mceip_mu/quadratic/check.py
QUADRATIC_BB_FORMAT = "mceip-mu-quadratic-bb/1"
_METHOD_EXACT = ("exact determinant polynomial of every support (rational arithmetic), its real roots isolated, "
                 "the signs of the null vector and of y by ball arithmetic (FLINT)")
_METHOD_BB = ("branch and bound over families of supports and mu intervals, closed by the sign argument and "
              "Farkas vectors at the four corners of the lifting of mu^2 and by nonsingularity (rigorous "
              "rounding bounds), single supports decided exactly (FLINT); the log re-verified by an independent checker")


def quadratic_mu_result(A0: np.ndarray, A1: np.ndarray, A2: np.ndarray, cap: float, max_slip: int,
                        certify: bool = True, seconds: float | None = None, pairs=None,
                        nodes: int | None = None) -> MceipMuOutcome:
    """The MCEIP-mu outcome for a curved obstacle: the solutions found by the exhaustive
    floating-point enumeration and (``certify``) a proof on ``[0, cap]``, the exact per-support
    proof up to ``PROOF_MAX_S`` slip nodes, the checked branch and bound above (also above
    ``max_slip``, where nothing is enumerated): each solution it proves is ``certified`` with
    its ``enclosure``; candidates it proves not to be solutions are dropped. Without a proof
    every solution is found, not proven; a branch and bound out of budget may still prove the onset.
    ``pairs``: the ``(a, b)`` halves of the zero-reaction nodes' split tangential rates (no
    support holds both; the proofs verify them on the pencil).

    Budgets count work: the per-support proof decides at most the ``2^PROOF_MAX_S - 1`` supports,
    the branch and bound builds at most ``nodes`` tree nodes (``None``:
    :data:`app.analyses.mceip_mu.quadratic.bb.NODES`; ``settings.mcp.certify_quadratic_nodes`` in
    a study). ``seconds`` is only a wall-clock safety stop (``None``: none); a proof it ends is
    reported as "stopped by the time limit"."""
    pairs = [(int(a), int(b)) for a, b in (pairs or [])]
    t0 = time.perf_counter()
    s = A0.shape[0]
    how = "quadratic MCEIP-mu: every support enumerated, companion linearisation + QZ, sign checks (26) in floating point"
    try:
        sols = enumerate_quadratic(A0, A1, A2, max_slip, pairs=pairs)
        search = {"method": how, "attempts": _supports(s, pairs), "found": len(sols), "intervals": ["[0, inf)"],
                  "complete": False, "note": "every support enumerated; decided in floating point (not a proof)"}
    except TooManySlipNodes as err:
        sols, search = None, {"method": how, "complete": False, "note": str(err)}
    for d in sols or []:
        d.update(certified=False, found_by=["exhaustive enumeration of the quadratic pattern problems"],
                 found_count=1, iterations=0)
    search["seconds"] = round(time.perf_counter() - t0, 4)
    proof = None
    if certify and s <= PROOF_MAX_S:
        from app.analyses.mceip_mu.quadratic.proof import prove_quadratic
        proof = prove_quadratic(A0, A1, A2, cap, max_s=PROOF_MAX_S, pairs=pairs,
                                deadline=None if seconds is None else time.perf_counter() + seconds)
    elif certify:
        from app.analyses.mceip_mu.quadratic.bb import prove_bb
        proof = prove_bb(A0, A1, A2, cap, max_nodes=nodes, pairs=pairs,
                         deadline=math.inf if seconds is None else time.perf_counter() + seconds)
    if sols is None and (proof is None or not proof.proven):
        if proof is not None and proof.onset_proven:      # nothing enumerated, the onset proven all the same
            return _unproven(A0, A1, A2, [], search, proof, s, cap, t0)
        return _not_searched(search, proof, s, cap)
    if proof is None or not proof.proven:
        return _unproven(A0, A1, A2, sols, search, proof, s, cap, t0)
    out, rejected = _proven_list(A0, A1, A2, sols or [], proof, cap)
    on = proof.onset
    pat = "".join("S" if i in on.support else "-" for i in range(s)) if on else ""
    result = ((f"proven onset: mu = {on.value:.10g} (pattern {pat}, enclosure [{on.enclosure[0]:.10g}, "
               f"{on.enclosure[1]:.10g}])" if on else f"proven: no critical mu in [0, {cap:.6g}]")
              + f"; proven complete: {len(proof.solutions)} critical value(s) in [0, {cap:.6g}]"
              + (f"; {sum(1 for d in out if d['value'] > cap)} more found above the cap (not proven)"
                 if any(d["value"] > cap for d in out) else ""))
    bb = hasattr(proof, "log")
    cert = _certificate(_METHOD_BB if bb else _METHOD_EXACT, cap, "proven", t0, proof, s, rejected)
    cert.cap, cert.onset = float(cap), on.value if on else None
    log = dict(proof.log) if bb else {"format": QUADRATIC_FORMAT, "cap": float(cap), "max_s": PROOF_MAX_S,
                                      "pairs": [list(p) for p in pairs]}
    return MceipMuOutcome(
        solutions=[Solution.from_fields(d) for d in out], result=result, certified=True,
        onset=OnsetClaim(proven=True, status="proven", value=on.value if on else None,
                         enclosure=list(on.enclosure) if on else None),
        complete=CompleteClaim(proven=True, status="proven", interval=[0.0, float(cap)], count=len(proof.solutions)),
        certificate=cert, search={**search, "complete": True}, quadratic=True,
        # the pencil travels to proofs/ (app/io/proofs.py), where `app check` verifies it again
        proof={"A0": np.asarray(A0, dtype=float), "A1": np.asarray(A1, dtype=float),
               "A2": np.asarray(A2, dtype=float), "log": log})


def _supports(s: int, pairs) -> int:
    """How many supports the enumeration decides: ``2^s - 1`` without those holding a pair."""
    return (2 ** (s - 2 * len(pairs))) * (3 ** len(pairs)) - 1


def _certificate(method: str, cap: float, status: str, t0: float, proof, s: int, rejected: int):
    from app.analyses.mceip_mu.state import certificate  # the certificate record's format only
    extra = {"s": s, "cap": float(cap), "supports": proof.supports, "proof_seconds": round(proof.seconds, 4),
             "rejected_floating_point_candidates": rejected}
    if hasattr(proof, "log"):
        extra.update(nodes=len(proof.log["nodes"]), prover_seconds=round(proof.prover_seconds, 4))
    return certificate(method, (0.0, cap), status, time.perf_counter() - t0, extra, gap=0.0)


def _not_searched(search: dict, proof, s: int, cap: float) -> MceipMuOutcome:
    """Above ``max_slip`` without the onset proven: nothing enumerated; what the branch and bound
    proved (no critical mu below the mu where it stopped, checked) is said."""
    from app.analyses.mceip_mu.state import certificate  # the certificate record's format only
    note = search["note"] + ("" if proof is None else f"; the branch and bound was {STOPPED}" if proof.timed_out
                             else "; the branch and bound did not finish within its node budget")
    rep = getattr(proof, "report", None)
    lb = float(min(rep.open_from, cap)) if rep is not None and not rep.errors and not rep.solutions else 0.0
    if lb > 0.0:
        status = (f"{STOPPED}: " if proof.timed_out else "not proven: ") + \
            f"proven only that no critical mu lies in [0, {lb:.6g}]"
        result = f"{status} ({note})"
        cert = certificate(_METHOD_BB, (0.0, lb), status, proof.seconds, {"s": s, "cap": float(cap), "lower_bound": lb})
    else:
        status, result = ("not searched: " + STOPPED if proof is not None and proof.timed_out else "not searched",
                          f"not searched: {note}")
        cert = certificate("none", (0.0, 0.0), "not attempted", 0.0)
    return MceipMuOutcome(solutions=[], result=result, certified=False,
                          onset=OnsetClaim(proven=False, status=status),
                          complete=CompleteClaim(proven=False, status=status, interval=[0.0, lb]),
                          certificate=cert, search={**search, "note": note}, quadratic=True)


def _unproven(A0, A1, A2, sols: list[dict], search: dict, proof, s: int, cap: float, t0: float) -> MceipMuOutcome:
    """The record when no proof was attempted or it is incomplete: the enumerated solutions,
    found, not proven, except a branch and bound's proven onset (and the proven solutions)."""
    from app.analyses.mceip_mu.state import certificate  # the certificate record's format only
    if proof is not None and getattr(proof, "onset_proven", False):
        out, rejected = _proven_list(A0, A1, A2, sols, proof, proof.report.open_from)
        on = proof.onset
        open_from = proof.report.open_from
        stopped = f" ({STOPPED})" if proof.timed_out else ""
        result = (f"proven onset: mu = {on.value:.10g} (enclosure [{on.enclosure[0]:.10g}, {on.enclosure[1]:.10g}]); "
                  f"not proven complete: every critical mu below {open_from:.6g} is listed, the branch and bound "
                  f"left mu in [{open_from:.6g}, {cap:.6g}] open{stopped}")
        cert = _certificate(_METHOD_BB, cap, f"proven onset; complete only below mu = {open_from:.6g}{stopped}", t0,
                            proof, s, rejected)
        cert.cap, cert.onset = float(cap), on.value
        return MceipMuOutcome(
            solutions=[Solution.from_fields(d) for d in out], result=result, certified=False,
            onset=OnsetClaim(proven=True, status="proven", value=on.value, enclosure=list(on.enclosure)),
            complete=CompleteClaim(proven=False, status=(STOPPED if proof.timed_out else "not proven")
                                   + f" (complete below mu = {open_from:.6g})",
                                   interval=[0.0, 0.0]),
            certificate=cert, search=search, quadratic=True,
            proof={"A0": np.asarray(A0, dtype=float), "A1": np.asarray(A1, dtype=float),
                   "A2": np.asarray(A2, dtype=float), "log": dict(proof.log)})
    first = sols[0]["value"] if sols else None
    unproven = "found, " + (STOPPED if proof is not None and getattr(proof, "timed_out", False) else "not proven")
    why = ("" if proof is None else
           f"; the proof left {len(proof.undecided)} support(s) or node(s) undecided, e.g. {proof.undecided[0][1]}")
    result = ((f"{len(sols)} solution(s) found, smallest mu = {first:.10g}" if sols else "no solution found")
              + " (found by exhaustive floating-point enumeration of the quadratic pattern problems, not proven"
              + why + ")")
    cert = certificate("none (floating-point enumeration)", (0.0, 0.0),
                       ("not proven" if unproven.endswith("not proven") else STOPPED)
                       + ": exhaustive floating-point enumeration of the 2^s supports",
                       time.perf_counter() - t0, {"s": s, "cap": float(cap), "solutions": len(sols),
                                                  **({"undecided": len(proof.undecided)} if proof else {})})
    return MceipMuOutcome(solutions=[Solution.from_fields(d) for d in sols], result=result, certified=False,
                          onset=OnsetClaim(proven=False, status=unproven, value=first),
                          complete=CompleteClaim(proven=False, status=unproven, interval=[0.0, 0.0]),
                          certificate=cert, search=search, quadratic=True)


def _proven_list(A0, A1, A2, sols: list[dict], proof, cap: float) -> tuple[list[dict], int]:
    """The proof is complete on ``[0, cap]`` (``cap``: the end of what it proves complete): its list replaces the floating-point candidates
    there (each matched one ``certified`` with its enclosure, the others dropped as rounding
    artefacts, the proven ones the enumeration missed added). Returns the solutions and the
    number of dropped candidates."""
    s = A0.shape[0]
    out, rejected = [], 0
    unmatched = [p for p in proof.solutions if p.enclosure[0] <= cap]
    for d in sols:
        if d["value"] > cap:
            out.append(d)                                   # above the cap: found, not proven
            continue
        sup = tuple(i for i, p in enumerate(d["pattern"]) if p == "slip")
        hit = next((p for p in unmatched if p.support == sup and
                    (p.enclosure[0] <= d["value"] <= p.enclosure[1]
                     or abs(d["value"] - p.value) <= 1e-9 * max(1.0, p.value))), None)
        if hit is None:
            rejected += 1                                   # proven not a solution (a rounding artefact)
            continue
        unmatched.remove(hit)
        d.update(certified=True, enclosure=[hit.enclosure[0], hit.enclosure[1]], value=hit.value)
        out.append(d)
    for p in unmatched:                                     # proven, missed by the floating-point enumeration
        x = _null_vector(A0, A1, A2, p.support, p.value)
        out.append({"value": p.value, "x_Ts": x, "pattern": ["slip" if i in p.support else "stick" for i in range(s)],
                    "certified": True, "enclosure": list(p.enclosure), "found_by": ["exact proof"], "found_count": 1,
                    "iterations": 0, "ill_conditioned": False})
    out.sort(key=lambda d: (d["value"], d["pattern"]))
    return out, rejected


def _null_vector(A0, A1, A2, support, mu) -> list[float]:
    J = list(support)
    B = (A0 + mu * A1 + mu * mu * A2)[np.ix_(J, J)]
    v = np.linalg.svd(B)[2][-1]
    v = v * np.sign(v.sum())
    x = np.zeros(A0.shape[0])
    x[J] = v / v.sum()
    return [float(t) for t in x]
