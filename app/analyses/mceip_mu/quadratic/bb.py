r"""The branch and bound that proves the quadratic MCEIP-mu of a curved obstacle beyond the reach of
the per-support proof (docs/method.md section 8, paper eqs. (21)-(23) condensed on the slip nodes).

A node is a family ``F <= P <= U`` of supports with mu in ``[a, b]``, the root every support on
``[0, cap]``. A node is closed by a witness of the trusted kernel
(:mod:`app.analyses.mceip_mu.quadratic.check`: the sign argument at the four corners of the
lifting of ``mu^2``, with ``D = I`` or a Perron-like scaling; a Farkas vector found by an LP;
nonsingularity of ``A_UU`` when ``F = U``), or, when ``F = U = J``, is a *leaf* decided exactly by
the per-support proof. A node nothing closes is split: its interval halved while it is wide,
else on an index ``i`` of ``U \ F`` (``i`` out of the support, or forced in) where the smallest
eigenvector of ``sym(A_UU)`` at the midpoint is largest. Nodes are explored lowest ``a`` first, so
the budget (in tree nodes: the same answer on any machine) leaves the nodes of high mu open and the
onset is proven first.

Zero-reaction nodes (``pairs``: the halves ``(a, b)`` of a split tangential rate, whose columns
are opposite, so no test can close a family holding both): a family with a pair inside
``U \ F`` is split on it first, ``(U \ {a}, F)`` and ``(U \ {b}, F + {a})``, and every forced
index drops its partner from ``U``, as in the linear engine (:mod:`app.analyses.mceip_mu.prover.branch`);
a family whose ``F`` holds a pair is closed as ``pair``.

The prover decides nothing itself: the log goes to :func:`check_log`, which verifies every
witness from the pencil and decides the leaves exactly; only what it accepts is proven.
"""
from __future__ import annotations

import heapq
import math
import time
from dataclasses import dataclass, field

import numpy as np

from app.analyses.mceip_mu.prover import lp
from app.analyses.mceip_mu.quadratic.check import (
    Report,
    check_log,
    cop_closes,
    corners,
    farkas_closes,
    holds_pair,
    nonsingular_closes,
)
from app.analyses.outcomes import STOPPED
from app.linalg import one_blas_thread

#: an interval wider than this (relative to ``max(b, WIDE_FLOOR cap)``) is halved before an index split
WIDE_REL = 0.2
WIDE_FLOOR = 0.05
#: a single support (``F = U``) that no float test closes is halved down to this relative width
#: before its exact decision (which costs more than a few float tests)
LEAF_REL = 0.02
#: the default budget in tree nodes (``settings.mcp.certify_quadratic_nodes`` in a study): work, not
#: time, decides what is proven; the shipped curved scenes need at most about 600
NODES = 20_000
#: never more nodes than this, whatever the budget asked
MAX_NODES = 400_000


@dataclass
class BBProof:
    """The checker's verdict on the log, in the fields of the per-support proof."""

    report: Report
    cap: float
    log: dict
    seconds: float = 0.0
    prover_seconds: float = 0.0
    supports: int = 0
    undecided: list = field(default_factory=list)
    timed_out: bool = False      # the wall-clock safety stop (not the node budget) left nodes open

    @property
    def proven(self) -> bool:
        """Whether the checker accepted the complete list of solutions in ``[0, cap]``."""
        return self.report.complete

    @property
    def onset_proven(self) -> bool:
        """Whether the checker proved the onset (the smallest solution, or none below the cap)."""
        return self.report.onset_proven

    @property
    def solutions(self):
        """The solutions the checker proved: enclosures of mu with their supports, lowest first."""
        return self.report.solutions

    @property
    def onset(self):
        """The proven solution whose enclosure starts lowest (None without one); the onset only when
        :attr:`onset_proven`."""
        return self.report.onset


