r"""The branch and bound of the MCEIP-mu prover: the proof tree and how its nodes are closed or split.

A node is a family ``F <= P <= U`` of supports (``F`` forced, ``U`` allowed) with mu in ``[a, b]``:
"no solution with such a support and such a mu other than the listed ones". It is closed by a
test of the trusted kernel (:mod:`app.analyses.mceip_mu.kernel.closing`, :mod:`app.analyses.mceip_mu.kernel.windows`),
tried from the cheapest:

* ``cop``: the sign argument, ``sym(D A_UU)`` strictly copositive at ``a`` and ``b``, with ``D = I``
  or the diagonal ``z / x`` of the right and left eigenvectors of ``A_UU`` at an end (a
  Perron-like scaling that keeps the asymmetry of the pencil; it proves the onset of the block's
  all-slip states where no symmetric test can);
* ``farkas``: a Farkas vector of the family's linear relaxation (found by the LP of :mod:`.lp`);
* ``rlt``: products of constraints, ``x^T M y <= 0`` (off by default: ``USE_RLT``);
* ``leaf`` (``F = U``, one exact support, paper eqs. (25)-(26)): :mod:`.leaves`.

A family that no test closes is split: ``bisect`` (the interval halved, while it is wide) or
``branch`` on an index ``i`` of ``U \ F`` (``i`` out of the support, or forced into it), chosen
where the LP's relaxed point breaks complementarity most; pairs of zero-reaction halves first.
The nodes are explored best first (lowest ``a``); :mod:`.prover` runs the two claims.
"""
from __future__ import annotations

import heapq
import math
import time
from dataclasses import dataclass, field

import numpy as np

from app.analyses.mceip_mu.kernel import checker, closing, prooflog
from app.analyses.mceip_mu.prover import lp
from app.analyses.mceip_mu.prover.heuristics import perron_scaling, perron_scaling_large
from app.analyses.mceip_mu.prover.leaves import Found, LeafTests
from app.analyses.mceip_mu.prover.live import LIVE

#: a family whose LP relaxation is complementary is halved down to this relative width, then
#: split on an index
HALVE_MIN_REL = 1e-3
#: a family on an interval wider than this (relative to its end) is halved before any index split
WIDE_REL = 0.03
#: the width rule of the onset claim (families of at most ``LARGE_U`` slip nodes): wider pieces
#: than for the list, since below the onset every piece closes and fewer pieces mean fewer index
#: splits (dense s = 30: 15,000 nodes against 47,000 at 0.03)
WIDE_REL_ONSET = 0.1
#: the width rule of a family of more than ``LARGE_U`` slip nodes, and of the cheap proof of "none
#: below the cap" (:func:`app.analyses.mceip_mu.prover.claims.prove_none_below_cap`)
WIDE_REL_LARGE = 0.03
#: near mu = 0 the width rule is relative to this fraction of the cap (else it would halve forever)
WIDE_FLOOR = 0.1
#: a family with at most this many free indices is split on them at once (its leaves are few and
#: cover any interval themselves)
FEW_FREE = 3
#: subgradient steps and step size of the multiplier search of the product argument
RLT_STEPS = 40
RLT_RATE = 0.05
#: the product argument is off: its multiplier search closed 12 % of the families it was tried on
#: and took 80 % of the time of the dense s = 30 onset proof (168 s with it, 85 s without), and no
#: stored study pencil was proven faster with it (docs/proofs.md). When on, it is tried on families
#: with at least ``RLT_MIN_FREE`` free indices and at most ``RLT_MAX`` slip nodes
USE_RLT = False
RLT_MIN_FREE = 12
RLT_MAX = 64
#: above this many slip nodes in ``U``: a wide family is halved without its LP (a dense LP of
#: hundreds of columns costs seconds and closes no wide family of the block's large states), and
#: the diagonal scalings come from inverse iteration instead of a full eigendecomposition
LARGE_U = 64



