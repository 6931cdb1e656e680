"""Linear elasticity operators of the block, reduced to the non-Dirichlet DOFs.

Units: mm, N, MPa (N/mm^2), tonne/mm^3, so that K is in N/mm and M in
tonne. The top side CD carries a prescribed displacement and is removed
from the system; nothing is prescribed on the contact side AB or on the
lateral sides.

Reduced numbering: every rank keeps its OWNED DOLFINx dofs (blocked
numbering, ``node*2 + component``) that are not on CD, in ascending
order. The reduced global index of a kept dof is its position in the
rank-ordered concatenation of these lists, i.e. the row of ``K``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.mesh
import numpy as np
import numpy.typing as npt
import ufl
from dolfinx.cpp.mesh import MeshTags_int32
from mpi4py import MPI
from petsc4py import PETSc

from app.systems import jit
from app.systems.block.mesh import AB, CD
from app.systems.elasticity import lame_parameters
from app.systems.stress import strain, stress

__all__ = ["BlockOperators", "block_operators"]


@dataclass
class BlockOperators:
    """Reduced stiffness (and mass) operators of the block.

    Attributes
    ----------
    mesh
        The mesh.
    facet_tags
        Facet tags (AB, CD, LATERAL).
    V
        Vector Lagrange space of the displacement.
    K
        Reduced stiffness in N/mm (CD dofs removed), SPD, distributed.
    kept
        Owned global DOLFINx (unrolled) dof indices kept in the
        reduced system, ascending; rank-ordered they define the
        reduced numbering.
    load_x
        Reduced right-hand side -K_{kept,D} u_D for u_D = (1, 0) on CD.
    load_y
        Same for u_D = (0, 1).
    contact_x
        x coordinate of every dof-carrying node of AB, sorted
        from A to B, identical on every rank.
    contact_dof_x
        Reduced global index of the ux dof of each contact node.
    contact_dof_y
        Reduced global index of the uy dof of each contact node.
    mass_kind
        "consistent" or "lumped" (row sums).
    """

    mesh: dolfinx.mesh.Mesh
    facet_tags: MeshTags_int32
    V: dolfinx.fem.FunctionSpace
    K: PETSc.Mat
    kept: PETSc.IS
    load_x: PETSc.Vec
    load_y: PETSc.Vec
    contact_x: npt.NDArray[np.float64]
    contact_dof_x: npt.NDArray[np.int64]
    contact_dof_y: npt.NDArray[np.int64]
    mass_kind: str = "consistent"
    #: the mixed element's pressure space (None: the displacement element); its owned DOFs follow
    #: each rank's kept displacement DOFs in the reduced numbering, and :attr:`pressure` holds the
    #: pressure of the last field :meth:`to_function` made
    Q: dolfinx.fem.FunctionSpace | None = None
    pressure: dolfinx.fem.Function | None = None
    static: npt.NDArray[np.int64] | None = None       # the pressure DOFs (reduced, all ranks'), else None
    # Local (unrolled) indices of the owned kept dofs, in reduced order
    _kept_local: npt.NDArray[np.int32] = field(default=None, repr=False)
    # Local (unrolled, owned and ghost) indices of the CD dofs, per component
    _cd_local_x: npt.NDArray[np.int32] = field(default=None, repr=False)
    _cd_local_y: npt.NDArray[np.int32] = field(default=None, repr=False)
    _mass_form: dolfinx.fem.FormMetaClass = field(default=None, repr=False)
    _M: PETSc.Mat | None = field(default=None, repr=False)
    _M_full: PETSc.Mat | None = field(default=None, repr=False)

    @property
    def reduced_offset(self) -> int:
        """Reduced global index of this rank's first kept dof."""
        return self.K.getOwnershipRange()[0]

    def mass(self, full: bool = False) -> PETSc.Mat:
        """Mass matrix in tonne (density * thickness * int u.v), built on first call and cached.

        Parameters
        ----------
        full
            If True, return the matrix on all dofs of ``V`` (CD
            included, DOLFINx numbering) instead of the reduced one.

        Returns
        -------
        PETSc.Mat
            The consistent or row-sum lumped mass matrix, according to :attr:`mass_kind`.
        """
        if self._M_full is None:
            M_full = (dolfinx.fem.petsc.assemble_matrix_block(self._mass_form) if isinstance(self._mass_form, list)
                      else dolfinx.fem.petsc.assemble_matrix(self._mass_form))   # mixed: no mass on the pressure
            M_full.assemble()
            if self.mass_kind == "lumped":
                # Row sums of the consistent matrix, on a diagonal matrix
                d = M_full.getRowSum()
                M_full.destroy()
                M_full = _diagonal_matrix(d)
                d.destroy()
            self._M_full = M_full
        if full:
            return self._M_full
        if self._M is None:
            self._M = self._M_full.createSubMatrix(self.kept, self.kept)
        return self._M

    def to_function(self, u_reduced: PETSc.Vec | np.ndarray, gx: float, gy: float) -> dolfinx.fem.Function:
        """Full displacement field from a reduced vector and the displacement (gx, gy) of CD.

        Parameters
        ----------
        u_reduced
            Reduced displacement: a PETSc vector with the layout
            of ``K``, or a numpy array holding either this rank's part
            (length ``kept.getLocalSize()``) or the whole reduced vector
            (length ``kept.getSize()``).
        gx
            Prescribed x displacement of CD.
        gy
            Prescribed y displacement of CD.

        Returns
        -------
        dolfinx.fem.Function
            The displacement in ``V`` (ghosts updated).
        """
        n_local = self.kept.getLocalSize()
        if isinstance(u_reduced, PETSc.Vec):
            values = u_reduced.getArray(readonly=True)
            if values.size != n_local:
                raise ValueError(f"Reduced vector has local size {values.size}, expected {n_local}")
        else:
            values = np.asarray(u_reduced, dtype=PETSc.ScalarType).ravel()
            if values.size == n_local:
                pass
            elif values.size == self.kept.getSize():
                start = self.reduced_offset
                values = values[start:start + n_local]
            else:
                raise ValueError(f"Reduced array has size {values.size}, expected {n_local} (local) "
                                 f"or {self.kept.getSize()} (global)")

        u = dolfinx.fem.Function(self.V, name="displacement")
        u.x.array[:] = 0.0
        u.x.array[self._kept_local] = values[:self._kept_local.size]
        if self.pressure is not None:               # then the rank's pressure DOFs (mixed element)
            self.pressure.x.array[:values.size - self._kept_local.size] = values[self._kept_local.size:]
            self.pressure.x.scatter_forward()
        u.x.array[self._cd_local_x] = gx
        u.x.array[self._cd_local_y] = gy
        u.x.scatter_forward()
        return u

    def destroy(self) -> None:
        """Destroy the PETSc objects held by the operators."""
        for obj in (self.K, self.kept, self.load_x, self.load_y, self._M, self._M_full):
            if obj is not None:
                obj.destroy()
        self._M = self._M_full = None


