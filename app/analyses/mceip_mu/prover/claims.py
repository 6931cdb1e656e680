"""The MCEIP-mu prover: the two claims (paper eqs. (21)-(23), condensed on the slip nodes).

Two claims, in this order: the **onset** (no solution in ``[0, L]``, and a verified solution just
above ``L``; or none below the cap), then **every solution in [0, cap]** (roots tiling
``[0, cap]``). The tree is built by :class:`app.analyses.mceip_mu.prover.branch.Prover`; the
floating-point candidates (search or enumeration) only guide it; every claim is what
:func:`app.analyses.mceip_mu.kernel.checker.check_log` accepts.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from app.analyses.mceip_mu.kernel import closing, prooflog, windows
from app.analyses.mceip_mu.prover import branch
from app.analyses.mceip_mu.prover.branch import Prover
from app.analyses.mceip_mu.prover.heuristics import polish
from app.analyses.mceip_mu.prover.leaves import WINDOW_REL, Found
from app.analyses.mceip_mu.prover.live import LIVE
from app.linalg import one_blas_thread


@dataclass
class ProofOutcome:
    """What the prover built (to be accepted by the checker): the log and the open nodes."""

    log: prooflog.ProofLog
    found: list[Found]
    ill: list[Found]
    onset_done: bool
    all_done: bool
    nodes: int
    seconds: float
    timed_out: bool = False    # the wall-clock safety stop (not the node budget) left a claim unfinished


def _seed_candidates(P: Prover, candidates) -> None:
    """Verify the search's candidate solutions (support, mu, x) as leaves of their own support."""
    for U, mu, x in candidates:
        U = tuple(sorted(int(i) for i in U))
        if not U or not (0.0 <= mu <= P.cap * (1 + 1e-9)):
            continue
        Ua = np.asarray(U, dtype=np.int64)
        h = WINDOW_REL * max(abs(mu), 1e-3)
        xs = np.asarray(x, dtype=float)
        if len(xs) == P.s:
            xs = xs[Ua]
        mu, xs = polish(P.a0[np.ix_(Ua, Ua)], P.a1[np.ix_(Ua, Ua)], float(mu), xs)
        res = windows.verify_window(P.a0, P.a1, Ua, float(mu), xs, h, P.cap, P.pairs)
        if res.ok and res.verdict == "solution":
            P.found[(U, round(res.enc_lo, 12))] = Found(U, float(mu), h, xs.copy(), (res.enc_lo, res.enc_hi),
                                                       res.min_x, res.min_y, res.verdict)


def _onset_target(P: Prover, w: Found) -> float:
    """The end ``L`` of "no solution in [0, L]" below the witness: ``WINDOW_REL`` below its
    enclosure, or a wider gap (up to 1e-6 relative) when the sign argument on every support
    cannot resolve the narrow one. Near an all-slip onset ``sym(D A(mu))`` is PD with a smallest
    eigenvalue about proportional to the distance to the onset, which must exceed the rounding
    bound of the verified Cholesky (about ``s^2 u``): at s = 180 that needs about 1e-8."""
    top = float(np.nextafter(min(w.enc[0], w.mu - w.h), -np.inf))
    all_idx = np.arange(P.s)
    for rel in (0.0, 1e-8, 1e-7, 1e-6):
        L = top if rel == 0.0 else float(w.enc[0] * (1.0 - rel))
        for d in P._dvectors(all_idx, L, L):
            if any(closing.copositive_at(P.a0, P.a1, L, d, th) for th in (0.0, 1.0)):
                return L
    return top


def _bound(P: Prover, hi: float) -> tuple[int | None, float | None]:
    """A fallback claim when the onset is not proven: the largest ``L`` (bisection) with the
    sign argument on all supports closing ``[0, L]`` in one node."""
    all_idx = tuple(range(P.s))
    best = None
    lo, up = 0.0, hi
    for it in range(40):
        m = hi if it == 0 else 0.5 * (lo + up)
        n, new = P.tree.add(all_idx, 0.0, m, tag="bound")     # its own nodes: not those of the onset tree
        if n.kind == "cop" or (new and P._try_cop(n)):
            best, lo = n, m
            if m >= hi:
                break
        else:
            up = m
        if up - lo <= 1e-6 * max(up, 1e-3):
            break
    return (best.id, best.b) if best is not None else (None, None)


