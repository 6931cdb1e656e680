"""A proof for the quadratic MCEIP-mu of a curved obstacle, in exact and ball arithmetic (FLINT).

Problem (docs/method.md section 8): ``A(mu) x = y``, ``A(mu) = A0 + mu A1 + mu^2 A2``,
``mu >= 0``, ``0 <= x ⊥ y >= 0``, ``x != 0``; the floating-point entries of ``A0, A1, A2`` are
the data and the proof is about them exactly. For every support ``J`` (the unknowns with
``x > 0``) a solution is an eigenpair of ``A_JJ(mu) x_J = 0`` with ``x_J > 0`` and
``y_{J^c} = A_{J^c J}(mu) x_J >= 0``. The proof, support by support:

1. ``p_J(mu) = det A_JJ(mu)`` exactly: a polynomial of degree at most ``2|J|`` with rational
   coefficients, interpolated from exact rational determinants (``fmpq_mat``) at the integers
   ``0 .. 2|J|``. ``p_J = 0`` identically: the support is undecided (not proven).
2. Its real roots: the squarefree part ``p_J / gcd(p_J, p_J')`` (exact), whose roots FLINT
   isolates rigorously (``complex_roots``: real roots are returned with an exactly zero
   imaginary part); only the roots whose enclosure meets ``[0, cap]`` matter, and an enclosure
   that straddles an end of ``[0, cap]`` is undecided.
3. At a real root of ``p_J`` of multiplicity 1 the null space of ``A_JJ`` is one-dimensional and
   spanned by any non-zero column of the adjugate; the column's entries (cofactors, determinants
   in ball arithmetic at the root's enclosure, ``arb_mat``) give the signs of ``x_J``, and
   ``y_{J^c}`` follows in ball arithmetic. Proven a solution when ``x_J > 0`` (after the sign of
   the column is chosen) and ``y_{J^c} > 0``; proven not one when some ``x_i`` has the opposite
   sign, some ``y_i < 0`` or some ``x_i`` is exactly 0 (its cofactor the zero polynomial, decided
   by exact integer determinants: the solution of a smaller support); otherwise (a ball that
   contains 0, a multiple root) undecided.

Zero-reaction nodes (``pairs``, docs/method.md section 8): the split tangential rate
``v_T = a - b`` of a zero-reaction node gives columns ``a`` and ``b`` that are exact negatives
(:func:`pairs_hold`, checked on the data, else the proof refuses the pairs). A solution whose
support holds both has ``y_a = y_b = 0``; subtracting ``min(a, b)`` from both leaves ``A(mu) x``
unchanged and gives a solution with a smaller support (or ``x`` on the spurious direction
``a = b``, no motion), so those supports are not decided. Where the exact identity
``y_b = -y_a + 2 mu y_N`` of the split rows holds (:func:`structural_zeros`), ``y_b`` vanishes on
every support holding ``a`` and ``N``: it is ``y = 0 >= 0``, not an undecided sign.

When every support is decided, the list of solutions with ``mu`` in ``[0, cap]`` is complete,
each with a rigorous enclosure of its ``mu``, and the onset is the smallest of them (or none).
Exponential in ``s`` (``2^s - 1`` supports, each ``2|J| + 1`` exact determinants): attempted up
to ``max_s`` slip nodes. Nothing here trusts a floating-point solver: the floating-point
enumeration only names the candidates that are compared with the proof's list.
"""
from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field

import numpy as np

from app.analyses.outcomes import STOPPED

PREC = 256          # bits of the ball arithmetic at the roots


@dataclass
class ProvenSolution:
    """A solution of the quadratic MCEIP-mu proven exactly: its mu (the midpoint of the enclosure),
    the rigorous enclosure of mu (rounded outwards to doubles) and its support ``J``."""

    value: float                      # midpoint of the enclosure
    enclosure: tuple[float, float]    # rigorous (rounded outwards to doubles)
    support: tuple[int, ...]


