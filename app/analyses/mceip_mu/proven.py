"""Proven condensed MCEIP-mu (paper eqs. (21)-(23)): prover, independent checker, typed result.

    >>> from app import mceip_mu
    >>> r = mceip_mu(A0, A1, cap=11.0)
    >>> r.onset.proven, r.onset.value, r.all.proven, r.all.values

:func:`mceip_mu` runs the branch and bound of :mod:`app.analyses.mceip_mu.prover` (guided by
floating-point candidates: exhaustive enumeration for small ``s``, the dense semismooth Newton
search above), then re-verifies the proof log with :mod:`app.analyses.mceip_mu.kernel.checker`,
which does not import the prover; a claim is ``proven`` only when the checker accepted it.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from app.analyses.mceip_mu.kernel import checker, prooflog
from app.analyses.mceip_mu.prover import claims
from app.analyses.mceip_mu.prover.leaves import Found
from app.analyses.outcomes import STOPPED
from app.linalg import one_blas_thread

#: below this many slip nodes the float candidates come from exhaustive enumeration
ENUMERATE_CANDIDATES_MAX = 12


@dataclass
class Solution:
    """A critical mu: support (slip nodes that keep slipping), enclosure, mode and margins."""

    value: float
    enclosure: tuple[float, float]     # proven to contain the exact critical mu (if ``proven``)
    support: np.ndarray                # bool over the s slip nodes
    x: np.ndarray                      # slip rates on the s slip nodes, sum 1
    min_x: float                       # proven lower bound of min x_P / max x_P
    min_y: float                       # proven lower bound of the stick margins (inf: none)
    proven: bool                       # the checker verified it (listed as part of a proven claim)
    ill_conditioned: bool = False


@dataclass
class Claim:
    """One of the two claims: ``onset`` (the smallest critical mu, or none below the cap) and
    ``all`` (every critical mu in ``[0, cap]``). ``interval``: the part of ``[0, cap]`` the claim
    is proven on (``[0, lower_bound]`` when unfinished)."""

    name: str
    proven: bool
    status: str
    interval: tuple[float, float]
    value: float | None = None                        # onset: the value (None: none below the cap)
    enclosure: tuple[float, float] | None = None      # onset: proven enclosure
    values: list[float] = field(default_factory=list)  # all: the critical values in [0, cap]


@dataclass
class MuProof:
    """The result of :func:`mceip_mu` for one pencil."""

    s: int
    cap: float
    onset: Claim
    all: Claim
    solutions: list[Solution]
    lower_bound: float                 # proven: no critical mu in [0, lower_bound]
    ill_conditioned: bool              # some decision could not be resolved in double precision
    certified: bool                    # both claims accepted by the checker
    log: prooflog.ProofLog
    nodes: int
    seconds: float                     # prover
    check_seconds: float               # checker
    candidates: int = 0
    timed_out: bool = False            # the wall-clock safety stop, not the node budget, ended a claim
    method: str = ("branch and bound over support families F <= P <= U and mu intervals: sign argument with "
                   "diagonal scalings, Farkas vectors of the linear relaxation, Krawczyk windows, verified "
                   "nonsingularity; re-verified by an independent checker")


def _candidates(a0: np.ndarray, a1: np.ndarray, cap: float, pairs, search_kw: dict | None):
    """Floating-point candidates ``(support, mu, x)`` below the cap: they guide the proof, never
    decide it (:func:`app.analyses.mceip_mu.candidates.policy`)."""
    from app.analyses.mceip_mu import candidates
    sols, _ = candidates.policy(a0, a1, list(pairs), ENUMERATE_CANDIDATES_MAX, **(search_kw or {}))
    return [(np.flatnonzero(p.support), p.value, p.x) for p in sols if p.value <= cap * (1 + 1e-9)]


def mceip_mu(A0: np.ndarray, A1: np.ndarray, cap: float, pairs=None, seconds: float | None = None,
             want_all: bool = True, candidates=None, search: dict | None = None,
             all_seconds: float | None = None, onset_nodes: int = 20000, all_nodes: int = 4000) -> MuProof:
    """Proven critical friction coefficients of the condensed pencil ``A0 + mu A1`` (s x s).

    Parameters
    ----------
    A0, A1
        The condensed MCEIP-mu pencil (paper eq. (15) condensed on the slip nodes; any real
        square matrices are accepted, ``A0`` is typically symmetric positive definite).
    cap
        The claims speak about ``[0, cap]``.
    pairs
        Index pairs ``(a, b)`` that may not both slip (split tangential rates of zero-reaction
        nodes).
    seconds
        Wall-clock safety stop of the search and proof (``None``: none). Not a budget: a claim it
        ends is reported as "stopped by the time limit" (``timed_out``).
    want_all
        Also prove the complete list in ``[0, cap]`` (else the onset only).
    all_seconds
        Wall-clock safety stop of the complete-list claim once the onset is proven (``None``: none
        of its own).
    onset_nodes, all_nodes
        The budgets of the two claims, in tree nodes (deterministic: the same answer on any
        machine, under any load); an unfinished claim says what is proven (``lower_bound``).
    candidates
        Optional ``(support indices, mu, x)`` from another search (guidance only).
    search
        Keyword arguments for the dense candidate search (large ``s``).

    Returns
    -------
    MuProof
        The two claims, the solutions (verified enclosures), the proof log and timings.
    """
    A0 = np.asarray(A0, dtype=float)
    A1 = np.asarray(A1, dtype=float)
    if A0.ndim != 2 or A0.shape[0] != A0.shape[1] or A1.shape != A0.shape:
        raise ValueError(f"A0 and A1 must be square and of one shape, got {A0.shape} and {A1.shape}")
    if not (np.all(np.isfinite(A0)) and np.all(np.isfinite(A1))):
        raise ValueError("A0 and A1 must be finite")
    if not (np.isfinite(cap) and cap > 0):
        raise ValueError(f"cap must be a positive finite number, got {cap!r}")
    pairs = [tuple(int(i) for i in p) for p in (pairs or [])]
    with one_blas_thread():
        t0 = time.perf_counter()
        cands = list(candidates) if candidates is not None else _candidates(A0, A1, cap, pairs, search)
        out = claims.prove(A0, A1, cap, pairs=pairs, candidates=cands,
                           seconds=None if seconds is None else max(seconds - (time.perf_counter() - t0), 0.0),
                           want_all=want_all,
                           all_seconds=all_seconds, onset_nodes=onset_nodes, all_nodes=all_nodes)
        t1 = time.perf_counter()
        rep = checker.check_log(A0, A1, out.log)
        t_check = time.perf_counter() - t1
    return _result(A0, A1, cap, out, rep, len(cands), t_check)


def mceip_mu_none_below_cap(A0: np.ndarray, A1: np.ndarray, cap: float, pairs=None,
                            max_nodes: int = 63) -> MuProof | None:
    """The proof that the condensed pencil has no critical mu in ``[0, cap]`` by the sign argument
    alone (:func:`.prover.prove_none_below_cap`, re-verified by the checker), or ``None``. It needs
    no search: a study tries it first at large ``s`` and searches only when it fails."""
    A0 = np.asarray(A0, dtype=float)
    A1 = np.asarray(A1, dtype=float)
    pairs = [tuple(int(i) for i in p) for p in (pairs or [])]
    with one_blas_thread():
        out = claims.prove_none_below_cap(A0, A1, cap, pairs=pairs, max_nodes=max_nodes)
        if out is None:
            return None
        t1 = time.perf_counter()
        rep = checker.check_log(A0, A1, out.log)
        t_check = time.perf_counter() - t1
    proof = _result(A0, A1, cap, out, rep, 0, t_check)
    return proof if proof.certified and proof.onset.value is None else None


def _result(A0, A1, cap, out: claims.ProofOutcome, rep: prooflog.CheckReport, n_cands: int,
            t_check: float) -> MuProof:
    s = A0.shape[0]
    proven_keys = {(tuple(u), round(lo, 12)) for u, lo, hi in rep.solutions}
    def solution(f: Found, proven: bool, ill: bool) -> Solution:
        sup = np.zeros(s, dtype=bool)
        sup[list(f.U)] = True
        x = np.zeros(s)
        x[list(f.U)] = f.x / np.sum(f.x)
        return Solution(f.mu, f.enc, sup, x, f.min_x, f.min_y, proven, ill)

    sols = [solution(f, bool(rep.all_ok and (tuple(f.U), round(f.enc[0], 12)) in proven_keys), False)
            for f in out.found]
    sols += [solution(f, False, True) for f in out.ill]
    sols.sort(key=lambda p: p.value)
    lb = rep.lower_bound
    if rep.onset_ok:
        if rep.onset is None:
            onset = Claim("onset", True, f"proven: no critical mu in [0, {cap:.6g}]", (0.0, cap))
        else:
            first = min((p for p in sols if p.enclosure[0] >= rep.onset[0] and not p.ill_conditioned),
                        key=lambda p: p.value, default=None)
            value = first.value if first is not None else rep.onset[1]
            onset = Claim("onset", True, f"proven: onset mu in [{rep.onset[0]:.12g}, {rep.onset[1]:.12g}]",
                          (0.0, rep.onset[1]), value=value, enclosure=rep.onset)
    else:
        why = "ill-conditioned" if out.ill else STOPPED if out.timed_out else "not proven"
        onset = Claim("onset", False, f"{why}: proven only that no critical mu lies in [0, {lb:.6g}]", (0.0, lb))
    if rep.all_ok:
        vals = [p.value for p in sols if p.proven]
        allc = Claim("all", True, f"proven: {len(vals)} critical value(s) in [0, {cap:.6g}]", (0.0, cap), values=vals)
    else:
        to = rep.lower_bound if not rep.onset_ok else max(rep.lower_bound, 0.0)
        why = "ill-conditioned" if out.ill else STOPPED if out.timed_out else "not proven"
        allc = Claim("all", False, f"{why}: the list is proven complete only on [0, {to:.6g}]", (0.0, to),
                     values=[p.value for p in sols if p.value <= to and not p.ill_conditioned])
    return MuProof(s, float(cap), onset, allc, sols, lb, bool(out.ill), bool(rep.onset_ok and rep.all_ok),
                   out.log, out.nodes, out.seconds, t_check, n_cands, timed_out=bool(out.timed_out))


__all__ = ["Claim", "MuProof", "Solution", "mceip_mu", "mceip_mu_none_below_cap"]
