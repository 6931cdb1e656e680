"""Reduced pencils of an equilibrium state: paper eqs. (10)-(16) (docs/method.md section 2).

For any matrix A of the system (A = K or A = M) the state's classification defines

    A*(mu) = A0 + mu A1,   A0 = D A_kk D,   A1 = -P sign_N A_{Ns,k} D,

where ``k`` are the kept DOFs (everything except the DOFs of stick nodes and the normal DOFs of
slip nodes), ``D = diag(1 on f, -S sign_T on Ts)`` is the change of variables (10), and ``P``
places the normal rows of the slip nodes on the rows of their tangential DOFs (11).
The kept DOFs keep the system's order, so ``A0`` is distributed like ``A``.

For MCEIP-mu the exact condensation onto the slip nodes (docs/method.md section 2) gives the small
dense pencil ``S Ŝ_TT S + mu Ŝ_NT S`` from the contact Schur complement.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from app.loading.classify import FREE, SLIP, STICK, ZERO, Classification
from app.systems.base import System


class UnsupportedState(Exception):
    """The state has a feature the analyses do not handle (reported in the state's results)."""


@dataclass
class ReducedSpace:
    """Kept DOFs of a classified state and where the slip nodes' x_Ts sit among them."""

    kept: PETSc.IS            # system DOFs kept (owned part on each rank), ascending
    n: int                    # global number of kept DOFs (N* of the paper)
    comp: np.ndarray          # global positions of x_Ts in the kept numbering, slip-node order
    slip_nodes: np.ndarray    # indices of the slip nodes (into system.nodes)
    d_local: np.ndarray       # diagonal of D on the owned kept DOFs

    def to_system(self, y: np.ndarray, rows: tuple[int, int]) -> np.ndarray:
        """The kept-space vector ``y`` (this rank's part) as a vector on the system's owned rows
        ``rows = (r0, r1)`` (``x = D y`` on the kept DOFs, zero on the removed ones)."""
        x = np.zeros(rows[1] - rows[0])
        x[self.kept.getIndices() - rows[0]] = self.d_local * y
        return x

    def from_system(self, x: np.ndarray, rows: tuple[int, int]) -> np.ndarray:
        """The kept-space part ``y = D x`` of this rank's system vector ``x`` (inverse of
        :meth:`to_system` on the kept DOFs; ``D`` is its own inverse)."""
        return self.d_local * x[self.kept.getIndices() - rows[0]]

    def positions(self, dofs: np.ndarray) -> np.ndarray:
        """Global positions in the kept numbering of the system DOFs ``dofs`` (all kept, e.g. the
        pressure's). MPI collective (the kept DOFs gathered: the numbering is rank by rank,
        ascending)."""
        kept = np.concatenate(self.kept.getComm().tompi4py().allgather(self.kept.getIndices()))   # MPI collective
        at = np.searchsorted(kept, dofs)
        if len(dofs) and (at.max() >= len(kept) or np.any(kept[at] != dofs)):
            raise ValueError("positions: a DOF that the reduction removed")
        return at

    def destroy(self) -> None:
        """Destroy the PETSc index set of the kept DOFs."""
        self.kept.destroy()


def _check_supported(cls: Classification) -> None:
    if ZERO in cls.status:
        raise UnsupportedState(
            "zero-reaction contact nodes (the paper's set Z) are present; their rate conditions (9) "
            "are not part of the reduced pencils (10)-(16)")


def reduced_space(system: System, cls: Classification) -> ReducedSpace:
    """Kept DOFs ``f + Ts`` of the classified state, as an IS in the system's numbering."""
    _check_supported(cls)
    comm = system.comm
    removed: list[int] = []
    ts_dof: dict[int, int] = {}
    d_ts: dict[int, float] = {}
    for i, (node, st) in enumerate(zip(system.nodes, cls.status)):
        if st == STICK:
            removed += [node.dof_T, node.dof_N]
        elif st == SLIP:
            removed.append(node.dof_N)
            ts_dof[i] = node.dof_T
            d_ts[node.dof_T] = -cls.signs[i] * node.sign_T
    r0, r1 = system.K.getOwnershipRange()
    owned = np.arange(r0, r1, dtype=np.int64)
    kept_local = np.setdiff1d(owned, np.asarray(removed, dtype=np.int64), assume_unique=True)
    offset = comm.exscan(len(kept_local)) or 0          # MPI collective
    n = comm.allreduce(len(kept_local))                  # MPI collective
    slip = cls.slip
    pos_local = {}
    for i in slip:
        dof = ts_dof[int(i)]
        if r0 <= dof < r1:
            pos_local[int(i)] = offset + int(np.searchsorted(kept_local, dof))
    pos_all: dict[int, int] = {}
    for d in comm.allgather(pos_local):                  # MPI collective
        pos_all.update(d)
    comp = np.array([pos_all[int(i)] for i in slip], dtype=np.int64)
    d_local = np.array([d_ts.get(int(dof), 1.0) for dof in kept_local])
    kept = PETSc.IS().createGeneral(kept_local.astype(PETSc.IntType), comm=comm)
    return ReducedSpace(kept=kept, n=n, comp=comp, slip_nodes=slip, d_local=d_local)


def reduced_pencil(A: PETSc.Mat, system: System, cls: Classification,
                   space: ReducedSpace) -> tuple[PETSc.Mat, PETSc.Mat]:
    """``(A0, A1)`` of eq. (16) for the matrix ``A`` (K or M) of ``system``; caller destroys them."""
    comm = system.comm
    A0 = A.createSubMatrix(space.kept, space.kept)
    d = A0.createVecRight()
    d.setArray(space.d_local)
    A0.diagonalScale(d, d)

    # Rows of the slip nodes' normal DOFs, moved to the rows of their x_Ts.
    r0, r1 = A.getOwnershipRange()
    ns_local = [system.nodes[int(i)].dof_N for i in space.slip_nodes if r0 <= system.nodes[int(i)].dof_N < r1]
    is_ns = PETSc.IS().createGeneral(np.asarray(ns_local, dtype=PETSc.IntType), comm=comm)
    ANk = A.createSubMatrix(is_ns, space.kept)
    A1 = PETSc.Mat().createAIJ(A0.getSizes(), comm=comm)
    A1.setPreallocationNNZ(0)
    A1.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    A1.setUp()
    pos = {system.nodes[int(i)].dof_N: (int(p), system.nodes[int(i)].sign_N)
           for i, p in zip(space.slip_nodes, space.comp)}
    q0, q1 = ANk.getOwnershipRange()
    for row, dof in zip(range(q0, q1), ns_local):
        cols, vals = ANk.getRow(row)
        p, sign_n = pos[dof]
        A1.setValues(p, cols, -sign_n * vals)
    A1.assemble()
    A1.diagonalScale(None, d)
    for obj in (d, is_ns, ANk):
        obj.destroy()
    return A0, A1


def combine(A0: PETSc.Mat, A1: PETSc.Mat, mu: float) -> PETSc.Mat:
    """A new matrix ``A0 + mu A1`` (the pencil (15) at a given mu); the caller destroys it."""
    A = A0.copy()
    A.axpy(mu, A1, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    return A


def _same_pattern(A: PETSc.Mat, B: PETSc.Mat) -> bool:
    """Same sparsity pattern on this rank (then ``axpy`` can skip the pattern merge)."""
    ia, ja, _ = A.getValuesCSR()
    ib, jb, _ = B.getValuesCSR()
    return len(ia) == len(ib) and len(ja) == len(jb) and bool(np.all(ia == ib) and np.all(ja == jb))


def axpy_structure(A: PETSc.Mat, B: PETSc.Mat) -> int:
    """The cheapest ``Mat.Structure`` valid for ``A.axpy(a, B)`` (decided on every rank alike)."""
    same = A.getComm().tompi4py().allreduce(_same_pattern(A, B), op=MPI.LAND)   # MPI collective
    return PETSc.Mat.Structure.SAME_NONZERO_PATTERN if same else PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN


def sym_part(A: PETSc.Mat) -> PETSc.Mat:
    """New matrix ``(A + A^T) / 2``, the symmetric part used by (19) and the lambda^2 bounds
    (the caller destroys it)."""
    S = A.copy()
    S.transpose()
    S.axpy(1.0, A, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    S.scale(0.5)
    return S


def diag_scale(A: PETSc.Mat) -> float:
    """Largest diagonal entry in magnitude (the infinity norm if the diagonal is zero): the
    unit-free scale that tolerances are relative to."""
    d = A.getDiagonal()
    try:
        s = d.norm(PETSc.NormType.NORM_INFINITY)
    finally:
        d.destroy()
    return s if s > 0 else max(A.norm(PETSc.NormType.NORM_INFINITY), 1e-300)


def dense(A: PETSc.Mat) -> np.ndarray:
    """Replicated dense copy of a small distributed matrix (MPI collective)."""
    comm = A.getComm().tompi4py()
    m, n = A.getSize()
    r0, r1 = A.getOwnershipRange()
    local = np.zeros((r1 - r0, n))
    for i in range(r0, r1):
        cols, vals = A.getRow(i)
        local[i - r0, cols] = vals
    return np.vstack(comm.allgather(local))


def eliminate_static(K: np.ndarray, M: np.ndarray, static: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Dense ``(K_e, M_kk, keep)``: the static DOFs ``static`` (the mixed element's pressure: no
    mass, ``K_ss`` invertible) eliminated, ``K_e = K_kk - K_ks K_ss^-1 K_sk`` and the mass on the
    kept DOFs ``keep`` (docs/method.md section 10). ``K`` may be a reduced, non-symmetric ``K*(mu)``:
    the reduction leaves the static rows as they are, so this is the eliminated system's."""
    keep = np.setdiff1d(np.arange(K.shape[0]), static)
    Ke = K[np.ix_(keep, keep)] - K[np.ix_(keep, static)] @ np.linalg.solve(K[np.ix_(static, static)],
                                                                          K[np.ix_(static, keep)])
    return Ke, M[np.ix_(keep, keep)], keep


#: up to this size a problem distributed over several ranks is solved whole on every rank
#: (:func:`serial_copy`): its collectives would cost more than the work they share out
REPLICATE_MAX = 2000


def serial_copy(A: PETSc.Mat) -> PETSc.Mat:
    """The whole of a distributed ``A`` as a sequential matrix on every rank (MPI collective; the
    caller owns it), rows and columns in the global numbering."""
    n, m = A.getSize()
    rows = PETSc.IS().createStride(n, 0, 1, comm=PETSc.COMM_SELF)
    cols = rows if m == n else PETSc.IS().createStride(m, 0, 1, comm=PETSc.COMM_SELF)
    try:
        return A.createSubMatrices(rows, cols)[0]
    finally:
        rows.destroy()
        if cols is not rows:
            cols.destroy()


def gather_vec(v: PETSc.Vec) -> np.ndarray:
    """Replicated numpy copy of a distributed vector (MPI collective)."""
    comm = v.getComm().tompi4py()
    return np.concatenate(comm.allgather(v.getArray(readonly=True).copy()))


def condensed_mu_pencil(Sc: np.ndarray, cls: Classification) -> tuple[np.ndarray, np.ndarray]:
    """Exact condensation of MCEIP-mu (21)-(23) onto the slip nodes: ``(S Ŝ_TT S, Ŝ_NT S)``.

    ``Sc`` is the contact Schur complement (paper axes, order T_0, N_0, T_1, ...). Stick DOFs are
    deleted (clamped), the free nodes' DOFs eliminated, and ``Ŝ`` is the Schur complement onto
    the slip nodes' (T, N) DOFs (quotient property of Schur complements).
    """
    _check_supported(cls)
    slip = cls.slip
    free = cls.indices(FREE)
    T = 2 * slip
    N = 2 * slip + 1
    F = np.sort(np.concatenate([2 * free, 2 * free + 1]))
    c = np.concatenate([T, N])
    S_cc = Sc[np.ix_(c, c)]
    if len(F):
        S_cc = S_cc - Sc[np.ix_(c, F)] @ np.linalg.solve(Sc[np.ix_(F, F)], Sc[np.ix_(F, c)])
    s = len(slip)
    S = np.diag(cls.slip_signs)
    A0 = S @ S_cc[:s, :s] @ S
    A1 = S_cc[s:, :s] @ S
    return A0, A1


# --- Zero-reaction nodes (the paper's set Z): the general rate conditions (9) -------------------
#
# For a node in contact with zero reaction the rates satisfy v_N <= 0, w_N <= 0, v_N w_N = 0,
# |w_T| <= -mu w_N, and sliding opposes the tangential reaction rate. With v_T = a - b
# (a, b >= 0) and x_N = -v_N this is complementarity in (a, b, x_N):
#     0 <= a   ⊥  y_a = w_T - mu w_N >= 0      (a > 0: slides in +T, w_T = mu w_N)
#     0 <= b   ⊥  y_b = -w_T - mu w_N >= 0     (b > 0: slides in -T, w_T = -mu w_N)
#     0 <= x_N ⊥  y_N = -w_N >= 0              (lift-off or contact)
# The pencil is then A*(mu) = R(mu) A Q with rectangular Q (v = Q x) and R (y = R w). The split
# of v_T has the spurious null direction a = b: solutions are reported with min(a, b) = 0.


@dataclass
class SplitPencil:
    """Dense pencil (A0, A1) with zero-reaction nodes; x = (x_f, x_c), x_c complementarity block."""

    A0: np.ndarray
    A1: np.ndarray
    comp: np.ndarray                 # positions of x_c in x
    pairs: list[tuple[int, int]]     # positions (a, b) of each zero node's split tangential rate
    labels: list[str]                # what each x_c entry is: "T<node>" (slip), "a<node>", "b<node>", "N<node>"


def split_pencil(A: np.ndarray, T: np.ndarray, N: np.ndarray, sT: np.ndarray, sN: np.ndarray,
                 cls: Classification, f: np.ndarray) -> SplitPencil:
    """``A0 = R0 A Q`` and ``A1 = R1 A Q`` for a dense matrix ``A`` whose node ``i`` has DOFs
    ``T[i], N[i]`` with paper-axis signs ``sT[i], sN[i]``; ``f`` are the DOFs kept as x_f."""
    nf = len(f)
    cols = [("T", i) for i, st in enumerate(cls.status) if st == SLIP]
    cols += [(kind, i) for i, st in enumerate(cls.status) if st == ZERO for kind in ("a", "b", "N")]
    n = nf + len(cols)
    Q = np.zeros((A.shape[0], n))
    R0 = np.zeros((n, A.shape[0]))
    R1 = np.zeros((n, A.shape[0]))
    Q[f, np.arange(nf)] = 1.0
    R0[np.arange(nf), f] = 1.0
    pos = {}
    for k, (kind, i) in enumerate(cols):
        j = nf + k
        pos[(kind, i)] = j
        S = cls.signs[i]
        if kind == "T":                       # slip node: v_T = -S x, y = -(S w_T + mu w_N)
            Q[T[i], j] = R0[j, T[i]] = -S * sT[i]
            R1[j, N[i]] = -sN[i]
        elif kind == "a":                     # v_T += a, y_a = w_T - mu w_N
            Q[T[i], j] = R0[j, T[i]] = sT[i]
            R1[j, N[i]] = -sN[i]
        elif kind == "b":                     # v_T -= b, y_b = -w_T - mu w_N
            Q[T[i], j] = R0[j, T[i]] = -sT[i]
            R1[j, N[i]] = -sN[i]
        else:                                 # v_N = -x_N, y_N = -w_N
            Q[N[i], j] = R0[j, N[i]] = -sN[i]
    pairs = [(j, pos[("b", i)]) for (kind, i), j in pos.items() if kind == "a"]
    AQ = A @ Q
    return SplitPencil(R0 @ AQ, R1 @ AQ, np.arange(nf, n), pairs, [f"{k}{i}" for k, i in cols])


def split_pencils(system: System, cls: Classification, A: np.ndarray | None = None,
                  Sc: np.ndarray | None = None) -> SplitPencil:
    """Dense split pencil of a state with zero-reaction nodes.

    Without ``A``: MCEIP-mu on the contact Schur complement (free nodes eliminated, stick DOFs
    deleted, no x_f; ``Sc``: that complement in other frames, default the system's). With ``A``
    (dense, system DOFs): the full pencil, x_f the DOFs of the free nodes and of the interior.
    """
    nodes = system.nodes
    if A is None:
        Sc = system.contact_schur() if Sc is None else Sc
        free = cls.indices(FREE)
        keep = [i for i, st in enumerate(cls.status) if st in (SLIP, ZERO)]
        F = np.sort(np.concatenate([2 * free, 2 * free + 1])).astype(int)
        c = np.ravel([[2 * i, 2 * i + 1] for i in keep]).astype(int)
        S = Sc[np.ix_(c, c)]
        if len(F):
            S = S - Sc[np.ix_(c, F)] @ np.linalg.solve(Sc[np.ix_(F, F)], Sc[np.ix_(F, c)])
        T = np.full(len(nodes), -1)
        N = np.full(len(nodes), -1)
        for k, i in enumerate(keep):
            T[i], N[i] = 2 * k, 2 * k + 1
        ones = np.ones(len(nodes))
        return split_pencil(S, T, N, ones, ones, cls, np.array([], dtype=int))
    T = np.array([nd.dof_T for nd in nodes])
    N = np.array([nd.dof_N for nd in nodes])
    sT = np.array([nd.sign_T for nd in nodes], dtype=float)
    sN = np.array([nd.sign_N for nd in nodes], dtype=float)
    removed = {int(d) for i, st in enumerate(cls.status) if st in (STICK, SLIP, ZERO) for d in (T[i], N[i])}
    f = np.array(sorted(set(range(A.shape[0])) - removed), dtype=int)
    return split_pencil(A, T, N, sT, sN, cls, f)
