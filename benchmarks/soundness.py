"""Soundness benchmark of MCEIP-mu provers: random pencils against an independent ground truth.

The problem. Given real ``s x s`` matrices ``A0, A1`` (``A(mu) = A0 + mu A1``), a cap > 0 and
index pairs that may not both be in a support, the solutions are ``(mu, v)`` with mu in
[0, cap], ``v >= 0``, ``sum(v) = 1``, ``y = A(mu) v >= 0``, ``v_i y_i = 0``. For a support
``P = {i : v_i > 0}`` they are the real eigenvalues mu in [0, cap] of ``A0[P,P] + mu A1[P,P]``
whose null vector is > 0 on P and whose ``y = A(mu)[:, P] v_P`` is >= 0 off P. The critical
values are the distinct mu of all solutions; the onset is the smallest (or none).

Ground truth (:func:`ground_truth`), independent of the app's provers (it imports nothing
from ``app``):

1. Floating point, every allowed support, batched per support size (numpy LAPACK). The pencil
   is scaled by its largest diagonal entry of ``A0``. Eigenvalues come from ``eig(B0^-1 B1)``
   (``mu = -1/nu``) or, where ``B0`` is numerically singular, from QZ. Every eigenvalue near the
   real axis and the interval (within 1 %) gets an SVD of ``A(mu)`` on P: its residual, its
   condition ``kappa = (||B0|| + |mu| ||B1||) / |u^H B1 w|`` (u, w the singular vectors of the
   smallest singular value) and so an error bound ``err = 10 k eps kappa``, the null vector's
   error bound ``(err ||B1|| + 10 k eps ||A||) / sigma_{k-1}``, and the same for ``y``.
   Each decision - complex or real (``|Im mu|``, distance to the other eigenvalues), inside or
   outside [0, cap] (distance to 0 and to cap), null vector one-signed or mixed
   (``min x / max |x|``), ``y`` off P nonnegative or not (``min y / ||A(mu)[:, P]||``) - is taken
   in floating point only when its margin exceeds ``max(1e-6 (relative), 1000 x its error
   bound)``. Otherwise the whole support is re-decided exactly (step 2).
2. Exact / ball arithmetic (python-flint) on a flagged support: ``det(A0[P,P] + t A1[P,P])`` is
   interpolated exactly (``fmpq_mat`` determinants at t = 0..k, Lagrange in ``fmpq_poly``; the
   doubles are exact rationals), factored over Z. Rational roots (linear factors; the planted
   pencils put their solutions at exact double mu) are decided exactly: membership of [0, cap]
   by rational comparison, nullity and the null vector from an ``fmpq_mat`` rref, the signs of
   ``v_P`` and of ``y`` off P exactly. Irrational roots are isolated by arb
   (``fmpz_poly.complex_roots``: real roots come with an exact zero imaginary part), their
   position against 0 and cap is decided by refining the ball (they are not rational, so
   this ends), and the null vector is enclosed by an ``arb_mat`` solve of the system with one
   row deleted and one entry fixed to 1: the solve succeeding proves the deleted-row minor
   nonsingular, so rank = k - 1, the null space is that one vector, and its enclosure holds
   for every mu in the root's ball. Signs of ``v_P`` and ``y`` are then decided by balls that
   exclude 0, at 128, 256, 512 and 1024 bits.
3. Where even that is inconclusive - a pencil singular on P (det identically 0), nullity > 1
   at a root, an exact zero of ``y`` or ``v`` at an irrational root, balls still containing 0
   at 1024 bits - the pencil's truth is "unknown": counted, printed, excluded from the
   false-proof count. Roots just outside [0, cap] (within the matching tolerance) are
   "optional": a prover may list them or not.

The floating-point step is not a proof: its clear decisions trust LAPACK's backward stability
through the stated first-order error bounds with a factor 1000 of safety; every decision closer
than that is exact. A false proof is a claim labelled "proven" whose content disagrees with the
truth: the onset not within 1e-7 (relative to max(1, |mu|)) of the true onset (or claimed absent
when there is one, or present when there is none), or a true critical value missing from /
a value absent from the truth present in the proven list, values matched within the same
tolerance. Claims labelled "not proven" or "ill-conditioned" are counted, never false.

Pencils (:func:`make_pencil`, seeded by ``(base seed, index)``, reproducible), s = 1..10:
``dense`` (A0 = B B^T + s I, A1 = 3 N(0,1), as tests/test_certify.py), ``condensed`` (the
slip-node condensation ``(D S_TT D, S_NT D)`` of a random SPD Schur complement S), ``sparse``
(condensed with zero rows/columns and zero entries in A1), ``contact`` (the app's random
contact system condensed, as tests/test_certify.py), ``zero`` (split tangential rates of
zero-reaction nodes with their pairs, as app/analyses/pencils/reduced.py builds them) and planted ones:
a solution (mu*, v*, y*) is put in by rewriting one column of A1 (or of A0 at mu* = 0) so that
``A(mu*) v* = y*`` holds in exact rational arithmetic - ``interior``; ``close`` (two values
within 1e-9, disjoint or nested supports); ``double`` (one support whose pencil has two real
roots within 1e-9, the first with a positive null vector, the second with a mixed one); ``at_cap`` (mu* = cap, a power of two, exact);
``at_zero`` (mu* = 0, exact); ``small_x`` (min x_P / max x_P = 2^-30 ~ 9.3e-10); ``small_y``
(a stick margin y = 2^-30 relative); ``miss_x`` / ``miss_y`` (the same with the sign flipped:
planted near-solutions that are not solutions).

Provers go through one adapter ``prove(A0, A1, cap, pairs) -> (onset_status, onset_value,
all_status, values)``, statuses "proven" / "not proven" / "ill-conditioned": ``mceip_mu`` (the
new engine, ``app.mceip_mu``: ``r.onset.proven``, ``r.onset.value``, ``r.all.proven``,
``r.all.values``, ``r.ill_conditioned``) and ``app-result`` (the state's MCEIP-mu result as the
app reports it: ``condensed_mu_result``, search + certificate, the values it keeps below the
cap). ``auto`` is ``mceip_mu``.

The dense series (:func:`section_dense`): onset proof time on ``A0 = B B^T + s I``,
``A1 = 3 N(0, 1)``, cap 10, at s = 10, 20, 30, ... until the first s not proven within 60 s.

    .venv/bin/python benchmarks/soundness.py [--quick | --n N] [--start I]
        [--prover auto|mceip_mu|app-result] [--no-dense] [--limit SECONDS]
"""
from __future__ import annotations

