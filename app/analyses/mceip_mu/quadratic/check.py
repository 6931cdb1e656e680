r"""The trusted kernel and the independent checker of the quadratic MCEIP-mu branch and bound.

Problem (paper eqs. (21)-(23) condensed on the slip nodes, docs/method.md section 8): ``mu`` in
``[0, cap]``, ``v >= 0``, ``v != 0``, ``y = A(mu) v >= 0``, ``v_i y_i = 0``, with
``A(mu) = A0 + mu A1 + mu^2 A2``. A node of the proof is a family ``F <= P <= U`` of supports with
``mu`` in ``[a, b]``; its claim is "no solution with such a support and such a mu other than the
ones the exact leaves list".

**The lifting.** On ``[a, b]``, ``mu^2 = (a + b) mu - a b + e`` with ``e = (mu - a)(mu - b)`` in
``[-w, 0]``, ``w = (b - a)^2 / 4``; so ``A(mu) = (A0 - a b A2) + mu (A1 + (a + b) A2) + e A2`` is
affine in ``(mu, e)`` and lies in the convex hull of the four *corners* ``A(a)``, ``A(b)``,
``A(a) - w A2``, ``A(b) - w A2`` (:func:`corners`, each a midpoint with a rigorous radius, ``w``
rounded up). Every test below is convex in the matrix, so holding at the four corners proves it
on the whole interval:

* ``cop`` (sign argument): at a solution ``v^T D A_UU(mu) v = sum_i d_i v_i y_i = 0``; a strictly
  copositive ``sym(D A_UU)`` (exact split ``P + N``, ``N >= 0``, ``P`` proven positive definite by a
  verified Cholesky) at every corner excludes every support in ``U`` (the copositive cone is convex);
* ``farkas``: ``w_i <= 0`` off ``F`` and ``(C^T w)_U > 0`` at every corner ``C`` excludes the family
  (``w^T y <= 0`` at a solution, ``= (A^T w)_P^T v_P > 0``; linear in ``C``);
* ``nonsing`` (``F = U``): ``||I - R C||_inf < 1`` at every corner with one ``R``, so every matrix of
  the hull is nonsingular (the norm is convex): ``A_UU(mu)`` has no null vector on ``[a, b]``;
* ``leaf`` (``F = U = J``): the exact per-support proof of
  :mod:`app.analyses.mceip_mu.quadratic.proof` on ``[0, cap]`` (rational determinants, isolated
  roots, ball arithmetic); its solutions are proven, its undecided roots leave the node open.

**Pairs** (zero-reaction nodes, ``log["pairs"]``): the two halves ``(a, b)`` of a split
tangential rate, whose columns must be exact negatives in the pencil (verified:
:func:`app.analyses.mceip_mu.quadratic.proof.pairs_hold`); no support needs both, so a node whose
``F`` holds a pair is closed (``pair``), a ``leaf`` whose support holds one has nothing to decide,
and a ``branch`` on ``i`` may drop ``i``'s partner from the child that forces ``i``
(``(U \ partners(i), F + {i})``), as the linear engine's checker accepts
(:mod:`app.analyses.mceip_mu.kernel.checker`).

:func:`check_log` re-verifies a whole proof log from the pencil (this module does not import
the prover): the root covers every support and ``[0, cap]``, every split covers its node, every
witness holds, every leaf is decided again. Only then are the claims accepted.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from app.analyses.mceip_mu.kernel.closing import farkas_at, pd_plus_nn
from app.analyses.mceip_mu.kernel.rounding import U_ROUND, gamma, mr_mul, rounded_up, safe_inv

THETAS = (0.0, 0.5, 1.0)


def corners(a0: np.ndarray, a1: np.ndarray, a2: np.ndarray, a: float, b: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """The four corners of the lifting on ``[a, b]`` as (midpoint, radius): every ``A(mu)``,
    ``mu`` in ``[a, b]``, is a convex combination of matrices within the radii of them."""
    w = float(rounded_up(0.25 * (b - a) * (b - a), 4))          # >= (b - a)^2 / 4
    out = []
    for mu in (a, b):
        mu2 = mu * mu
        base = a0 + mu * a1 + mu2 * a2
        size = np.abs(a0) + abs(mu) * np.abs(a1) + mu2 * np.abs(a2)
        out.append((base, rounded_up(gamma(8) * size, 8)))
        if w > 0:
            out.append((base - w * a2, rounded_up(gamma(8) * (size + w * np.abs(a2)), 8)))
    return out


def cop_closes(a0, a1, a2, U, a: float, b: float, d, theta: float) -> bool:
    """No solution with support in ``U`` and mu in ``[a, b]``: ``sym(D A_UU)`` strictly copositive
    at the four corners (``D = diag(d) > 0``)."""
    U = np.asarray(U, dtype=np.int64)
    d = np.asarray(d, dtype=float)
    if len(U) == 0 or d.shape != (len(U),) or np.any(~(d > 0)) or not np.all(np.isfinite(d)) \
            or theta not in THETAS or not (0 <= a <= b):
        return False
    ix = np.ix_(U, U)
    for C, rC in corners(a0[ix], a1[ix], a2[ix], a, b):
        M, rM = mr_mul(np.diag(d), None, C, rC)
        H = 0.5 * (M + M.T)
        R = rounded_up(0.5 * (rM + rM.T) + U_ROUND * np.abs(H), 2)
        if not pd_plus_nn(H, R, theta):
            return False
    return True


def farkas_closes(a0, a1, a2, U, F, a: float, b: float, w) -> bool:
    """No solution with ``F <= P <= U`` and mu in ``[a, b]``: ``w_i <= 0`` off ``F`` and
    ``(C^T w)_U > 0`` at the four corners (rigorously, with the radii)."""
    U = np.asarray(U, dtype=np.int64)
    if len(U) == 0 or not (0 <= a <= b):
        return False
    return farkas_at(corners(a0[:, U], a1[:, U], a2[:, U], a, b), w, F, a0.shape[0])


def nonsingular_closes(a0, a1, a2, U, a: float, b: float) -> bool:
    """Every ``A_UU(mu)``, mu in ``[a, b]``, is nonsingular: ``||I - R C||_inf < 1`` at the four
    corners for ``R ~ A_UU((a + b) / 2)^-1`` (any ``R``: the bound is rigorous)."""
    U = np.asarray(U, dtype=np.int64)
    if len(U) == 0 or not (0 <= a <= b):
        return False
    ix = np.ix_(U, U)
    m = 0.5 * (a + b)
    with np.errstate(all="ignore"):
        R = safe_inv(a0[ix] + m * a1[ix] + m * m * a2[ix])
        if not np.all(np.isfinite(R)):
            return False
        for C, rC in corners(a0[ix], a1[ix], a2[ix], a, b):
            P, rP = mr_mul(R, None, C, rC)
            G = np.eye(len(U)) - P
            rG = rounded_up(rP + U_ROUND * np.abs(G), 2)
            if not rounded_up(np.max(np.sum(np.abs(G) + rG, axis=1)), len(U)) < 1.0:
                return False
    return True


@dataclass
class Report:
    """What the checker accepts: the proven solutions (union of the leaves), the open nodes'
    intervals, the errors (any error: nothing is accepted)."""

    errors: list[str] = field(default_factory=list)
    solutions: list = field(default_factory=list)
    open_from: float = np.inf                 # every solution below this mu is in ``solutions``
    undecided: list = field(default_factory=list)     # (support, why) of the leaves' undecided roots
    nodes: int = 0
    leaves: int = 0

    @property
    def complete(self) -> bool:
        """Whether the list is complete: no error and no open node, so every solution in ``[0, cap]`` is
        in ``solutions``."""
        return not self.errors and self.open_from == np.inf

    @property
    def onset(self):
        """The proven onset: the smallest proven solution when no open node reaches below its
        enclosure's upper end, else None (``onset_proven`` says which)."""
        return min(self.solutions, key=lambda p: p.enclosure[0]) if self.solutions else None

    @property
    def onset_proven(self) -> bool:
        """Whether the onset is proven: no error, and either the list is complete (the onset is its
        smallest solution, or there is none below the cap) or the smallest proven solution's enclosure
        ends below every open node (``open_from``)."""
        if self.errors:
            return False
        on = self.onset
        return self.complete or (on is not None and on.enclosure[1] < self.open_from)


