"""The bordered MCP of Propositions 1-2 (paper eqs. (27)-(34)) on PETSc objects, solved by SNES VI.

``F(z)`` and ``J(z)`` of the MCP in ``z = (x_f, x_c, t)`` for the pencil ``A0 + t A1``, the lifts
of a start through the free rows (one factorisation of ``A_ff(t)`` per ``t``, kept), one SNES VI
run from a start, and the check of a converged point (:class:`app.analyses.snes_vi.results.McpSolution`).
The search over starts and intervals is :func:`app.analyses.snes_vi.search.search_mceip`.
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from app.analyses.pencils.reduced import axpy_structure
from app.analyses.snes_vi.results import McpSolution
from app.linalg import configure_direct, from_options, lu_solver, set_linesearch, snes_solve, with_prefix
from app.scene.schema import McpSettings

RSLS, SSLS = "vinewtonrsls", "vinewtonssls"
MAX_LIFT_FACTORS = 16   # factorisations of A_ff(t) kept per problem (lifts at a t already seen reuse them)


class BorderedMcp:
    """The MCP function F(z) and Jacobian J(z) of Propositions 1-2 on PETSc objects.

    ``t = t_bar + sigma * zeta`` with the MCP variable ``zeta`` in ``[0, zeta_max]``; the
    plain problem is ``t_bar = 0, sigma = +1``. Distributed like ``A0``; the ``zeta`` row lives
    on the last rank. ``pivoting``: the linear solves pivot (MUMPS), for matrices with a
    saddle-point block (the mixed element's pressure), which an unpivoted LU cannot factorise.
    """

    def __init__(self, A0: PETSc.Mat, A1: PETSc.Mat, comp: np.ndarray, c: float = 1.0,
                 pairs: list[tuple[int, int]] | None = None, pivoting: bool = False):
        self.comm = A0.getComm().tompi4py()
        self.pivoting = pivoting
        self.pairs = list(pairs or [])   # (a, b) positions of split tangential rates (zero nodes)
        self.A0, self.A1, self.c = A0, A1, c
        self.n = A0.getSize()[0]
        self.r0, self.r1 = A0.getOwnershipRange()
        self.nloc = self.r1 - self.r0
        self.last = self.comm.size - 1
        self.is_last = self.comm.rank == self.last
        self.comp = np.asarray(comp, dtype=np.int64)
        self.comp_local = self.comp[(self.comp >= self.r0) & (self.comp < self.r1)] - self.r0
        self.tbar, self.sigma = 0.0, 1.0

        # Union sparsity pattern of A0 and A1 (plus the diagonal), values aligned on it.
        B = A0.copy()
        B.axpy(1.0, A1, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        B.shift(0.0)
        C0, C1 = B.duplicate(copy=False), B.duplicate(copy=False)
        C0.zeroEntries()
        C1.zeroEntries()
        C0.axpy(1.0, A0, structure=PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
        C1.axpy(1.0, A1, structure=PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
        I, J, self.V0 = C0.getValuesCSR()
        _, _, self.V1 = C1.getValuesCSR()
        self.I, self.Jc = I, J
        free_local = np.setdiff1d(np.arange(self.r0, self.r1), self.comp)
        self.has_free = self.comm.allreduce(len(free_local)) > 0           # MPI collective
        self.is_f = PETSc.IS().createGeneral(free_local.astype(PETSc.IntType), comm=self.comm)
        self.free_mask = np.ones(self.n, dtype=bool)
        self.free_mask[self.comp] = False
        for m in (B, C0, C1):
            m.destroy()
        # Bordered pattern: one extra column (index n) per row, one extra row on the last rank.
        self.ins = I[1:]
        Jb = np.insert(J, self.ins, self.n)
        Ib = I + np.arange(len(I), dtype=I.dtype)
        if self.is_last:
            extra = np.concatenate([self.comp, [self.n]]).astype(J.dtype)
            Jb = np.concatenate([Jb, extra])
            Ib = np.concatenate([Ib, [Ib[-1] + len(extra)]]).astype(I.dtype)
        self.Ib, self.Jb = Ib, Jb
        nb_loc = self.nloc + (1 if self.is_last else 0)
        self.sizes = ((nb_loc, self.n + 1), (nb_loc, self.n + 1))
        self.dense = self.comm.size == 1 and len(Jb) > 0.3 * (self.n + 1) ** 2
        if self.dense:   # small, nearly full problems (the condensed pencils): dense LU is faster
            self.J = PETSc.Mat().createDense(self.sizes, comm=self.comm)
            self.J.setUp()
            self.J.assemble()
        else:
            self.J = PETSc.Mat().createAIJ(self.sizes, csr=(Ib, Jb, np.zeros(len(Jb))), comm=self.comm)
            self.J.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
        self.F = self.J.createVecLeft()
        self.v = A0.createVecRight()
        self.y0 = A0.createVecLeft()
        self.y1 = A0.createVecLeft()
        # Positions of the A-values and of the border column in the bordered CSR values (no
        # np.insert per Jacobian) and, for the dense Jacobian, their (row, column) pairs.
        border = self.ins + np.arange(len(self.ins))
        self.nvals = len(J) + len(self.ins)
        self.pos_border = border
        self.pos_main = np.setdiff1d(np.arange(self.nvals), border)
        if self.dense:
            self.dense_rows = np.repeat(np.arange(len(self.Ib) - 1), np.diff(self.Ib))
        self.one_rank = self.comm.size == 1
        # Work objects kept for every run (vectors, bounds; the SNES is one per run, see solve()).
        self.X = self.J.createVecRight()
        self.xl, self.xu = self.X.duplicate(), self.X.duplicate()
        self._lifts: dict[float, tuple] = {}      # t -> (KSP, A_ff(t)): one factorisation per t
        self._ff = None                           # (A0_ff, A1_ff), built on the first lift
        self.history: list[float] = []
        self.stagnation = 0                        # iterations without progress that stop a run (0: off)

    # -- evaluation --------------------------------------------------------------------------
    def _split(self, X: PETSc.Vec) -> float:
        xa = X.getArray(readonly=True)
        self.v.setArray(xa[:self.nloc])
        zeta = float(xa[-1]) if self.is_last else 0.0
        if not self.one_rank:
            zeta = self.comm.bcast(zeta, root=self.last)            # MPI collective
        self.A0.mult(self.v, self.y0)
        self.A1.mult(self.v, self.y1)
        return self.tbar + self.sigma * zeta

    def residual(self, snes, X: PETSc.Vec, F: PETSc.Vec) -> None:
        """SNES function: ``F(z) = ((A0 + t A1) x, sum(x_c) - c)`` at ``z = (x, zeta)``, with
        ``t = t_bar + sigma * zeta``; the last row, the normalisation of ``x_c``, lives on the last
        rank (MPI collective)."""
        t = self._split(X)
        xa = X.getArray(readonly=True)
        csum = float(np.sum(xa[self.comp_local]))
        if not self.one_rank:
            csum = self.comm.allreduce(csum)                         # MPI collective
        fa = F.getArray()
        with np.errstate(invalid="ignore", over="ignore"):   # a diverging t: the run fails, the search goes on
            fa[:self.nloc] = self.y0.getArray(readonly=True) + t * self.y1.getArray(readonly=True)
        if self.is_last:
            fa[-1] = csum - self.c

    def jacobian(self, snes, X: PETSc.Vec, J: PETSc.Mat, P: PETSc.Mat) -> None:
        """SNES Jacobian: ``P`` assembled as ``[A0 + t A1, sigma A1 x]`` with, on the last rank, the
        border row (ones on the complementarity columns, 0 on ``zeta``); ``P`` is the matrix ``J`` the
        SNES was given (MPI collective)."""
        t = self._split(X)
        vals = np.empty(self.nvals + (len(self.comp) + 1 if self.is_last else 0))
        vals[self.pos_main] = self.V0 + t * self.V1
        vals[self.pos_border] = self.sigma * self.y1.getArray(readonly=True)
        if self.is_last:
            vals[self.nvals:-1] = 1.0
            vals[-1] = 0.0
        if self.dense:
            P.zeroEntries()
            P.getDenseArray()[self.dense_rows, self.Jb] = vals
        else:
            P.setValuesCSR(self.Ib, self.Jb, vals)
        P.assemble()

    def _converged(self, snes, its: int, norms: tuple, settings: McpSettings) -> int:
        """PETSc's SNESConvergedDefault (same tests, same order) plus an optional stagnation stop:
        a run whose residual norm has not halved in ``self.stagnation`` iterations is stopped
        (reported as DIVERGED_MAX_IT: a failed run, exactly what it would have become)."""
        xnorm, snorm, fnorm = norms
        if its == 0:
            self.history = []
            self._ttol = fnorm * settings.rtol
        self.history.append(fnorm)
        if not np.isfinite(fnorm):
            return PETSc.SNES.ConvergedReason.DIVERGED_FNORM_NAN
        if fnorm < self._atol:                       # (SNESSetForceIteration is never set here)
            return PETSc.SNES.ConvergedReason.CONVERGED_FNORM_ABS
        if snes.getFunctionEvaluations() >= self._max_funcs:
            return PETSc.SNES.ConvergedReason.DIVERGED_FUNCTION_COUNT
        if its:
            if fnorm <= self._ttol:
                return PETSc.SNES.ConvergedReason.CONVERGED_FNORM_RELATIVE
            if snorm < settings.stol * xnorm:
                return PETSc.SNES.ConvergedReason.CONVERGED_SNORM_RELATIVE
            if fnorm > 1e4 * self.history[0]:
                return PETSc.SNES.ConvergedReason.DIVERGED_DTOL
            k = self.stagnation
            if k and its >= k and min(self.history[-k:]) > 0.5 * min(self.history[:-k]):
                return PETSc.SNES.ConvergedReason.DIVERGED_MAX_IT
        return PETSc.SNES.ConvergedReason.ITERATING

    def _solver(self, method: str, settings: McpSettings) -> PETSc.SNES:
        """A new SNES of ``method`` for one run (destroyed by :meth:`solve`)."""
        snes = with_prefix(PETSc.SNES().create(self.comm), "cd_mcp_")
        try:
            snes.setType(method)
            snes.setFunction(self.residual, self.F)
            snes.setJacobian(self.jacobian, self.J)
            snes.setTolerances(rtol=settings.rtol, atol=1e-13, stol=settings.stol, max_it=settings.max_it)
            snes.setMaxFunctionEvaluations(100 * settings.max_it)
            self._atol, self._max_funcs = 1e-13, 100 * settings.max_it
            snes.setConvergenceTest(self._converged, args=(settings,))
            # serial: minimum-degree ordering (3x less fill than nd with the dense border), tiny pivot shift
            if self.pivoting:
                configure_direct(snes.getKSP(), mumps=True)
            else:
                configure_direct(snes.getKSP(), shift=1e-14, ordering="qmd")
            from_options(snes)
            if method == RSLS and settings.rsls_linesearch != "bt":
                set_linesearch(snes, settings.rsls_linesearch)
        except BaseException:
            snes.destroy()
            raise
        return snes

    # -- one SNES VI run ---------------------------------------------------------------------
    def solve(self, method: str, x0_c: np.ndarray, zeta0: float, tbar: float, sigma: float,
              zeta_max: float, settings: McpSettings,
              x_full: np.ndarray | None = None) -> tuple[np.ndarray, float, int, int]:
        """Run one SNES VI solve; returns (x replicated, t, converged reason, iterations).

        The start is ``x_c = x0_c`` scaled to ``e^T x_c = c`` and ``x_f = 0``, or ``x_full``.
        """
        self.tbar, self.sigma = tbar, sigma
        X, xl, xu = self.X, self.xl, self.xu
        lo = np.full(X.getLocalSize(), PETSc.NINFINITY)
        hi = np.full(X.getLocalSize(), PETSc.INFINITY)
        lo[self.comp_local] = 0.0
        x = np.zeros(X.getLocalSize())
        if x_full is not None:
            x[:self.nloc] = x_full[self.r0:self.r1]
        else:
            mine = (self.comp >= self.r0) & (self.comp < self.r1)
            x[self.comp_local] = x0_c[mine] * self.c / max(np.sum(x0_c), 1e-300)
        if self.is_last:
            lo[-1], hi[-1], x[-1] = 0.0, zeta_max, zeta0
        xl.setArray(lo)
        xu.setArray(hi)
        X.setArray(x)
        snes = self._solver(method, settings)
        try:
            snes.setVariableBounds(xl, xu)
            snes_solve(snes, None, X)      # the interpreter released: progress and signals go on
            reason, its = snes.getConvergedReason(), snes.getIterationNumber()
        except PETSc.Error:          # e.g. a zero pivot in a dense reduced Jacobian: a failed run
            reason, its = -3, snes.getIterationNumber()
        finally:
            # One SNES per run: reusing it across runs crashed (memory corruption) after a run
            # that ended in a PETSc error on small dense problems, so it is not kept.
            snes.destroy()
        z = X.getArray(readonly=True).copy()
        if not self.one_rank:
            z = np.concatenate(self.comm.allgather(z))                 # MPI collective
        return z[:self.n], tbar + sigma * float(z[self.n]), reason, its

    def _free_blocks(self):
        """``A0_ff``, ``A1_ff`` (free rows and columns), built once for the lifts."""
        if self._ff is None:
            A0ff = self.A0.createSubMatrix(self.is_f, self.is_f)
            A1ff = self.A1.createSubMatrix(self.is_f, self.is_f)
            self._ff = (A0ff, A1ff)
            self._ff_structure = axpy_structure(A0ff, A1ff)
        return self._ff

    def _lift_solver(self, t: float) -> PETSc.KSP:
        """LU of ``A_ff(t) = A0_ff + t A1_ff``, factorised once per ``t`` and kept (at most
        ``MAX_LIFT_FACTORS`` of them, oldest dropped first)."""
        hit = self._lifts.get(t)
        if hit is not None:
            return hit[0]
        A0ff, A1ff = self._free_blocks()
        Aff = A0ff.copy()
        Aff.axpy(t, A1ff, structure=self._ff_structure)
        try:
            ksp = lu_solver(Aff, prefix="cd_mcp_free_", mumps=True if self.pivoting else None)
        except BaseException:
            Aff.destroy()
            raise
        if len(self._lifts) >= MAX_LIFT_FACTORS:
            old = next(iter(self._lifts))
            for obj in self._lifts.pop(old):
                obj.destroy()
        self._lifts[t] = (ksp, Aff)
        return ksp

    def lift(self, x0_c: np.ndarray, t: float) -> np.ndarray:
        """Full start vector with the given ``x_c`` and ``x_f`` solving the free rows at ``t``:
        ``A_ff(t) x_f = -A_fc(t) x_c`` (one sparse LU per distinct ``t``, reused), so starts are
        as good as condensed ones."""
        x = np.zeros(self.n)
        x[self.comp] = x0_c
        if not self.has_free:
            return x
        ksp = self._lift_solver(t)
        self.v.setArray(x[self.r0:self.r1])
        self.A0.mult(self.v, self.y0)
        self.A1.mult(self.v, self.y1)
        fidx = self.is_f.getIndices() - self.r0
        rhs, xf = ksp.getOperators()[0].createVecs()
        try:
            rhs.setArray(-(self.y0.getArray(readonly=True)[fidx] + t * self.y1.getArray(readonly=True)[fidx]))
            ksp.solve(rhs, xf)
            local = np.zeros(self.nloc)
            local[fidx] = xf.getArray(readonly=True)
        finally:
            rhs.destroy()
            xf.destroy()
        full = local if self.one_rank else np.concatenate(self.comm.allgather(local))  # MPI collective
        x[self.free_mask] = full[self.free_mask]
        return x

    def consistent_t(self, x0_c: np.ndarray, t_guess: float = 1.0, lifts: int = 2) -> tuple[float | None, np.ndarray]:
        """Least-squares eigenvalue guess for a start: ``t`` minimising ``|((A0 + t A1) x)_P|``
        over the rows ``P`` where ``x0_c > 0``, with ``x_f`` lifted (:meth:`lift`) at the current
        guess; returns (t or None when it is not positive, the lifted start)."""
        t = t_guess
        for _ in range(lifts):
            x = self.lift(x0_c, t)
            self.v.setArray(x[self.r0:self.r1])
            self.A0.mult(self.v, self.y0)
            self.A1.mult(self.v, self.y1)
            mine = (self.comp >= self.r0) & (self.comp < self.r1) & (x0_c > 0)
            rows = self.comp[mine] - self.r0
            a0 = self.y0.getArray(readonly=True)[rows]
            a1 = self.y1.getArray(readonly=True)[rows]
            num, den = float(a0 @ a1), float(a1 @ a1)
            if not self.one_rank:
                num = self.comm.allreduce(num)                            # MPI collective
                den = self.comm.allreduce(den)                            # MPI collective
            t_new = -num / den if den > 0 else -1.0
            if t_new <= 0:
                return None, x
            t = t_new
        return t, self.lift(x0_c, t)

    def _apply(self, x: np.ndarray, t: float) -> np.ndarray:
        """``y = (A0 + t A1) x``, replicated."""
        self.v.setArray(x[self.r0:self.r1])
        self.A0.mult(self.v, self.y0)
        self.A1.mult(self.v, self.y1)
        with np.errstate(invalid="ignore", over="ignore"):   # a diverging t: rejected by the checks
            y = self.y0.getArray(readonly=True) + t * self.y1.getArray(readonly=True)
        return y if self.one_rank else np.concatenate(self.comm.allgather(y))   # MPI collective

    def _measure(self, x: np.ndarray, t: float) -> tuple[np.ndarray, float, float, float, float]:
        y = self._apply(x, t)
        xc, yc = x[self.comp], y[self.comp]
        return (y, float(np.max(np.abs(y[self.free_mask]), initial=0.0)),
                float(np.max(np.abs(xc * yc), initial=0.0)), float(np.min(xc)), float(np.min(yc)))

    def check(self, x: np.ndarray, t: float, tol: float) -> McpSolution | None:
        """Check a candidate against (12)-(14)/(21)-(23) in the scaled problem; None if not a solution.

        The pattern is part of the answer: ``slip`` where ``x_c > 0``, ``stick`` where ``x_c = 0``
        (entries below zero within the tolerance are set to 0), and it must solve its own
        restricted eigenproblem (25)-(26): ``|y| <= tol`` on the free and slip rows, ``y >= -tol``
        on the stick rows. A candidate whose tiny positive entries (at most ``sqrt(tol)`` of the
        largest) are really stick is reported with them set to 0 when that vector passes the same
        test; otherwise it is kept and flagged ``pattern_verified = False`` (ill-conditioned).
        """
        x = x.copy()
        for ia, ib in self.pairs:     # v_T = a - b: remove the spurious common part min(a, b)
            m = min(x[ia], x[ib])
            if m > 0:
                x[ia] -= m
                x[ib] -= m
        xc = x[self.comp]
        total = float(np.sum(xc))
        if not np.isfinite(t) or t < -tol or total <= 0 or not np.all(np.isfinite(x)):
            return None
        x = x / total
        y, res, compl, min_x, min_y = self._measure(x, t)
        if res > tol or compl > tol or min_x < -tol or min_y < -tol:
            return None

        def restricted(xv: np.ndarray, yv: np.ndarray) -> float:
            on = xv[self.comp] > 0
            return float(max(np.max(np.abs(yv[self.free_mask]), initial=0.0),
                             np.max(np.abs(yv[self.comp][on]), initial=0.0),
                             np.max(-yv[self.comp][~on], initial=0.0)))

        xr = x.copy()
        xr[self.comp] = np.maximum(x[self.comp], 0.0)
        yr = self._apply(xr, t)
        pres = restricted(xr, yr)
        verified = pres <= tol
        if not verified:
            xs = xr.copy()
            small = xs[self.comp] <= np.sqrt(tol) * np.max(xs[self.comp])
            xs[self.comp[small]] = 0.0
            xs /= float(np.sum(xs[self.comp]))
            ys, r2, c2, mx2, my2 = self._measure(xs, t)
            p2 = restricted(xs, ys)
            if p2 <= tol and r2 <= tol and c2 <= tol and my2 >= -tol:
                xr, pres, verified = xs, p2, True
                res, compl, min_x, min_y = r2, c2, mx2, my2
        xc = xr[self.comp]
        pattern = ["slip" if v > 0 else "stick" for v in xc]
        return McpSolution(value=max(t, 0.0), x_c=xc.copy(), pattern=pattern, residual=res,
                           complementarity=compl, min_x=min_x, min_y=min_y, x=xr,
                           pattern_residual=pres, pattern_verified=bool(verified))

    def destroy(self) -> None:
        """Destroy the PETSc objects of the problem: the kept factorisations of ``A_ff(t)``, the free
        blocks, the Jacobian and the work vectors (collective)."""
        for pair in self._lifts.values():
            for obj in pair:
                obj.destroy()
        for obj in (self._ff or ()):
            obj.destroy()
        for obj in (self.J, self.F, self.v, self.y0, self.y1, self.is_f, self.X, self.xl, self.xu):
            obj.destroy()
        self._lifts, self._ff = {}, None