def prove_none_below_cap(A0: np.ndarray, A1: np.ndarray, cap: float, pairs=(), max_nodes: int = 63) -> ProofOutcome | None:
    """The cheap proof of "no critical mu in ``[0, cap]``": the sign argument on every support,
    the interval halved while it is wide (as :meth:`Prover._wide`), at most ``max_nodes`` nodes.
    ``None`` when a piece stays open (then a search and :func:`prove` are needed). Below an onset
    this is what :func:`prove` would build first, without the search that guides it."""
    with one_blas_thread():
        t0 = time.perf_counter()
        P = Prover(A0, A1, cap, pairs)
        P.wide_rel = branch.WIDE_REL_LARGE
        root, _ = P.tree.add(tuple(range(P.s)), 0.0, P.cap)
        todo = [root]
        LIVE.reset("sign argument on [0, cap]")
        while todo:
            n = todo.pop()
            LIVE.nodes, LIVE.mu = len(P.tree.nodes), n.a
            if P._try_cop(n):
                continue
            if not P._wide(n) or len(P.tree.nodes) + 2 > max_nodes:
                return None
            todo += P._split(n, None)
        log = P.log(root.id, P.cap, [root.id], None)
        return ProofOutcome(log, [], [], True, True, len(P.tree.nodes), time.perf_counter() - t0)


def prove(A0: np.ndarray, A1: np.ndarray, cap: float, pairs=(), candidates=(), seconds: float | None = None,
          want_all: bool = True, all_seconds: float | None = None, onset_nodes: int = 20000,
          all_nodes: int = 4000) -> ProofOutcome:
    """Build the proof of the onset and (``want_all``) of every solution in ``[0, cap]``.

    ``candidates``: ``(support indices, mu, x)`` from a search (they only guide the proof).
    Budgets: ``onset_nodes`` and ``all_nodes`` tree nodes for the two claims (deterministic: the
    same answer on any machine, under any load and on any number of ranks). ``seconds`` (the
    whole proof) and ``all_seconds`` (the list, from its start) are a wall-clock safety stop,
    ``None``: none; when one ends a claim, ``timed_out`` says so."""
    with one_blas_thread():
        return _prove(A0, A1, cap, pairs, candidates, seconds, want_all, all_seconds, onset_nodes, all_nodes)


def _prove(A0, A1, cap, pairs, candidates, seconds, want_all, all_seconds, onset_nodes, all_nodes) -> ProofOutcome:
    t0 = time.perf_counter()
    LIVE.reset("onset proof")
    P = Prover(A0, A1, cap, pairs, deadline=math.inf if seconds is None else t0 + seconds)
    P.max_nodes = onset_nodes
    P.wide_rel = branch.WIDE_REL_ONSET
    all_idx = tuple(range(P.s))
    _seed_candidates(P, candidates)
    onset_root = onset_below = None
    witness = None
    onset_done = False
    for _ in range(50):        # restarts when the tree finds a solution below the target
        below = sorted(P.found.values(), key=lambda f: f.enc[0])
        witness = below[0] if below else None
        target = P.cap if witness is None else _onset_target(P, witness)
        if target < 0:
            target = 0.0
        root, _ = P.tree.add(all_idx, 0.0, target)
        left = P.explore(root, stop_below=target)
        newer = [f for f in P.found.values() if f.enc[0] <= target]
        if newer and (witness is None or min(f.enc[0] for f in newer) < witness.enc[0]):
            continue
        onset_root, onset_below = root.id, target
        onset_done = not left
        break
    bound_root, bound = None, None
    if not onset_done:
        bound_root, bound = _bound(P, onset_below if onset_below is not None else P.cap)
        if bound is not None and bound >= P.cap:      # the sign argument alone: none below the cap
            onset_root, onset_below, onset_done, witness = bound_root, P.cap, True, None
            bound_root = bound = None
    all_roots: list[int] = []
    all_done = False
    if want_all and onset_done:
        all_roots = [onset_root]
        if onset_below < P.cap:
            if all_seconds is not None:
                P.deadline = min(P.deadline, time.perf_counter() + all_seconds)
            P.max_nodes = len(P.tree.nodes) + all_nodes
            LIVE.phase = "list proof"
            P.wide_rel = branch.WIDE_REL
            root2, _ = P.tree.add(all_idx, onset_below, P.cap)
            all_roots.append(root2.id)
            left = P.explore(root2)
            all_done = not left
            if not all_done:
                all_roots = []          # an unfinished list is not logged (the checker would reject it)
        else:
            all_done = True
    log = P.log(onset_root if onset_done else None, onset_below if onset_done else None, all_roots,
                witness if onset_done else None)
    log.bound_root, log.bound = bound_root, bound
    log.prune()
    return ProofOutcome(log, sorted(P.found.values(), key=lambda f: f.enc[0]), P.ill, onset_done, all_done,
                        len(P.tree.nodes), time.perf_counter() - t0, timed_out=P.timed_out)