@dataclass
class QuadraticProof:
    """The per-support proof on ``[0, cap]``: ``proven`` when every support was decided (the list of
    solutions is then complete), the proven solutions by enclosure, the undecided supports with the
    reason, the number of supports examined and the wall time in seconds."""

    proven: bool                      # every support decided: the list in [0, cap] is complete
    cap: float
    solutions: list[ProvenSolution] = field(default_factory=list)
    undecided: list[tuple[tuple[int, ...], str]] = field(default_factory=list)
    supports: int = 0
    seconds: float = 0.0
    timed_out: bool = False           # the wall-clock safety stop left supports undecided

    @property
    def onset(self) -> ProvenSolution | None:
        """The proven solution whose enclosure starts lowest (None without one); the onset only when
        :attr:`proven` (an undecided support may hide a lower one)."""
        return min(self.solutions, key=lambda p: p.enclosure[0]) if self.solutions else None


def pairs_hold(A0: np.ndarray, A1: np.ndarray, A2: np.ndarray, pairs) -> bool:
    """Every pair ``(a, b)`` names two distinct columns that are exact negatives in ``A0, A1, A2``
    (the split of a zero-reaction node's tangential rate): then no support needs both."""
    s = A0.shape[0]
    for a, b in pairs:
        a, b = int(a), int(b)
        if not (0 <= a < s and 0 <= b < s and a != b):
            return False
        if not all(np.array_equal(M[:, b], -M[:, a]) for M in (A0, A1, A2)):
            return False
    return True


def structural_zeros(M0, M1, M2, J, pairs) -> np.ndarray:
    """Rows ``j`` off ``J`` whose ``y_j`` vanishes at every eigenpair of support ``J`` by an exact
    identity of the split pencil of a zero-reaction node (pair ``(a, b)``, normal rate ``N``):
    ``M0[b] = -M0[a]``, ``M1[b] = M1[a] = M0[N]``, ``M2[b] = -M2[a]``, ``M1[N] = M2[N] = 0``
    (exact equality of the data: floats, or the exact integers of :func:`exact_data`) give
    ``y_b = -y_a + 2 mu y_N``, zero when ``a`` and ``N`` are in ``J``."""
    def same(u, v):
        return all(p == q for p, q in zip(u, v))

    def neg(u):
        return [-p for p in u]

    inJ = set(int(i) for i in J)
    out = set()
    for a, b in pairs:
        for i, j in ((int(a), int(b)), (int(b), int(a))):
            if i not in inJ or j in inJ:
                continue
            if not (same(M0[j], neg(M0[i])) and same(M1[j], M1[i]) and same(M2[j], neg(M2[i]))):
                continue
            if any(n != i and same(M1[i], M0[n]) and not any(p != 0 for p in M1[n]) and not any(p != 0 for p in M2[n])
                   for n in inJ):
                out.add(j)
    return np.array(sorted(out), dtype=np.int64)


def exact(v: float):
    """The double ``v`` as the exact rational number it stores (a FLINT ``fmpq``)."""
    import flint
    return flint.fmpq(*float(v).as_integer_ratio())


def _qmat(A: np.ndarray):
    import flint
    return flint.fmpq_mat([[exact(v) for v in row] for row in A])


def exact_data(A0: np.ndarray, A1: np.ndarray, A2: np.ndarray):
    """``2^E A0, 2^E A1, 2^E A2`` as exact integers (one power of two for all: the dyadic floats
    become integers; determinants scale by a positive power of two, roots and signs do not change)."""
    import flint
    ratios = [[[float(v).as_integer_ratio() for v in row] for row in A] for A in (A0, A1, A2)]
    E = max([d.bit_length() - 1 for R in ratios for row in R for _, d in row] + [0])     # d: powers of two
    return [[[flint.fmpz(n << (E - (d.bit_length() - 1))) for n, d in row] for row in R] for R in ratios]