import argparse
import functools
import inspect
import itertools
import math
import os
import pathlib
import sys
import time
from dataclasses import dataclass, field
from fractions import Fraction

ROOT = pathlib.Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import flint  # noqa: E402
import numpy as np  # noqa: E402
import scipy.linalg  # noqa: E402

EPS = np.finfo(float).eps
#: Decisions with a relative margin below this are re-decided exactly.
MARGIN = 1e-6
#: A floating decision also needs its margin above SAFETY x its first-order error bound.
SAFETY = 1e3
#: Values match within MATCH_RTOL * max(1, |mu|).
MATCH_RTOL = 1e-7
#: Precisions (bits) of the ball re-checks.
PRECS = (128, 256, 512, 1024)
SMALL = 2.0 ** -30           # the planted near-degenerate margins (~9.3e-10)


def say(*a) -> None:
    print(*a, flush=True)


class quiet_c_output:
    """Silence what C code prints on file descriptors 1 and 2 inside the block (SCIP's
    messages); Python exceptions still propagate."""

    def __enter__(self):
        sys.stdout.flush()
        sys.stderr.flush()
        self.null = os.open(os.devnull, os.O_WRONLY)
        self.saved = [os.dup(1), os.dup(2)]
        os.dup2(self.null, 1)
        os.dup2(self.null, 2)
        return self

    def __exit__(self, *exc):
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(self.saved[0], 1)
        os.dup2(self.saved[1], 2)
        for fd in (*self.saved, self.null):
            os.close(fd)
        return False


def _tol(mu: float) -> float:
    return MATCH_RTOL * max(1.0, abs(mu))


# =================================================================================================
# Ground truth
# =================================================================================================

@dataclass
class Truth:
    known: bool                                  # False: some decision inconclusive (see reasons)
    values: list[float]                          # distinct critical mu in [0, cap], sorted
    optional: list[float]                        # solutions (or undecided roots) just outside [0, cap]
    solutions: list[tuple[float, tuple[int, ...], str]]  # (mu, support, "float" | "exact" | "ball")
    reasons: list[str] = field(default_factory=list)
    supports: int = 0
    exact_supports: int = 0

    @property
    def onset(self) -> float | None:
        return self.values[0] if self.values else None


def allowed_supports(s: int, k: int, pairs) -> np.ndarray:
    P = np.array(list(itertools.combinations(range(s), k)), dtype=np.int64).reshape(-1, k)
    if pairs and len(P):
        keep = np.ones(len(P), dtype=bool)
        for a, b in pairs:
            keep &= ~((P == a).any(axis=1) & (P == b).any(axis=1))
        P = P[keep]
    return P


