"""One quasi-static increment of node-to-flat Signorini contact with Coulomb friction.

Unknowns per contact node ``i`` (paper axes): the gap ``g_i = -u_N,i`` (bounded below by 0)
and the slip increment ``d_i`` (free), ``u_T,i = u_T,i^prev + d_i``. The reactions follow from
the contact displacements through the contact stiffness ``Kc = W^-1``:
``r = Kc (u_c - u0(load))``, ``p = -r_N``. The increment is the mixed complementarity problem

    0 <= g ⊥ p >= 0                                           (Signorini, eq. (1))
    r_T - proj_[-mu p+, mu p+](r_T - c d) = 0                 (time-discrete Coulomb law (2))

(the tangential condition is the standard semismooth projection form: inside the cone d = 0,
on it r_T = -mu p sign(d)). It is solved exactly with PETSc SNES VI (``vinewtonrsls``, with
``vinewtonssls`` as a fallback) on the small dense problem, replicated on every rank, and the
result is checked against the complementarity conditions. Writing the tangential law as an
equation avoids the degenerate split d = a - b of the LCP form, whose reduced Jacobians are
singular at free nodes.
"""
from __future__ import annotations

from contextlib import ExitStack
from dataclasses import dataclass
from typing import Optional

import numpy as np
from petsc4py import PETSc

from app.common.interrupt import checkpoint
from app.linalg import configure_direct, from_options, one_blas_thread, owned, set_linesearch, with_prefix


@dataclass
class IncrementResult:
    """One contact increment, per contact node in its contact frame (paper axes): displacements
    ``u_T``, ``u_N`` (``u_N = -g``, minus the gap), reactions ``r_T``, ``r_N``, the slip increment
    ``d`` since the previous state; the solver's iterations and method, the largest violation of
    (1)-(2) relative to the reaction scale, and the solver's own records (``extra``)."""

    u_T: np.ndarray
    u_N: np.ndarray
    r_T: np.ndarray
    r_N: np.ndarray
    slip_increment: np.ndarray
    iterations: int
    method: str
    violation: float              # largest violation of (1)-(2), relative to the reaction scale
    extra: Optional[dict] = None  # solver-specific records (the exact-gap solver of app/loading/curved.py)


class ContactSolveError(RuntimeError):
    """A contact increment that no solver run brought to the conditions (1)-(2) (on a curved
    obstacle also: one whose exact geometry breaks them, or a node slid past an end of the curve);
    the loading path ends there, with the message as its failure."""

    pass


# SNES VI runs tried in turn until one satisfies (1)-(2): the reduced-space method with PETSc's
# backtracking line search, the semismooth one, then the reduced-space method with full Newton
# steps. The last is what a floating body on a weak foundation needs at gross sliding: the slip
# increment (excess force / k) is far from the previous state, Kc has a nearly rigid tangential
# mode (condition number ~ E / (k L^2)), and backtracking stalls on the first (too long) steps
# while full steps of the piecewise linear problem find the active set.
ATTEMPTS = (("vinewtonrsls", "bt"), ("vinewtonssls", "bt"), ("vinewtonrsls", "basic"))


