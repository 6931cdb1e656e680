"""An obstacle body (``system.obstacle.type: body``): the interface between the body's contact
curve and the obstacle body's contact curve, and the change of variables to relative contact DOFs
(docs/method.md section 9).

Each contact node ``a`` of the body faces a point of the obstacle's contact curve: a node of it
(``pairing: node``, conforming meshes) or a point of a segment (``pairing: segment``, any meshes),
found once in the reference configuration (small sliding, as the rest of the app) with the
interpolation weights ``w`` of the segment's nodes (P1: linear, P2: quadratic along the edge). A
straight curve gives one frame (t, n) for every node; a curved one keeps the global axes and its
smooth geometry (gaps, frames and curvature of a ``curve`` obstacle, app/loading/curve.py).
The contact DOFs become the relative displacement in the obstacle frame,

    q_a = R_a^T (u_a - sum_m w_m u_m),   i.e.   u_a = R_a q_a + sum_m w_m u_m,

every other DOF (the obstacle's included) is kept: ``u = P u'`` with P the identity but for the
contact nodes' rows. P is unimodular (block triangular with the orthogonal R_a on the diagonal), so
``K' = P^T K P`` and ``M' = P^T M P`` stay symmetric positive definite and sparse, and the
paper's reduction applies to the relative DOFs unchanged; a reaction ``r`` on ``q_a`` acts with
``R_a r`` on the body's node and ``-w_m R_a r`` on the obstacle's (``P^-T``). For a rigid obstacle
P is the rotation alone (app/systems/gmsh/operators.py).

The pairing itself (:func:`pair`) is plain arithmetic on gathered coordinates; the functions after
it read the interface from the DOLFINx mesh (``sp``: the body's space and numbering of
app/systems/gmsh/operators.py).
"""
from __future__ import annotations

import pathlib
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from app.common.errors import point_text

#: segments (nearest midpoints) searched for a contact node's foot
CANDIDATES = 16
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


def contact_line(ends: np.ndarray, obstacle_mean: np.ndarray, size: float, curve: str
                 ) -> tuple[np.ndarray, np.ndarray] | None:
    """``(point, unit outward normal of the body)`` of a straight obstacle contact curve from its
    segments' ends ``(m, 2, 2)`` (every rank the same), the normal pointing towards the obstacle
    body's nodes' mean ``obstacle_mean``; None when the curve is not straight (to 1e-9 of the
    body's size)."""
    pts = ends.reshape(-1, 2)
    p0 = pts[0]
    far = pts[int(np.argmax(np.linalg.norm(pts - p0, axis=1)))]
    d = far - p0
    length = float(np.linalg.norm(d))
    if length <= SNAP * size:
        raise InterfaceError(f"system.obstacle.contact = '{curve}': the curve has no length")
    d = d / length
    n = np.array([-d[1], d[0]])
    if np.abs((pts - p0) @ n).max() > 1e-9 * size:
        return None
    if (obstacle_mean - p0) @ n < 0:
        n = -n
    return p0, n


def masters(comm: MPI.Comm, xy: np.ndarray, dof_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The obstacle contact curve's nodes gathered on every rank: ``(coordinates, reduced DOFs
    (x, y), -1 where prescribed)`` from each rank's owned ones (MPI collective)."""
    gathered = comm.allgather((xy, dof_xy))                                      # MPI collective
    return (np.concatenate([g[0] for g in gathered]).reshape(-1, 2),
            np.concatenate([g[1] for g in gathered]).reshape(-1, 2).astype(np.int64))


def pair(contact_xy: np.ndarray, m_xy: np.ndarray, m_dofs: np.ndarray, ends: np.ndarray, degree: int, pairing: str,
         size: float, curve: str) -> list[list[tuple[float, int, int]]]:
    """Each contact node's obstacle nodes and weights (every rank the same): a node at the same
    place (``node``), or the foot of the node on the closest segment of the curve and the
    interpolation there (``segment``; a straight curve or the chords of a curved one)."""
    from scipy.spatial import cKDTree
    tol = SNAP * size
    seg_nodes = _segment_nodes(ends, m_xy, degree, tol, curve)
    # the closest segment is among those whose midpoints are nearest (its neighbours' too)
    near = cKDTree(0.5 * (ends[:, 0] + ends[:, 1]))
    k = min(CANDIDATES, len(ends))
    links = []
    for x in contact_xy:
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
            cand = np.atleast_1d(near.query(x, k=k)[1])
            nodes = _foot(x, ends[cand], seg_nodes[cand], m_xy, degree, tol, seg_nodes)
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