def check_log(A0, A1, A2, log: dict) -> Report:
    """Re-verify the proof log ``log`` (format in docs/proofs.md) of the pencil from scratch."""
    import flint

    from app.analyses.mceip_mu.quadratic.proof import PREC, exact, exact_data, pairs_hold
    rep = Report()
    s, cap, nodes = A0.shape[0], float(log["cap"]), log["nodes"]
    try:
        pairs = [(int(a), int(b)) for a, b in log.get("pairs", [])]
    except (TypeError, ValueError):
        pairs = None
    if pairs is None or not pairs_hold(A0, A1, A2, pairs):
        rep.errors.append("the log's pairs are not pairs of exactly opposite columns of the pencil")
        return rep
    if not nodes or nodes[0]["U"] != list(range(s)) or nodes[0]["F"] or nodes[0]["a"] != 0.0 \
            or nodes[0]["b"] != cap or not cap >= 0:
        rep.errors.append("the root is not every support on [0, cap]")
        return rep
    old = flint.ctx.prec
    flint.ctx.prec = PREC
    try:
        Q, capq, cache, found = exact_data(A0, A1, A2), exact(cap), {}, {}

        def leaf(J, a, b):
            from app.analyses.mceip_mu.quadratic.proof import decide_support
            sols, und = decide_support(*Q, J, s, capq, window=(a, b), cache=cache, pairs=pairs)
            found.update(((p.support, p.enclosure), p) for p in sols)
            return und

        seen, todo = set(), [0]
        while todo and len(rep.errors) < 3:
            k = todo.pop()
            if k in seen or not 0 <= k < len(nodes):
                rep.errors.append(f"node {k}: reached twice or missing")
                break
            seen.add(k)
            rep.nodes += 1
            todo += _check_node(A0, A1, A2, nodes, k, rep, leaf, pairs)
        rep.solutions = list(found.values())
    finally:
        flint.ctx.prec = old
    rep.solutions.sort(key=lambda p: (p.enclosure[0], p.support))
    return rep


