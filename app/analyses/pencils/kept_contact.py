"""The kept contact unknowns of a classified state and the maps of the paper's change of
variables (10)-(16) onto them, on the contact DOFs alone (docs/method.md section 2): shared by
the exact slip-node reduction of MCEIP-lambda^2 (app/analyses/mceip_lambda2/exact.py) and the
values of the necessary condition (19) (app/analyses/conditions/contact_spectrum.py)."""
from __future__ import annotations

import numpy as np
import scipy.sparse

from app.analyses.pencils.curvature import frame_matrix, is_curved
from app.loading.classify import FREE, Classification


class KeptContact:
    """The kept contact unknowns of one classification at mu (free nodes' DOFs, then the slip
    nodes' ``T``) and the maps of the paper's change of variables onto them, for ``n_c`` contact
    DOFs in paper axes: ``x_c = Q u`` (columns) and ``y_kept = R y_c`` (rows); ``self.R`` holds
    ``R^T``. One or two entries per column, so products cost ``O(n_c k)``.

    On a curved obstacle (docs/method.md section 8) the pencils are those of ``F^T X F``, ``F``
    rotating each slip node's two DOFs into its contact frame; the interior is untouched, so ``F``
    folds into the maps (``Q -> F Q``, ``R -> F R``), and ``bend`` holds the diagonal that ``K*``
    (not ``M*``) carries on the kept DOFs, ``(1 + mu^2) G`` on the slip nodes' ``x_Ts``."""

    def __init__(self, nC: int, cls: Classification, mu: float):
        slip, free = cls.slip, cls.indices(FREE)
        s = len(slip)
        F = np.sort(np.concatenate([2 * free, 2 * free + 1])).astype(int)
        self.nF = nF = len(F)
        self.n = k = nF + s
        # Q: x_F = u_F, x_T = S u_Ts; R^T: y_F -> F rows, y_T -> S at T and mu at N of each slip node
        cols = np.arange(k)
        q_rows = np.concatenate([F, 2 * slip]).astype(int)
        q_vals = np.concatenate([np.ones(nF), cls.slip_signs]).astype(float)
        r_rows = np.concatenate([F, 2 * slip, 2 * slip + 1]).astype(int)
        r_cols = np.concatenate([cols[:nF], nF + np.arange(s), nF + np.arange(s)])
        r_vals = np.concatenate([np.ones(nF), cls.slip_signs, np.full(s, float(mu))]).astype(float)
        self.Q = scipy.sparse.csc_matrix((q_vals, (q_rows, cols)), shape=(nC, k))
        self.R = scipy.sparse.csc_matrix((r_vals, (r_rows, r_cols)), shape=(nC, k))
        self.bend = np.zeros(k)
        if is_curved(cls):
            if cls.rotated():
                F = scipy.sparse.csc_matrix(frame_matrix(cls.frames, nC // 2))
                self.Q, self.R = (F @ self.Q).tocsc(), (F @ self.R).tocsc()
            self.bend[nF:] = (1.0 + mu * mu) * cls.slip_geometric()
        self.D = (self.Q - self.R).tocsc()

    @staticmethod
    def sandwich(L, X: np.ndarray, Rm) -> np.ndarray:
        """``L^T X Rm`` for sparse ``L``, ``Rm`` and dense ``X`` (C order): ``(Rm^T (L^T X)^T)^T``, the
        sparse products on C-ordered dense operands (scipy copies any other into C order)."""
        LX = np.asarray(L.T @ np.ascontiguousarray(X))
        return np.asarray(Rm.T @ np.ascontiguousarray(LX.T)).T

    def reduced(self, X: np.ndarray, bend: bool = False) -> np.ndarray:
        """``R X Q`` on the kept contact DOFs, plus the curvature diagonal when ``bend`` (``X`` a
        stiffness-like matrix: ``K``'s Schur complements)."""
        A = self.sandwich(self.R, X, self.Q)
        if bend:
            A[np.diag_indices_from(A)] += self.bend
        return A

    def kept(self, Z: np.ndarray, H: np.ndarray, bend: bool = False) -> np.ndarray:
        """The Schur complement of ``sym A*(mu)`` onto the kept contact DOFs (free nodes', slip
        nodes' ``T``), ``A`` the symmetric matrix whose contact block is ``H`` and whose Schur
        complement onto the contact DOFs is ``Z`` (docs/method.md section 2): with ``A*`` coupling
        the interior through ``P = (Q + R^T) / 2``, it is ``sym(R H Q) - P^T (H - Z) P``, which is
        ``sym(R Z Q) - (Q - R^T)^T (H - Z) (Q - R^T) / 4`` (with the curvature diagonal when
        ``bend``)."""
        A = self.reduced(Z, bend)
        return 0.5 * (A + A.T) - 0.25 * self.sandwich(self.D, H - Z, self.D)