def _diagonal_matrix(d: PETSc.Vec) -> PETSc.Mat:
    """Distributed AIJ matrix with diagonal ``d`` and the layout of ``d``."""
    A = PETSc.Mat().createAIJ((d.getSizes(), d.getSizes()), nnz=(1, 0), comm=d.getComm())
    A.setUp()
    A.setDiagonal(d)
    A.assemble()
    return A


def _snap_to_facet_points(x: npt.NDArray[np.float64], mesh: dolfinx.mesh.Mesh,
                          facets: npt.NDArray[np.int32]) -> npt.NDArray[np.float64]:
    """Replace tabulated dof x coordinates by the exact vertex or midpoint x of the facets.

    ``tabulate_dof_coordinates`` pushes reference points forward with
    round-off (e.g. -4e-17 instead of 0) that depends on the cell, hence on
    the partition. Dofs of P1/P2 on straight facets sit at the vertices or
    midpoints, whose coordinates are computed here from the geometry alone.
    """
    fdim = mesh.topology.dim - 1
    nodes = dolfinx.cpp.mesh.entities_to_geometry(mesh._mesh, fdim, np.asarray(facets, dtype=np.int32), False)
    ends = mesh.geometry.x[nodes[:, [0, 1]], 0]  # first two geometry nodes are the facet vertices
    candidates = np.unique(np.concatenate([ends.ravel(), 0.5 * (ends[:, 0] + ends[:, 1])]))
    if x.size == 0:
        return x.copy()
    pos = np.clip(np.searchsorted(candidates, x), 1, candidates.size - 1)
    nearest = np.where(np.abs(candidates[pos - 1] - x) <= np.abs(candidates[pos] - x), pos - 1, pos) \
        if candidates.size > 1 else np.zeros(x.size, dtype=np.intp)
    scale = max(1.0, float(np.abs(candidates).max()))
    if np.any(np.abs(candidates[nearest] - x) > 1e-10 * scale):
        raise RuntimeError("Contact dofs are not at facet vertices or midpoints")
    return candidates[nearest]