def _segment_nodes(ends: np.ndarray, m_xy: np.ndarray, degree: int, tol: float, curve: str) -> np.ndarray:
    """The curve's nodes of each segment ``(m, degree + 1)``: its first end, (P2) its mid-side
    node, its second end (the node at each place, within ``tol``)."""
    from scipy.spatial import cKDTree
    places = [ends[:, 0], 0.5 * (ends[:, 0] + ends[:, 1]), ends[:, 1]] if degree == 2 else [ends[:, 0], ends[:, 1]]
    if not len(m_xy):
        raise InterfaceError(f"system.obstacle.contact = '{curve}': no node of it is free")
    tree = cKDTree(m_xy)
    out = []
    for p in places:
        d, j = tree.query(p)
        if np.any(d > tol):
            raise InterfaceError(f"system.obstacle.contact = '{curve}': its nodes and segments do not match")
        out.append(j)
    return np.column_stack(out).astype(np.int64)


def _foot(x: np.ndarray, ends: np.ndarray, seg_nodes: np.ndarray, m_xy: np.ndarray, degree: int,
          tol: float, all_nodes: np.ndarray) -> list[tuple[float, int]] | None:
    """The nodes (indices) and weights of the foot of ``x`` on the closest of the segments ``ends``
    (their nodes ``seg_nodes``; ``all_nodes`` every segment's, to tell the curve's ends); a foot within
    ``tol`` of a node is that node (weight 1). A node whose closest point is a vertex shared by two
    segments (outside a kink of the chords) faces that vertex; None when it lies beyond an end of
    the curve."""
    a, b = ends[:, 0], ends[:, 1]
    d = b - a
    length2 = np.einsum("ij,ij->i", d, d)
    xi_raw = np.einsum("ij,ij->i", x - a, d) / length2
    xi = np.clip(xi_raw, 0.0, 1.0)
    foot = a + xi[:, None] * d
    k = int(np.argmin(np.linalg.norm(foot - x, axis=1)))
    for j in seg_nodes[k]:
        if np.linalg.norm(m_xy[j] - foot[k]) <= tol:
            beyond = (xi_raw[k] - xi[k]) * np.sqrt(length2[k])
            if abs(beyond) > tol and np.count_nonzero(all_nodes[:, [0, -1]] == j) < 2:
                return None                 # beyond an end of the curve
            return [(1.0, int(j))]
    t = float(xi[k])
    if degree == 1:
        w = (1.0 - t, t)
    else:        # quadratic along the (straight, affine) edge: ends at 0 and 1, the mid-side node at 1/2
        w = ((1.0 - t) * (1.0 - 2.0 * t), 4.0 * t * (1.0 - t), t * (2.0 * t - 1.0))
    return [(float(wk), int(j)) for wk, j in zip(w, seg_nodes[k])]


# ---- from the mesh (DOLFINx) ----------------------------------------------------------------
def surface_blocks(sp, cell_tags, surface: str) -> np.ndarray:
    """The local DOF blocks (ghosts included) of the cells of a physical surface."""
    cells = cell_tags.indices[cell_tags.values == sp.tag_of_surface[surface]]
    per_cell = sp.V.dofmap.dof_layout.num_dofs
    return np.unique(sp.V.dofmap.list.array.reshape(-1, per_cell)[cells].ravel()).astype(np.int64)


def body_geometry(cfg, sp, dof_x: np.ndarray, obstacle_blocks: np.ndarray, ends: np.ndarray) -> tuple:
    """An obstacle body's contact geometry ``(line, curve)`` from its contact curve's segments
    ``ends`` (:func:`contact_edges`): its line (:func:`contact_line`), or for a curved contact curve
    (``line`` None) the smooth curve of the .geo with the body on the side away from the obstacle's
    cells (MPI collective). ``sp``: the body's space and numbering (app/systems/gmsh/operators.py)."""
    comm = sp.comm
    mine = obstacle_blocks[obstacle_blocks < sp.im.size_local]
    total = np.array(comm.allreduce([*dof_x[mine].sum(axis=0), len(mine)], op=MPI.SUM), dtype=float)  # MPI collective
    box = np.array(comm.allgather(np.concatenate([dof_x.min(axis=0), dof_x.max(axis=0)]) if len(dof_x)
                                  else np.array([np.inf, np.inf, -np.inf, -np.inf])))      # MPI collective
    size = float(np.max(box[:, 2:].max(axis=0) - box[:, :2].min(axis=0)))
    line = contact_line(ends, total[:2] / max(total[2], 1.0), size, cfg.obstacle.contact)
    return line, (None if line is not None else body_curve(cfg, sp, size))               # MPI collective