def holds_pair(S, pairs) -> bool:
    """Whether the index set ``S`` holds both halves of some pair."""
    S = set(int(i) for i in S)
    return any(a in S and b in S for a, b in pairs)


def _check_node(A0, A1, A2, nodes, k, rep: Report, leaf, pairs=()) -> list[int]:
    """Verify node ``k``; returns its children to verify."""
    n = nodes[k]
    U, F, a, b, kind = tuple(n["U"]), tuple(n["F"]), float(n["a"]), float(n["b"]), n["kind"]
    bad = lambda why: rep.errors.append(f"node {k} ({kind}): {why}") or []      # noqa: E731
    if not set(F) <= set(U) or len(set(U)) != len(U) or not all(0 <= int(i) < A0.shape[0] for i in U) \
            or not 0 <= a <= b:
        return bad("not a family")
    if kind in ("bisect", "branch"):
        c = [nodes[i] if 0 <= i < len(nodes) else None for i in n.get("children", [])]
        if len(c) != 2 or None in c:
            return bad("two children expected")
        partners: set = set()
        if kind == "bisect":
            m = c[0]["b"]
            want = [(U, F, a, m), (U, F, m, b)]
            if not a < m < b:
                return bad("the split point is not inside the interval")
        else:
            i = int(n["i"])
            if i not in U or i in F:
                return bad("the index is not free")
            want = [(tuple(j for j in U if j != i), F, a, b), (U, tuple(sorted(F + (i,))), a, b)]
            # forcing i in: its partner may leave U (no support holds both halves of a pair)
            partners = {q for p in pairs if i in p for q in p if q != i}
            alt = (tuple(j for j in U if j not in partners), tuple(sorted(F + (i,))), a, b)
        got = [(tuple(x["U"]), tuple(x["F"]), float(x["a"]), float(x["b"])) for x in c]
        if got != want and not (kind == "branch" and partners and got == [want[0], alt]):
            return bad("the children do not cover the node")
        return list(n["children"])
    if kind == "pair":
        return [] if holds_pair(F, pairs) else bad("F holds no pair")
    if kind == "leaf" and F == U and holds_pair(U, pairs):
        return []                                       # no allowed support: nothing to decide
    if kind == "cop" and cop_closes(A0, A1, A2, U, a, b, n["d"], float(n["theta"])):
        return []
    if kind == "farkas" and farkas_closes(A0, A1, A2, U, F, a, b, n["w"]):
        return []
    if kind == "nonsing" and F == U and nonsingular_closes(A0, A1, A2, U, a, b):
        return []
    if kind in ("leaf", "open") and F == U and len(U) == 0:
        return []                                       # the empty support is no solution (v != 0)
    if kind == "leaf" and F == U:
        rep.leaves += 1
        for why, (lo, hi) in leaf(U, a, b):
            rep.open_from = min(rep.open_from, max(a, lo))
            rep.undecided.append((U, why))
        return []
    if kind == "open":
        rep.open_from = min(rep.open_from, a)
        return []
    return bad("the witness does not hold")