def block_operators(mesh: dolfinx.mesh.Mesh, facet_tags: MeshTags_int32, E: float, nu: float,
                    thickness: float, density: float, plane: str = "stress", degree: int = 1,
                    mass_kind: str = "consistent", element: str = "displacement") -> BlockOperators:
    """Assemble the reduced elasticity operators of the block (collective).

    Parameters
    ----------
    mesh
        Mesh of the block (see :func:`app.systems.block.mesh.block_mesh`).
    facet_tags
        Facet tags with AB and CD.
    E
        Young's modulus in MPa.
    nu
        Poisson's ratio.
    thickness
        Out-of-plane thickness in mm (multiplies K and M).
    density
        Density in tonne/mm^3.
    plane
        "stress" or "strain".
    degree
        Degree of the vector Lagrange space (1 or 2).
    mass_kind
        "consistent" or "lumped" (row sums of the consistent
        matrix; singular for degree 2, whose vertex row sums vanish).
    element
        "displacement", or "mixed": Taylor-Hood, the displacement of ``degree`` 2 and a P1
        pressure (app/systems/stress.py ``mixed_forms``), the pressure DOFs after each rank's
        kept displacement DOFs.

    Returns
    -------
    BlockOperators
        The reduced operators.
    """
    if degree not in (1, 2):
        raise ValueError(f"degree must be 1 or 2, got {degree}")
    if mass_kind not in ("consistent", "lumped"):
        raise ValueError(f"mass_kind must be 'consistent' or 'lumped', got {mass_kind!r}")
    if mass_kind == "lumped" and degree == 2:
        warnings.warn("Row-sum lumping of P2 triangles gives zero vertex masses (singular M)",
                      stacklevel=2)
    if not (thickness > 0 and density > 0):
        raise ValueError(f"thickness and density must be positive, got {thickness}, {density}")
    mixed = element == "mixed"
    if mixed and degree != 2:
        raise ValueError("the mixed element is Taylor-Hood P2-P1: degree must be 2")

    V = dolfinx.fem.FunctionSpace(mesh, ufl.VectorElement("CG", mesh.ufl_cell(), degree), **jit.params())
    Q = dolfinx.fem.FunctionSpace(mesh, ("CG", 1), **jit.params()) if mixed else None
    bs = V.dofmap.index_map_bs
    a, m = _forms(V, Q, E, nu, thickness, density, plane)
    K_full = dolfinx.fem.petsc.assemble_matrix_block(a) if mixed else dolfinx.fem.petsc.assemble_matrix(a)
    K_full.assemble()
    # each rank's rows: its owned displacement DOFs (unrolled), then (mixed) its owned pressure DOFs
    row_start = K_full.getOwnershipRange()[0]
    n_extra = Q.dofmap.index_map.size_local if mixed else 0

    cd_blocks, cd_owned = _cd_dofs(V, facet_tags)
    cd_local_x = (cd_blocks * bs).astype(np.int32)
    cd_local_y = (cd_blocks * bs + 1).astype(np.int32)
    kept_local, reduced_index, kept, rows, static = _kept_dofs(V, cd_owned, row_start, n_extra)

    # Stiffness: full assembly without bcs, then restriction
    K = K_full.createSubMatrix(kept, kept)
    loads = _cd_loads(K_full, K, cd_owned, row_start, bs, rows)
    K_full.destroy()
    cx, cdx, cdy, order = _contact_nodes(V, facet_tags, reduced_index)

    return BlockOperators(mesh=mesh, facet_tags=facet_tags, V=V, K=K, kept=kept,
                          load_x=loads[0], load_y=loads[1],
                          contact_x=cx[order], contact_dof_x=cdx[order].astype(np.int64),
                          contact_dof_y=cdy[order].astype(np.int64), mass_kind=mass_kind,
                          Q=Q, pressure=dolfinx.fem.Function(Q, name="pressure") if mixed else None, static=static,
                          _kept_local=kept_local, _cd_local_x=cd_local_x, _cd_local_y=cd_local_y,
                          _mass_form=m)


