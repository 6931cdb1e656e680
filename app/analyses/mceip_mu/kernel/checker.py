"""The trusted kernel: rigorous tests on a condensed MCEIP-mu pencil, and the proof-log checker.

Problem (paper eqs. (21)-(23), condensed on the ``s`` slip nodes): ``A(mu) = A0 + mu A1``;
a solution is ``mu >= 0``, ``v >= 0``, ``v != 0`` with ``y = A(mu) v >= 0`` and ``v_i y_i = 0``.
Its support ``P = {i : v_i > 0}`` must not hold both halves ``(a, b)`` of a ``pair`` (split
tangential rates of zero-reaction nodes). The pencil's floating-point entries are the data: the
proof is about them exactly.

The trusted kernel is five modules, none of which imports the prover
(:mod:`app.analyses.mceip_mu.prover.claims`, which uses their tests): :mod:`.rounding` (the rigorous
rounding-error bounds), :mod:`.closing` (sign argument, nonsingularity, products of constraints,
Farkas vectors), :mod:`.windows` (Krawczyk windows of isolated eigenpairs), :mod:`.prooflog` (the
log) and this module, which re-verifies a log from the pencil alone.

The log (:class:`~app.analyses.mceip_mu.kernel.prooflog.ProofLog`) is a tree of nodes ``(U, [a, b])`` ("no solution with support in ``U``
and mu in ``[a, b]`` other than the listed ones"); :func:`check_log` re-runs every node's test from
the pencil and checks that the children of each node cover it. The format is documented in
docs/proofs.md.
"""
from __future__ import annotations

import numpy as np

from app.analyses.mceip_mu.kernel.closing import closes_subsets, cover_nonsingular, covers, farkas_closes, rlt_closes
from app.analyses.mceip_mu.kernel.prooflog import CheckReport, Node, ProofLog
from app.analyses.mceip_mu.kernel.windows import verify_window


def scaled(A0: np.ndarray, A1: np.ndarray, scale_exp: int) -> tuple[np.ndarray, np.ndarray]:
    """The pencil divided by ``2^scale_exp`` (exact)."""
    return np.ldexp(np.asarray(A0, dtype=float), -scale_exp), np.ldexp(np.asarray(A1, dtype=float), -scale_exp)


def allowed(U: list[int], pairs) -> bool:
    """Whether the support ``U`` holds no pair ``(a, b)`` of ``pairs`` whole (both halves of a split
    tangential rate in one support: not a solution to report)."""
    su = set(U)
    return not any(a in su and b in su for a, b in pairs)


def check_node(a0, a1, node: Node, pairs, cap: float) -> tuple[bool, list, int, str]:
    """Re-run one node's own test. Returns ``(ok, solutions, ill, why)``."""
    U = np.asarray(node.U, dtype=np.int64)
    if node.kind == "cop":
        ok = node.d is not None and closes_subsets(a0, a1, U, node.a, node.b, np.asarray(node.d, float),
                                                   float(node.theta))
        return ok, [], 0, "" if ok else "sign argument fails"
    if node.kind == "rlt":
        ok = node.M is not None and rlt_closes(a0, a1, U, node.F, node.a, node.b, node.M, float(node.theta))
        return ok, [], 0, "" if ok else "product argument fails"
    if node.kind == "farkas":
        ok = node.w is not None and farkas_closes(a0, a1, U, node.F, node.a, node.b, node.w)
        return ok, [], 0, "" if ok else "Farkas vector fails"
    if node.kind == "empty":
        ok = not node.U or not set(node.F) <= set(node.U)
        return ok, [], 0, "" if ok else "the family is not empty"
    if node.kind == "pair":
        ok = not allowed(node.F, pairs)
        return ok, [], 0, "" if ok else "F holds no pair"
    if node.kind == "leaf":
        if sorted(set(node.F)) != sorted(set(node.U)):
            return False, [], 0, "a leaf proves its exact support only (F must equal U)"
        if not allowed(node.U, pairs):
            return True, [], 0, ""
        pieces, sols, ill = [], [], 0
        for w in node.windows:
            res = verify_window(a0, a1, U, float(w["mu"]), np.asarray(w["x"], float), float(w["h"]), cap, pairs)
            if not res.ok:
                return False, [], 0, f"window at mu = {w['mu']} not verified"
            pieces.append((res.mu_lo, res.mu_hi))
            if res.verdict == "solution":
                sols.append((list(node.U), res.enc_lo, res.enc_hi))
            elif res.verdict != "not a solution":
                ill += 1
                sols.append((list(node.U), res.enc_lo, res.enc_hi, res.verdict))
        for pc in node.pieces:
            lo, hi = float(pc["a"]), float(pc["b"])
            if not farkas_closes(a0, a1, U, node.U, lo, hi, pc["w"]):
                return False, [], 0, f"Farkas piece [{lo}, {hi}] fails"
        gaps = pieces + [(float(pc["a"]), float(pc["b"])) for pc in node.pieces]
        if not cover_nonsingular(a0, a1, U, node.a, node.b, gaps):
            return False, [], 0, "the rest of [a, b] not proven free of eigenvalues"
        return True, sols, ill, ""
    return False, [], 0, f"node kind {node.kind!r} proves nothing by itself"


