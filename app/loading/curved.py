"""Quasi-static contact increments against a rigid curved obstacle, with the exact gap (docs/method.md section 8).

The obstacle is a :class:`Circle` or a smooth curve of the Gmsh file
(:class:`app.loading.curve.SmoothCurve`); :class:`CurvedContact` uses only their common
interface: ``gap(x)`` (signed distance, positive on the body's side), ``frames(x)`` (unit tangent
and outward normal of the body at the closest points), ``curvatures(x)`` (signed curvature
there), ``arc(x)``, ``anchor`` and ``position_scale(x)`` (the point and the magnitude the gaps'
round-off is relative to) and ``describe()``.

Geometry (:class:`Circle`): centre ``c``, radius ``R``; a point ``x`` at ``rho = |x - c|``,
``e = (x - c) / rho``. Body outside (convex cylinder): gap ``g = rho - R``, outward normal of the
body ``n = -e``; body inside (concave bore): ``g = R - rho``, ``n = +e``; tangent
``t = (-n_y, n_x)``; signed curvature ``kappa = -1/R`` outside, ``+1/R`` inside.

Increment (:class:`CurvedContact`): the system's contact DOFs are in fixed node frames
``(t0, n0)`` (the same for every node); the contact displacements ``u`` (2n, paper axes of those
frames) and the node positions ``x = X + t0 u_T + n0 u_N`` are the unknowns. Each
*linearisation* takes the current iterate ``u^k``, the frames ``(t_i, n_i)`` at the contact
points of ``x^k`` and the gap linearised there, ``g_i(u) = g_i(x^k) - n_i . (u_i - u_i^k)``; in
those frames the increment is exactly the flat problem of app/loading/contact.py (contact
stiffness ``Q^T Kc Q``, initial gaps ``g_i(x^k) + n_i . u_i^k``, slip increment
``d_i = t_i . (u_i - u_i^prev)``), solved by the same SNES VI. The linearisations are repeated
until the iterate stops moving (``1e-13`` of the displacement scale); then the *exact*
conditions are checked at the final positions and frames: the exact gaps ``g >= 0``, ``p >= 0``,
``g p = 0``, ``|r_T| <= mu p`` and the slip rule, with reactions ``r = Q^T Kc Q (u' - u0')`` in the
frames of the final contact points. The largest violation is reported per increment
(``violation``), as on the flat obstacle.

A state's ``u_N`` is then ``-g`` (the exact gap), ``u_T = t . (t0 u_T + n0 u_N)`` the tangential
displacement in its contact frame, and ``r_T``, ``r_N`` the components in that frame;
``curved_contact`` records the frames (``(a, b, c, d)``: ``t = a t0 + b n0``, ``n = c t0 + d n0``),
the exact gaps, the displacements in the system frames (``u_system``, interleaved T, N), the arc
coordinates, the number of linearisations and the signed curvature at each contact point
(``curvature``, what the pencils of the state use: app/analyses/pencils/curvature.py).
"""
from __future__ import annotations

import numpy as np

from app.common.errors import point_text
from app.loading.contact import ContactSolveError, FrictionalContact, IncrementResult

MAX_LINEARISATIONS = 50


