"""The leaves of the MCEIP-mu proof tree: one exact support ``U`` (paper eqs. (25)-(26)).

Every real eigenvalue of ``A_UU(mu)`` in the leaf's interval that looks like a solution gets a
Krawczyk window (:func:`app.analyses.mceip_mu.kernel.windows.verify_window`: one verified eigenpair,
decided as solution or not); the gaps between are closed by Farkas vectors where one exists
(:func:`app.analyses.mceip_mu.kernel.closing.farkas_closes`), and what is left by the checker's
nonsingularity cover (:func:`app.analyses.mceip_mu.kernel.closing.cover_nonsingular`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from app.analyses.mceip_mu.kernel import closing, prooflog, windows
from app.analyses.mceip_mu.prover.heuristics import polish

#: relative half-width of the window around a verified eigenvalue (the accuracy of a proven value)
WINDOW_REL = 1e-9
#: halvings of a leaf's gap tried with Farkas vectors before windows and nonsingularity take over
FARKAS_DEPTH = 6


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


class LeafTests:
    """The leaf tests of :class:`app.analyses.mceip_mu.prover.branch.Prover` (a mixin: it uses the
    prover's scaled pencil ``a0, a1``, ``cap``, ``pairs``, its LP ``_lp`` and records
    what it proves in ``found``, ``ill`` and ``leaf_cache``)."""

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
            mu, x = polish(s0, s1, float(w[j].real), V[:, j].real.copy())
            out.append((mu, x))
        out.sort(key=lambda t: t[0])
        self.leaf_cache[key] = out
        return out

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
        if closing.cover_nonsingular(self.a0, self.a1, U, a, b, done):
            return True
        n.kind = "open"
        return False