def _forms(V, Q, E: float, nu: float, thickness: float, density: float, plane: str):
    """The compiled stiffness and mass forms ``(a, m)``: one form each, or with the mixed element's
    pressure space ``Q`` the 2x2 blocks (app/systems/stress.py ``mixed_forms``; no mass on the
    pressure). The parameters are Constants, so that the generated code is reused."""
    mesh = V.mesh
    t = dolfinx.fem.Constant(mesh, PETSc.ScalarType(thickness))
    rho = dolfinx.fem.Constant(mesh, PETSc.ScalarType(density))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    mass = rho * t * ufl.inner(u, v) * ufl.dx
    if Q is None:
        mu_value, lmbda_value = lame_parameters(E, nu, plane)
        mu = dolfinx.fem.Constant(mesh, PETSc.ScalarType(mu_value))
        lmbda = dolfinx.fem.Constant(mesh, PETSc.ScalarType(lmbda_value))
        return (dolfinx.fem.form(t * ufl.inner(stress(u, mu, lmbda), strain(v)) * ufl.dx, **jit.params()),
                dolfinx.fem.form(mass, **jit.params()))
    from app.systems.elasticity import bulk_compliance
    from app.systems.stress import mixed_forms, mixed_mass
    mu = dolfinx.fem.Constant(mesh, PETSc.ScalarType(E / (2.0 * (1.0 + nu))))
    inv_kappa = dolfinx.fem.Constant(mesh, PETSc.ScalarType(bulk_compliance(E, nu, plane)))
    p, q = ufl.TrialFunction(Q), ufl.TestFunction(Q)
    a = [[dolfinx.fem.form(f, **jit.params()) for f in row] for row in mixed_forms(u, p, v, q, mu, inv_kappa, t)]
    return a, [[None if f is None else dolfinx.fem.form(f, **jit.params()) for f in row] for row in mixed_mass(mass, p, q)]


def _cd_dofs(V, facet_tags: MeshTags_int32) -> tuple[np.ndarray, np.ndarray]:
    """The Dirichlet (CD) dofs: local block indices, owned and ghost (remote=True also finds dofs
    of CD reachable only through another rank's facets), and the owned ones."""
    mesh = V.mesh
    fdim = mesh.topology.dim - 1
    cd_facets = facet_tags.indices[facet_tags.values == CD]
    cd_blocks = dolfinx.fem.locate_dofs_topological(V, fdim, cd_facets)
    if mesh.comm.allreduce(cd_blocks.size, op=MPI.SUM) == 0:
        raise ValueError(f"No facets tagged CD={CD}")
    return cd_blocks, cd_blocks[cd_blocks < V.dofmap.index_map.size_local]