class _Tree:
    def __init__(self, A0, A1, A2, cap: float, max_nodes: int, deadline: float, pairs=()):
        self.pairs = [tuple(sorted((int(a), int(b)))) for a, b in pairs]
        self.A = (np.asarray(A0, dtype=float), np.asarray(A1, dtype=float), np.asarray(A2, dtype=float))
        sc = float(np.max(np.abs(self.A[0]))) or 1.0
        self.S = tuple(M / sc for M in self.A)             # the LP's and eigensolver's copy only
        self.s, self.cap = self.A[0].shape[0], float(cap)
        self.max_nodes = min(int(max_nodes), MAX_NODES)   # the budget
        self.deadline = deadline                          # a wall-clock safety stop only (inf: none)
        self.timed_out = False
        self.nodes: list[dict] = []
        self.heap: list[tuple[float, int]] = []
        self.relaxed = None
        self.leaves: set = set()

    def add(self, U, F, a, b) -> int:
        k = len(self.nodes)
        self.nodes.append({"U": sorted(int(i) for i in U), "F": sorted(int(i) for i in F),
                           "a": float(a), "b": float(b), "kind": "open"})
        heapq.heappush(self.heap, (float(a), k))
        return k

    def run(self) -> None:
        self.add(range(self.s), (), 0.0, self.cap)
        while self.heap and len(self.nodes) < self.max_nodes:
            if self.deadline < math.inf and time.perf_counter() > self.deadline:
                self.timed_out = True
                return
            _, k = heapq.heappop(self.heap)
            n = self.nodes[k]
            if not self._close(n):
                self._split(k, n)

    def _close(self, n: dict) -> bool:
        A0, A1, A2 = self.A
        U, F, a, b = n["U"], n["F"], n["a"], n["b"]
        if holds_pair(F, self.pairs):
            n["kind"] = "pair"
            return True
        if not U or tuple(U) in self.leaves and F == U:
            n["kind"] = "leaf"
            return True
        if self._pair_inside(U, F) is not None:
            return False                                   # opposite columns: split on the pair first
        ix = np.ix_(U, U)
        Cs = [C for C, _ in corners(self.S[0][ix], self.S[1][ix], self.S[2][ix], a, b)]
        for d in self._scalings(U, a, b):
            for theta in (0.5, 0.0, 1.0):
                if _float_copositive(Cs, d, theta) and cop_closes(A0, A1, A2, U, a, b, d, theta):
                    n.update(kind="cop", d=[float(t) for t in d], theta=theta)
                    return True
        self.relaxed = None
        if F == U and nonsingular_closes(A0, A1, A2, U, a, b):
            n["kind"] = "nonsing"
            return True
        w = self._farkas(U, F, a, b)
        if w is not None and farkas_closes(A0, A1, A2, U, F, a, b, w):
            n.update(kind="farkas", w=[float(t) for t in w])
            return True
        if F == U and (b - a <= LEAF_REL * max(b, WIDE_FLOOR * self.cap) or tuple(U) in self.leaves):
            n["kind"] = "leaf"                             # decided exactly by the checker
            self.leaves.add(tuple(U))
            return True
        return False

    def _scalings(self, U, a, b):
        """``D = I`` and the Perron-like ``z / x`` of the smallest eigenvalue of ``A_UU`` at the
        midpoint (right and left eigenvectors of one sign), when it exists."""
        yield np.ones(len(U))
        m = 0.5 * (a + b)
        ix = np.ix_(U, U)
        A = self.S[0][ix] + m * self.S[1][ix] + m * m * self.S[2][ix]
        try:
            lam, X = np.linalg.eig(A)
            lt, Z = np.linalg.eig(A.T)
        except np.linalg.LinAlgError:
            return
        i, j = int(np.argmin(lam.real)), int(np.argmin(lt.real))
        if abs(lam[i].imag) > 1e-12 * max(1.0, abs(lam[i])):
            return
        x, z = X[:, i].real, Z[:, j].real
        x, z = x * np.sign(x.sum() or 1.0), z * np.sign(z.sum() or 1.0)
        if np.all(x > 0) and np.all(z > 0):
            d = z / x
            d = d / np.max(d)
            if np.all(d > 1e-12):
                yield d

    def _farkas(self, U, F, a, b):
        """A candidate Farkas vector: ``max t`` with ``(C^T w)_U >= t`` at the four corners,
        ``-1 <= w <= 1``, ``w <= 0`` off ``F``; None unless ``t > 0``. The LP's duals (a point of
        the family's relaxation) are kept in ``self.relaxed`` for the index split."""
        s = self.s
        Cs = [C for C, _ in corners(*(M[:, U] for M in self.S), a, b)]
        rows = [np.hstack([-C.T, np.ones((len(U), 1))]) for C in Cs]
        ub = np.zeros(s + 1)
        ub[list(F)] = 1.0
        ub[s] = 1.0
        lb = np.full(s + 1, -1.0)
        lb[s] = -np.inf
        c = np.zeros(s + 1)
        c[s] = -1.0
        r = lp.solve(c, np.vstack(rows), lb, ub)
        self.relaxed = None
        if r.ok and r.marginals is not None and len(r.marginals) == len(Cs) * len(U):
            X = np.maximum(-r.marginals.reshape(len(Cs), len(U)), 0.0)
            y = sum(C @ x for C, x in zip(Cs, X))
            self.relaxed = (X.sum(axis=0), y[U])
        if not r.ok or r.x is None or not r.x[s] > 1e-9:
            return None
        return np.minimum(r.x[:s], ub[:s])

    def _pair_inside(self, U, F):
        r"""A pair with both halves in ``U \ F``, else None."""
        free = set(U) - set(F)
        return next((p for p in self.pairs if p[0] in free and p[1] in free), None)

    def _branch(self, n: dict, U, F, i: int) -> None:
        """Branch on ``i``: out of the support, or forced in (its partners leave ``U``)."""
        partners = {q for p in self.pairs if i in p for q in p if q != i}
        a, b = n["a"], n["b"]
        n.update(kind="branch", i=i, children=[self.add([j for j in U if j != i], F, a, b),
                                               self.add([j for j in U if j not in partners], list(F) + [i], a, b)])

    def _split(self, k: int, n: dict) -> None:
        U, F, a, b = n["U"], n["F"], n["a"], n["b"]
        pair = self._pair_inside(U, F)
        if pair is not None:
            self._branch(n, U, F, pair[0])
            return
        if b - a > WIDE_REL * max(b, WIDE_FLOOR * self.cap) or len(U) == len(F):
            m = 0.5 * (a + b)
            if a < m < b:
                n.update(kind="bisect", children=[self.add(U, F, a, m), self.add(U, F, m, b)])
                return
        if len(U) == len(F):
            n["kind"] = "open"                             # an interval no float can halve
            return
        self._branch(n, U, F, self._index(U, F, 0.5 * (a + b)))

    def _index(self, U, F, m: float) -> int:
        """The free index where the LP's relaxed point breaks complementarity most (``x_i y_i``),
        else where the smallest eigenvector of ``sym(A_UU(m))`` is largest."""
        free = np.array([j not in F for j in U])
        if self.relaxed is not None:
            x, y = self.relaxed
            v = np.where(free, x * np.abs(y), -1.0)
            if np.max(v) > 1e-12:
                return int(U[int(np.argmax(v))])
        ix = np.ix_(U, U)
        A = self.S[0][ix] + m * self.S[1][ix] + m * m * self.S[2][ix]
        try:
            v = np.abs(np.linalg.eigh(0.5 * (A + A.T))[1][:, 0])
        except np.linalg.LinAlgError:
            v = np.ones(len(U))
        v = np.where(free & np.isfinite(v), v, -1.0)
        return int(U[int(np.argmax(v))])


