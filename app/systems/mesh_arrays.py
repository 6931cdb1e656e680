"""A DOLFINx mesh from the arrays of a gmsh model, without gmsh (start-up).

DOLFINx 0.5.2's :mod:`dolfinx.io.gmshio` imports gmsh at module level and its
:func:`~dolfinx.io.gmshio.model_to_mesh` needs a live gmsh model. It does two things: it
extracts arrays from the model on one rank (node coordinates sorted by node tag, the
highest-dimensional elements and the elements one dimension lower, each with its physical
tag), then it distributes them with :func:`dolfinx.mesh.create_mesh` and builds the cell and
facet tags. :func:`extract` is the first half (it needs gmsh), :func:`build` is the second half
(it needs only DOLFINx), line for line as in ``model_to_mesh``, so a mesh built from saved
arrays has the same node and cell numbering as one built from the gmsh model.
"""
from __future__ import annotations

import os
import pathlib
import uuid
from dataclasses import dataclass

import dolfinx.cpp
import dolfinx.mesh
import numpy as np
import numpy.typing as npt
import ufl

# gmsh element type -> (DOLFINx cell name, degree), as in dolfinx.io.gmshio._gmsh_to_cells
_GMSH_CELLS = {1: ("interval", 1), 2: ("triangle", 1), 3: ("quadrilateral", 1), 8: ("interval", 2),
               9: ("triangle", 2), 10: ("quadrilateral", 2), 21: ("triangle", 3), 26: ("interval", 3),
               36: ("quadrilateral", 3)}
FORMAT = 1          # layout of the saved arrays (bump when it changes)


@dataclass(frozen=True)
class MeshArrays:
    """What ``model_to_mesh`` hands to DOLFINx on the reading rank (gmsh node order in cells)."""

    x: npt.NDArray[np.float64]             # (N, 3) node coordinates, row i = gmsh node tag i + 1
    cells: npt.NDArray[np.int64]           # (C, k) the highest-dimensional elements
    cell_values: npt.NDArray[np.int32]     # (C,) their physical tags
    gmsh_cell: int                         # gmsh element type of the cells (2: linear triangle)
    facets: npt.NDArray[np.int64]          # (F, m) elements one dimension lower (may be empty)
    facet_values: npt.NDArray[np.int32]    # (F,) their physical tags
    gmsh_facet: int                        # gmsh element type of the facets, -1 if there are none


def extract(gmsh) -> MeshArrays:
    """The arrays of gmsh's current model, exactly as ``model_to_mesh`` extracts them."""
    from dolfinx.io.gmshio import extract_geometry, extract_topology_and_markers
    x = extract_geometry(gmsh.model)
    topologies = extract_topology_and_markers(gmsh.model)
    dims = {t: gmsh.model.mesh.getElementProperties(t)[1] for t in topologies}
    order = sorted(topologies, key=lambda t: dims[t])          # ascending dimension (as np.argsort)
    cell_id = order[-1]
    facet_id = order[-2] if len(order) > 1 and dims[order[-2]] == dims[cell_id] - 1 else -1
    k = gmsh.model.mesh.getElementProperties(cell_id)[3]
    facets = (np.asarray(topologies[facet_id]["topology"], dtype=np.int64) if facet_id != -1
              else np.empty((0, 0), dtype=np.int64))
    fvals = (np.asarray(topologies[facet_id]["cell_data"], dtype=np.int32) if facet_id != -1
             else np.empty(0, dtype=np.int32))
    return MeshArrays(x=np.asarray(x, dtype=np.float64),
                      cells=np.asarray(topologies[cell_id]["topology"], dtype=np.int64).reshape(-1, k),
                      cell_values=np.asarray(topologies[cell_id]["cell_data"], dtype=np.int32),
                      gmsh_cell=int(cell_id), facets=facets, facet_values=fvals, gmsh_facet=int(facet_id))


