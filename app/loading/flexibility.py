"""Factor K once per study and build the contact flexibility W = B K^-1 B^T (docs/method.md section 2).

For linear elasticity K does not change along the loading, so one sparse LU factorisation
(MUMPS) gives the flexibility of the n contact nodes, the 2n x 2n contact block of K^-1
(:func:`flexibility_inverse`: MUMPS's selected entries of the inverse; on several ranks from a
copy of K gathered on rank 0, :func:`flexibility_gathered`; where neither is available,
:func:`flexibility_matsolve`: block solves with the 2n unit right-hand sides), and,
by two more solves, the contact displacements caused by a unit motion of the loaded side. Every quasi-static increment
is then a small dense complementarity problem, and the contact Schur complement W^-1 feeds the
exact condensation of MCEIP-mu.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from app.linalg import lu_solver


def contact_entries(v: PETSc.Vec, dofs: np.ndarray, signs: np.ndarray) -> np.ndarray:
    """Paper-axis contact entries ``signs * v[dofs]`` of a distributed vector, replicated on every
    rank (MPI collective: each entry comes from its owner)."""
    r0, r1 = v.getOwnershipRange()
    mine = (dofs >= r0) & (dofs < r1)
    local = np.zeros(len(dofs))
    local[mine] = v.getArray(readonly=True)[dofs[mine] - r0]
    return signs * v.getComm().tompi4py().allreduce(local, op=MPI.SUM)     # MPI collective


@dataclass
class ContactFlexibility:
    """Contact flexibility in the paper's axes, order (T_0, N_0, T_1, N_1, ...)."""

    W: np.ndarray                 # u_c = u0x gx + u0y gy + W r   [mm/N]
    u0x: np.ndarray               # contact displacements for a unit gx with r = 0 [mm/mm]
    u0y: np.ndarray
    K: PETSc.Mat                  # the stiffness (not owned)
    dofs: np.ndarray              # system DOFs of (T_0, N_0, T_1, ...)
    signs: np.ndarray             # paper-axis signs of those DOFs
    loads: tuple[PETSc.Vec, PETSc.Vec]
    _ksp: PETSc.KSP | None = None  # factorised K (owned), to rebuild whole fields

    @property
    def ksp(self) -> PETSc.KSP:
        """The factorised K on K's communicator (MPI collective on first use). On several ranks W
        comes from a copy of K on rank 0 (:func:`flexibility_gathered`), so K itself is factorised
        only when whole fields are asked for (ParaView files, screenshots)."""
        if self._ksp is None:
            self._ksp = lu_solver(self.K, prefix="cd_flex_")
        return self._ksp

    @functools.cached_property
    def schur(self) -> np.ndarray:
        """Schur complement of K onto the contact DOFs: W^-1 (symmetrised), computed once."""
        S = np.linalg.inv(self.W)
        return 0.5 * (S + S.T)

    def contact_response(self, b: PETSc.Vec) -> np.ndarray:
        """Paper-axis contact displacements ``B K^-1 b`` with zero reactions (one solve with the
        factorised K; MPI collective)."""
        x = b.duplicate()
        try:
            self.ksp.solve(b, x)
            return contact_entries(x, self.dofs, self.signs)
        finally:
            x.destroy()

    def field(self, gx: float, gy: float, r: np.ndarray) -> PETSc.Vec:
        """Reduced displacement solving K u = gx f_x + gy f_y + B^T (signs * r) (one solve)."""
        return self.response(((gx, self.loads[0]), (gy, self.loads[1])), r)

    def response(self, loads, r: np.ndarray) -> PETSc.Vec:
        """Displacement solving K u = sum_j a_j f_j + B^T (signs * r) for ``loads`` = ((a_j, f_j), ...)
        (one solve with the factorised K; the caller destroys the returned Vec)."""
        rhs = self.ksp.getOperators()[0].createVecLeft()
        try:
            rhs.zeroEntries()
            for a, f in loads:
                if a != 0.0:
                    rhs.axpy(a, f)
            r0, r1 = rhs.getOwnershipRange()
            mine = (self.dofs >= r0) & (self.dofs < r1)
            rhs.setValues(self.dofs[mine].astype(PETSc.IntType), (self.signs * np.asarray(r))[mine],
                          addv=PETSc.InsertMode.ADD_VALUES)
            rhs.assemble()
            u = rhs.duplicate()
            try:
                self.ksp.solve(rhs, u)
            except BaseException:
                u.destroy()
                raise
        finally:
            rhs.destroy()
        return u

    def destroy(self) -> None:
        """Free the factorisation of K this object owns (if it was made)."""
        if self._ksp is not None:
            self._ksp.destroy()
            self._ksp = None

    def __enter__(self) -> "ContactFlexibility":
        return self

    def __exit__(self, *exc) -> None:
        self.destroy()


