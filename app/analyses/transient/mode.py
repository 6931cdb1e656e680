"""The divergence mode of a state, in the system's own DOFs, from MCEIP-lambda^2's answer.

The paper's solution (8), ``u(t) = u0 + a(t) v``, ``r(t) = r0 + a(t) w`` with ``a'' = lambda^2 a``,
satisfies the equations of motion and the contact laws while the statuses hold when

    (K + lambda^2 M) v = B^T w                       (motion, eq. (3) with u'' = lambda^2 a v)
    w = 0                                            at the free nodes,
    (B v)_N = 0                                      at the nodes in contact,
    (B v)_T = 0                                      at the stick nodes and the slip nodes the mode keeps stuck,
    w_T = -S mu w_N                                  at the slip nodes that slip in the mode

(``B`` maps the DOFs to the contact displacements in paper axes, ``u_T = sign_T u[dof_T]``;
a slip node's reaction stays on the Coulomb cone, ``r_T = S mu |r_N| = -S mu r_N``). At the
eigenvalue ``lambda^2`` this square linear system in ``(v, w)`` is singular; its null vector,
the right singular vector of the smallest singular value, is the mode. The smallest singular
value relative to the largest measures how well ``lambda^2`` and the pattern fit together: an
independent check of the MCEIP-lambda^2 answer. The sign of ``v`` is chosen so that the slip
nodes slip the way friction allows, ``x_Ts = -S v_T >= 0`` (paper axes). Dense: for systems of at
most :data:`MAX_DENSE` DOFs.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

#: the dense null-vector computation's size limit (DOFs)
MAX_DENSE = 4000


@dataclass
class DivergenceMode:
    """A state's divergence mode: ``v`` (system DOFs, largest |component| 1), the reaction change
    ``w`` (paper axes, T_0, N_0, ...), ``lambda2``, and the relative smallest singular value of
    the system above (near 0 when ``lambda2`` and the pattern fit)."""

    v: np.ndarray
    w: np.ndarray
    lambda2: float
    singular: float


def contact_operator(nodes, n_dofs: int) -> np.ndarray:
    """``B`` (``2 n_c x n_dofs``): the DOFs to the contact displacements in paper axes (T_0, N_0, ...)."""
    B = np.zeros((2 * len(nodes), n_dofs))
    for i, nd in enumerate(nodes):
        B[2 * i, nd.dof_T] = nd.sign_T
        B[2 * i + 1, nd.dof_N] = nd.sign_N
    return B


def divergence_mode(K: np.ndarray, M: np.ndarray, nodes, status: Sequence[str], signs: Sequence[int],
                    pattern: Sequence[str], mu: float, lambda2: float) -> DivergenceMode:
    """The mode of a state (``status``, ``signs`` per contact node) at MCEIP-lambda^2's ``lambda2``
    with its slip ``pattern`` (per slip node, in node order: ``"slip"`` or ``"stick"`` in the mode)."""
    n, nc = K.shape[0], len(nodes)
    if n > MAX_DENSE:
        raise ValueError(f"the divergence mode is computed densely up to {MAX_DENSE} DOFs; this system has {n}")
    if "zero" in status:
        raise ValueError("a state with zero-reaction nodes: their status in the mode is not determined here")
    B = contact_operator(nodes, n)
    rows = [np.hstack([K + lambda2 * M, -B.T])]
    slip_k = 0
    for i, st in enumerate(status):
        T, N = 2 * i, 2 * i + 1

        def on_v(r):
            return np.hstack([B[r], np.zeros(2 * nc)])

        def on_w(coef: dict):
            row = np.zeros(n + 2 * nc)
            for j, c in coef.items():
                row[n + j] = c
            return row
        if st == "free":
            rows += [on_w({T: 1.0}), on_w({N: 1.0})]
            continue
        rows.append(on_v(N))
        if st == "slip":
            slips = pattern[slip_k] == "slip"
            slip_k += 1
            rows.append(on_w({T: 1.0, N: signs[i] * mu}) if slips else on_v(T))
        else:                                                         # stick
            rows.append(on_v(T))
    A = np.vstack(rows)
    scale = np.abs(A).max(axis=1, keepdims=True)
    _, sv, vt = np.linalg.svd(A / scale)
    z = vt[-1]
    v, w = z[:n], z[n:]
    xs = np.array([-signs[i] * (B[2 * i] @ v) for i, st in enumerate(status) if st == "slip"])
    if xs.sum() < 0:
        v, w = -v, -w
    big = np.abs(v).max()
    return DivergenceMode(v=v / big, w=w / big, lambda2=float(lambda2), singular=float(sv[-1] / sv[0]))
