"""Curved rigid obstacles in the stability pencils (docs/method.md section 8).

A node slipping along a rigid curve of signed curvature ``kappa`` (``dN/ds = kappa T``,
``dT/ds = -kappa N``, N the body's outward normal; a circle of radius R: ``kappa = -1/R`` with
the body outside it, ``+1/R`` inside a bore) sees its reaction frame rotate with the contact
point. The rates of the reaction components in the rotating frame are then

    w_T = (A v)_T - kappa r_N v_T,    w_N = (A v)_N + kappa r_T v_T,

and with ``r_T = -mu S r_N`` at impending slip (``P = -r_N > 0``) the reduction (10)-(11)
gives, on the slip nodes' ``x_Ts`` only,

    K*(mu) = K0 + mu K1 + mu^2 K2,   K0 <- K0 + G,   K2 = G,   G = diag(kappa_i P_i).

``kappa_i`` is the curvature at node i's contact point *of the state* (constant on a circle; on a
curve of the Gmsh file it moves with the contact point, app/loading/curve.py). Everything else
(M*, the free and stick DOFs) is unchanged. With a curved obstacle the pencils
depend on the static normal reactions and on the frames at the contact points, so the
classification used to share analyses carries them (:class:`CurvedClassification`).

``frames``: per contact node the frame at its contact point in the system's paper axes,
``(a, b, c, d)`` with ``t' = a T + b N`` and ``n' = c T + d N`` (identity ``(1, 0, 0, 1)``).

Zero-reaction nodes (the paper's set Z, r = 0): the curvature terms above are proportional to
the reaction and vanish, so their rate conditions (9) are the flat ones, written in the frame of
the obstacle at *their* contact point. Their frames are recorded like the slip nodes' and the
split pencil of :func:`app.analyses.pencils.reduced.split_pencil` is built in them
(:mod:`app.analyses.pencils.curved_split`); the slip nodes keep their ``G`` terms.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from app.loading.classify import SLIP, ZERO, Classification

IDENTITY = (1.0, 0.0, 0.0, 1.0)


@dataclass(frozen=True)
class CurvedClassification(Classification):
    """A classification on a curved obstacle: also ``geometric[i] = kappa_i P_i`` (0 off the
    slip nodes) and the contact frames of the slip and zero-reaction nodes (``frames[i]``,
    identity elsewhere: free and stick nodes' frames change no answer)."""

    geometric: tuple[float, ...] = ()
    frames: tuple[tuple[float, float, float, float], ...] = ()

    @property
    def key(self) -> tuple:
        """Equal keys, equal pencils: the statuses and signs, kappa P of the slip nodes and the
        frames of the slip and zero-reaction nodes."""
        return (super().key, tuple(self.geometric), tuple(self.frames))

    def slip_geometric(self) -> np.ndarray:
        """``kappa_i P_i`` of the slip nodes, in slip-node order (the diagonal of ``G``)."""
        return np.array([self.geometric[i] for i in self.slip], dtype=float)

    def rotated(self) -> bool:
        """Whether some slip or zero-reaction node's contact frame differs from the system's node frame."""
        return any(f != IDENTITY for f in self.frames)


def is_curved(cls: Classification) -> bool:
    """Whether the classification is of a state on a curved obstacle (:class:`CurvedClassification`,
    whose pencils carry the curvature terms ``G``)."""
    return isinstance(cls, CurvedClassification)


def node_curvature(system, state=None) -> Optional[np.ndarray]:
    """Signed curvature per contact node of a system on a curved obstacle, else None: at each
    node's contact point of ``state`` when the loading path recorded it
    (``curved_contact.curvature``, app/loading/curved.py), else the system's (the constant of a
    circle, a curve's at the initial positions)."""
    k = getattr(system, "curvature", None)
    if k is None:
        return None
    cc = (getattr(state, "extra", None) or {}).get("curved_contact") if state is not None else None
    if cc is not None and cc.get("curvature") is not None:
        return np.asarray(cc["curvature"], dtype=float)
    return np.asarray(k, dtype=float)


def attach(cls: Classification, state, system) -> Classification:
    """``cls`` with the curvature data of ``state`` (unchanged on a straight obstacle).

    ``state.extra["curved_contact"]["frame"]`` gives the contact frames (the loading path on a
    curved obstacle records them); without it every frame is the node's own."""
    kappa = node_curvature(system, state)
    if kappa is None:
        return cls
    rN = np.asarray(state.r_N, dtype=float)
    frames_in = (state.extra.get("curved_contact") or {}).get("frame")
    geo, frames = [], []
    for i, st in enumerate(cls.status):
        # kappa P of a slip node; a zero-reaction node has P = 0, no curvature term (only its frame)
        geo.append(float(kappa[i] * -rN[i]) if st == SLIP else 0.0)
        turns = st in (SLIP, ZERO) and frames_in is not None
        frames.append(tuple(float(v) for v in frames_in[i]) if turns else IDENTITY)
    return CurvedClassification(cls.status, cls.signs, tuple(geo), tuple(frames))


def condensed_quadratic(Sc: np.ndarray, cls: CurvedClassification) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A0, A1, A2)`` of the condensed MCEIP-mu on a curved obstacle:
    ``A(mu) = S Ŝ_TT S + G + mu Ŝ_NT S + mu^2 G`` (docs/method.md section 8), the contact Schur
    complement first rotated into the contact frames of the slip nodes."""
    from app.analyses.pencils.reduced import condensed_mu_pencil
    Sc = rotate_schur(Sc, cls)
    A0, A1 = condensed_mu_pencil(Sc, cls)
    G = np.diag(cls.slip_geometric())
    return A0 + G, A1, G


def frame_matrix(frames, n: int) -> np.ndarray:
    """Block-diagonal ``Q`` (2n x 2n, paper axes, order T_0, N_0, ...): old components = Q new."""
    Q = np.eye(2 * n)
    for i, (a, b, c, d) in enumerate(frames):
        Q[2 * i:2 * i + 2, 2 * i:2 * i + 2] = [[a, c], [b, d]]
    return Q


def rotate_schur(Sc: np.ndarray, cls: CurvedClassification) -> np.ndarray:
    """The contact Schur complement in the contact frames (``Q^T Sc Q``); ``Sc`` itself if none rotates."""
    if not cls.rotated():
        return Sc
    Q = frame_matrix(cls.frames, Sc.shape[0] // 2)
    return Q.T @ Sc @ Q


def rotate_petsc(A, system, cls: CurvedClassification):
    """A new PETSc matrix ``Q^T A Q`` in the contact frames of the slip (and zero-reaction) nodes (system DOFs, the
    node's own paper-axis signs kept); None when no frame rotates. The caller destroys it."""
    if not cls.rotated():
        return None
    from petsc4py import PETSc
    Q = PETSc.Mat().createAIJ(A.getSizes(), nnz=(2, 2), comm=A.getComm())
    Q.setUp()
    r0, r1 = Q.getOwnershipRange()
    blocks = _frame_rows(system, cls)
    for row in range(r0, r1):
        for col, v in blocks.get(row, ((row, 1.0),)):
            Q.setValue(row, col, v)
    Q.assemble()
    try:
        return A.ptap(Q)
    finally:
        Q.destroy()


def _frame_rows(system, cls: CurvedClassification) -> dict:
    """The rows of ``Q`` (system DOFs, old components = Q new) that differ from the identity:
    row -> ((column, value), (column, value)), each rotating node's (T, N) block with the
    node's own paper-axis signs kept."""
    rows = {}
    for node, f in zip(system.nodes, cls.frames):
        if f == IDENTITY:
            continue
        a, b, c, d = f
        sT, sN = node.sign_T, node.sign_N
        rows[node.dof_T] = ((node.dof_T, a), (node.dof_N, sT * sN * c))
        rows[node.dof_N] = ((node.dof_T, sN * sT * b), (node.dof_N, d))
    return rows


def system_frame_matrix(system, cls: CurvedClassification) -> np.ndarray:
    """Dense ``Q`` of :func:`rotate_petsc` (system DOFs, old components = Q new)."""
    Q = np.eye(system.n_dofs)
    for row, entries in _frame_rows(system, cls).items():
        for col, v in entries:
            Q[row, col] = v
    return Q


def add_geometric(Ks, space, cls: CurvedClassification, factor: float) -> None:
    """``Ks += factor * G`` on the rows of the slip nodes' ``x_Ts`` (in place, owned rows)."""
    from petsc4py import PETSc
    g = cls.slip_geometric()
    r0, r1 = Ks.getOwnershipRange()
    for p, gi in zip(space.comp, g):
        if r0 <= p < r1 and gi != 0.0:
            Ks.setValue(int(p), int(p), factor * gi, addv=PETSc.InsertMode.ADD_VALUES)
    Ks.assemble()
