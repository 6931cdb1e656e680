"""Contact tractions of a 2D body from its nodal contact reactions (results.json
``states[].contact_traction``), for the Hertz comparison and the pressure output.

A nodal reaction is the moment of the traction against the node's shape function,
``r_i = t int p phi_i ds`` (t the thickness), so a traction in the displacement space follows from
the boundary mass matrix of the contact curve, ``p = M^-1 r / t`` (the consistent recovery). For P2
this matters: a vertex carries L/3 and a mid-side node 2L/3 of a uniform pressure, so reaction /
tributary length is about 30 % off; and node-wise contact reactions are not exactly the P2 moments
of a smooth pressure, so their consistent recovery alternates between vertex and mid-side nodes;
the least-squares P1 traction on the vertices is given as a smooth alternative.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class ContactRecovery:
    """Tractions from nodal reactions on the contact curve (contact nodes in the order of ``xy``).

    ``M``: boundary mass matrix ``int phi_i phi_j ds`` of the displacement space (element matrices
    ``L/6 [[2, 1], [1, 2]]`` for P1, ``L/30 [[4, -1, 2], [-1, 4, 2], [2, 2, 16]]`` for P2: ends,
    mid-side node), so ``r = t M p`` for a traction ``p`` in that space (t the thickness): the
    consistent recovery ``p = M^-1 r / t``. For P2 a vertex carries ``L/3`` and a mid-side node ``2L/3``
    (nodal reaction / tributary length is 30 % off), and the consistent recovery of node-wise
    contact reactions alternates between vertex and mid-side nodes; ``C`` (P2 only) maps a P1
    traction on the vertices to P2 nodal forces, ``C_ij = int phi_i psi_j ds``, and ``I``
    interpolates it to every contact node: ``p = I argmin |t C q - r|`` is the smooth recovery.
    Curve nodes outside the contact set (a prescribed component) are left out."""

    M: np.ndarray
    C: np.ndarray | None = None
    I: np.ndarray | None = None

    def tractions(self, thickness: float, r: np.ndarray) -> dict[str, np.ndarray]:
        """Recovered tractions of nodal reactions ``r`` (one row per state, one column per node)."""
        import scipy.linalg
        r = np.atleast_2d(r)
        out = {"consistent": scipy.linalg.cho_solve(scipy.linalg.cho_factor(self.M), r.T).T / thickness}
        if self.C is not None:
            q = np.linalg.lstsq(thickness * self.C, r.T, rcond=None)[0]
            out["vertex_fit"] = (self.I @ q).T
        return out


def contact_recovery(edges: np.ndarray, xy: np.ndarray, degree: int) -> ContactRecovery:
    """The :class:`ContactRecovery` of the contact curve's facets ``edges`` (end points)."""
    from scipy.spatial import cKDTree
    n = len(xy)
    M = np.zeros((n, n))
    if n == 0 or len(edges) == 0:
        return ContactRecovery(M)
    # matching tolerance: relative to the curve's extent, and to the coordinates' round-off far from the origin
    tol = 1e-9 * float(np.ptp(edges.reshape(-1, 2), axis=0).max()) + 1e-13 * float(np.abs(edges).max())
    pts = [edges[:, 0], edges[:, 1]] + ([0.5 * (edges[:, 0] + edges[:, 1])] if degree == 2 else [])
    tree = cKDTree(xy)
    idx = []
    for q in pts:
        dist, j = tree.query(q)
        idx.append(np.where(dist <= tol, j, -1))
    idx = np.column_stack(idx)
    L = np.linalg.norm(edges[:, 1] - edges[:, 0], axis=1)
    Me = (np.array([[2.0, 1.0], [1.0, 2.0]]) / 6.0 if degree == 1 else
          np.array([[4.0, -1.0, 2.0], [-1.0, 4.0, 2.0], [2.0, 2.0, 16.0]]) / 30.0)
    for e in range(len(edges)):
        for a in range(idx.shape[1]):
            for b in range(idx.shape[1]):
                if idx[e, a] >= 0 and idx[e, b] >= 0:
                    M[idx[e, a], idx[e, b]] += L[e] * Me[a, b]
    if degree == 1:
        return ContactRecovery(M)
    verts = np.unique(idx[:, :2][idx[:, :2] >= 0])
    col = {int(v): j for j, v in enumerate(verts)}
    C, Ip = np.zeros((n, len(verts))), np.zeros((n, len(verts)))
    Ce = np.array([[1.0, 0.0], [0.0, 1.0], [2.0, 2.0]]) / 6.0     # rows: ends, mid; columns: the P1 hats
    for e in range(len(edges)):
        for a in range(3):
            for b in range(2):
                if idx[e, a] >= 0 and idx[e, b] >= 0:
                    C[idx[e, a], col[int(idx[e, b])]] += L[e] * Ce[a, b]
                    if a == 2:
                        Ip[idx[e, 2], col[int(idx[e, b])]] = 0.5
    for v, j in col.items():
        Ip[v, j] = 1.0
    return ContactRecovery(M, C, Ip)