class FrictionalContact:
    """Incremental frictional contact on the contact stiffness (one instance per study)."""

    def __init__(self, Kc: np.ndarray, mu: float):
        n = Kc.shape[0] // 2
        self.n, self.mu = n, mu
        self.kscale = float(np.max(np.abs(np.diag(Kc))))
        self.Kc = Kc / self.kscale                       # scaled: forces in mm
        # u_c = P z + u_fixed,  z = (g, d)
        P = np.zeros((2 * n, 2 * n))
        P[1::2, :n] = -np.eye(n)
        P[0::2, n:] = np.eye(n)
        self.KP = self.Kc @ P
        self.row_abs = np.abs(self.KP).sum(axis=1)      # for the rounding floor: its row sums, not |KP| kept
        self.base = np.zeros(2 * n)
        self.J = PETSc.Mat().createDense((2 * n, 2 * n), comm=PETSc.COMM_SELF)
        self.J.setUp()
        self.J.assemble()

    def _reactions(self, z: np.ndarray) -> np.ndarray:
        return self.KP @ z + self.base

    def _F(self, z: np.ndarray) -> np.ndarray:
        n, mu = self.n, self.mu
        r = self._reactions(z)
        rT, p = r[0::2], -r[1::2]
        d = z[n:]
        bound = mu * np.maximum(p, 0.0)
        return np.concatenate([p, rT - np.clip(rT - d, -bound, bound)])

    def _residual(self, snes, X, F):
        F.setArray(self._F(X.getArray(readonly=True)))

    def _jacobian(self, snes, X, J, Pm):
        n, mu = self.n, self.mu
        z = X.getArray(readonly=True)
        r = self._reactions(z)
        rT, p = r[0::2], -r[1::2]
        w = rT - z[n:]
        dT, dN = self.KP[0::2], self.KP[1::2]
        b = mu * np.maximum(p, 0.0)
        stick = (-b < w) & (w < b)                     # F = c d
        slip = ~stick & (p > 0)                        # F = r_T -/+ mu p; otherwise no pressure: F = r_T
        Jd = Pm.getDenseArray()                        # the dense matrix's own storage
        Jd[:n] = -dN
        Jd[n:] = dT
        Jd[n:][slip] += np.where(w[slip] >= b[slip], mu, -mu)[:, None] * dN[slip]
        Jd[n:][stick] = 0.0
        i = np.flatnonzero(stick)
        Jd[n + i, n + i] = 1.0
        Pm.assemble()

    def _snes(self, method: str, z0: np.ndarray, atol: float, linesearch: str = "bt") -> tuple[np.ndarray, int, int]:
        m = 2 * self.n
        with ExitStack() as owns:
            X = owns.enter_context(owned(PETSc.Vec().createSeq(m, comm=PETSc.COMM_SELF)))
            X.setArray(z0)
            lo, hi, F = (owns.enter_context(owned(X.duplicate())) for _ in range(3))
            lo.setArray(np.concatenate([np.zeros(self.n), np.full(self.n, PETSc.NINFINITY)]))
            hi.set(PETSc.INFINITY)
            snes = owns.enter_context(owned(with_prefix(PETSc.SNES().create(PETSc.COMM_SELF), "cd_loading_")))
            snes.setType(method)
            snes.setFunction(self._residual, F)
            snes.setJacobian(self._jacobian, self.J)
            snes.setVariableBounds(lo, hi)
            snes.setTolerances(rtol=1e-14, atol=atol, stol=1e-16, max_it=100)
            configure_direct(snes.getKSP(), mumps=False)
            from_options(snes)
            if linesearch != "bt":
                set_linesearch(snes, linesearch)
            snes.solve(None, X)
            return X.getArray().copy(), snes.getConvergedReason(), snes.getIterationNumber()

    def rounding_floor(self, z: np.ndarray) -> float:
        """The rounding of the residual's 2-norm near ``z``: the reactions ``KP z + base`` carry an
        error of about ``sqrt(2n) u (|KP| |z| + |base|)`` per entry (the probabilistic bound of
        Higham and Mary, ``sqrt(k) u`` for the ``k u`` of the worst case, ``k`` terms per entry),
        here with ``|KP| |z|`` bounded by the row sums of ``|KP|`` times ``max |z|``, and doubled
        for the clip. Newton reaches it in one step once the active set is right (the problem is
        piecewise linear) and cannot go below it. An absolute tolerance under it is never met: the
        next step's line search fails and SNES VI returns a point far from the solution it had
        found. On meshes graded towards a corner (large gaps beside tiny reactions) that sent most
        increments through every fallback, 100 iterations each."""
        u = np.finfo(float).eps / 2
        per_entry = np.sqrt(2 * self.n) * u * (self.row_abs * np.max(np.abs(z), initial=0.0) + np.abs(self.base))
        return 2.0 * float(np.linalg.norm(per_entry))

    def violation(self, z: np.ndarray, scale: float, u_scale: float = 0.0) -> float:
        """Largest violation of g >= 0, p >= 0, g p = 0, |r_T| <= mu p and of the slip rule. A
        slip increment counts as sliding above 1e-12 of the largest one and above 1e-13 of the
        contact displacements' scale ``u_scale`` (below that it is the rounding of the
        displacements themselves: the tiny increments of a perturbed state's dynamics)."""
        n, mu = self.n, self.mu
        r = self._reactions(z)
        rT, p = r[0::2], -r[1::2]
        g, d = z[:n], z[n:]
        dscale = max(float(np.max(np.abs(d), initial=0.0)), 1e-300, 10.0 * u_scale)
        v = [-np.min(g) / max(np.max(np.abs(g)), 1e-300) if np.min(g) < 0 else 0.0,
             -np.min(p) / scale, np.max(np.abs(g * p)) / (scale * max(np.max(np.abs(g)), 1e-300)),
             np.max(np.abs(rT) - mu * p) / scale,
             # sliding nodes carry r_T = -mu p sign(d)
             np.max(np.where(np.abs(d) > 1e-12 * dscale, np.abs(rT + mu * p * np.sign(d)), 0.0)) / scale]
        return float(max(0.0, *v))

    def solve(self, u0: np.ndarray, u_T_prev: np.ndarray, g_prev: np.ndarray,
              d_prev: np.ndarray | None = None) -> IncrementResult:
        """Equilibrium for the contact displacements ``u0`` caused by the load with r = 0.

        The Newton iteration starts from the previous gaps ``g_prev`` and slip increments
        ``d_prev`` (the previous increment's ``slip_increment``; zero when None): along a steady
        loading the nodes that slid keep sliding by about the same amount, so the start is
        near the new active set."""
        checkpoint()                  # a Ctrl-C whose KeyboardInterrupt was swallowed (app/common/interrupt.py)
        # the dense 2n x 2n work (LU factorisations, products with Kc) is 2-3x faster on one BLAS
        # thread on this kind of machine
        with one_blas_thread():
            return self._solve(u0, u_T_prev, g_prev, d_prev)

    def _solve(self, u0, u_T_prev, g_prev, d_prev) -> IncrementResult:
        n = self.n
        u_fixed = np.zeros(2 * n)
        u_fixed[0::2] = u_T_prev
        self.base = self.Kc @ (u_fixed - u0)
        scale = max(float(np.max(np.abs(self.base))), 1e-300)
        u_scale = max(float(np.max(np.abs(u0), initial=0.0)), float(np.max(np.abs(u_T_prev), initial=0.0)))
        z0 = np.concatenate([g_prev, np.zeros(n) if d_prev is None else d_prev])
        atol = max(1e-14 * scale, self.rounding_floor(z0))
        best = None
        for method, linesearch in ATTEMPTS:
            z, reason, its = self._snes(method, z0, atol, linesearch)
            viol = self.violation(z, scale, u_scale) if np.all(np.isfinite(z)) else np.inf
            if best is None or viol < best[1]:
                best = (z, viol, its, method if linesearch == "bt" else f"{method} ({linesearch} line search)")
            if viol <= 1e-9:
                break
        z, viol, its, method = best
        if viol > 1e-9:
            cond = np.linalg.cond(self.Kc)
            hint = (f"; the contact stiffness is ill-conditioned (condition number {cond:.2g}): a body held only by "
                    "a weak system.foundation slides by excess force / k, raise it" if cond > 1e8 else "")
            raise ContactSolveError(f"SNES VI did not solve the contact increment (violation {viol:.3g}, tried "
                                    f"{', '.join(m + ('' if ls == 'bt' else ' + ' + ls) for m, ls in ATTEMPTS)}){hint}")
        z[:n] = np.maximum(z[:n], 0.0)
        u_c = u_fixed                                  # u_c = P z + u_fixed: u_T += d, u_N = -g
        u_c[0::2] += z[n:]
        u_c[1::2] = -z[:n]
        r = self._reactions(z) * self.kscale
        return IncrementResult(u_T=u_c[0::2], u_N=u_c[1::2], r_T=r[0::2], r_N=r[1::2],
                               slip_increment=z[n:], iterations=its, method=method, violation=viol)

    def destroy(self) -> None:
        """Free the PETSc Jacobian this solver created."""
        self.J.destroy()

    def __enter__(self) -> "FrictionalContact":
        return self

    def __exit__(self, *exc) -> None:
        self.destroy()