def check_log(A0: np.ndarray, A1: np.ndarray, log: ProofLog) -> CheckReport:
    """Re-verify a proof log from the pencil alone (:func:`_check_log`, with one BLAS thread:
    the tests are stacks of small matrices)."""
    from app.linalg import one_blas_thread
    with one_blas_thread():
        return _check_log(A0, A1, log)


def _check_log(A0: np.ndarray, A1: np.ndarray, log: ProofLog) -> CheckReport:
    """Re-verify a proof log from the pencil alone.

    Every node reachable from the roots is checked: its own test (``cop``, ``rlt``, ``farkas``,
    ``leaf``, ``pair``, ``empty``), or, for the split kinds, that its children exist and cover it
    (:func:`_children_cover`). A reachable ``open`` node fails the claim."""
    A0 = np.asarray(A0, dtype=float)
    A1 = np.asarray(A1, dtype=float)
    if A0.shape != (log.s, log.s) or A1.shape != (log.s, log.s):
        return CheckReport(False, False, None, 0.0, [], 0, [f"pencil is {A0.shape}, log is for s = {log.s}"])
    a0, a1 = scaled(A0, A1, log.scale_exp)
    tree = _Tree(a0, a1, log)
    onset_ok, onset = _onset_claim(tree, log)
    lower_bound = 0.0
    if onset_ok:
        lower_bound = float(log.onset_below)
    elif log.bound_root is not None and log.bound is not None:
        ok, sols, ill = tree.visit(log.bound_root)
        if ok and ill == 0 and not sols and tree.is_root(log.bound_root, log.bound):
            lower_bound = float(log.bound)
        else:
            tree.errors.append("bound tree not verified")
    all_ok, sols, ill_all = _all_claim(tree, log)
    return CheckReport(onset_ok, all_ok, onset, lower_bound, sols, ill_all, tree.errors)


class _Tree:
    """The log's nodes, each verified once (post-order, without recursion: trees can be deep and
    nodes shared); ``visit(i)`` is ``(ok, solutions, ill-conditioned count)`` of node ``i``'s subtree."""

    def __init__(self, a0: np.ndarray, a1: np.ndarray, log: ProofLog):
        self.a0, self.a1, self.s, self.cap = a0, a1, log.s, log.cap
        self.pairs = [tuple(int(i) for i in p) for p in log.pairs]
        self.byid = {n.id: n for n in log.nodes}
        self.memo: dict[int, tuple[bool, list, int]] = {}
        self.errors: list[str] = []

    def is_root(self, i: int, b: float) -> bool:
        """Node ``i`` holds every support on ``[0, b]``."""
        n = self.byid.get(i)
        return n is not None and sorted(n.U) == list(range(self.s)) and not n.F and n.a <= 0.0 and n.b >= b

    def _order(self, i: int) -> list[int]:
        order, stack, placed = [], [(i, False)], set()
        while stack:
            j, expanded = stack.pop()
            if j in self.memo or (not expanded and j in placed):
                continue
            if expanded:
                order.append(j)
                continue
            placed.add(j)
            stack.append((j, True))
            n = self.byid.get(j)
            if n is not None:
                stack.extend((c, False) for c in n.children if c not in self.memo and c not in placed)
        return order

    def visit(self, i: int) -> tuple[bool, list, int]:
        for j in self._order(i):
            n = self.byid.get(j)
            if n is None:
                self.memo[j] = (False, [], 0)
                self.errors.append(f"node {j} missing")
            elif n.kind in ("bisect", "branch", "drop", "pairsplit"):
                ok, why = _children_cover(n, self.byid, self.pairs)
                sols, ill = [], 0
                for c in n.children:
                    cok, cs, ci = self.memo.get(c, (False, [], 0))
                    ok = ok and cok
                    sols += cs
                    ill += ci
                if why:
                    self.errors.append(f"node {j}: {why}")
                self.memo[j] = (ok, sols, ill)
            elif n.kind == "open":
                self.memo[j] = (False, [], 0)
                self.errors.append(f"node {j} is open (unfinished)")
            else:
                ok, sols, ill, why = check_node(self.a0, self.a1, n, self.pairs, self.cap)
                if not ok:
                    self.errors.append(f"node {j}: {why}")
                self.memo[j] = (ok, sols, ill)
        return self.memo[i]