def _float_copositive(Cs, d, theta: float) -> bool:
    """A floating-point screen of the sign argument (a Cholesky per corner, no bounds): the
    rigorous test :func:`cop_closes` is run only where this succeeds."""
    for C in Cs:
        M = d[:, None] * C
        H = 0.5 * (M + M.T)
        if theta > 0:
            H = H - theta * np.maximum(H - np.diag(np.diag(H)), 0.0)
        try:
            np.linalg.cholesky(H)
        except np.linalg.LinAlgError:
            return False
    return True


def prove_bb(A0, A1, A2, cap: float, max_nodes: int | None = None, deadline: float = math.inf,
             pairs=()) -> BBProof:
    """The branch and bound on ``[0, cap]`` and the checker's verdict on its log (``pairs``: the
    zero-reaction nodes' ``(a, b)``, recorded in the log and verified by the checker).

    ``max_nodes``: the budget in tree nodes (``None``: :data:`NODES`; at most :data:`MAX_NODES`),
    so that what is proven does not depend on the machine. ``deadline`` (a ``time.perf_counter()``
    value) is only a safety stop; ``timed_out`` says when it left nodes open."""
    t0 = time.perf_counter()
    tree = _Tree(A0, A1, A2, cap, NODES if max_nodes is None else max_nodes, deadline, pairs)
    with one_blas_thread():
        tree.run()
    for _, k in tree.heap:
        tree.nodes[k]["kind"] = "open"
    t1 = time.perf_counter()
    log = {"format": "mceip-mu-quadratic-bb/1", "cap": float(cap), "nodes": tree.nodes,
           "pairs": [list(p) for p in tree.pairs]}
    with one_blas_thread():
        rep = check_log(tree.A[0], tree.A[1], tree.A[2], log)
    out = BBProof(rep, float(cap), log, seconds=time.perf_counter() - t0, prover_seconds=t1 - t0,
                  supports=rep.leaves, timed_out=tree.timed_out)
    why = f"open node ({STOPPED})" if tree.timed_out else f"open node (node budget {tree.max_nodes})"
    out.undecided = [(tuple(n["U"]), why) for n in tree.nodes if n["kind"] == "open"] + \
        rep.undecided + [((), e) for e in rep.errors]
    return out