def _kept_dofs(V, cd_owned: np.ndarray, row_start: int, n_extra: int
               ) -> tuple[np.ndarray, np.ndarray, PETSc.IS, np.ndarray, np.ndarray | None]:
    """Kept dofs: owned minus CD, ascending, then the ``n_extra`` pressure DOFs (mixed element);
    reduced numbering by exscan offset. Returns the local kept displacement dofs, the reduced index
    of every owned dof (-1 on CD), the kept rows' global IS (the assembled matrix's rows start at
    ``row_start`` on this rank), the kept rows' local indices and the pressure DOFs' reduced
    indices (every rank's; None without a pressure). MPI collective."""
    comm = V.mesh.comm
    bs = V.dofmap.index_map_bs
    index_map = V.dofmap.index_map
    n_owned = index_map.size_local * bs
    is_dirichlet = np.zeros(n_owned, dtype=bool)
    is_dirichlet[cd_owned * bs] = True
    is_dirichlet[cd_owned * bs + 1] = True
    kept_local = np.flatnonzero(~is_dirichlet).astype(np.int32)
    n_kept = kept_local.size
    offset = comm.exscan(n_kept + n_extra, op=MPI.SUM)
    offset = 0 if comm.rank == 0 else offset
    reduced_index = np.full(n_owned, -1, dtype=np.int64)
    reduced_index[kept_local] = offset + np.arange(n_kept, dtype=np.int64)
    rows = np.concatenate([kept_local, n_owned + np.arange(n_extra, dtype=np.int32)])
    kept = PETSc.IS().createGeneral((row_start + rows).astype(PETSc.IntType), comm=comm)
    static = (np.concatenate(comm.allgather(offset + n_kept + np.arange(n_extra))).astype(np.int64)   # MPI collective
              if comm.allreduce(n_extra, op=MPI.SUM) else None)
    return kept_local, reduced_index, kept, rows, static


def _cd_loads(K_full: PETSc.Mat, K: PETSc.Mat, cd_owned: np.ndarray, owned_start: int, bs: int,
              kept_local: np.ndarray) -> list[PETSc.Vec]:
    """Loads -K_{kept,D} u_D of a unit displacement of CD in x, resp. y.

    Rows of K_full u_D on kept dofs are K_{kept,D} u_D (u_D vanishes off CD); kept dofs are
    owned, so the restriction is local. ``owned_start``: the assembled matrix's first row on this
    rank; ``kept_local``: the kept rows' local indices (the mixed element's pressure rows too)."""
    u_D, Ku_D = K_full.createVecs()
    loads = []
    for component in range(bs):
        u_D.zeroEntries()
        rows = (owned_start + cd_owned * bs + component).astype(PETSc.IntType)
        u_D.setValues(rows, np.ones(rows.size, dtype=PETSc.ScalarType), addv=PETSc.InsertMode.INSERT_VALUES)
        u_D.assemble()
        K_full.mult(u_D, Ku_D)
        load = K.createVecRight()
        load.setArray(-Ku_D.getArray(readonly=True)[kept_local])
        loads.append(load)
    u_D.destroy()
    Ku_D.destroy()
    return loads


def _contact_nodes(V, facet_tags: MeshTags_int32, reduced_index: np.ndarray):
    """Contact nodes on AB: owned dof-carrying nodes, gathered on every rank. Returns their x,
    reduced x and y dofs (every rank's, concatenated) and the order of the distinct ones by x."""
    mesh = V.mesh
    comm = mesh.comm
    fdim = mesh.topology.dim - 1
    bs = V.dofmap.index_map_bs
    ab_facets = facet_tags.indices[facet_tags.values == AB]
    ab_blocks = dolfinx.fem.locate_dofs_topological(V, fdim, ab_facets)
    ab_blocks = ab_blocks[ab_blocks < V.dofmap.index_map.size_local]
    x_contact = _snap_to_facet_points(V.tabulate_dof_coordinates()[ab_blocks, 0], mesh, ab_facets)
    local_contact = (x_contact, reduced_index[ab_blocks * bs], reduced_index[ab_blocks * bs + 1])
    if comm.allreduce(bool(np.any(local_contact[1] < 0)), op=MPI.LOR):
        raise RuntimeError("A contact dof on AB is also on CD")
    gathered = comm.allgather(local_contact)
    cx = np.concatenate([g[0] for g in gathered])
    cdx = np.concatenate([g[1] for g in gathered])
    cdy = np.concatenate([g[2] for g in gathered])
    _, unique = np.unique(cdx, return_index=True)
    order = unique[np.argsort(cx[unique], kind="stable")]
    return cx, cdx, cdy, order
