"""Split pencils of a state with zero-reaction nodes on a curved obstacle (docs/method.md section 8).

A zero-reaction node (the paper's set Z) has ``r = 0``, so the curvature terms of its rates,
``-kappa r_N v_T`` and ``kappa r_T v_T``, vanish: its rate conditions (9) are the flat ones of
:func:`app.analyses.pencils.reduced.split_pencil` (variables ``(a, b, x_N)``, ``v_T = a - b``), written
in the frame of the obstacle at its own contact point. The slip nodes keep theirs, so the
pencil of MCEIP-mu (21)-(23) is quadratic,

    A(mu) = A0 + mu A1 + mu^2 A2,   A0 = R0 Â Q + G,   A1 = R1 Â Q,   A2 = G,

with ``Â`` the contact Schur complement (or ``K``) rotated into the contact frames of the slip
and zero-reaction nodes (:mod:`app.analyses.pencils.curvature`) and ``G = diag(kappa_i P_i)`` on the
slip nodes' columns ``T<i>`` of ``x_c``; the mass pencil has no ``G``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.analyses.pencils import curvature
from app.analyses.pencils.reduced import split_pencils
from app.loading.classify import Classification
from app.systems.base import System


@dataclass
class QuadraticSplitPencil:
    """Dense split pencil ``A0 + mu A1 + mu^2 A2`` with zero-reaction nodes; fields as
    :class:`app.analyses.pencils.reduced.SplitPencil` (``pairs``: the ``(a, b)`` halves of each zero node)."""

    A0: np.ndarray
    A1: np.ndarray
    A2: np.ndarray
    comp: np.ndarray
    pairs: list[tuple[int, int]]
    labels: list[str]

    def at(self, mu: float) -> np.ndarray:
        """The pencil at ``mu`` (``K*(mu)`` of (15) for the stiffness)."""
        return self.A0 + mu * self.A1 + mu * mu * self.A2


def _geometric(sp, cls: Classification, with_g: bool) -> QuadraticSplitPencil:
    G = np.zeros_like(sp.A0)
    if with_g:
        for k, lab in zip(sp.comp, sp.labels):
            if lab[0] == "T":                   # a slip node's x_T: its kappa P on the diagonal
                G[k, k] = cls.geometric[int(lab[1:])]
    return QuadraticSplitPencil(sp.A0 + G, sp.A1, G, sp.comp, sp.pairs, sp.labels)


def curved_split_condensed(system: System, cls: curvature.CurvedClassification) -> QuadraticSplitPencil:
    """MCEIP-mu's split pencil on the contact Schur complement in the contact frames (no x_f)."""
    Sc = curvature.rotate_schur(system.contact_schur(), cls)
    return _geometric(split_pencils(system, cls, Sc=Sc), cls, True)


def curved_split_full(system: System, cls: curvature.CurvedClassification, A: np.ndarray,
                      stiffness: bool) -> QuadraticSplitPencil:
    """The full split pencil of a dense system matrix ``A`` (``K``: ``stiffness``, with ``G``;
    ``M``: without) in the contact frames."""
    if cls.rotated():
        Q = curvature.system_frame_matrix(system, cls)
        A = Q.T @ A @ Q
    return _geometric(split_pencils(system, cls, A), cls, stiffness)
