"""Branch and bound that proves the condensed MCEIP-mu (21)-(23) and writes the proof log.

A node ``(U, [a, b])`` stands for "every solution whose support lies in ``U`` and whose mu lies in
``[a, b]``". It is closed by one of the tests of :mod:`app.analyses.mceip_mu.closing` and :mod:`app.analyses.mceip_mu.windows`:

* ``cop``: the sign argument, ``sym(D A_UU)`` strictly copositive at ``a`` and ``b``, with ``D = I``
  or the diagonal ``z / x`` of the right and left eigenvectors of ``A_UU`` at an end (a
  Perron-like scaling that keeps the asymmetry of the pencil; it proves the onset of the 100k-DOF
  block's all-slip states where no symmetric test can);
* ``bisect``: the interval is halved;
* ``drop``: the supports in ``U`` are those in some ``U \\ {i}`` plus ``U`` itself, whose exact
  support problem (25)-(26) becomes a ``leaf``: every real eigenvalue of ``A_UU(mu)`` in
  ``[a, b]`` gets a Krawczyk window (one verified eigenpair, decided as solution or not), and the
  rest of ``[a, b]`` is proven free of eigenvalues (nonsingular on sub-intervals).

Two claims, in this order: the **onset** (no solution in ``[0, L]``, and a verified solution just
above ``L``; or none below the cap), then **every solution in [0, cap]** (roots tiling
``[0, cap]``). The floating-point candidates (search or enumeration) only guide the tree; every
claim is what :func:`app.analyses.mceip_mu.checker.check_log` accepts.
"""
from __future__ import annotations

import heapq
import math
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from app.analyses.mceip_mu import checker, closing, lp, prooflog, windows
from app.linalg import one_blas_thread

#: relative half-width of the window around a verified eigenvalue (the accuracy of a proven value)
WINDOW_REL = 1e-9
#: a family whose LP relaxation is complementary is halved down to this relative width, then
#: split on an index
HALVE_MIN_REL = 1e-3
#: a family on an interval wider than this (relative to its end) is halved before any index split
WIDE_REL = 0.03
#: near mu = 0 the width rule is relative to this fraction of the cap (else it would halve forever)
WIDE_FLOOR = 0.1
#: a family with at most this many free indices is split on them at once (its leaves are few and
#: cover any interval themselves)
FEW_FREE = 3
#: subgradient steps and step size of the multiplier search of the product argument
RLT_STEPS = 40
RLT_RATE = 0.05
#: the product argument is tried on families with at least this many free indices (2^12 supports
#: or more: splitting them is what it saves) and at most this many slip nodes
RLT_MIN_FREE = 12
RLT_MAX = 64
#: halvings of a leaf's gap tried with Farkas vectors before windows and nonsingularity take over
FARKAS_DEPTH = 6
#: above this many slip nodes in ``U``: a wide family is halved without its LP (a dense LP of
#: hundreds of columns costs seconds and closes no wide family of the block's large states), and
#: the diagonal scalings come from inverse iteration instead of a full eigendecomposition
LARGE_U = 64


@dataclass
class Found:
    """A verified solution: exact support ``U``, window witness and enclosure."""
    U: tuple[int, ...]
    mu: float
    h: float
    x: np.ndarray
    enc: tuple[float, float]
    min_x: float
    min_y: float
    verdict: str


@dataclass
class Tree:
    """The nodes built so far, with the memo ``(U, a, b) -> id``."""
    nodes: list[prooflog.Node] = field(default_factory=list)
    memo: dict = field(default_factory=dict)

    def add(self, U: tuple[int, ...], a: float, b: float, kind: str = "open", tag: str = "",
            F: tuple[int, ...] = ()) -> tuple[prooflog.Node, bool]:
        U, F = tuple(sorted(U)), tuple(sorted(F))
        key = (U, F, a, b, tag)
        if key in self.memo:
            return self.nodes[self.memo[key]], False
        n = prooflog.Node(len(self.nodes), list(U), float(a), float(b), kind, F=list(F))
        self.nodes.append(n)
        self.memo[key] = n.id
        return n, True


