"""A meshed system's nodes, cells and fields gathered on rank 0 in a canonical order (sorted by
coordinates), so that the files written from them do not depend on the number of MPI ranks."""
from __future__ import annotations

import numpy as np


class MeshGather:
    """Nodes and cells of the displacement space on rank 0, in a canonical (rank-independent) order."""

    def __init__(self, V, length_scale: float):
        import dolfinx.cpp
        mesh = V.mesh
        self.comm = mesh.comm
        im = V.dofmap.index_map
        self.n_own = im.size_local
        self.gidx = np.arange(im.local_range[0], im.local_range[1], dtype=np.int64)
        x = V.tabulate_dof_coordinates()[:self.n_own, :2]
        tdim = mesh.topology.dim
        self.n_cells = mesh.topology.index_map(tdim).size_local
        ndofs = V.dofmap.dof_layout.num_dofs
        perm = np.argsort(dolfinx.cpp.io.perm_vtk(mesh.topology.cell_type, ndofs))   # DOLFINx -> VTK order
        local = V.dofmap.list.array.reshape(-1, ndofs)[:self.n_cells][:, perm]
        cells = im.local_to_global(local.ravel().astype(np.int32)).reshape(local.shape)
        parts = self.comm.gather((self.gidx, x, cells), root=0)              # MPI collective
        self.points = self.cells = self.point_order = self.cell_order = None
        self.cell_type = "triangle" if ndofs == 3 else "triangle6"
        if self.comm.rank == 0:
            g = np.concatenate([p[0] for p in parts])
            xs = np.concatenate([p[1] for p in parts])
            n = len(g)
            pts = np.empty((n, 2))
            pts[g] = xs
            key = np.round(pts / length_scale, 9)
            order = np.lexsort((key[:, 0], key[:, 1]))            # by y, then x
            new_of_global = np.empty(n, dtype=np.int64)
            new_of_global[order] = np.arange(n)
            self.points = pts[order]
            cells = new_of_global[np.concatenate([p[2] for p in parts])]
            # each cell starts at its smallest vertex (a cyclic rotation: orientation and the VTK
            # order of the mid-side nodes kept), whatever the mesh generator's local order
            rot = (np.argmin(cells[:, :3], axis=1)[:, None] + np.arange(3)) % 3
            cells = np.hstack([np.take_along_axis(cells[:, 3 * b:3 * b + 3], rot, axis=1)
                               for b in range(cells.shape[1] // 3)])
            ckey = np.sort(cells, axis=1)
            self.cell_order = np.lexsort(ckey.T[::-1])
            self.cells = cells[self.cell_order]
            self.new_of_global = new_of_global

    def nodal(self, values: np.ndarray) -> np.ndarray | None:
        """(N, 2) nodal vector on rank 0 from a blocked Function array (local, with ghosts)."""
        own = np.asarray(values)[:2 * self.n_own].reshape(-1, 2)
        parts = self.comm.gather((self.gidx, own), root=0)                 # MPI collective
        if self.comm.rank != 0:
            return None
        out = np.empty((len(self.points), 2))
        for g, v in parts:
            out[self.new_of_global[g]] = v
        return out

    def cellwise(self, values: np.ndarray) -> np.ndarray | None:
        """(C,) cell values on rank 0 from this rank's owned-cell values (in local cell order)."""
        parts = self.comm.gather(np.asarray(values)[:self.n_cells], root=0)   # MPI collective
        if self.comm.rank != 0:
            return None
        return np.concatenate(parts)[self.cell_order]

    def contact_points(self, xy: np.ndarray, length_scale: float) -> np.ndarray:
        """Indices (rank 0) of the mesh nodes at the contact nodes' coordinates ``xy`` (n, 2)."""
        from scipy.spatial import cKDTree
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        dist, idx = cKDTree(self.points).query(xy)
        if len(xy) and dist.max() > 1e-9 * length_scale:
            k = int(np.argmax(dist))
            raise RuntimeError(f"no mesh node at contact position ({xy[k, 0]}, {xy[k, 1]})")
        return np.asarray(idx, dtype=np.int64)