def _det_poly(Z0, Z1, Z2, J: tuple[int, ...]):
    """``det A_JJ(mu)`` (of the integer data) as an exact ``fmpq_poly``: integer determinants
    (``fmpz_mat``) at ``mu = 0 .. 2|J|``, Lagrange interpolation."""
    import flint
    k = len(J)
    pts = list(range(2 * k + 1))
    vals = []
    for t in pts:
        vals.append(flint.fmpz_mat([[Z0[i][j] + t * Z1[i][j] + t * t * Z2[i][j] for j in J] for i in J]).det())
    x = flint.fmpq_poly([0, 1])
    p = flint.fmpq_poly([0])
    for a, ta in enumerate(pts):
        L = flint.fmpq_poly([1])
        den = 1
        for b, tb in enumerate(pts):
            if b != a:
                L = L * (x - tb)
                den *= ta - tb
        p = p + L * flint.fmpq(vals[a], den)
    return p


def _arb_interval(r):
    """(lo, hi) doubles enclosing the real ball ``r`` (outward)."""
    lo, hi = r.lower(), r.upper()
    return float(np.nextafter(float(lo), -np.inf)), float(np.nextafter(float(hi), np.inf))


def _decide(Q0, Q1, Q2, J, s, root, pairs=()) -> tuple[str, str]:
    """'solution' / 'not' / 'undecided' for the simple real root ``root`` (an arb) of ``p_J``
    (the rows of :func:`structural_zeros` are ``y = 0`` exactly)."""
    import flint
    k = len(J)
    zero = set(structural_zeros(Q0, Q1, Q2, J, pairs).tolist()) if pairs else set()
    rest = [i for i in range(s) if i not in J and i not in zero]

    def entry(i, j):
        return flint.arb(Q0[i][j]) + root * (flint.arb(Q1[i][j]) + root * flint.arb(Q2[i][j]))

    A = [[entry(i, j) for j in J] for i in J]
    if k == 1:
        x = [flint.arb(1)]
    else:
        x = None
        for row in range(k):          # a non-zero adjugate column: x_c = (-1)^(row+c) det(minor(row, c))
            col = []
            for c in range(k):
                minor = flint.arb_mat([[A[a][b] for b in range(k) if b != c] for a in range(k) if a != row])
                col.append(minor.det() * (-1) ** (row + c))
            if any(v > 0 or v < 0 for v in col):
                x = col
                break
        if x is None:
            return "undecided", "no adjugate column is provably non-zero at the root"
    pos = all(v > 0 for v in x)
    neg = all(v < 0 for v in x)
    if not (pos or neg):
        if any(v > 0 for v in x) and any(v < 0 for v in x):
            return "not", "x_J has entries of both signs"
        if k > 1 and any(not (v > 0 or v < 0) and _cofactor_vanishes(Q0, Q1, Q2, J, row, c) for c, v in enumerate(x)):
            # the null space is spanned by this column: x_c = 0 in every null vector
            return "not", "x_J has an entry that is exactly 0 (a cofactor vanishing identically)"
        return "undecided", "the sign of an entry of x_J is not resolved"
    if neg:
        x = [-v for v in x]
    y = [sum((entry(i, j) * x[b] for b, j in enumerate(J)), flint.arb(0)) for i in rest]
    if any(v < 0 for v in y):
        return "not", "y < 0 off the support"
    if all(v > 0 for v in y):
        return "solution", ""
    return "undecided", "the sign of y off the support is not resolved (y = 0 within the enclosure)"


def _cofactor_vanishes(Q0, Q1, Q2, J, row: int, c: int) -> bool:
    """Whether the minor of ``A_JJ(mu)`` without row ``row`` and column ``c`` is the zero
    polynomial (exact integer determinants at ``2 (|J| - 1) + 1`` points: its degree is lower)."""
    import flint
    R = [J[i] for i in range(len(J)) if i != row]
    C = [J[j] for j in range(len(J)) if j != c]
    for t in range(2 * len(R) + 1):
        if flint.fmpz_mat([[Q0[i][j] + t * Q1[i][j] + t * t * Q2[i][j] for j in C] for i in R]).det() != 0:
            return False
    return True