def _batch_eigs(B0: np.ndarray, B1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues mu of ``det(B0 + mu B1) = 0`` per stacked pencil (inf: infinite), and a flag
    per pencil: singular-looking (QZ gave 0/0) - decided exactly."""
    m, k, _ = B0.shape
    out = np.full((m, k), np.inf, dtype=complex)
    sing = np.zeros(m, dtype=bool)
    n0 = np.linalg.norm(B0, axis=(1, 2))
    n1 = np.linalg.norm(B1, axis=(1, 2))
    try:
        C = np.linalg.solve(B0, B1)
        ok = np.all(np.isfinite(C), axis=(1, 2)) & (np.linalg.norm(C, axis=(1, 2)) * n0 < 1e8 * np.maximum(n1, 1e-300))
    except np.linalg.LinAlgError:
        C, ok = None, np.zeros(m, dtype=bool)
    if ok.any():
        nu = np.linalg.eigvals(C[ok])
        zero = np.abs(nu) <= 1e-14 * np.linalg.norm(C[ok], axis=(1, 2))[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            out[ok] = np.where(zero, np.inf, -1.0 / np.where(zero, 1.0, nu))
    for j in np.flatnonzero(~ok):
        alpha, beta = scipy.linalg.eig(B0[j], -B1[j], right=False, homogeneous_eigvals=True)
        scale = max(n0[j], n1[j], 1e-300)
        if np.any((np.abs(alpha) <= 1e-10 * scale) & (np.abs(beta) <= 1e-10 * scale)):
            sing[j] = True
        with np.errstate(divide="ignore", invalid="ignore"):
            w = np.where(np.abs(beta) > 1e-14 * scale, alpha / np.where(beta == 0, 1, beta), np.inf)
        out[j] = w
    return out, sing


def _float_support_batch(a0, a1, cap, P):
    """Floating decisions for the supports ``P`` (m, k). Returns (solutions [(mu, row)], flagged rows)."""
    m, k = P.shape
    s = a0.shape[0]
    B0 = a0[P[:, :, None], P[:, None, :]]
    B1 = a1[P[:, :, None], P[:, None, :]]
    lam, sing = _batch_eigs(B0, B1)
    flagged = sing.copy()
    fin = np.isfinite(lam)
    re, im = np.where(fin, lam.real, np.inf), np.where(fin, lam.imag, np.inf)
    wide = 1e-2 * max(1.0, cap)
    near = fin & (re >= -wide) & (re <= cap + wide) & (np.abs(im) <= 1e-2 * np.maximum(1.0, np.abs(re)))
    near &= ~sing[:, None]
    ii, jj = np.nonzero(near)
    sols: list[tuple[float, int]] = []
    if not len(ii):
        return sols, flagged
    lm = lam[ii, jj]
    A = B0[ii] + lm[:, None, None] * B1[ii]
    U, sv, Vh = np.linalg.svd(A)
    n0 = np.linalg.norm(B0[ii], axis=(1, 2))
    n1 = np.linalg.norm(B1[ii], axis=(1, 2))
    nrm = n0 + np.abs(lm) * n1
    u = U[:, :, -1]
    w = Vh[:, -1, :].conj()
    den = np.abs(np.einsum("mi,mij,mj->m", u.conj(), B1[ii], w))
    with np.errstate(divide="ignore"):
        err = 10 * k * EPS * nrm / den                 # first-order error bound of mu (absolute)
    thr = np.maximum(MARGIN * np.maximum(1.0, np.abs(lm)), SAFETY * err)
    resid = sv[:, -1] / np.maximum(nrm, 1e-300)
    # distance to the nearest other eigenvalue of the same support (near-double roots)
    D = np.abs(lam[ii] - lm[:, None])
    D[np.arange(len(ii)), jj] = np.inf
    dist = np.min(np.where(np.isfinite(D), D, np.inf), axis=1)
    real = lm.imag == 0
    bad = (resid > 1e-10) | ~np.isfinite(err)
    bad |= ~real & (np.abs(lm.imag) <= thr)
    bad |= real & (dist <= thr)
    rin = real & (lm.real >= 0) & (lm.real <= cap)
    bad |= real & ((np.abs(lm.real) <= thr) | (np.abs(lm.real - cap) <= thr))
    cand = rin & ~bad
    # null vector (real for a real eigenvalue; fix the phase) and its sign margins
    gap = sv[:, -2] if k > 1 else np.full(len(ii), np.inf)
    xerr = (err * n1 + 10 * k * EPS * nrm) / np.maximum(gap, 1e-300) if k > 1 else np.zeros(len(ii))
    thx = np.maximum(MARGIN, SAFETY * xerr)
    piv = np.argmax(np.abs(w), axis=1)
    ph = w[np.arange(len(ii)), piv]
    x = (w * (np.abs(ph) / ph)[:, None]).real
    x /= np.max(np.abs(x), axis=1, keepdims=True)
    mx = np.min(x, axis=1)
    bad |= cand & (np.abs(mx) <= thx) & ~(mx < -thx)
    pos = cand & (mx > thx)
    for c in np.flatnonzero(pos & ~bad):
        b = ii[c]
        Pc = P[b]
        off = np.setdiff1d(np.arange(s), Pc)
        mu = float(lm[c].real)
        if len(off):
            Ac = a0[:, Pc] + mu * a1[:, Pc]
            y = Ac[off] @ x[c]
            ysc = max(np.linalg.norm(Ac) * np.linalg.norm(x[c]), 1e-300)
            yerr = ysc * xerr[c] + err[c] * np.linalg.norm(a1[:, Pc]) * np.linalg.norm(x[c])
            thy = max(MARGIN, SAFETY * yerr / ysc)
            my = float(np.min(y)) / ysc
            if my < -thy:
                continue
            if my <= thy:
                bad[c] = True
                continue
        sols.append((mu, int(b)))
    flagged[np.unique(ii[bad])] = True
    bad_rows = set(np.unique(ii[bad]).tolist())
    return [(mu, b) for mu, b in sols if b not in bad_rows], flagged


def _q(x: float) -> flint.fmpq:
    n, d = float(x).as_integer_ratio()
    return flint.fmpq(n, d)


def _qmat(M: np.ndarray) -> flint.fmpq_mat:
    r, c = M.shape
    return flint.fmpq_mat(r, c, [_q(v) for v in M.ravel()])


def _det_poly(M0: flint.fmpq_mat, M1: flint.fmpq_mat, k: int) -> flint.fmpq_poly:
    """``det(M0 + t M1)`` exactly: determinants at t = 0..k, Lagrange interpolation."""
    pts = list(range(k + 1))
    return _interp(pts, [(M0 + M1 * t).det() for t in pts])


def _exact_rational_root(A0q, A1q, P, off, r: flint.fmpq) -> str:
    """'yes' / 'no' / 'unknown': is mu = r (rational) a solution with support P?"""
    k = len(P)
    M = A0q[0] + A1q[0] * r
    R, rank = M.rref()
    if rank != k - 1:
        return "unknown"                          # nullity > 1 (a cone of null vectors)
    piv, free, row = [], None, 0
    for j in range(k):
        if row < rank and R[row, j] != 0:
            piv.append(j)
            row += 1
        elif free is None:
            free = j
    v = [flint.fmpq(0)] * k
    v[free] = flint.fmpq(1)
    for i, j in enumerate(piv):
        v[j] = -R[i, free]
    if any(e == 0 for e in v):
        return "no"
    if not (all(e > 0 for e in v) or all(e < 0 for e in v)):
        return "no"
    sg = 1 if v[0] > 0 else -1
    if not off:
        return "yes"
    Moff = A0q[1] + A1q[1] * r
    y = Moff * flint.fmpq_mat(k, 1, [sg * e for e in v])
    return "yes" if all(y[i, 0] >= 0 for i in range(len(off))) else "no"


def _interp(pts, vals) -> flint.fmpq_poly:
    """The polynomial of degree < len(pts) through ``(pts[i], vals[i])`` (Lagrange, exact)."""
    x = flint.fmpq_poly([0, 1])
    p = flint.fmpq_poly([0])
    for i, ti in enumerate(pts):
        if vals[i] == 0:
            continue
        term = flint.fmpq_poly([vals[i]])
        for j, tj in enumerate(pts):
            if j != i:
                term = term * (x - tj) * flint.fmpq(1, ti - tj)
        p = p + term
    return p


def _cofactor_vector(M0, M1, k: int, i: int) -> list[flint.fmpq_poly]:
    """Entries ``(-1)^(i+l) det(M(t)[-i, -l])``: with rank M(r) = k - 1 and this row's cofactors
    not all zero at r, the null vector of ``M(r) = M0 + r M1`` (exact polynomials in t)."""
    pts = list(range(k))
    rows = [a for a in range(k) if a != i]
    vals: list[list] = [[] for _ in range(k)]
    for tq in pts:
        Mt = M0 + M1 * tq
        for l in range(k):
            cols = [b for b in range(k) if b != l]
            sub = flint.fmpq_mat(k - 1, k - 1, [Mt[a, b] for a in rows for b in cols])
            vals[l].append(sub.det() * (-1) ** (i + l))
    return [_interp(pts, v) for v in vals]


def _sign_at(poly: flint.fmpq_poly, fz: flint.fmpz_poly, idx: int) -> int | None:
    """Sign of ``poly`` at the real root number ``idx`` of the irreducible ``fz``, known not to be
    a root of ``poly``; None if the balls do not decide it at the largest precision."""
    old = flint.ctx.prec
    try:
        for prec in PRECS:
            flint.ctx.prec = prec
            roots = sorted((z.real for z, _ in fz.complex_roots() if z.imag.is_zero()), key=lambda b: float(b.mid()))
            val = flint.arb_poly(poly)(roots[idx])
            if val > 0:
                return 1
            if val < 0:
                return -1
        return None
    finally:
        flint.ctx.prec = old


def _root_position(fz: flint.fmpz_poly, idx: int, cap_q) -> tuple[str, float]:
    """'in' / 'band' / 'out' / 'unknown' of the irrational real root number ``idx`` of ``fz``
    against [0, cap] (band: outside by less than the matching tolerance)."""
    old = flint.ctx.prec
    mu = float("nan")
    try:
        for prec in PRECS:
            flint.ctx.prec = prec
            roots = sorted((z.real for z, _ in fz.complex_roots() if z.imag.is_zero()), key=lambda b: float(b.mid()))
            r = roots[idx]
            mu = float(r.mid())
            capb = flint.arb(cap_q)
            band = flint.arb(_q(_tol(float(cap_q))))
            if r > 0 and r < capb:
                return "in", mu
            if r < -band or r > capb + band:
                return "out", mu
            if (r < 0 and r > -band) or (r > capb and r < capb + band):
                return "band", mu
        return "unknown", mu
    finally:
        flint.ctx.prec = old


def _irrational_root(M0, M1, O0, O1, k: int, off, fz: flint.fmpz_poly, idx: int, hint_rows) -> str:
    """'yes' / 'no' / 'unknown': is the irrational real root number ``idx`` of the irreducible
    ``fz`` a solution with this support? Exact zero tests by divisibility by ``fz`` (its minimal
    polynomial), signs of the nonzero values by balls."""
    fq = flint.fmpq_poly(fz)
    if k == 1:
        v = [flint.fmpq_poly([1])]
    else:
        v = None
        for i in hint_rows:
            cand = _cofactor_vector(M0, M1, k, i)
            if any(not (c % fq).is_zero() for c in cand):
                v = cand
                break
        if v is None:
            return "unknown"                     # every cofactor vanishes: nullity > 1
    if any((c % fq).is_zero() for c in v):
        return "no"                              # an entry of v_P is exactly 0: not this support
    sg = [_sign_at(c % fq, fz, idx) for c in v]
    if None in sg:
        return "unknown"
    if len(set(sg)) > 1:
        return "no"
    x = flint.fmpq_poly([0, 1])
    for j in range(len(off)):
        yj = flint.fmpq_poly([0])
        for l in range(k):
            yj = yj + (flint.fmpq_poly([O0[j, l]]) + x * O1[j, l]) * v[l]
        yj = (yj * sg[0]) % fq
        if yj.is_zero():
            continue                             # y_j = 0 exactly
        sy = _sign_at(yj, fz, idx)
        if sy is None:
            return "unknown"
        if sy < 0:
            return "no"
    return "yes"


def exact_support(A0: np.ndarray, A1: np.ndarray, cap: float, P: np.ndarray):
    """Every root of support P in [0, cap] decided in exact / ball arithmetic (the unscaled pencil:
    scaling does not change the roots or the signs). Returns (solutions mu, optional mu, reasons)."""
    s = A0.shape[0]
    P = [int(p) for p in P]
    off = [i for i in range(s) if i not in P]
    k = len(P)
    M0 = _qmat(A0[np.ix_(P, P)])
    M1 = _qmat(A1[np.ix_(P, P)])
    O0 = _qmat(A0[np.ix_(off, P)]) if off else None
    O1 = _qmat(A1[np.ix_(off, P)]) if off else None
    p = _det_poly(M0, M1, k)
    if p.is_zero():
        return [], [], [f"support {P}: pencil singular (det identically 0)"]
    cap_q = _q(cap)
    band = _q(_tol(cap))
    sols, opt, reasons = [], [], []
    fz = p.numer()
    if fz.degree() <= 0:
        return sols, opt, reasons
    _, factors = fz.factor()
    for f, _mult in factors:
        if f.degree() == 1:
            r = -flint.fmpq(f[0], f[1])
            if r < -band or r > cap_q + band:
                continue
            ans = _exact_rational_root((M0, O0), (M1, O1), P, off, r)
            inside = 0 <= r <= cap_q
            mu = float(r.p) / float(r.q) if abs(r.p) < 2 ** 1000 else float(r.p / r.q)
            if ans == "unknown" and inside:
                reasons.append(f"support {P}: rational root {mu!r} with nullity > 1")
            elif ans == "yes" and inside:
                sols.append(mu)
            elif ans != "no":
                opt.append(mu)
            continue
        nreal = len([z for z, _ in f.complex_roots() if z.imag.is_zero()])
        for idx in range(nreal):
            pos, mu = _root_position(f, idx, cap_q)
            if pos == "out":
                continue
            if pos == "unknown":
                reasons.append(f"support {P}: root {mu!r} not separated from 0 or cap at {PRECS[-1]} bits")
                continue
            hint_rows = list(dict.fromkeys(i for i, _ in _hints(A0, A1, P, mu))) + list(range(k))
            ans = _irrational_root(M0, M1, O0, O1, k, off, f, idx, list(dict.fromkeys(hint_rows)))
            if pos == "band":
                if ans != "no":
                    opt.append(mu)
            elif ans == "yes":
                sols.append(mu)
            elif ans == "unknown":
                reasons.append(f"support {P}: root {mu!r}: nullity > 1 or signs not decided at {PRECS[-1]} bits")
    return sols, opt, reasons


def _hints(A0, A1, P, mu: float) -> list[tuple[int, int]]:
    """(deleted row, fixed entry) choices for the ball null-vector solve, the most promising first:
    largest products of the floating left and right null vectors at ``mu``."""
    k = len(P)
    if k == 1:
        return [(0, 0)]
    U, _, Vh = np.linalg.svd(A0[np.ix_(P, P)] + mu * A1[np.ix_(P, P)])
    score = np.abs(U[:, -1])[:, None] * np.abs(Vh[-1])[None, :]
    order = np.argsort(-score, axis=None)[:12]
    return [(int(q // k), int(q % k)) for q in order]


def ground_truth(A0: np.ndarray, A1: np.ndarray, cap: float, pairs=None, exact_all: bool = False) -> Truth:
    """All critical mu in [0, cap] (see the module docstring for the method and its guarantees).
    ``exact_all``: every support in exact/ball arithmetic (slow; the check of the floating step)."""
    A0 = np.asarray(A0, dtype=float)
    A1 = np.asarray(A1, dtype=float)
    s = A0.shape[0]
    pairs = [tuple(map(int, p)) for p in (pairs or [])]
    scale = float(np.max(np.abs(np.diag(A0)), initial=0.0)) or float(np.max(np.abs(A0), initial=1.0)) or 1.0
    a0, a1 = A0 / scale, A1 / scale
    sols: list[tuple[float, tuple[int, ...], str]] = []
    opt: list[float] = []
    reasons: list[str] = []
    nsup = nex = 0
    for k in range(1, s + 1):
        P = allowed_supports(s, k, pairs)
        if not len(P):
            continue
        nsup += len(P)
        if exact_all:
            fs, flagged = [], np.ones(len(P), dtype=bool)
        else:
            fs, flagged = _float_support_batch(a0, a1, cap, P)
        sols += [(mu, tuple(P[b].tolist()), "float") for mu, b in fs if not flagged[b]]
        for b in np.flatnonzero(flagged):
            nex += 1
            ex, op, why = exact_support(A0, A1, cap, P[b])
            sols += [(mu, tuple(P[b].tolist()), "exact") for mu in ex]
            opt += op
            reasons += why
    sols.sort()
    vals: list[float] = []
    for mu, _, _ in sols:
        if not vals or abs(mu - vals[-1]) > 1e-13 * max(1.0, abs(mu)):
            vals.append(mu)
    return Truth(not reasons, vals, sorted(opt), sols, reasons, nsup, nex)


# =================================================================================================
# Pencils
# =================================================================================================

@dataclass
class Pencil:
    kind: str
    seed: tuple[int, int]
    A0: np.ndarray
    A1: np.ndarray
    cap: float
    pairs: list[tuple[int, int]]
    planted: list[dict] = field(default_factory=list)   # {"mu", "support", "solution": bool, "exact": bool}


KINDS = {  # kind: weight
    "dense": 14, "condensed": 14, "sparse": 8, "contact": 8, "zero": 14,
    "interior": 6, "close": 7, "double": 5, "at_cap": 6, "at_zero": 5, "small_x": 6, "small_y": 6, "miss_x": 3, "miss_y": 3,
}


def _spd(rng, n):
    G = rng.normal(size=(n, n))
    return G @ G.T / n + rng.uniform(0.05, 1.0) * np.eye(n)


def _condensed(rng, s, sparse=False):
    S = _spd(rng, 2 * s)
    T, N = np.arange(0, 2 * s, 2), np.arange(1, 2 * s, 2)
    D = np.diag(rng.choice([-1.0, 1.0], size=s))
    A0 = D @ S[np.ix_(T, T)] @ D
    A1 = S[np.ix_(N, T)] @ D
    if sparse:
        A1 = A1 * (rng.random(A1.shape) < 0.6)
        for _ in range(int(rng.integers(0, max(1, s // 2) + 1))):
            (A1.__setitem__((int(rng.integers(s)), slice(None)), 0.0) if rng.random() < 0.5
             else A1.__setitem__((slice(None), int(rng.integers(s))), 0.0))
    return A0, A1


def _dense(rng, s):
    B = rng.normal(size=(s, s))
    return B @ B.T + s * np.eye(s), 3.0 * rng.normal(size=(s, s))


def _zero_nodes(rng, s):
    """Split pencil (as app/analyses/pencils.split_pencil): slip nodes (one unknown T) and
    zero-reaction nodes (a, b, N); pairs (a, b)."""
    nz = int(rng.integers(1, s // 3 + 1))
    ns = s - 3 * nz
    nodes = ns + nz
    Sm = _spd(rng, 2 * nodes)
    cols = [("T", i) for i in range(ns)] + [(kd, i) for i in range(ns, nodes) for kd in ("a", "b", "N")]
    Q = np.zeros((2 * nodes, s))
    R0 = np.zeros((s, 2 * nodes))
    R1 = np.zeros((s, 2 * nodes))
    sign = rng.choice([-1.0, 1.0], size=nodes)
    pos = {}
    for j, (kd, i) in enumerate(cols):
        pos[(kd, i)] = j
        t, n = 2 * i, 2 * i + 1
        if kd == "T":
            Q[t, j] = R0[j, t] = -sign[i]
            R1[j, n] = -1.0
        elif kd == "a":
            Q[t, j] = R0[j, t] = 1.0
            R1[j, n] = -1.0
        elif kd == "b":
            Q[t, j] = R0[j, t] = -1.0
            R1[j, n] = -1.0
        else:
            Q[n, j] = R0[j, n] = -1.0
    pairs = [(pos[("a", i)], pos[("b", i)]) for i in range(ns, nodes)]
    return R0 @ Sm @ Q, R1 @ Sm @ Q, pairs


def _contact(rng, s):
    """The app's random contact system condensed onto its slip nodes (tests/test_certify.py)."""
    from mpi4py import MPI

    from app.analyses.pencils.reduced import condensed_mu_pencil
    from app.common.stages import Stages
    from app.loading.classify import classify
    from app.systems.discrete import random_contact_problem
    n_stick, n_free, n_int = int(rng.integers(0, 3)), int(rng.integers(0, 3)), int(rng.integers(0, 5))
    mu = float(rng.uniform(0.3, 4.0))
    sub = np.random.default_rng(int(rng.integers(2 ** 31)))
    system, state = random_contact_problem(sub, s + n_stick + n_free, n_int, s, n_stick, mu, MPI.COMM_WORLD, Stages())
    A0, A1 = condensed_mu_pencil(system.contact_schur(), classify(state, mu))
    system.destroy()
    return A0, A1


def _grid(M, bits=20):
    return np.round(np.asarray(M) * 2.0 ** bits) / 2.0 ** bits


def plant(A0, A1, mu, v, y, col, adjust="A1") -> bool:
    """Rewrite column ``col`` of A1 (or A0) so that ``(A0 + mu A1) v = y`` row by row, computed in
    exact rationals and rounded; returns whether every row of the support holds exactly."""
    s = A0.shape[0]
    F = Fraction
    fm = F(mu)
    exact = True
    vf = [F(float(e)) for e in v]
    for i in range(s):
        if adjust == "A1":
            rest = F(float(y[i])) - sum(F(A0[i, j]) * vf[j] for j in range(s) if vf[j]) \
                - fm * sum(F(A1[i, j]) * vf[j] for j in range(s) if vf[j] and j != col)
            val = rest / (fm * vf[col])
            A1[i, col] = float(val)
            ok = F(A1[i, col]) == val
        else:
            rest = F(float(y[i])) - sum(F(A0[i, j]) * vf[j] for j in range(s) if vf[j] and j != col) \
                - fm * sum(F(A1[i, j]) * vf[j] for j in range(s) if vf[j])
            val = rest / vf[col]
            A0[i, col] = float(val)
            ok = F(A0[i, col]) == val
        if y[i] == 0:                 # the rows of the support
            exact &= ok
    return exact


def _planted(rng, s, kind):
    # at mu* = 0 a sparse A1 can make the pencil singular on the support (a continuum of solutions)
    base = rng.choice(["dense", "condensed"] + ([] if kind == "at_zero" else ["sparse"]))
    A0, A1 = _dense(rng, s) if base == "dense" else _condensed(rng, s, sparse=base == "sparse")
    A0, A1 = _grid(A0), _grid(A1)
    sc = float(np.max(np.abs(np.diag(A0))))
    cap = float(np.round(rng.uniform(2.0, 40.0) * 16) / 16)
    planted = []

    def support(kmin=1, kmax=None, avoid=()):
        pool = [i for i in range(s) if i not in avoid]
        kmax = min(kmax or len(pool), len(pool))
        k = int(rng.integers(kmin, kmax + 1))
        return sorted(rng.choice(pool, size=k, replace=False).tolist())

    def vec(P, c):
        v = np.zeros(s)
        v[P] = np.round(rng.uniform(0.1, 1.0, size=len(P)) * 256) / 256
        v[c] = 1.0
        return v

    def ystar(P):
        y = np.round(rng.uniform(0.05, 1.0, size=s) * sc * 2 ** 20) / 2 ** 20
        y[P] = 0.0
        return y

    if s < 2 and kind in ("small_x", "miss_x", "small_y", "miss_y", "close", "double"):
        kind = "interior"
    if kind in ("interior", "small_x", "small_y", "miss_x", "miss_y"):
        mu = float(rng.uniform(0.05, 0.95) * cap)
        kmin = 2 if kind in ("small_x", "miss_x") else 1
        P = support(kmin, s - 1 if kind in ("small_y", "miss_y") else None)
        c = int(rng.choice(P))
        v, y = vec(P, c), ystar(P)
        sol = True
        if kind in ("small_x", "miss_x"):
            t = int(rng.choice([i for i in P if i != c]))
            v[t] = SMALL if kind == "small_x" else -SMALL
            sol = kind == "small_x"
        if kind in ("small_y", "miss_y"):
            t = int(rng.choice([i for i in range(s) if i not in P]))
            y[t] = (SMALL if kind == "small_y" else -SMALL) * sc
            sol = kind == "small_y"
        ex = plant(A0, A1, mu, v, y, c)
        planted.append({"mu": mu, "support": tuple(P), "solution": sol, "exact": ex, "v": v})
    elif kind == "close":
        mu1 = float(rng.uniform(0.05, 0.9) * cap)
        mu2 = mu1 + float(rng.uniform(1e-11, 1e-9))
        P1 = support(1, s - 1)
        c1 = int(rng.choice(P1))
        rest = [i for i in range(s) if i not in P1]
        if rng.random() < 0.5:                       # nested: P2 = P1 + {c2}
            c2 = int(rng.choice(rest))
            P2 = sorted(P1 + [c2])
        else:                                        # disjoint
            P2 = support(1, None, avoid=P1)
            c2 = int(rng.choice(P2))
        v1, y1 = vec(P1, c1), ystar(P1)
        ex1 = plant(A0, A1, mu1, v1, y1, c1)
        v2, y2 = vec(P2, c2), ystar(P2)
        ex2 = plant(A0, A1, mu2, v2, y2, c2)
        planted += [{"mu": mu1, "support": tuple(P1), "solution": True, "exact": ex1, "v": v1},
                    {"mu": mu2, "support": tuple(P2), "solution": True, "exact": ex2, "v": v2}]
    elif kind == "double":
        # one support with two real roots within 1e-9: A0[P,P] = V diag(m, m + d) V^T, A1[P,P] = -I;
        # the root m has the positive null vector (cos th, sin th), m + d a mixed one
        P = sorted(rng.choice(s, size=2, replace=False).tolist())
        th = float(rng.uniform(0.25, 1.3))
        m = float(rng.uniform(0.1, 0.9) * cap)
        d = float(rng.uniform(1e-11, 1e-9))
        V = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
        A0[np.ix_(P, P)] = V @ np.diag([m, m + d]) @ V.T
        A1[np.ix_(P, P)] = -np.eye(2)
        v1 = V[:, 0]
        for j in (j for j in range(s) if j not in P):
            target = float(rng.uniform(0.05, 1.0)) * sc
            rest = target - A0[j, P] @ v1 - m * A1[j, P[1]] * v1[1]
            A1[j, P[0]] = rest / (m * v1[0])
        planted += [{"mu": m, "support": tuple(P), "solution": True, "exact": False, "v": v1},
                    {"mu": m + d, "support": tuple(P), "solution": False, "exact": False, "v": V[:, 1]}]
    elif kind == "at_cap":
        cap = float(2.0 ** int(rng.integers(-1, 6)))
        P = support(1)
        c = int(rng.choice(P))
        v, y = vec(P, c), ystar(P)
        ex = plant(A0, A1, cap, v, y, c)
        planted.append({"mu": cap, "support": tuple(P), "solution": True, "exact": ex, "v": v})
    elif kind == "at_zero":
        P = support(1)
        c = int(rng.choice(P))
        v, y = vec(P, c), ystar(P)
        ex = plant(A0, A1, 0.0, v, y, c, adjust="A0")
        planted.append({"mu": 0.0, "support": tuple(P), "solution": True, "exact": ex, "v": v})
    return A0, A1, cap, planted


def make_pencil(index: int, base_seed: int = 2026, kind: str | None = None, s: int | None = None) -> Pencil:
    """Pencil number ``index`` of the benchmark (reproducible from ``(base_seed, index)``)."""
    rng = np.random.default_rng([base_seed, index])
    names = list(KINDS)
    w = np.array([KINDS[k] for k in names], dtype=float)
    kd = kind or str(rng.choice(names, p=w / w.sum()))
    s = s or int(rng.integers(1, 11))
    pairs: list = []
    planted: list = []
    cap = float(np.round(rng.uniform(2.0, 60.0) * 16) / 16)
    if kd == "dense":
        A0, A1 = _dense(rng, s)
    elif kd in ("condensed", "sparse"):
        A0, A1 = _condensed(rng, s, sparse=kd == "sparse")
    elif kd == "contact":
        A0, A1 = _contact(rng, min(s, 9))
    elif kd == "zero":
        s = max(s, 3)
        A0, A1, pairs = _zero_nodes(rng, s)
    else:
        A0, A1, cap, planted = _planted(rng, s, kd)
    return Pencil(kd, (base_seed, index), np.ascontiguousarray(A0), np.ascontiguousarray(A1), cap, pairs, planted)


# =================================================================================================
# Provers
# =================================================================================================

def _prove_mceip_mu(A0, A1, cap, pairs, seconds=None, want_all=True):
    from app import mceip_mu
    kw = {}
    if seconds is not None and "seconds" in inspect.signature(mceip_mu).parameters:
        kw["seconds"] = seconds
    if not want_all:
        kw["want_all"] = False
    r = mceip_mu(A0, A1, cap=cap, pairs=pairs, **kw)
    ill = bool(getattr(r, "ill_conditioned", False))
    on_ill = bool(getattr(r.onset, "ill_conditioned", ill))
    all_ill = bool(getattr(r.all, "ill_conditioned", ill))
    on = "ill-conditioned" if on_ill else ("proven" if r.onset.proven else "not proven")
    al = "ill-conditioned" if all_ill else ("proven" if r.all.proven else "not proven")
    val = None if r.onset.value is None else float(r.onset.value)
    return on, val, al, sorted(float(x) for x in r.all.values)


def _prove_app_result(A0, A1, cap, pairs, seconds=None):
    """The state-level MCEIP-mu result as the app reports it today (search + certificate,
    ``condensed_mu_result``: the values it lists below the cap, its ``certified`` flag)."""
    from app.analyses.mceip_mu.state import condensed_mu_result
    from app.scene.schema import McpSettings
    st = McpSettings() if seconds is None else McpSettings(certify_seconds=seconds, certify_seconds_large=seconds)
    d = condensed_mu_result(A0, A1, cap, st, pairs=pairs or None)
    vals = sorted(float(x["value"]) for x in d["solutions"] if x["value"] <= cap)
    ill = bool(d["certificate"].get("ill_conditioned"))
    status = "ill-conditioned" if (d["certified"] and ill) else ("proven" if d["certified"] else "not proven")
    return status, d["certificate"].get("onset"), status, vals


PROVERS = {"mceip_mu": _prove_mceip_mu, "app-result": _prove_app_result}


def get_prover(name: str = "auto"):
    """``(name, prove)``: ``auto`` is ``mceip_mu``."""
    return ("mceip_mu" if name == "auto" else name), PROVERS["mceip_mu" if name == "auto" else name]


# =================================================================================================
# Judging
# =================================================================================================

def _near(a: float, b: float) -> bool:
    return abs(a - b) <= MATCH_RTOL * max(1.0, abs(a), abs(b))


def judge(truth: Truth, onset_status, onset_value, all_status, values) -> dict:
    """Is each claim labelled proven consistent with the truth? (None: not judged.)"""
    out = {"onset_false": None, "all_false": None}
    if not truth.known:
        return out
    T, O = truth.values, truth.optional
    if onset_status == "proven":
        if onset_value is None:
            out["onset_false"] = bool(T)
        else:
            ok_vals = ([T[0]] if T else []) + [o for o in O if not T or o < T[0]]
            out["onset_false"] = not any(_near(onset_value, t) for t in ok_vals)
    if all_status == "proven":
        missing = [t for t in T if not any(_near(t, v) for v in values)]
        extra = [v for v in values if not any(_near(t, v) for t in T + O)]
        out["all_false"] = bool(missing or extra)
        out["missing"], out["extra"] = missing, extra
    return out


# =================================================================================================
# Sections
# =================================================================================================

def section_soundness(n: int = 10_000, prover: str = "auto", base_seed: int = 2026, show: int = 8,
                      seconds: float = 60.0, start: int = 0) -> dict:
    from threadpoolctl import threadpool_limits
    name, prove = get_prover(prover)
    say(f"\n== soundness: {n} random pencils (s = 1-10, kinds {', '.join(KINDS)}) against exhaustive "
        f"enumeration with exact re-checks; prover: {name} ==")
    counts = dict.fromkeys(("pencils", "proven_onset", "proven_all", "not_proven", "ill_conditioned",
                            "false_onset", "false_all", "false_proofs", "unknown_truth", "labelled_disagree",
                            "truth_exact_supports", "truth_supports", "planted_missed",
                            "planted_nonsolution_listed"), 0)
    by_kind: dict = {}
    t_truth = t_prove = t_gen = 0.0
    examples: list[str] = []
    unknown: list[str] = []
    with threadpool_limits(1):
        for i in range(start, start + n):
            t0 = time.perf_counter()
            p = make_pencil(i, base_seed)
            t1 = time.perf_counter()
            tr = ground_truth(p.A0, p.A1, p.cap, p.pairs)
            t2 = time.perf_counter()
            try:
                with quiet_c_output():
                    on, ov, al, vals = prove(p.A0, p.A1, p.cap, p.pairs, seconds)
            except Exception as err:          # a crash is no proof
                on, ov, al, vals = "not proven", None, "not proven", []
                examples.append(f"  pencil {p.seed} ({p.kind}, s={p.A0.shape[0]}): prover raised {err!r}")
            t3 = time.perf_counter()
            t_gen += t1 - t0
            if n >= 2000 and (i - start + 1) % 1000 == 0:
                say(f"  ... {i - start + 1} pencils, {counts['false_proofs']} false proofs so far")
            t_truth += t2 - t1
            t_prove += t3 - t2
            j = judge(tr, on, ov, al, vals)
            c = counts
            c["pencils"] += 1
            c["proven_onset"] += on == "proven"
            c["proven_all"] += al == "proven"
            c["not_proven"] += "not proven" in (on, al)
            c["ill_conditioned"] += "ill-conditioned" in (on, al)
            c["truth_exact_supports"] += tr.exact_supports
            c["truth_supports"] += tr.supports
            for pl in p.planted:
                if not tr.known:
                    continue
                if pl["solution"] and pl["mu"] <= p.cap and not any(
                        abs(mu - pl["mu"]) <= 1e-9 * max(1, pl["mu"]) and sup == pl["support"] for mu, sup, _ in tr.solutions):
                    c["planted_missed"] += 1
                if not pl["solution"] and any(abs(mu - pl["mu"]) <= 1e-13 * max(1, pl["mu"]) and sup == pl["support"]
                                              for mu, sup, _ in tr.solutions):
                    c["planted_nonsolution_listed"] += 1
            k = by_kind.setdefault(p.kind, {"n": 0, "false": 0, "unknown": 0, "exact": 0})
            k["n"] += 1
            k["exact"] += tr.exact_supports > 0
            if not tr.known:
                c["unknown_truth"] += 1
                k["unknown"] += 1
                unknown.append(f"  pencil {p.seed} ({p.kind}, s={p.A0.shape[0]}): {'; '.join(tr.reasons[:2])}")
                continue
            c["false_onset"] += bool(j["onset_false"])
            c["false_all"] += bool(j["all_false"])
            bad = bool(j["onset_false"] or j["all_false"])
            c["false_proofs"] += bad
            k["false"] += bad
            if not bad and (on != "proven" or al != "proven"):
                # a labelled claim: does its content disagree with the truth?
                jj = judge(tr, "proven", ov, "proven", vals)
                c["labelled_disagree"] += bool(jj["onset_false"] or jj["all_false"])
            if bad and len(examples) < show:
                examples.append(
                    f"  FALSE PROOF pencil {p.seed} ({p.kind}, s={p.A0.shape[0]}, cap={p.cap:g}, pairs={p.pairs}): "
                    f"truth {[round(v, 9) for v in tr.values]}; claimed onset {on} {ov}, all {al} "
                    f"{[round(v, 9) for v in vals]}" + (f" (missing {j.get('missing')}, extra {j.get('extra')})"
                                                        if j["all_false"] else ""))
    c = counts
    say(f"pencils {c['pencils']}: proven onset {c['proven_onset']}, proven all {c['proven_all']}, "
        f"not proven {c['not_proven']}, ill-conditioned {c['ill_conditioned']}")
    say(f"FALSE PROOFS: {c['false_proofs']} (onset {c['false_onset']}, all values {c['false_all']}); "
        f"labelled not proven / ill-conditioned but disagreeing: {c['labelled_disagree']}; "
        f"unknown truth: {c['unknown_truth']}")
    say(f"truth: {c['truth_supports']} supports, {c['truth_exact_supports']} re-decided in exact/ball arithmetic; "
        f"planted solutions missed by the truth: {c['planted_missed']}, planted near-misses listed by it: "
        f"{c['planted_nonsolution_listed']}")
    say(f"time: truth {t_truth:.1f} s, prover {t_prove:.1f} s, pencil generation {t_gen:.1f} s")
    say("by kind (pencils / with exact re-checks / false proofs / unknown): " + ", ".join(
        f"{k} {v['n']}/{v['exact']}/{v['false']}/{v['unknown']}" for k, v in sorted(by_kind.items())))
    for e in examples:
        say(e)
    for u in unknown[:show]:
        say("  unknown truth:" + u)
    return {"prover": name, "counts": counts, "by_kind": by_kind, "t_truth_s": t_truth, "t_prover_s": t_prove,
            "examples": examples, "unknown": unknown}


def section_dense(prover: str = "auto", limit: float = 60.0, s_values=None, seed: int = 11) -> dict:
    """Onset proof time on dense random pencils (A0 = B B^T + s I, A1 = 3 N(0, 1), cap 10) at
    growing s (the onset claim alone, ``want_all=False``: the list is not attempted); stops after
    the first s not proven within ``limit``."""
    name, prove = get_prover(prover)
    if name == "mceip_mu":
        prove = functools.partial(_prove_mceip_mu, want_all=False)
    s_values = list(s_values or range(10, 201, 10))
    say(f"\n== dense random pencils: onset proof time, s = {s_values[0]}, {s_values[1]}, ... (limit {limit:g} s, "
        f"prover {name}) ==")
    say(f"{'s':>4} {'onset':>14} {'value':>14} {'all':>14} {'#values':>8} {'time[s]':>8}")
    rows, largest = [], None
    for s in s_values:
        rng = np.random.default_rng([seed, s])
        A0, A1 = _dense(rng, s)
        t0 = time.perf_counter()
        try:
            with quiet_c_output():
                on, ov, al, vals = prove(A0, A1, 10.0, [], limit)
        except Exception as err:
            on, ov, al, vals = f"error {err!r}"[:40], None, "-", []
        t = time.perf_counter() - t0
        ok = on == "proven" and t <= limit
        largest = s if ok else largest
        say(f"{s:>4} {on:>14} {('none' if ov is None else f'{ov:.8g}'):>14} {al:>14} {len(vals):>8} {t:>8.2f}")
        rows.append({"s": s, "onset": on, "value": ov, "all": al, "n_values": len(vals), "seconds": t})
        if not ok:
            break
    say(f"largest s with the onset proven within {limit:g} s: {largest}")
    return {"prover": name, "rows": rows, "largest_s": largest}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=10_000, help="number of random pencils (default 10000)")
    ap.add_argument("--quick", action="store_true", help="300 pencils, dense series up to s = 30")
    ap.add_argument("--prover", default="auto", choices=["auto", *PROVERS])
    ap.add_argument("--seed", type=int, default=2026, help="base seed: pencil i is make_pencil(i, seed)")
    ap.add_argument("--start", type=int, default=0, help="index of the first pencil (to re-run one: --start i --n 1)")
    ap.add_argument("--no-dense", action="store_true", help="skip the dense random series")
    ap.add_argument("--limit", type=float, default=60.0, help="time limit of one dense proof (s)")
    args = ap.parse_args(argv)
    n = 300 if args.quick else args.n
    out = {"soundness": section_soundness(n, args.prover, args.seed, start=args.start)}
    if not args.no_dense:
        out["dense"] = section_dense(args.prover, args.limit, [10, 20, 30] if args.quick else None)
    return out


if __name__ == "__main__":
    main()