@dataclass
class Tree:
    """The nodes built so far, with the memo ``(U, F, a, b, tag) -> id`` (see :meth:`add`)."""

    nodes: list[prooflog.Node] = field(default_factory=list)
    memo: dict = field(default_factory=dict)

    def add(self, U: tuple[int, ...], a: float, b: float, kind: str = "open", tag: str = "",
            F: tuple[int, ...] = ()) -> tuple[prooflog.Node, bool]:
        """The node of the family ``F <= P <= U`` with mu in ``[a, b]``, and whether it is new: a node
        already built with the same ``U``, ``F``, interval and ``tag`` is returned as it is (its kind and
        children kept), so that a family is closed once."""
        U, F = tuple(sorted(U)), tuple(sorted(F))
        key = (U, F, a, b, tag)
        if key in self.memo:
            return self.nodes[self.memo[key]], False
        n = prooflog.Node(len(self.nodes), list(U), float(a), float(b), kind, F=list(F))
        self.nodes.append(n)
        self.memo[key] = n.id
        return n, True


class Prover(LeafTests):
    """The proof of one pencil (scaled exactly by a power of two)."""

    def __init__(self, A0: np.ndarray, A1: np.ndarray, cap: float, pairs=(), deadline: float = math.inf):
        """The prover of ``A0 + mu A1`` on ``[0, cap]``. The budget is ``max_nodes`` tree nodes (set
        by the caller); ``deadline`` (a ``time.perf_counter()`` value, ``inf``: none) is only a
        safety stop, recorded in ``timed_out`` when it ends the exploration."""
        A0 = np.asarray(A0, dtype=float)
        A1 = np.asarray(A1, dtype=float)
        self.s = A0.shape[0]
        diag = np.abs(np.diag(A0))
        ref = float(np.max(diag)) if np.max(diag, initial=0.0) > 0 else float(np.max(np.abs(A0), initial=1.0))
        self.scale_exp = int(math.frexp(ref)[1]) if ref > 0 and math.isfinite(ref) else 0
        self.a0, self.a1 = checker.scaled(A0, A1, self.scale_exp)
        self.cap = float(cap)
        self.pairs = [tuple(sorted((int(a), int(b)))) for a, b in pairs]
        self.tree = Tree()
        self.deadline = deadline         # safety stop only (wall clock): never the budget
        self.timed_out = False           # the safety stop ended an exploration
        self.max_nodes = math.inf        # the budget, in nodes: answers independent of the machine's speed
        self.found: dict[tuple, Found] = {}
        self.ill: list[Found] = []
        self.leaf_cache: dict = {}
        self.cop_failed: set = set()
        self.dvec_cache: dict = {}
        self.wide_rel = WIDE_REL         # the claim's width rule (WIDE_REL_ONSET for the onset)

    def _dvectors(self, U: np.ndarray, a: float, b: float) -> list[np.ndarray]:
        """Candidate diagonals: ``I`` and ``z / x`` at each end (when both vectors are positive),
        ``x`` and ``z`` the right and left eigenvectors of the eigenvalue of ``A_UU`` with the
        smallest real part. They only guide the sign argument, which proves or fails on its own."""
        out = [np.ones(len(U))]
        for mu in (b, a) if a != b else (b,):
            key = (tuple(U), mu)
            if key not in self.dvec_cache:
                A = self.a0[np.ix_(U, U)] + mu * self.a1[np.ix_(U, U)]
                self.dvec_cache[key] = perron_scaling(A) if len(U) <= LARGE_U else perron_scaling_large(A)
            d = self.dvec_cache[key]
            if d is not None:
                out.append(d)
        return out

    def _try_cop(self, n: prooflog.Node) -> bool:
        key = (tuple(n.U), n.a, n.b)
        if key in self.cop_failed:          # the same test already failed (a sibling with a larger F)
            return False
        if self._cop(n):
            return True
        self.cop_failed.add(key)
        return False

    def _cop(self, n: prooflog.Node) -> bool:
        U = np.asarray(n.U, dtype=np.int64)
        one = np.ones(len(U))
        for theta in (0.0, 1.0):
            if closing.closes_subsets(self.a0, self.a1, U, n.a, n.b, one, theta):
                n.kind, n.d, n.theta = "cop", [1.0] * len(U), theta
                return True
        for d in self._dvectors(U, n.a, n.b)[1:]:
            for theta in (0.0, 1.0, 0.5):
                if closing.closes_subsets(self.a0, self.a1, U, n.a, n.b, d, theta):
                    n.kind, n.d, n.theta = "cop", [float(v) for v in d], theta
                    return True
        return False

    def _try_rlt(self, n: prooflog.Node) -> bool:
        """Close ``n`` by :func:`app.analyses.mceip_mu.kernel.closing.rlt_closes`: a multiplier matrix
        ``M`` found by projected subgradient ascent on ``min(lambda_min sym(M A_UU))`` over the
        two ends (from ``M = I``, the sign argument's start), then proven by the checker."""
        U = np.asarray(n.U, dtype=np.int64)
        p = len(U)
        if not USE_RLT or p - len(n.F) < RLT_MIN_FREE or p > RLT_MAX:
            return False             # a small family splits cheaply; a large U makes each step cost
        As = [self.a0[np.ix_(U, U)] + mu * self.a1[np.ix_(U, U)] for mu in ((n.a, n.b) if n.a != n.b else (n.a,))]
        free = np.eye(p, dtype=bool) | np.isin(U, np.asarray(n.F, dtype=np.int64))[None, :]
        M = np.eye(p)
        best, best_M = -np.inf, M
        for _ in range(RLT_STEPS):
            low = None
            for A in As:
                C = M @ A
                w, V = np.linalg.eigh(0.5 * (C + C.T))
                if low is None or w[0] < low[0]:
                    low = (w[0], V[:, 0], A)
            lam, v, A = low
            if lam > best:
                best, best_M = lam, M.copy()
                if lam > 1e-8 * float(np.max(np.abs(np.diag(C)), initial=1.0)):
                    break
            G = np.outer(v, A @ v)
            g = float(np.max(np.abs(G)))
            if not (g > 0) or not np.isfinite(g):
                break
            M = M + RLT_RATE * G / g
            M = np.where(free, M, np.minimum(M, 0.0))
            M = M * (p / max(float(np.sum(np.abs(np.diag(M)))), 1e-300))
        if not best > 0:
            return False
        for theta in (0.0, 1.0):
            if closing.rlt_closes(self.a0, self.a1, U, n.F, n.a, n.b, best_M, theta):
                n.kind, n.M, n.theta = "rlt", best_M.tolist(), theta
                return True
        return False

    def _lp(self, U: tuple[int, ...], F: set[int], a: float, b: float):
        """The LP ``max t`` subject to ``(A(mu)^T w)_U >= t`` at ``a`` and ``b``, ``w_i <= 0`` off
        ``F``, ``|w| <= 1``: a Farkas vector when ``t > 0``, else the dual point (the relaxed
        ``x`` at each end and the ``y`` of their sum), which says where complementarity fails."""
        s = self.s
        Ul = list(U)
        mus = (a, b) if a != b else (a,)
        G = np.vstack([-(self.a0[:, Ul] + mu * self.a1[:, Ul]).T for mu in mus])
        m = G.shape[0]
        A_ub = np.hstack([G, np.ones((m, 1))])
        lb = np.array([-1.0] * s + [-np.inf])
        ub = np.array([1.0 if i in F else 0.0 for i in range(s)] + [1.0])
        c = np.zeros(s + 1)
        c[-1] = -1.0
        r = lp.solve(c, A_ub, lb, ub)
        if not r.ok or r.marginals is None:
            return None, None
        if r.x[-1] > 0:
            w = r.x[:s].copy()
            off = np.ones(s, dtype=bool)
            off[list(F)] = False
            w[off] = np.minimum(w[off], 0.0)        # the sign pattern exactly (the LP's tolerance aside)
            return w, None
        lam = np.maximum(-r.marginals, 0.0)
        k = len(Ul)
        x = np.zeros(s)
        y = np.zeros(s)
        for q, mu in enumerate(mus):
            lq = lam[q * k:(q + 1) * k]
            x[Ul] += lq
            y += (self.a0[:, Ul] + mu * self.a1[:, Ul]) @ lq
        return None, (x, y)

    def _try_farkas(self, n: prooflog.Node):
        """Close ``n`` by a Farkas vector (kind ``farkas``); else return the LP's dual point."""
        w, relaxed = self._lp(tuple(n.U), set(n.F), n.a, n.b)
        if w is not None and closing.farkas_closes(self.a0, self.a1, np.asarray(n.U), n.F, n.a, n.b, w):
            n.kind, n.w = "farkas", [float(v) for v in w]
            return True, None
        return False, relaxed

    def _split(self, n: prooflog.Node, relaxed) -> list[prooflog.Node]:
        r"""Split an unclosed family: on a pair inside ``U \ F`` first (each child then holds one
        half), else on the index of ``U \ F`` where the LP's relaxed point breaks complementarity
        most; by halving the interval when it is wide (more than ``WIDE_REL`` of its end, or of
        ``WIDE_FLOOR`` times the cap near 0) or when the relaxed point breaks no complementarity
        (it mixes the two ends of the interval)."""
        U, F = set(n.U), set(n.F)
        free = sorted(U - F)
        width = n.b - n.a
        scale = max(abs(n.b), WIDE_FLOOR * self.cap, 1e-300)
        i = free[0]
        halve = False
        pair = next((p for p in self.pairs if p[0] in U - F and p[1] in U - F), None)
        if pair is not None:
            i = pair[0]
        elif width > self._wide_rel(n) * scale and len(free) > FEW_FREE:
            halve = True
        elif relaxed is not None:
            x, y = relaxed
            v = x[free] * np.maximum(y[free], 0.0)
            size = float(max(np.max(np.abs(x)), 1e-300) * max(np.max(np.abs(y)), 1e-300))
            if np.max(v) <= 1e-9 * size:
                halve = width > HALVE_MIN_REL * scale
                i = free[int(np.argmax(x[free]))]
            else:
                i = free[int(np.argmax(v))]
        if halve:
            m = 0.5 * (n.a + n.b)
            if n.a < m < n.b:
                c1, _ = self.tree.add(tuple(n.U), n.a, m, F=tuple(n.F))
                c2, _ = self.tree.add(tuple(n.U), m, n.b, F=tuple(n.F))
                n.kind, n.children = "bisect", [c1.id, c2.id]
                return [c1, c2]
        partners = {q for p in self.pairs if i in p for q in p if q != i}
        c0, _ = self.tree.add(tuple(U - {i}), n.a, n.b, F=tuple(F))
        c1, _ = self.tree.add(tuple(U - partners), n.a, n.b, F=tuple(F | {i}))
        n.kind, n.children = "branch", [c0.id, c1.id]
        return [c0, c1]

    def explore(self, root: prooflog.Node, stop_below: float | None = None) -> list[prooflog.Node]:
        """Close every node under ``root`` (best first: lowest ``a``, depth first among equals).
        Returns the nodes left open (budget or undecidable). ``stop_below``: for the onset,
        abandon as soon as a solution with mu at or below it is found (the caller restarts with
        a lower target)."""
        heap = [(n.a, -n.id, n.id) for n in self._open_under([root])]
        heapq.heapify(heap)
        left: list[prooflog.Node] = []
        queued = {i for _, _, i in heap}
        while heap:
            _, _, i = heapq.heappop(heap)
            n = self.tree.nodes[i]
            LIVE.nodes, LIVE.mu = len(self.tree.nodes), n.a
            over = len(self.tree.nodes) > self.max_nodes
            if not over and self.deadline < math.inf and time.perf_counter() > self.deadline:
                over = self.timed_out = True
            if over:
                left.append(n)
                left += [self.tree.nodes[j] for _, _, j in heap]
                break
            if n.kind != "open":
                continue
            if not checker.allowed(n.F, self.pairs):
                n.kind = "pair"
                continue
            if not n.U:
                n.kind = "empty"     # no nonempty support left in the family
                continue
            if set(n.F) == set(n.U):
                if not self._leaf(n):
                    left.append(n)
                if stop_below is not None and any(f.enc[0] <= stop_below for f in self.found.values()):
                    return [n]
                continue
            if any(p[0] in n.U and p[1] in n.U and p[0] not in n.F and p[1] not in n.F for p in self.pairs):
                kids = self._split(n, None)         # a pair inside U: one half per child first
                for c in self._open_under(kids):
                    if c.id not in queued:
                        queued.add(c.id)
                        heapq.heappush(heap, (c.a, -c.id, c.id))
                continue
            if self._try_cop(n):
                continue
            if len(n.U) > LARGE_U and self._wide(n):
                self._push(heap, queued, self._split(n, None))     # halved: its LP would not close it
                continue
            closed, relaxed = self._try_farkas(n)
            if closed or self._try_rlt(n):
                continue
            if n.b - n.a <= 1e-14 * max(abs(n.b), 1e-3) and relaxed is None:
                left.append(n)       # undecidable in double precision at this width
                continue
            kids = self._split(n, relaxed)
            for c in self._open_under(kids):
                if c.id not in queued:
                    queued.add(c.id)
                    heapq.heappush(heap, (c.a, -c.id, c.id))
        return left

    def _wide_rel(self, n: prooflog.Node) -> float:
        return WIDE_REL_LARGE if len(n.U) > LARGE_U else self.wide_rel

    def _wide(self, n: prooflog.Node) -> bool:
        """:meth:`_split` halves ``n`` whatever its LP says (no pair inside, a wide interval)."""
        U, F = set(n.U), set(n.F)
        if any(p[0] in U - F and p[1] in U - F for p in self.pairs):
            return False
        scale = max(abs(n.b), WIDE_FLOOR * self.cap, 1e-300)
        return n.b - n.a > self._wide_rel(n) * scale and len(U - F) > FEW_FREE

    def _push(self, heap: list, queued: set, kids: list[prooflog.Node]) -> None:
        for c in self._open_under(kids):
            if c.id not in queued:
                queued.add(c.id)
                heapq.heappush(heap, (c.a, -c.id, c.id))

    def _open_under(self, kids: list[prooflog.Node]) -> list[prooflog.Node]:
        """The open nodes among ``kids`` and under them (a memoised child may have been split by
        an earlier, abandoned exploration and still hold open nodes)."""
        out, stack, seen = [], list(kids), set()
        while stack:
            c = stack.pop()
            if c.id in seen:
                continue
            seen.add(c.id)
            if c.kind == "open":
                out.append(c)
            else:
                stack.extend(self.tree.nodes[j] for j in c.children)
        return out

    def log(self, onset_root, onset_below, all_roots, witness: Found | None) -> prooflog.ProofLog:
        """The proof log of this pencil: the tree built so far with its roots (the onset claim's root and
        the mu below which it says there is no solution, the roots of the complete list) and the
        verified solution just above the onset, if one was found (``witness``)."""
        w = None if witness is None else {"U": list(witness.U), "mu": witness.mu, "h": witness.h,
                                          "x": [float(v) for v in witness.x]}
        return prooflog.ProofLog(self.s, self.cap, self.scale_exp, [list(p) for p in self.pairs], self.tree.nodes,
                           onset_root, onset_below, all_roots, w)