def prove_quadratic(A0: np.ndarray, A1: np.ndarray, A2: np.ndarray, cap: float, max_s: int = 10,
                    deadline: float | None = None, pairs=()) -> QuadraticProof | None:
    """The proof above on ``[0, cap]``; None when ``s > max_s`` (not attempted). Its budget is
    ``max_s``: at most ``2^max_s - 1`` supports, each decided exactly (work, not time, decides
    what is proven). ``deadline`` (a ``time.perf_counter()`` value) is only a safety stop: the
    supports left are reported undecided and ``timed_out`` is set.
    ``pairs``: the zero-reaction nodes' ``(a, b)``, verified by :func:`pairs_hold` (refused:
    nothing proven)."""
    import flint
    t0 = time.perf_counter()
    s = A0.shape[0]
    if s > max_s:
        return None
    pairs = [(int(a), int(b)) for a, b in pairs]
    if not pairs_hold(A0, A1, A2, pairs):
        return QuadraticProof(proven=False, cap=float(cap), undecided=[((), "a pair's columns are not exact negatives")])
    old = flint.ctx.prec
    flint.ctx.prec = PREC
    try:
        Q0, Q1, Q2 = exact_data(A0, A1, A2)            # exact: the proof is about these data
        out = QuadraticProof(proven=True, cap=float(cap))
        capq = exact(cap)
        for k in range(1, s + 1):
            for J in itertools.combinations(range(s), k):
                if any(a in J and b in J for a, b in pairs):
                    continue                        # reduced to a smaller support (docstring)
                out.supports += 1
                if out.timed_out or (deadline is not None and time.perf_counter() > deadline):
                    out.timed_out = True
                    out.undecided.append((J, STOPPED))
                    continue
                sols, und = decide_support(Q0, Q1, Q2, J, s, capq, pairs=pairs)
                out.solutions += sols
                out.undecided += [(J, why) for why, _ in und]
        out.proven = not out.undecided
        out.solutions.sort(key=lambda p_: (p_.enclosure[0], p_.support))
        out.seconds = time.perf_counter() - t0
        return out
    finally:
        flint.ctx.prec = old


def decide_support(Q0, Q1, Q2, J: tuple[int, ...], s: int, capq, window=None, cache=None, pairs=()):
    """Steps 1-3 above for the one support ``J`` on ``[0, cap]`` (``capq`` exact): its proven
    solutions and its undecided roots, each ``(why, (lo, hi))`` with the mu it concerns (all of
    ``[0, cap]`` when no root is isolated). With ``window = (lo, hi)`` only the roots whose
    enclosure meets it are decided; ``cache`` (a dict) keeps the polynomial, its roots and the
    decisions between calls; ``pairs``: the zero-reaction nodes' pairs, for
    :func:`structural_zeros` (the caller has verified them). Runs at the caller's ball precision."""
    cache = {} if cache is None else cache
    if J not in cache:
        cache[J] = _support_roots(Q0, Q1, Q2, J, capq)
    roots, und, sq = cache[J]
    sols: list[ProvenSolution] = []
    und = [u for u in und if window is None or (u[1][0] <= window[1] and window[0] <= u[1][1])]
    for idx, (r, enc) in enumerate(roots):
        if window is not None and not (enc[0] <= window[1] and window[0] <= enc[1]):
            continue
        if (J, idx) not in cache:
            cache[J, idx] = _decide_root(Q0, Q1, Q2, J, s, sq, r, pairs)
        verdict, why, hit = cache[J, idx]
        if verdict == "solution":
            sols.append(hit)
        elif verdict == "undecided":
            und.append((why, enc))
    return sols, und