class Prover:
    """The proof of one pencil (scaled exactly by a power of two)."""

    def __init__(self, A0: np.ndarray, A1: np.ndarray, cap: float, pairs=(), deadline: float = math.inf):
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
        self.deadline = deadline
        self.max_nodes = math.inf        # a budget in nodes: answers independent of the machine's speed
        self.found: dict[tuple, Found] = {}
        self.ill: list[Found] = []
        self.leaf_cache: dict = {}
        self.cop_failed: set = set()
        self.dvec_cache: dict = {}

    # --- tests ------------------------------------------------------------------------------

    def _dvectors(self, U: np.ndarray, a: float, b: float) -> list[np.ndarray]:
        """Candidate diagonals: ``I`` and ``z / x`` at each end (when both vectors are positive),
        ``x`` and ``z`` the right and left eigenvectors of the eigenvalue of ``A_UU`` with the
        smallest real part. They only guide the sign argument, which proves or fails on its own."""
        out = [np.ones(len(U))]
        for mu in (b, a) if a != b else (b,):
            key = (tuple(U), mu)
            if key not in self.dvec_cache:
                A = self.a0[np.ix_(U, U)] + mu * self.a1[np.ix_(U, U)]
                self.dvec_cache[key] = _perron_scaling(A) if len(U) <= LARGE_U else _perron_scaling_large(A)
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

    def _eigen(self, U: np.ndarray) -> list[tuple[float, np.ndarray]]:
        """Real eigenpairs ``(mu, x)`` of ``(A0 + mu A1)[U, U] x = 0`` (floating point)."""
        key = tuple(U)
        if key in self.leaf_cache:
            return self.leaf_cache[key]
        s0, s1 = self.a0[np.ix_(U, U)], self.a1[np.ix_(U, U)]
        try:
            w, V = scipy.linalg.eig(s0, -s1)
        except (np.linalg.LinAlgError, ValueError):
            w, V = np.array([]), np.zeros((len(U), 0))
        out = []
        for j in range(len(w)):
            if not np.isfinite(w[j]) or abs(w[j].imag) > 1e-7 * max(1.0, abs(w[j].real)):
                continue
            mu, x = _polish(s0, s1, float(w[j].real), V[:, j].real.copy())
            out.append((mu, x))
        out.sort(key=lambda t: t[0])
        self.leaf_cache[key] = out
        return out

    # --- products of constraints ---------------------------------------------------------

    def _try_rlt(self, n: prooflog.Node) -> bool:
        """Close ``n`` by :func:`app.analyses.mceip_mu.closing.rlt_closes`: a multiplier matrix
        ``M`` found by projected subgradient ascent on ``min(lambda_min sym(M A_UU))`` over the
        two ends (from ``M = I``, the sign argument's start), then proven by the checker."""
        U = np.asarray(n.U, dtype=np.int64)
        p = len(U)
        if p - len(n.F) < RLT_MIN_FREE or p > RLT_MAX:
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

    # --- Farkas vectors ----------------------------------------------------------------------

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

    def _leaf_vector(self, U: np.ndarray, lo: float, hi: float, lp: bool = True):
        """A Farkas vector for the exact support ``U`` on ``[lo, hi]``: ``A_UU(m)^-T 1`` at the
        midpoint (no LP), else (``lp``) the LP's."""
        s0, s1 = self.a0[np.ix_(U, U)], self.a1[np.ix_(U, U)]
        m = 0.5 * (lo + hi)
        try:
            wu = np.linalg.solve((s0 + m * s1).T, np.ones(len(U)))
        except np.linalg.LinAlgError:
            wu = None
        if wu is not None and np.all(np.isfinite(wu)):
            w = np.zeros(self.s)
            w[U] = wu
            if closing.farkas_closes(self.a0, self.a1, U, U, lo, hi, w):
                return w
        if not lp:
            return None
        w, _ = self._lp(tuple(int(i) for i in U), set(int(i) for i in U), lo, hi)
        if w is not None and closing.farkas_closes(self.a0, self.a1, U, U, lo, hi, w):
            return w
        return None

    def _farkas_pieces(self, U: np.ndarray, lo: float, hi: float, depth: int, pieces: list, rest: list) -> None:
        """Cover ``[lo, hi]`` by Farkas pieces (halving up to ``depth`` times); what is left goes to ``rest``."""
        w = self._leaf_vector(U, lo, hi, lp=depth >= FARKAS_DEPTH - 1)   # the LP (which can cross an
        if w is not None:                                               # eigenvalue) on the wide pieces only
            pieces.append({"a": lo, "b": hi, "w": [float(v) for v in w]})
            return
        m = 0.5 * (lo + hi)
        if depth <= 0 or not (lo < m < hi):
            rest.append((lo, hi))
            return
        self._farkas_pieces(U, lo, m, depth - 1, pieces, rest)
        self._farkas_pieces(U, m, hi, depth - 1, pieces, rest)

    # --- leaves ------------------------------------------------------------------------------

    def _looks_like_solution(self, U: np.ndarray, mu: float, x: np.ndarray) -> bool:
        """Floating-point screen: ``x_U`` of one sign and ``y >= 0`` off ``U``, within 1e-6 relative."""
        x = x * np.sign(np.sum(x)) if np.sum(x) != 0 else x
        if np.min(x) < -1e-6 * np.max(np.abs(x)):
            return False
        full = np.zeros(self.s)
        full[U] = x
        y = (self.a0 + mu * self.a1) @ full
        off = np.setdiff1d(np.arange(self.s), U)
        return not len(off) or np.min(y[off]) >= -1e-6 * float(np.max(np.abs(y), initial=1.0) + np.max(np.abs(x)))

    def _window(self, n: prooflog.Node, U: np.ndarray, mu: float, x: np.ndarray, mus: list[float]):
        """A verified window around the eigenvalue ``mu`` of support ``U`` (recorded in ``n``)."""
        h = WINDOW_REL * max(abs(mu), 1e-3)
        near = [abs(mu - m) for m in mus if m != mu]
        if near and min(near) < 4 * h:
            h = 0.25 * min(near)
        for _ in range(3):
            if h <= 0:
                break
            res = windows.verify_window(self.a0, self.a1, U, mu, x, h, self.cap, self.pairs)
            if res.ok:
                n.windows.append({"mu": mu, "h": h, "x": [float(v) for v in x]})
                if res.verdict in ("solution", "ill-conditioned"):
                    f = Found(tuple(n.U), mu, h, x.copy(), (res.enc_lo, res.enc_hi), res.min_x, res.min_y, res.verdict)
                    if res.verdict == "solution":
                        self.found[(f.U, round(res.enc_lo, 12))] = f
                    else:
                        self.ill.append(f)
                return res
            h *= 0.1
        return None

    def _leaf(self, n: prooflog.Node) -> bool:
        """Exact support ``U`` (``F = U``) on ``[a, b]``: windows around the eigenvalues that look
        like solutions, Farkas pieces between them, and for what is left windows around every
        eigenvalue and proven nonsingularity between (the checker redoes the last part)."""
        U = np.asarray(n.U, dtype=np.int64)
        n.kind = "leaf"
        a, b = n.a, n.b
        eig = [(mu, x) for mu, x in self._eigen(U) if a - 1e-6 * max(1.0, abs(mu)) <= mu <= b + 1e-6 * max(1.0, abs(mu))]
        mus = [mu for mu, _ in eig]
        covered: list[tuple[float, float]] = []
        others = []
        for mu, x in eig:
            if self._looks_like_solution(U, mu, x):
                res = self._window(n, U, mu, x, mus)
                if res is None:
                    n.kind = "open"
                    return False
                covered.append((res.mu_lo, res.mu_hi))
            else:
                others.append((mu, x))
        gaps, reach = [], a
        for lo, hi in sorted(covered):
            if lo > reach:
                gaps.append((reach, min(lo, b)))
            reach = max(reach, hi)
        if reach < b:
            gaps.append((reach, b))
        rest: list[tuple[float, float]] = []
        for lo, hi in gaps:
            self._farkas_pieces(U, lo, hi, FARKAS_DEPTH, n.pieces, rest)
        for mu, x in others:
            if any(lo - 1e-6 * max(1.0, abs(mu)) <= mu <= hi + 1e-6 * max(1.0, abs(mu)) for lo, hi in rest):
                res = self._window(n, U, mu, x, mus)
                if res is None:
                    n.kind = "open"
                    return False
                covered.append((res.mu_lo, res.mu_hi))
        done = covered + [(p["a"], p["b"]) for p in n.pieces]
        if closing.cover_nonsingular(self.a0, self.a1, U, a, b, done, deadline=self.deadline):
            return True
        n.kind = "open"
        return False

    # --- the search --------------------------------------------------------------------------

    def _split(self, n: prooflog.Node, relaxed) -> list[prooflog.Node]:
        """Split an unclosed family: on a pair inside ``U \\ F`` first (each child then holds one
        half), else on the index of ``U \\ F`` where the LP's relaxed point breaks complementarity
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
        elif width > WIDE_REL * scale and len(free) > FEW_FREE:
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
            if time.perf_counter() > self.deadline or len(self.tree.nodes) > self.max_nodes:
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

    def _wide(self, n: prooflog.Node) -> bool:
        """:meth:`_split` halves ``n`` whatever its LP says (no pair inside, a wide interval)."""
        U, F = set(n.U), set(n.F)
        if any(p[0] in U - F and p[1] in U - F for p in self.pairs):
            return False
        scale = max(abs(n.b), WIDE_FLOOR * self.cap, 1e-300)
        return n.b - n.a > WIDE_REL * scale and len(U - F) > FEW_FREE

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
        w = None if witness is None else {"U": list(witness.U), "mu": witness.mu, "h": witness.h,
                                          "x": [float(v) for v in witness.x]}
        return prooflog.ProofLog(self.s, self.cap, self.scale_exp, [list(p) for p in self.pairs], self.tree.nodes,
                           onset_root, onset_below, all_roots, w)


def _perron_scaling(A: np.ndarray) -> np.ndarray | None:
    """``z / x`` (geometric mean 1) for the eigenvalue of ``A`` with the smallest real part, when
    it is real and both eigenvectors are positive (full eigendecomposition)."""
    try:
        w, vl, vr = scipy.linalg.eig(A, left=True, right=True)
    except (np.linalg.LinAlgError, ValueError):
        return None
    if not np.all(np.isfinite(w)):
        return None
    j = int(np.argmin(w.real))
    if abs(w[j].imag) > 1e-12 * max(1.0, abs(w[j].real)):
        return None
    return _ratio(vr[:, j].real, vl[:, j].real)


def _perron_scaling_large(A: np.ndarray, steps: int = 30) -> np.ndarray | None:
    """:func:`_perron_scaling` by inverse iteration (one LU factorisation, ``steps`` solves with
    ``A`` and with ``A^T``): the eigenvalue nearest 0, which below an onset is the one with the
    smallest real part; a guess that fails only costs the sign argument one candidate."""
    try:
        lu = scipy.linalg.lu_factor(A, check_finite=False)
    except (np.linalg.LinAlgError, ValueError):
        return None
    n = A.shape[0]
    x = np.ones(n) / math.sqrt(n)
    z = x.copy()
    with np.errstate(all="ignore"):
        for _ in range(steps):
            x = scipy.linalg.lu_solve(lu, x, check_finite=False)
            z = scipy.linalg.lu_solve(lu, z, trans=1, check_finite=False)
            nx, nz = np.linalg.norm(x), np.linalg.norm(z)
            if not (np.isfinite(nx) and np.isfinite(nz) and nx > 0 and nz > 0):
                return None
            x, z = x / nx, z / nz
        lam = float(x @ (A @ x))
        if np.linalg.norm(A @ x - lam * x) > 1e-6 * max(np.linalg.norm(A, 1), 1e-300):
            return None          # not converged: no candidate
    return _ratio(x, z)


def _ratio(x: np.ndarray, z: np.ndarray) -> np.ndarray | None:
    x = x * np.sign(np.sum(x))
    z = z * np.sign(np.sum(z))
    if not (np.all(x > 0) and np.all(z > 0)):
        return None
    d = z / x
    d = d / math.exp(float(np.mean(np.log(d))))
    return d if np.all(np.isfinite(d)) and np.max(d) / np.min(d) < 1e12 else None


def _polish(s0: np.ndarray, s1: np.ndarray, mu: float, x: np.ndarray, steps: int = 2) -> tuple[float, np.ndarray]:
    """Newton steps on ``[A(mu) x ; x_k - 1] = 0`` from an eigenpair of LAPACK (tighter windows)."""
    p = len(x)
    try:
        _, _, Vh = np.linalg.svd(s0 + mu * s1)
        x = Vh[-1]
    except np.linalg.LinAlgError:
        pass
    k = int(np.argmax(np.abs(x)))
    x = x / x[k]
    for _ in range(steps):
        J = np.zeros((p + 1, p + 1))
        J[:p, :p] = s0 + mu * s1
        J[:p, p] = s1 @ x
        J[p, k] = 1.0
        F = np.append((s0 + mu * s1) @ x, x[k] - 1.0)
        try:
            dz = np.linalg.solve(J, -F)
        except np.linalg.LinAlgError:
            break
        if not np.all(np.isfinite(dz)):
            break
        x, mu = x + dz[:p], mu + float(dz[p])
    return mu, x


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
        mu, xs = _polish(P.a0[np.ix_(Ua, Ua)], P.a1[np.ix_(Ua, Ua)], float(mu), xs)
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
        root, _ = P.tree.add(tuple(range(P.s)), 0.0, P.cap)
        todo = [root]
        while todo:
            n = todo.pop()
            if P._try_cop(n):
                continue
            if not P._wide(n) or len(P.tree.nodes) + 2 > max_nodes:
                return None
            todo += P._split(n, None)
        log = P.log(root.id, P.cap, [root.id], None)
        return ProofOutcome(log, [], [], True, True, len(P.tree.nodes), time.perf_counter() - t0)


def prove(A0: np.ndarray, A1: np.ndarray, cap: float, pairs=(), candidates=(), seconds: float = 60.0,
          want_all: bool = True, all_seconds: float | None = None, onset_nodes: int = 20000,
          all_nodes: int = 4000) -> ProofOutcome:
    """Build the proof of the onset and (``want_all``) of every solution in ``[0, cap]``.

    ``candidates``: ``(support indices, mu, x)`` from a search (they only guide the proof).
    Budgets: ``onset_nodes`` and ``all_nodes`` tree nodes for the two claims (deterministic: the
    same answer on any machine and any number of ranks), ``seconds`` and ``all_seconds`` as a
    safety limit in time."""
    with one_blas_thread():
        return _prove(A0, A1, cap, pairs, candidates, seconds, want_all, all_seconds, onset_nodes, all_nodes)


def _prove(A0, A1, cap, pairs, candidates, seconds, want_all, all_seconds, onset_nodes, all_nodes) -> ProofOutcome:
    t0 = time.perf_counter()
    P = Prover(A0, A1, cap, pairs, deadline=t0 + seconds)
    P.max_nodes = onset_nodes
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
                        len(P.tree.nodes), time.perf_counter() - t0)