def body_curve(cfg, sp, size: float):
    """The smooth curve (app/loading/curve.py) of an obstacle body's curved contact curve, sampled
    from the .geo (app/systems/gmsh/child_curves.py), the body on the side away from the obstacle:
    the cells of the obstacle along the curve lie beyond it (MPI collective)."""
    from app.loading.curve import CurveError, SmoothCurve
    from app.systems.gmsh.mesh import model_info, obstacle_samples
    ob, path = cfg.obstacle, pathlib.Path(cfg.file)
    entry = model_info(path, path.name, None, None, cfg.mesh_size_factor).boundary_curves.get(ob.contact, {})
    if entry.get("error") or not entry:
        raise InterfaceError(f"system.obstacle.contact = '{ob.contact}': the curve is not straight, and its smooth "
                             f"geometry is not known: {entry.get('error') or 'not sampled'}")
    entities, params, xy, ent_of = obstacle_samples(path, ob.contact, cfg.mesh_size_factor, bounding=True)
    try:
        curve = SmoothCurve(ob.contact, entities, params, xy, ent_of, "left", size)
    except CurveError as err:
        raise InterfaceError(f"system.obstacle.contact = '{ob.contact}': {err}") from None
    top = sp.mesh.topology
    top.create_connectivity(1, 2)
    top.create_connectivity(2, 0)
    f2c, c2v = top.connectivity(1, 2), top.connectivity(2, 0).array.reshape(-1, 3)
    geo = sp.mesh.geometry.dofmap.array.reshape(-1, 3)
    cells = np.array([c for f in sp.facets(ob.contact) for c in f2c.links(f) if c < len(c2v)], dtype=np.int64)
    centroids = sp.mesh.geometry.x[geo[cells], :2].mean(axis=1) if len(cells) else np.zeros((0, 2))
    votes = sp.comm.allreduce(float(np.sum(np.sign(curve.gap(centroids)))) if len(cells) else 0.0,
                              op=MPI.SUM)                                        # MPI collective
    if votes > 0:            # the obstacle's cells on the left: the body is on the right
        curve = SmoothCurve(ob.contact, entities, params, xy, ent_of, "right", size)
    return curve


def links(cfg, sp, dof_x: np.ndarray, reduced: np.ndarray, contact_xy: np.ndarray, size: float,
          ends: np.ndarray) -> list:
    """Each contact node's obstacle nodes and weights from the mesh (:func:`pair`, on the contact
    curve's segments ``ends``; MPI collective)."""
    import dolfinx.fem
    ob, bs = cfg.obstacle, sp.bs
    blocks = dolfinx.fem.locate_dofs_topological(sp.V, 1, sp.facets(ob.contact))
    blocks = blocks[blocks < sp.im.size_local]
    m_xy, m_dofs = masters(sp.comm, dof_x[blocks],
                           np.column_stack([reduced[blocks * bs], reduced[blocks * bs + 1]]))   # MPI collective
    return pair(contact_xy, m_xy, m_dofs, ends, cfg.degree, ob.pairing, size, ob.contact)


def contact_edges(mesh, facet_ids: np.ndarray, comm: MPI.Comm) -> np.ndarray:
    """End points of every facet of the contact curve, gathered on every rank, each once
    (MPI collective). The mesh is affine, so a P2 mid-side node is the mean of its ends."""
    top = mesh.topology
    top.create_connectivity(1, 0)
    top.create_connectivity(2, 0)
    c2v = top.connectivity(2, 0).array.reshape(-1, 3)
    geo_of_vertex = np.empty(int(c2v.max()) + 1 if c2v.size else 0, dtype=np.int64)
    geo_of_vertex[c2v.ravel()] = mesh.geometry.dofmap.array.reshape(-1, 3)[:len(c2v)].ravel()   # affine P1 geometry
    f2v = top.connectivity(1, 0)
    verts = np.array([f2v.links(f) for f in facet_ids], dtype=np.int64).reshape(-1, 2)
    ends = mesh.geometry.x[geo_of_vertex[verts.ravel()], :2].reshape(-1, 2, 2)
    allends = np.concatenate([e.reshape(-1, 2, 2) for e in comm.allgather(ends)])      # MPI collective
    key = np.round(np.sort(allends.reshape(-1, 4), axis=1), 12)
    _, first = np.unique(key, axis=0, return_index=True)
    return allends[np.sort(first)]
