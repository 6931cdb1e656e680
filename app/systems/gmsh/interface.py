"""An obstacle body (``system.obstacle.type: body``): the interface between the body's contact
curve and the obstacle body's straight contact curve, and the change of variables to relative
contact DOFs (docs/method.md section 10).

Each contact node ``a`` of the body faces a point of the obstacle's contact curve: a node of it
(``pairing: node``, conforming meshes) or a point of a segment (``pairing: segment``, any meshes),
found once in the reference configuration (small sliding, as the rest of the app) with the
interpolation weights ``w`` of the segment's nodes (P1: linear, P2: quadratic along the edge).
The contact DOFs become the relative displacement in the obstacle frame,

    q_a = R_a^T (u_a - sum_m w_m u_m),   i.e.   u_a = R_a q_a + sum_m w_m u_m,

every other DOF (the obstacle's included) is kept: ``u = P u'`` with P the identity but for the
contact nodes' rows. P is unimodular (block triangular with the orthogonal R_a on the diagonal), so
``K' = P^T K P`` and ``M' = P^T M P`` stay symmetric positive definite and sparse, and the
paper's reduction applies to the relative DOFs unchanged; a reaction ``r`` on ``q_a`` acts with
``R_a r`` on the body's node and ``-w_m R_a r`` on the obstacle's (``P^-T``). For a rigid obstacle
P is the rotation alone (app/systems/gmsh/operators.py).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from app.common.errors import point_text

#: a contact node facing a segment's end (or a node) within this fraction of the body's size faces
#: exactly that node (weights 1 and 0: a conforming interface gives node-to-node's operators)
SNAP = 1e-10


class InterfaceError(Exception):
    """A problem of the interface (one line; raised as the body's error by the caller)."""


@dataclass(frozen=True)
class Interface:
    """The obstacle body's contact line and each contact node's obstacle point."""

    point: np.ndarray                       # a point of the obstacle's contact line
    normal: np.ndarray                      # unit outward normal of the body (into the obstacle)
    links: list[list[tuple[float, int, int]]]   # per contact node: (w, reduced DOF x, DOF y) of its obstacle nodes
    n_masters: int                          # nodes of the obstacle's contact curve


def contact_line(ends: np.ndarray, obstacle_mean: np.ndarray, size: float, curve: str) -> tuple[np.ndarray, np.ndarray]:
    """``(point, unit outward normal of the body)`` of a straight obstacle contact curve from its
    segments' ends ``(m, 2, 2)`` (every rank the same), the normal pointing towards the obstacle
    body's nodes' mean ``obstacle_mean``."""
    pts = ends.reshape(-1, 2)
    p0 = pts[0]
    far = pts[int(np.argmax(np.linalg.norm(pts - p0, axis=1)))]
    d = far - p0
    length = float(np.linalg.norm(d))
    if length <= SNAP * size:
        raise InterfaceError(f"system.obstacle.contact = '{curve}': the curve has no length")
    d = d / length
    n = np.array([-d[1], d[0]])
    off = np.abs((pts - p0) @ n)
    if off.max() > 1e-9 * size:
        i = int(np.argmax(off))
        raise InterfaceError(f"system.obstacle.contact = '{curve}': an obstacle body's contact curve must be straight "
                             f"(the point {point_text(pts[i], size)} is {off[i]:.3g} off the line of its ends)")
    if (obstacle_mean - p0) @ n < 0:
        n = -n
    return p0, n


def masters(comm: MPI.Comm, xy: np.ndarray, dof_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The obstacle contact curve's nodes gathered on every rank: ``(coordinates, reduced DOFs
    (x, y), -1 where prescribed)`` from each rank's owned ones (MPI collective)."""
    gathered = comm.allgather((xy, dof_xy))                                      # MPI collective
    return (np.concatenate([g[0] for g in gathered]).reshape(-1, 2),
            np.concatenate([g[1] for g in gathered]).reshape(-1, 2).astype(np.int64))


def pair(contact_xy: np.ndarray, m_xy: np.ndarray, m_dofs: np.ndarray, ends: np.ndarray, point: np.ndarray,
         normal: np.ndarray, degree: int, pairing: str, size: float, curve: str) -> list[list[tuple[float, int, int]]]:
    """Each contact node's obstacle nodes and weights (every rank the same): a node at the same
    place (``node``) or the interpolation on the segment it faces (``segment``)."""
    t = np.array([-normal[1], normal[0]])
    s_m = (m_xy - point) @ t
    order = np.argsort(s_m, kind="stable")
    s_sorted = s_m[order]
    tol = SNAP * size
    segments = _segments(ends, point, t, s_sorted, degree, tol, curve)
    links = []
    for a, x in enumerate(contact_xy):
        s = float((x - point) @ t)
        if pairing == "node":
            dist = np.linalg.norm(m_xy - x, axis=1)
            j = int(np.argmin(dist)) if len(dist) else -1
            if j < 0 or dist[j] > tol:
                near = f" (the nearest is {dist[j]:.3g} away)" if j >= 0 else ""
                raise InterfaceError(f"system.obstacle.pairing = 'node': no node of '{curve}' at the contact node "
                                     f"{point_text(x, size)}{near}: the meshes do not match there; use "
                                     "pairing: segment")
            nodes = [(1.0, j)]
        else:
            nodes = _on_segment(s, segments, s_sorted, order, degree, tol)
            if nodes is None:
                raise InterfaceError(f"system.obstacle.contact = '{curve}': the contact node at {point_text(x, size)} "
                                     f"faces no segment of it: the obstacle's contact curve must extend past the "
                                     "body's")
        link = []
        for w, j in nodes:
            if m_dofs[j, 0] < 0 or m_dofs[j, 1] < 0:
                raise InterfaceError(f"system.obstacle.held: the node {point_text(m_xy[j], size)} of '{curve}' that "
                                     f"the contact node {point_text(x, size)} faces is held: hold curves away from "
                                     "the contact curve")
            link.append((float(w), int(m_dofs[j, 0]), int(m_dofs[j, 1])))
        links.append(link)
    return links


def _segments(ends: np.ndarray, point: np.ndarray, t: np.ndarray, s_sorted: np.ndarray, degree: int, tol: float,
              curve: str) -> np.ndarray:
    """The curve's segments as ``(s_lo, s_hi, first node)`` in the sorted node order (the nodes of
    a segment are consecutive there: 2 for P1, 3 for P2)."""
    s_ends = np.sort((ends - point) @ t, axis=1)
    s_ends = s_ends[np.argsort(s_ends[:, 0])]
    out = []
    for lo, hi in s_ends:
        i = int(np.searchsorted(s_sorted, lo - tol))
        if i + degree >= len(s_sorted) or abs(s_sorted[i] - lo) > tol or abs(s_sorted[i + degree] - hi) > tol:
            raise InterfaceError(f"system.obstacle.contact = '{curve}': its nodes and segments do not match (a "
                                 "segment overlaps another, or its nodes are held in part)")
        out.append((lo, hi, i))
    return np.array(out).reshape(-1, 3)


def _on_segment(s: float, segments: np.ndarray, s_sorted: np.ndarray, order: np.ndarray, degree: int,
                tol: float) -> list[tuple[float, int]] | None:
    """The nodes (original indices) and weights of the point at ``s`` of the first segment holding
    it; None when none does. A point within ``tol`` of a node is that node (weight 1)."""
    inside = np.flatnonzero((segments[:, 0] - tol <= s) & (s <= segments[:, 1] + tol))
    if not len(inside):
        return None
    lo, hi, i = segments[inside[0]]
    i = int(i)
    for k in range(degree + 1):
        if abs(s - s_sorted[i + k]) <= tol:
            return [(1.0, int(order[i + k]))]
    xi = min(max((s - lo) / (hi - lo), 0.0), 1.0)
    if degree == 1:
        w = (1.0 - xi, xi)
    else:        # quadratic along the (straight, affine) edge: ends at 0 and 1, the mid-side node at 1/2
        w = ((1.0 - xi) * (1.0 - 2.0 * xi), 4.0 * xi * (1.0 - xi), xi * (2.0 * xi - 1.0))
    return [(float(wk), int(order[i + k])) for k, wk in enumerate(w)]
