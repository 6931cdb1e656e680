"""A smooth curve of the scene's Gmsh file as the rigid obstacle (docs/method.md section 8, docs/curved.md).

Built from the samples the sandboxed child took of a free physical curve
(app/systems/gmsh/child_curves.py): per panel the positions at the ``q + 1`` Chebyshev-Lobatto
points of its parameter interval. The entities of the physical curve are chained end to end (the
first one in its own orientation, the others turned to follow it) and the panels numbered along
the chain: the curve is ``p(s)``, ``s`` in ``[0, P]``, panel ``j`` the interval ``[j, j + 1]`` with
``xi = 2 (s - j) - 1``, ``p`` on each panel the interpolating polynomial of degree ``q`` (Chebyshev
coefficients). Its derivatives are those of the polynomials (gmsh 4.8's built-in kernel gives
derivatives only by finite differences). **Error:** each panel matched gmsh's positions half-way
between its nodes to ``1e-11`` of the body's size (or to gmsh's round-off); for an analytic curve
the error of degree-``q`` interpolation on a panel of parameter length ``h`` is ``O(h^(q+1))``, and
the derivatives lose about one power of ``h / q^2`` each, so gaps are accurate to about ``1e-11`` and
curvatures to about ``1e-8`` relative (tests/test_curve_obstacle.py measures both).

Same interface as :class:`app.loading.curved.Circle`. With ``tau = p' / |p'|`` and its left normal
``nu = (-tau_y, tau_x)``, the body on the ``left`` of the curve's direction: gap
``g = (x - p) . nu``, outward normal of the body ``n = -nu``; on the ``right``: ``g = -(x - p) . nu``,
``n = +nu``; ``t = (-n_y, n_x)`` and the signed curvature ``kappa = +-(x' y'' - y' x'') / |p'|^3``
(``dn/ds = kappa t``): a counter-clockwise circle with the body on its left (inside) has
``kappa = +1/R``, on its right (outside) ``-1/R``, as :class:`Circle`. ``p`` is the closest point of
the curve to ``x``: the nearest of 16 points per panel, then safeguarded Newton on
``f(s) = (p(s) - x) . p'(s) = 0`` (bisection whenever a step leaves the bracket of the grid point's
neighbours).
"""
from __future__ import annotations

import numpy as np
from numpy.polynomial import chebyshev as C

GRID = 16                     # coarse search: points per panel
GAUSS = np.polynomial.legendre.leggauss(24)


class CurveError(ValueError):
    """The samples do not make one smooth curve: ``str(err)`` is the one-line reason."""


def _chain(entities, params, xy, ent_of, size: float) -> np.ndarray:
    """The panels' node positions (P, q + 1, 2), xi ascending, along one chain of the entities."""
    xy = np.asarray(xy, dtype=float)[:, ::-1, :]            # the child's nodes run xi = 1 .. -1
    pieces = []
    for e in entities:
        rows = np.flatnonzero(np.asarray(ent_of) == e)
        rows = rows[np.argsort(np.asarray(params)[rows, 0])]
        pieces.append(xy[rows])
    tol = 1e-8 * size
    chain, left = [pieces[0]], list(range(1, len(pieces)))
    while left:
        head, tail = chain[0][0, 0], chain[-1][-1, -1]
        for k in left:
            a, b = pieces[k][0, 0], pieces[k][-1, -1]
            flip = pieces[k][::-1, ::-1]
            if np.linalg.norm(a - tail) <= tol:
                chain.append(pieces[k])
            elif np.linalg.norm(b - tail) <= tol:
                chain.append(flip)
            elif np.linalg.norm(b - head) <= tol:
                chain.insert(0, pieces[k])
            elif np.linalg.norm(a - head) <= tol:
                chain.insert(0, flip)
            else:
                continue
            left.remove(k)
            break
        else:
            raise CurveError("its curves do not join end to end into one curve")
    return np.concatenate(chain)