def _support_roots(Q0, Q1, Q2, J, capq):
    """The simple real roots of ``det A_JJ(mu)`` in ``[0, cap]`` (arb balls with their float
    enclosures), the undecided ones (identically zero, multiple, at an end of ``[0, cap]``) and
    the squarefree part."""
    import flint
    whole = (0.0, float(np.nextafter(float(capq.p) / float(capq.q), np.inf)))
    p = _det_poly(Q0, Q1, Q2, J)
    if p.is_zero():
        return [], [("det A_JJ(mu) vanishes identically", whole)], None
    if p.degree() == 0:
        return [], [], None                                # a non-zero constant: no eigenvalue
    sq = p // p.gcd(p.derivative())                        # squarefree part, same roots
    multiple = sq.degree() < p.degree()
    try:
        found = _isolate(sq)
    except ValueError as err:                              # FLINT could not isolate the roots
        return [], [(f"root isolation failed ({err})", whole)], None
    cap = flint.arb(capq)
    roots, und = [], []
    for root, _ in found:
        if not root.imag.is_zero():
            continue                                       # FLINT returns real roots with imag exactly 0
        r = root.real
        if r < 0 or r > cap:
            continue
        if not (r > 0 or r.is_zero()) or not (r < cap):
            und.append(("a root at an end of [0, cap] is not separated from it", _arb_interval(r)))
        elif multiple and _is_multiple(p, sq, r):
            und.append(("a multiple root of det A_JJ(mu)", _arb_interval(r)))
        else:
            roots.append((r, _arb_interval(r)))
    return roots, und, sq


def _decide_root(Q0, Q1, Q2, J, s, sq, r, pairs=()):
    """('solution' | 'not' | 'undecided', why, the ProvenSolution or None) at the simple root ``r``."""
    verdict, why = _decide(Q0, Q1, Q2, J, s, r, pairs)
    if verdict == "undecided" or verdict == "solution":
        r = _refine(sq, r)                        # narrower: resolves more signs, a tight enclosure
        verdict, why = _decide(Q0, Q1, Q2, J, s, r, pairs)
    if verdict == "solution":
        lo, hi = _arb_interval(r)
        return verdict, why, ProvenSolution(float(r.mid()), (max(lo, 0.0), hi), J)
    return verdict, why, None


def _isolate(sq):
    """FLINT's rigorous isolation of the roots of ``sq`` (integer coefficients), at 53 bits first
    (faster; rigorous at any precision), then at more."""
    import flint
    z = sq.numer() if hasattr(sq, "numer") else sq
    saved = flint.ctx.prec
    try:
        for prec in (53, 212, 848):
            flint.ctx.prec = prec
            try:
                return z.complex_roots()
            except ValueError:
                if prec == 848:
                    raise
    finally:
        flint.ctx.prec = saved


def _refine(sq, r, steps: int = 80):
    """The simple real root of the squarefree ``sq`` in the ball ``r``, narrowed by exact
    bisection on the sign change of ``sq`` (rational arithmetic); ``r`` itself when the ends of
    the ball do not show the sign change."""
    import flint
    lo, hi = _exact(r.lower()), _exact(r.upper())
    flo, fhi = sq(lo), sq(hi)
    if flo == 0 or fhi == 0 or (flo > 0) == (fhi > 0):
        return r
    for _ in range(steps):
        mid = (lo + hi) / 2
        fm = sq(mid)
        if fm == 0:
            return flint.arb(mid)
        if (fm > 0) == (flo > 0):
            lo, flo = mid, fm
        else:
            hi = mid
    return flint.arb((lo + hi) / 2, (hi - lo) / 2)


def _exact(v):
    """The exact rational value of an arb with zero radius (an end point of a ball)."""
    import flint
    m, e = v.man_exp()
    return flint.fmpq(m) * flint.fmpq(2) ** int(e) if e >= 0 else flint.fmpq(m, flint.fmpz(2) ** int(-e))


def _is_multiple(p, sq, r) -> bool:
    """Whether the root ``r`` of the squarefree part ``sq`` may be a multiple root of ``p``: the
    cofactor ``p / sq`` does not provably vanish nowhere on ``r`` (it vanishes exactly at the
    multiple roots)."""
    import flint
    c = p // sq
    v = flint.arb(0)
    for i, a in enumerate(c.coeffs()):
        v += flint.arb(a) * r ** i
    return not (v > 0 or v < 0)