def flexibility_inverse(ksp: PETSc.KSP, dofs: np.ndarray, signs: np.ndarray) -> np.ndarray | None:
    """W = B K^-1 B^T as the signed contact block of K^-1, computed by MUMPS from its factors
    (:func:`app.loading.mumps_inverse.inverse_block`); None when the factor cannot (MPI collective)."""
    from app.loading.mumps_inverse import inverse_block
    try:
        block = inverse_block(ksp.getPC().getFactorMatrix(), dofs)
    except PETSc.Error:
        block = None
    if not ksp.getComm().tompi4py().allreduce(block is not None, op=MPI.LAND):   # MPI collective
        return None
    return signs[:, None] * block * signs[None, :]


def flexibility_gathered(K: PETSc.Mat, loads: tuple[PETSc.Vec, ...], dofs: np.ndarray,
                         signs: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]] | None:
    """W and the contact displacements of ``loads`` on several ranks: K gathered on rank 0
    (``MatCreateSubMatrices``) and factorised there alone, W taken from MUMPS's selected inverse
    entries (:func:`flexibility_inverse`, which a distributed factor cannot give: a solve after it
    fails in PETSc 3.18), each load solved with the same factors; broadcast to every rank. None
    when that fails (MPI collective). At 10^6 DOFs on 2 ranks this takes seconds where the block
    solves of :func:`flexibility_matsolve` take minutes (one dense solution column per contact DOF)."""
    comm = K.getComm().tompi4py()
    N = K.getSize()[0]
    rows = PETSc.IS().createStride(N if comm.rank == 0 else 0, 0, 1, comm=PETSc.COMM_SELF)
    out = None
    gathered = []
    try:
        for f in loads:                                            # MPI collective: each load on rank 0
            scatter, f0 = PETSc.Scatter.toZero(f)
            gathered.append(f0)
            try:
                scatter.scatter(f, f0, addv=PETSc.InsertMode.INSERT_VALUES, mode=PETSc.ScatterMode.FORWARD)
            finally:
                scatter.destroy()
        (K0,) = K.createSubMatrices(rows, rows)                   # MPI collective: all of K on rank 0
        try:
            if comm.rank == 0:
                out = _on_rank_zero(K0, gathered, dofs, signs)
        finally:
            K0.destroy()
    except PETSc.Error:
        out = None
    finally:
        rows.destroy()
        for f0 in gathered:
            f0.destroy()
    return comm.bcast(out, root=0)                                # MPI collective


def _on_rank_zero(K0: PETSc.Mat, loads: list[PETSc.Vec], dofs: np.ndarray,
                  signs: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]] | None:
    """W and the loads' contact displacements from the whole K on one process (None on failure)."""
    ksp0 = lu_solver(K0, prefix="cd_flex_")
    x = K0.createVecRight()
    try:
        W = flexibility_inverse(ksp0, dofs, signs)
        if W is None:
            return None
        u = []
        for f0 in loads:
            ksp0.solve(f0, x)
            u.append(signs * x.getArray(readonly=True)[dofs])
        return W, u
    finally:
        x.destroy()
        ksp0.destroy()


#: bytes of one chunk's dense solution block (N x columns doubles); bounds the W build's memory
CHUNK_BYTES = 100 * 2**20