def save(arrays: MeshArrays, path: pathlib.Path) -> None:
    """Write ``arrays`` to ``path`` (.npz) atomically and never over an existing file.

    The file is written under a temporary name in the same folder and hard-linked to ``path``,
    which fails if ``path`` exists (another run wrote the same mesh first: its file is kept).
    """
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp.npz")
    try:
        with open(tmp, "xb") as f:
            np.savez(f, format=np.int64(FORMAT), x=arrays.x, cells=arrays.cells, cell_values=arrays.cell_values,
                     gmsh_cell=np.int64(arrays.gmsh_cell), facets=arrays.facets,
                     facet_values=arrays.facet_values, gmsh_facet=np.int64(arrays.gmsh_facet))
        try:
            os.link(tmp, path)
        except FileExistsError:
            pass                                   # written meanwhile by another run: keep it
        except OSError:                            # no hard links on this file system
            if not path.exists():
                os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def load(path: pathlib.Path) -> MeshArrays:
    """Arrays saved by :func:`save` (numpy only)."""
    with np.load(path, allow_pickle=False) as z:
        if int(z["format"]) != FORMAT:
            raise ValueError(f"{path.name}: cached mesh format {int(z['format'])}, expected {FORMAT}")
        return MeshArrays(x=z["x"], cells=z["cells"], cell_values=z["cell_values"], gmsh_cell=int(z["gmsh_cell"]),
                          facets=z["facets"], facet_values=z["facet_values"], gmsh_facet=int(z["gmsh_facet"]))


def _ufl_mesh(gmsh_cell: int, gdim: int) -> ufl.Mesh:
    """As ``dolfinx.io.gmshio.ufl_mesh``: equispaced Lagrange coordinate element."""
    shape, degree = _GMSH_CELLS[gmsh_cell]
    cell = ufl.Cell(shape, geometric_dimension=gdim)
    return ufl.Mesh(ufl.VectorElement(ufl.FiniteElement("Lagrange", cell, degree, variant="equispaced")))


def build(comm, arrays: MeshArrays | None, rank: int, gdim: int):
    """Distributed mesh, cell tags and facet tags from ``arrays`` given on ``rank`` (None elsewhere);
    MPI collective. The body of ``dolfinx.io.gmshio.model_to_mesh`` after its extraction."""
    if comm.rank == rank:
        cell_id, num_nodes = comm.bcast([arrays.gmsh_cell, arrays.cells.shape[1]], root=rank)   # MPI collective
        has_facet_data = comm.bcast(arrays.gmsh_facet != -1, root=rank)
        if has_facet_data:
            num_facet_nodes = comm.bcast(arrays.facets.shape[1], root=rank)
            marked_facets, facet_values = arrays.facets, arrays.facet_values
        cells, x, cell_values = arrays.cells, arrays.x, arrays.cell_values
    else:
        cell_id, num_nodes = comm.bcast([None, None], root=rank)
        cells, x = np.empty([0, num_nodes], dtype=np.int32), np.empty([0, gdim])
        cell_values = np.empty((0,), dtype=np.int32)
        has_facet_data = comm.bcast(None, root=rank)
        if has_facet_data:
            num_facet_nodes = comm.bcast(None, root=rank)
            marked_facets = np.empty((0, num_facet_nodes), dtype=np.int32)
            facet_values = np.empty((0,), dtype=np.int32)
    ufl_domain = _ufl_mesh(cell_id, gdim)
    cell_type = dolfinx.cpp.mesh.to_type(str(ufl_domain.ufl_cell()))
    cells = cells[:, dolfinx.cpp.io.perm_gmsh(cell_type, num_nodes)]
    mesh = dolfinx.mesh.create_mesh(comm, cells, x[:, :gdim], ufl_domain)
    local_entities, local_values = dolfinx.cpp.io.distribute_entity_data(mesh._mesh, mesh.topology.dim, cells,
                                                                          cell_values)
    mesh.topology.create_connectivity(mesh.topology.dim, 0)
    ct = dolfinx.mesh.meshtags_from_entities(mesh, mesh.topology.dim, dolfinx.cpp.graph.AdjacencyList_int32(local_entities),
                                             local_values.astype(np.int32))
    ct.name = "Cell tags"
    tdim = mesh.topology.dim
    if has_facet_data:
        facet_type = dolfinx.cpp.mesh.cell_entity_type(cell_type, tdim - 1, 0)
        marked_facets = marked_facets[:, dolfinx.cpp.io.perm_gmsh(facet_type, num_facet_nodes)]
        local_entities, local_values = dolfinx.cpp.io.distribute_entity_data(mesh._mesh, tdim - 1, marked_facets,
                                                                              facet_values)
        mesh.topology.create_connectivity(tdim - 1, tdim)
        ft = dolfinx.mesh.meshtags_from_entities(mesh, tdim - 1, dolfinx.cpp.graph.AdjacencyList_int32(local_entities),
                                                 local_values.astype(np.int32))
        ft.name = "Facet tags"
    else:
        ft = dolfinx.mesh.meshtags(mesh, tdim - 1, np.empty(0, dtype=np.int32), np.empty(0, dtype=np.int32))
    return mesh, ct, ft