def _onset_claim(tree: _Tree, log: ProofLog) -> tuple[bool, tuple[float, float] | None]:
    """The onset claim: no solution (nothing listed, nothing undecided) on ``[0, onset_below]``,
    and a verified solution just above it (or ``onset_below >= cap``)."""
    if log.onset_root is None or log.onset_below is None:
        return False, None
    ok, sols, ill = tree.visit(log.onset_root)
    full = tree.is_root(log.onset_root, log.onset_below)
    if not full:
        tree.errors.append("onset root does not cover every support on [0, onset_below]")
    empty = ill == 0 and not any(sl[1] <= log.onset_below for sl in sols)
    if not (ok and full and empty):
        return False, None
    if log.onset_below >= log.cap:
        return True, None
    if log.onset_witness is None:
        tree.errors.append("no onset witness")
        return False, None
    w = log.onset_witness
    U = np.asarray(sorted(int(i) for i in w["U"]), dtype=np.int64)
    res = verify_window(tree.a0, tree.a1, U, float(w["mu"]), np.asarray(w["x"], float), float(w["h"]), log.cap,
                        tree.pairs)
    if res.ok and res.verdict == "solution" and allowed(list(U), tree.pairs) and res.enc_lo > log.onset_below:
        return True, (float(log.onset_below), float(res.enc_hi))
    tree.errors.append("onset witness is not a verified solution above onset_below")
    return False, None


def _all_claim(tree: _Tree, log: ProofLog) -> tuple[bool, list, int]:
    """The complete-list claim: roots holding every support tile ``[0, cap]``, every subtree
    verified, nothing undecided. Returns ``(ok, solutions sorted by mu, ill-conditioned count)``."""
    if not log.all_roots:
        return False, [], 0
    found: dict[tuple, tuple] = {}
    pieces, ok_all, ill_all = [], True, 0
    for r in log.all_roots:
        n = tree.byid.get(r)
        ok, sols, ill = tree.visit(r)
        if n is None or sorted(n.U) != list(range(log.s)) or n.F:
            ok = False
            tree.errors.append(f"root {r} does not hold every support")
        else:
            pieces.append((n.a, n.b))
        ok_all = ok_all and ok
        ill_all += ill
        for sl in sols:
            found[(tuple(sl[0]), round(sl[1], 12))] = sl
    sols = sorted((sl for sl in found.values() if len(sl) == 3), key=lambda t: t[1])
    return ok_all and covers(pieces, 0.0, log.cap) and ill_all == 0, sols, ill_all


def _contains(k: Node, U, F, a: float, b: float) -> bool:
    """Child ``k``'s family holds every support ``P`` with ``F <= P <= U`` on ``[a, b]``: a larger
    ``U``, a smaller ``F`` and a longer interval only make its claim stronger."""
    return set(k.U) >= set(U) and set(k.F) <= set(F) and k.a <= a and k.b >= b


def _partners(i: int, pairs) -> set[int]:
    return {b for a, b in pairs if a == i} | {a for a, b in pairs if b == i}


def _children_cover(n: Node, byid: dict, pairs) -> tuple[bool, str]:
    """The children of a split node hold, together, every allowed support of its family."""
    kids = [byid.get(c) for c in n.children]
    if any(k is None for k in kids):
        return False, "a child is missing"
    U, F = set(n.U), set(n.F)
    if n.kind == "bisect":
        if len(kids) != 2:
            return False, "bisect needs two children"
        k1, k2 = kids
        ok = _contains(k1, U, F, k1.a, k1.b) and _contains(k2, U, F, k2.a, k2.b) and k1.a <= n.a \
            and k2.b >= n.b and k1.b >= k2.a
        return ok, "" if ok else "bisection children do not cover the node"
    if n.kind == "branch":
        # index i of U \ F: either i is not in the support (U \ {i}, F), or it is, and then no
        # partner of i is (U \ partners(i), F + {i})
        if len(kids) != 2:
            return False, "branch needs two children"
        k0, k1 = kids
        for i in U - F:
            if _contains(k0, U - {i}, F, n.a, n.b) and _contains(k1, U - _partners(i, pairs), F | {i}, n.a, n.b):
                return True, ""
        return False, "branch children do not split the family on an index"
    if n.kind == "pairsplit":
        # (a, b) a pair inside U: the allowed supports in U lie in U \ {a} or in U \ {b}
        if len(kids) != 2:
            return False, "pair split needs two children"
        for a, b in pairs:
            if a in U and b in U and _contains(kids[0], U - {a}, F, n.a, n.b) \
                    and _contains(kids[1], U - {b}, F, n.a, n.b):
                return True, ""
        return False, "pair split children are not U minus either half of a pair"
    if n.kind == "drop":
        # every U \ {i} on an interval containing [a, b], and the exact-support leaf of U
        need = set(U) if len(U) > 1 else set()     # U \ {i} is empty for |U| = 1: nothing to cover
        leaf = False
        for k in kids:
            if not (k.a <= n.a and k.b >= n.b):
                continue
            if set(k.U) == U and set(k.F) == U and k.kind in ("leaf", "pair"):
                leaf = True
                continue
            for i in list(need):
                if _contains(k, U - {i}, F, n.a, n.b):
                    need.discard(i)
        ok = leaf and not need
        return ok, "" if ok else "drop children do not cover the node"
    return False, f"node kind {n.kind!r} has no children rule"