class SmoothCurve:
    """A smooth rigid curve (``side``: where the body is, ``left`` or ``right`` of the curve's
    direction); see the module docstring."""

    def __init__(self, name: str, entities, params, xy, ent_of, side: str, size: float, corner_rad: float = 1e-5):
        self.name, self.side, self.size = name, side, float(size)
        self.sign = 1.0 if side == "left" else -1.0
        nodes = _chain(list(entities), params, xy, ent_of, self.size)
        self.P, q = nodes.shape[0], nodes.shape[1] - 1
        xi = -np.cos(np.pi * np.arange(q + 1) / q)
        self.c0 = np.stack([C.chebfit(xi, nd, q) for nd in nodes])          # (P, q + 1, 2)
        self.c1 = C.chebder(self.c0, 1, scl=2.0, axis=1)
        self.c2 = C.chebder(self.c0, 2, scl=2.0, axis=1)
        # a closed chain (its ends meet): the parameter is periodic, the joint at s = 0 = P checked as the others
        self.closed = bool(len(entities) and np.linalg.norm(nodes[0, 0] - nodes[-1, -1]) <= 1e-8 * self.size)
        self._check_smooth(corner_rad)
        self._last = None
        g = (np.arange(GRID) + 0.5) / GRID
        self.grid_s = (np.arange(self.P)[:, None] + g[None, :]).ravel()
        self.grid_x = self.value(self.grid_s)
        self.cum = np.concatenate([[0.0], np.cumsum(self._arc_in_panel(np.arange(self.P), np.ones(self.P)))])
        self.anchor = np.zeros(2)              # positions are used as given (round-off eps |x|)
        self.s_ref = 0.0

    # evaluation -----------------------------------------------------------------------------
    def _eval(self, coef: np.ndarray, s: np.ndarray) -> np.ndarray:
        s = np.asarray(s, dtype=float)
        if self.closed:
            s = np.mod(s, float(self.P))
        j = np.clip(np.floor(s).astype(np.int64), 0, self.P - 1)
        xi = 2.0 * (s - j) - 1.0
        return C.chebval(xi[:, None], np.moveaxis(coef[j], 1, 0), tensor=False)   # (n, 2)

    def value(self, s):
        """Points ``p(s)`` of the curve at the parameters ``s``, shape (n, 2) (``s`` taken modulo ``P``
        on a closed curve)."""
        return self._eval(self.c0, np.atleast_1d(s))

    def _check_smooth(self, corner_rad: float) -> None:
        """The tangent is continuous across the panels' joins (a corner is refused) and p' != 0."""
        ends = np.arange(1, self.P + (1 if self.closed else 0), dtype=float)
        d = self._eval(self.c1, np.concatenate([[0.0], (np.arange(self.P) + 0.5), [float(self.P)]]))
        if np.min(np.hypot(*d.T)) <= 1e-12 * self.size:
            raise CurveError("its parametrization stops (zero derivative)")
        if len(ends) == 0:
            return
        j = ends.astype(np.int64)
        a = C.chebval(np.ones((len(j), 1)), np.moveaxis(self.c1[j - 1], 1, 0), tensor=False)
        b = C.chebval(-np.ones((len(j), 1)), np.moveaxis(self.c1[j % self.P], 1, 0), tensor=False)
        cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
        ang = np.arctan2(np.abs(cross), np.einsum("ij,ij->i", a, b))
        k = int(np.argmax(ang))
        if ang[k] > corner_rad:
            x, y = self.value(ends[k])[0]
            raise CurveError(f"its tangent turns by {np.degrees(ang[k]):.3g} degrees at ({x:.6g}, {y:.6g}): a corner; "
                             "the obstacle must have a continuous tangent")

    def _arc_in_panel(self, j: np.ndarray, xi: np.ndarray) -> np.ndarray:
        """Arc length on panel ``j`` from its start to ``xi`` (Gauss-Legendre, 24 points)."""
        t, w = GAUSS
        lo = -1.0
        xs = lo + (np.asarray(xi)[:, None] - lo) * (t[None, :] + 1.0) / 2.0            # (n, 24)
        d = C.chebval(xs[:, None, :], self.c1[j][:, :, :, None].transpose(1, 0, 2, 3), tensor=False)
        speed = np.hypot(d[:, 0, :], d[:, 1, :]) / 2.0     # |dp/dxi| (c1 is d/ds = 2 d/dxi)
        return (np.asarray(xi) - lo) / 2.0 * (speed @ w)

    # closest point ----------------------------------------------------------------------------
    def project(self, x: np.ndarray) -> np.ndarray:
        """Parameter ``s`` of the closest point of the curve to each point ``x`` (n, 2) (the last
        answer is kept: gap, frames and curvature are asked for at the same positions)."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        if self._last is not None and self._last[0].shape == x.shape and np.array_equal(self._last[0], x):
            return self._last[1].copy()
        s = self._project(x)
        self._last = (x.copy(), s.copy())
        return s

    def _project(self, x: np.ndarray) -> np.ndarray:
        s0 = np.empty(len(x))
        for a in range(0, len(x), 256):        # chunks: the distance table is (chunk, P GRID)
            d = np.sum((x[a:a + 256, None, :] - self.grid_x[None, :, :]) ** 2, axis=2)
            s0[a:a + 256] = self.grid_s[np.argmin(d, axis=1)]
        lo, hi = s0 - 1.0 / GRID, s0 + 1.0 / GRID
        if not self.closed:
            lo, hi = np.maximum(lo, 0.0), np.minimum(hi, float(self.P))
        f = lambda s: np.einsum("ij,ij->i", self._eval(self.c0, s) - x, self._eval(self.c1, s))   # noqa: E731
        flo, fhi = f(lo), f(hi)
        s = s0.copy()
        s = np.where(flo >= 0, lo, s)            # the minimum at the bracket's low end (the curve's start)
        s = np.where(fhi <= 0, hi, s)            # or at its high end
        inside = (flo < 0) & (fhi > 0)
        for _ in range(60):
            if not np.any(inside):
                break
            si = s[inside]
            p, d1, d2 = (self._eval(c, si) for c in (self.c0, self.c1, self.c2))
            fi = np.einsum("ij,ij->i", p - x[inside], d1)
            dfi = np.einsum("ij,ij->i", d1, d1) + np.einsum("ij,ij->i", p - x[inside], d2)
            l, h = lo[inside], hi[inside]
            l, h = np.where(fi < 0, si, l), np.where(fi > 0, si, h)
            with np.errstate(divide="ignore", invalid="ignore"):
                d = fi / dfi
            new = si - d
            newton = np.isfinite(new) & (dfi > 0) & (new >= l) & (new <= h)
            new = np.where(newton, new, 0.5 * (l + h))
            lo[inside], hi[inside] = l, h
            s[inside] = new
            idx = np.flatnonzero(inside)
            inside[idx[newton & (np.abs(d) <= 4 * np.finfo(float).eps * np.maximum(1.0, np.abs(si)))]] = False
        return np.mod(s, float(self.P)) if self.closed else s

    def _frame_at(self, s: np.ndarray):
        d1 = self._eval(self.c1, s)
        sp = np.hypot(d1[:, 0], d1[:, 1])
        tau = d1 / sp[:, None]
        return tau, np.column_stack([-tau[:, 1], tau[:, 0]]), sp

    def gap(self, x: np.ndarray) -> np.ndarray:
        """Signed distances of the points ``x`` (n, 2) (positive on the body's side)."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        s = self.project(x)
        _, nu, _ = self._frame_at(s)
        return self.sign * np.einsum("ij,ij->i", x - self.value(s), nu)

    def frames(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unit tangents ``t`` and outward normals ``n`` of the body at the closest points of ``x``."""
        _, nu, _ = self._frame_at(self.project(x))
        n = -self.sign * nu
        return np.column_stack([-n[:, 1], n[:, 0]]), n

    def curvatures(self, x: np.ndarray) -> np.ndarray:
        """Signed curvature ``kappa`` (``dn/ds = kappa t``) at the closest points of ``x``."""
        s = self.project(x)
        d1, d2 = self._eval(self.c1, s), self._eval(self.c2, s)
        return self.sign * (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / np.hypot(d1[:, 0], d1[:, 1]) ** 3

    def at_end(self, x: np.ndarray) -> np.ndarray:
        """Whether the closest point of each ``x`` is an end of the curve (not a foot of a normal)."""
        s = self.project(x)
        return np.zeros(len(s), dtype=bool) if self.closed else (s <= 0.0) | (s >= self.P)

    def set_reference(self, ref) -> "SmoothCurve":
        """Measure :meth:`arc` from the closest point of ``ref``."""
        self.s_ref = float(self.project(np.asarray(ref, dtype=float)[None, :])[0])
        return self

    def _sigma(self, s: np.ndarray) -> np.ndarray:
        j = np.clip(np.floor(s).astype(np.int64), 0, self.P - 1)
        return self.cum[j] + self._arc_in_panel(j, 2.0 * (s - j) - 1.0)

    def arc(self, x: np.ndarray) -> np.ndarray:
        """Arc coordinate along ``t`` from the reference point's closest point."""
        s = self.project(x)
        d = self._sigma(s) - self._sigma(np.array([self.s_ref]))[0]
        if self.closed:                          # the shorter way round from the reference
            L = self.cum[-1]
            d = d - L * np.round(d / L)
        return self.sign * d

    def position_scale(self, x: np.ndarray) -> float:
        """The magnitude the gaps' round-off is relative to (the positions themselves)."""
        return float(np.max(np.abs(np.atleast_2d(x))))

    def polyline(self, per_panel: int = 64) -> np.ndarray:
        """Points along the curve (for pictures)."""
        return self.value(np.linspace(0.0, float(self.P), self.P * per_panel + 1))

    def describe(self) -> str:
        """The curve in words for messages: its name, panels, length, range of signed curvature for the
        body's side, and that side."""
        k = self.sign * self._signed_curvature_range()
        return (f"curve '{self.name}' of the Gmsh file ({self.P} panels, length {self.cum[-1]:.6g}, curvature "
                f"{min(k):.4g} to {max(k):.4g}), body on its {self.side}")

    def _signed_curvature_range(self) -> np.ndarray:
        d1, d2 = self._eval(self.c1, self.grid_s), self._eval(self.c2, self.grid_s)
        return (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / np.hypot(d1[:, 0], d1[:, 1]) ** 3