def chunk_columns(n_rows: int, n_cols: int, chunk_bytes: int = CHUNK_BYTES) -> int:
    """Right-hand sides per :func:`flexibility_matsolve` chunk: as many as fit in ``chunk_bytes``
    of an ``n_rows``-row dense block of doubles, at least 1, at most ``n_cols``."""
    return int(max(1, min(n_cols, chunk_bytes // (8 * max(n_rows, 1)))))


def flexibility_matsolve(ksp: PETSc.KSP, K: PETSc.Mat, dofs: np.ndarray, signs: np.ndarray,
                         chunk_bytes: int = CHUNK_BYTES) -> np.ndarray | None:
    """W = B K^-1 B^T from the LU factors by chunks of right-hand sides (MPI collective).

    Each chunk is one ``MatMatSolve`` of the factor with a sparse B^T (an AIJ matrix of the
    chunk's columns held on rank 0, passed as its ``MATTRANSPOSEVIRTUAL``: MUMPS's sparse
    right-hand sides, whose forward elimination skips the zero rows) into a distributed dense
    solution of ``chunk_columns`` columns. Every rank keeps the rows of W it owns; one allreduce
    assembles W on all ranks. Returns None when the factor cannot solve a sparse block (a factor
    package other than MUMPS)."""
    comm = K.getComm().tompi4py()
    N = K.getSize()[0]
    r0, r1 = K.getOwnershipRange()
    n2 = len(dofs)
    mine = np.flatnonzero((dofs >= r0) & (dofs < r1))
    host = comm.rank == 0
    nb = chunk_columns(N, n2, chunk_bytes)
    W = np.zeros((n2, n2))
    ok = True
    try:
        F = ksp.getPC().getFactorMatrix()
        for c0 in range(0, n2, nb):
            m = min(nb, n2 - c0)
            # MUMPS reads the sparse right-hand sides on its host: rank 0 holds every row and column
            Bt = PETSc.Mat().createAIJ(((m if host else 0, m), (N if host else 0, N)), nnz=1, comm=K.getComm())
            Bv = X = None
            try:
                if host:
                    rows = np.arange(m + 1, dtype=PETSc.IntType)
                    Bt.setValuesCSR(rows, dofs[c0:c0 + m].astype(PETSc.IntType), signs[c0:c0 + m])
                Bt.assemble()
                Bv = PETSc.Mat().createTranspose(Bt)
                X = PETSc.Mat().createDense(((r1 - r0, N), (PETSc.DECIDE, m)), comm=K.getComm())
                X.setUp()
                X.assemble()
                F.matSolve(Bv, X)
                W[mine, c0:c0 + m] = signs[mine, None] * X.getDenseArray()[dofs[mine] - r0, :]
            finally:
                for obj in (Bt, Bv, X):
                    if obj is not None:
                        obj.destroy()
    except PETSc.Error:
        ok = False
    if not comm.allreduce(ok, op=MPI.LAND):                   # MPI collective
        return None
    return comm.allreduce(W, op=MPI.SUM)                      # MPI collective: each row from its owner


def contact_flexibility(K: PETSc.Mat, load_x: PETSc.Vec, load_y: PETSc.Vec,
                        dofs: np.ndarray, signs: np.ndarray) -> ContactFlexibility:
    """Factor ``K`` and compute W and the unit-load contact displacements (MPI collective)."""
    dofs = np.asarray(dofs, dtype=np.int64)
    signs = np.asarray(signs, dtype=float)
    if K.getComm().getSize() > 1:
        got = flexibility_gathered(K, (load_x, load_y), dofs, signs)   # MPI collective
        if got is not None:
            W, (u0x, u0y) = got
            return ContactFlexibility(W=0.5 * (W + W.T), u0x=u0x, u0y=u0y, K=K, dofs=dofs, signs=signs,
                                      loads=(load_x, load_y))
    ksp = lu_solver(K, prefix="cd_flex_")
    try:
        return _flexibility(ksp, K, load_x, load_y, dofs, signs)
    except BaseException:
        ksp.destroy()
        raise


def _flexibility(ksp: PETSc.KSP, K: PETSc.Mat, load_x: PETSc.Vec, load_y: PETSc.Vec,
                 dofs: np.ndarray, signs: np.ndarray) -> ContactFlexibility:
    """W and the unit-load contact displacements from the factorised ``ksp`` (MPI collective)."""
    x, b = K.createVecRight(), K.createVecLeft()
    # Gather the contact entries of a distributed vector onto every rank.
    seq = PETSc.Vec().createSeq(len(dofs), comm=PETSc.COMM_SELF)
    is_from = PETSc.IS().createGeneral(dofs.astype(PETSc.IntType), comm=PETSc.COMM_SELF)
    scatter = PETSc.Scatter().create(x, is_from, seq, None)

    def contact_values(v: PETSc.Vec) -> np.ndarray:
        scatter.scatter(v, seq, addv=PETSc.InsertMode.INSERT_VALUES, mode=PETSc.ScatterMode.FORWARD)
        return signs * seq.getArray(readonly=True).copy()

    try:
        n2 = len(dofs)
        W = flexibility_inverse(ksp, dofs, signs)
        if W is None:
            W = flexibility_matsolve(ksp, K, dofs, signs)
        if W is None:                     # a factor without sparse block solves: one solve per column
            W = np.zeros((n2, n2))
            r0, r1 = b.getOwnershipRange()
            for j, dof in enumerate(dofs):
                b.zeroEntries()
                if r0 <= dof < r1:
                    b.setValue(int(dof), signs[j])
                b.assemble()
                ksp.solve(b, x)
                W[:, j] = contact_values(x)
        ksp.solve(load_x, x)
        u0x = contact_values(x)
        ksp.solve(load_y, x)
        u0y = contact_values(x)
    finally:
        for obj in (x, b, seq, is_from, scatter):
            obj.destroy()
    W = 0.5 * (W + W.T)
    return ContactFlexibility(W=W, u0x=u0x, u0y=u0y, K=K, dofs=dofs, signs=signs, loads=(load_x, load_y), _ksp=ksp)