class Circle:
    """A rigid circle (``side``: where the body is, ``outside`` or ``inside``).

    Computed relative to an anchor ``p0 = c + R m`` on the circle (``m`` the unit direction of
    ``ref`` from the centre, default +y): with ``w = x - p0`` small, ``theta = atan2(w . m_perp,
    R + w . m)`` and ``rho - R = (|w|^2 + 2 R w . m) / (rho + R)`` keep full relative precision for
    any radius (a radius of 1e12 body sizes included), where ``|x - c| - R`` would cancel.
    """

    def __init__(self, centre, radius: float, side: str, ref=None):
        self.c = np.asarray(centre, dtype=float)
        self.R = float(radius)
        self.sign = 1.0 if side == "outside" else -1.0      # g = sign (rho - R), n = -sign e
        self.side = side
        r = np.array([0.0, 1.0]) if ref is None else np.asarray(ref, dtype=float) - self.c
        big = float(np.max(np.abs(r)))
        r = r / big if big > 0 else np.array([0.0, 1.0])
        self.m = r / np.linalg.norm(r)
        self.mp = np.array([-self.m[1], self.m[0]])          # m rotated by +90 degrees
        self.p0 = self.c + self.R * self.m

    @property
    def curvature(self) -> float:
        """Signed curvature ``kappa``: ``-1/R`` with the body outside, ``+1/R`` inside."""
        return -self.sign / self.R

    @property
    def anchor(self) -> np.ndarray:
        """The point the gaps are computed from (their round-off is relative to ``|x - anchor|``)."""
        return self.p0

    def curvatures(self, x: np.ndarray) -> np.ndarray:
        """Signed curvature at the contact points of ``x``: the constant ``-1/R`` outside, ``+1/R`` inside."""
        return np.full(len(np.atleast_2d(x)), self.curvature)

    def position_scale(self, x: np.ndarray) -> float:
        """``max |x - c|``: the scale below which a gap counts as closed (1e-12 of it)."""
        return float(np.max(np.abs(np.atleast_2d(x) - self.c)))

    def _polar(self, x: np.ndarray):
        w = np.atleast_2d(np.asarray(x, dtype=float)) - self.p0
        a, b = w @ self.m, w @ self.mp                      # along m (radial at p0) and m_perp
        th = np.arctan2(b, self.R + a)
        rho = np.hypot(b, self.R + a)
        drho = (np.einsum("ij,ij->i", w, w) + 2.0 * self.R * a) / (rho + self.R)     # rho - R, no cancellation
        return th, drho

    def gap(self, x: np.ndarray) -> np.ndarray:
        """Exact gaps of the points ``x`` (n, 2)."""
        return self.sign * self._polar(x)[1]

    def frames(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unit tangents and outward normals of the body at the contact points of ``x`` (n, 2)."""
        th, _ = self._polar(x)
        e = np.outer(np.cos(th), self.m) + np.outer(np.sin(th), self.mp)
        n = -self.sign * e
        return np.column_stack([-n[:, 1], n[:, 0]]), n

    def arc(self, x: np.ndarray) -> np.ndarray:
        """Arc coordinate along the tangent ``t`` from the anchor ``p0``, in (-pi R, pi R]
        (t = (-n_y, n_x) runs clockwise outside the circle, counter-clockwise inside)."""
        return (-self.sign) * self.R * self._polar(x)[0]

    def describe(self) -> str:
        """The circle in words for messages: centre, radius and the body's side (convex cylinder or
        concave bore)."""
        return (f"circle, centre ({self.c[0]:.6g}, {self.c[1]:.6g}), radius {self.R:.6g}, body {self.side} "
                f"({'convex cylinder' if self.side == 'outside' else 'concave bore'})")


class CurvedContact:
    """Incremental frictional contact against a curved obstacle (a :class:`Circle` or a
    :class:`app.loading.curve.SmoothCurve`), exact gap (one instance per study).

    Same calling convention as :class:`FrictionalContact` inside app/loading/program.py:
    ``solve(u0, u_T_prev, g_prev, d_prev)`` with ``u0`` the contact displacements of the load
    (r = 0, system frames), ``(u_T_prev, -g_prev)`` the previous *displacements* in the system
    frames (:meth:`carry` gives them from a result).
    """

    def __init__(self, Kc: np.ndarray, mu: float, obstacle, X: np.ndarray, t0: np.ndarray, n0: np.ndarray):
        self.Kc_sys = np.asarray(Kc, dtype=float)
        self.n = Kc.shape[0] // 2
        self.mu = mu
        self.kscale = float(np.max(np.abs(np.diag(Kc))))
        self.Kc = self.Kc_sys / self.kscale               # what program.py reads (bonded estimate)
        self.obstacle, self.X = obstacle, np.asarray(X, dtype=float)
        self.t0, self.n0 = np.asarray(t0, dtype=float), np.asarray(n0, dtype=float)
        self.gaps0 = obstacle.gap(self.X)
        self.extent = max(float(np.max(np.ptp(self.X, axis=0))), 1e-300)
        self.reach = float(np.max(np.abs(self.X - obstacle.anchor)))     # size of the positions the gaps are computed from

    def positions(self, u: np.ndarray) -> np.ndarray:
        """Node positions ``x = X + t0 u_T + n0 u_N`` for the contact displacements ``u`` (interleaved
        T, N in the system frames), shape (n, 2)."""
        return self.X + np.outer(u[0::2], self.t0) + np.outer(u[1::2], self.n0)

    def frame_matrix(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``Q`` (old system components = Q contact-frame components) and the per-node (a, b, c, d)."""
        t, n = self.obstacle.frames(x)
        abcd = np.column_stack([t @ self.t0, t @ self.n0, n @ self.t0, n @ self.n0])
        Q = np.zeros((2 * self.n, 2 * self.n))
        for i, (a, b, c, d) in enumerate(abcd):
            Q[2 * i:2 * i + 2, 2 * i:2 * i + 2] = [[a, c], [b, d]]
        return Q, abcd

    def carry(self, inc: IncrementResult) -> np.ndarray:
        """The displacements (system frames, interleaved T, N) to continue from after ``inc``."""
        return inc.extra["u_system"]

    def solve(self, u0: np.ndarray, u_T_prev: np.ndarray, g_prev: np.ndarray,
              d_prev: np.ndarray | None = None) -> IncrementResult:
        """The increment for the load's contact displacements ``u0`` (r = 0, system frames) from the
        previous displacements ``(u_T_prev, -g_prev)``: linearisations of the exact gap, each solved as
        the flat problem, until the iterate stops moving, then the exact conditions checked at the final
        contact points (module docstring). ``d_prev`` is taken for the flat solver's signature and not
        used. Raises :class:`ContactSolveError` when the linearisations do not converge within
        :data:`MAX_LINEARISATIONS` or the exact conditions fail."""
        n = self.n
        u_prev = np.ravel(np.column_stack([u_T_prev, -np.asarray(g_prev)]))
        x_prev = self.positions(u_prev)
        uk = u_prev.copy()
        # displacement scale; floor: 1e-12 of the contact curve's extent (an unloaded increment is 0 + noise)
        scale = max(float(np.max(np.abs(u0), initial=0.0)), float(np.max(np.abs(u_prev), initial=0.0)),
                    1e-12 * self.extent)
        its, step = 0, np.inf
        if not np.any(u0) and not np.any(u_prev):
            # no load from the unloaded body (e.g. the force control's first trial): the body stays
            # where it is, r = 0 (the gaps are >= 0 by construction of the system)
            return self._result(u_prev, u0, x_prev, 0, 0, "no load", scale)
        for lin in range(1, MAX_LINEARISATIONS + 1):
            x = self.positions(uk)
            Q, _ = self.frame_matrix(x)
            Kl = Q.T @ self.Kc_sys @ Q
            ukl, u0l, upl = Q.T @ uk, Q.T @ u0, Q.T @ u_prev
            h = self.obstacle.gap(x) + ukl[1::2]          # linearised gap: g = h - u'_N
            H = np.zeros(2 * n)
            H[1::2] = h
            gk = np.maximum(h - ukl[1::2], 0.0)
            inc = self._flat(Kl, u0l - H, upl[0::2], gk)
            its += inc.iterations
            unew_l = np.ravel(np.column_stack([inc.u_T, inc.u_N + h]))
            unew = Q @ unew_l
            step, prev = float(np.max(np.abs(unew - uk))), step
            uk = unew
            # converged: the iterate stops moving (to 1e-13 of the displacements, or to the round-off
            # of the positions it is computed from), or it stagnates at round-off level
            if step <= max(1e-13 * scale, 8 * np.finfo(float).eps * self.reach) or \
                    (lin >= 3 and step <= 1e-10 * scale and step >= 0.5 * prev):
                break
        else:
            raise ContactSolveError(f"the exact-gap contact increment did not converge in {MAX_LINEARISATIONS} "
                                    f"linearisations (last step {step:.3g} of the displacement scale {scale:.3g})")
        return self._result(uk, u0, x_prev, its, lin, inc.method, scale)

    def _flat(self, Kl, u0, uT_prev, gk) -> IncrementResult:
        """The flat increment in the contact frames, started from the current gaps with those at
        the round-off of the positions closed (SNES VI does not leave a 1e-11 gap), else from all
        gaps closed."""
        tiny = 1e-9 * self.extent
        starts = [np.where(gk <= tiny, 0.0, gk), np.zeros_like(gk)]
        with FrictionalContact(Kl, self.mu) as flat:
            for k, g0 in enumerate(starts):
                try:
                    return flat.solve(u0, uT_prev, g0)
                except ContactSolveError:
                    if k == len(starts) - 1:
                        raise

    def _result(self, u, u0, x_prev, its, lin, method, uscale) -> IncrementResult:
        mu = self.mu
        x = self.positions(u)
        Q, abcd = self.frame_matrix(x)
        Kl = Q.T @ self.Kc_sys @ Q
        ul, u0l = Q.T @ u, Q.T @ u0
        r = Kl @ (ul - u0l)
        rT, rN = r[0::2], r[1::2]
        p = -rN
        g = self.obstacle.gap(x)
        t, _ = self.obstacle.frames(x)
        d = np.einsum("ij,ij->i", t, x - x_prev)         # slip since the previous state, along t
        # the reaction scale: the forces whose difference r is (as the flat solver's scale, Kc (u_prev - u0))
        rscale = max(float(np.max(np.abs(r))), float(np.max(np.abs(Kl @ ul))), float(np.max(np.abs(Kl @ u0l))))
        if rscale == 0.0:
            rscale = 1.0                                  # no load, no reaction: nothing is violated
        gscale = max(float(np.max(np.abs(g))), 1e-300)
        xscale = max(self.obstacle.position_scale(x), 1e-300)
        # exact conditions; a gap at the round-off of the positions (1e-14 of |x - c|) counts as closed
        closed = np.abs(g) <= 1e-12 * xscale
        v = [max(0.0, -float(np.min(g)) - 1e-12 * xscale) / max(gscale, 1e-12 * xscale),
             max(0.0, -float(np.min(p))) / rscale,
             float(np.max(np.where(closed, 0.0, np.abs(g * p)))) / (rscale * max(gscale, 1e-300)),
             max(0.0, float(np.max(np.abs(rT) - mu * p))) / rscale,
             # sliding nodes (moved along t by more than the round-off of the displacements) carry r_T = -mu p sign(d)
             float(np.max(np.where(np.abs(d) > 1e-10 * uscale, np.abs(rT + mu * p * np.sign(d)), 0.0))) / rscale]
        viol = float(max(v))
        if viol > 1e-9:
            raise ContactSolveError(f"the exact-gap contact increment violates Signorini-Coulomb at the exact "
                                    f"geometry (violation {viol:.3g} after {lin} linearisations)")
        self._check_ends(x, closed | (p > 1e-12 * rscale))
        arc = self.obstacle.arc(x)
        uT = ul[0::2]
        return IncrementResult(u_T=uT, u_N=-g, r_T=rT.copy(), r_N=rN.copy(), slip_increment=d,
                               iterations=its, method=f"{method}, {lin} exact-gap linearisation(s)", violation=viol,
                               extra={"u_system": u.copy(),
                                      "curved_contact": {"frame": abcd.tolist(), "gap": g.tolist(), "u_system": u.tolist(),
                                                         "arc": arc.tolist(), "linearisations": lin,
                                                         "curvature": self.obstacle.curvatures(x).tolist()}})

    def _check_ends(self, x: np.ndarray, touching: np.ndarray) -> None:
        """A node in contact whose closest point is an end of an open curve has slid past the end:
        the obstacle has a corner there (no normal), which the model does not include."""
        at_end = getattr(self.obstacle, "at_end", None)
        if at_end is None:
            return                                        # a circle has no ends
        past = at_end(x) & touching
        if np.any(past):
            i = int(np.flatnonzero(past)[0])
            raise ContactSolveError(f"contact node {i} at {point_text(x[i], self.extent)} has slid past an end of the curve "
                                    f"'{getattr(self.obstacle, 'name', 'obstacle')}': its contact point would be the "
                                    "curve's end, a corner this model does not include (extend the curve)")

    def destroy(self) -> None:
        """Nothing to free (each linearisation's flat solver is freed with its increment); kept for the
        calling convention of :class:`FrictionalContact`."""
        pass
