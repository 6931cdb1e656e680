"""``system.type: gmsh``: the operators of a 2D body from a Gmsh file, in the obstacle frames
(:func:`body_operators`; the System and the loading path are built by app/systems/gmsh/path.py).

Operators (DOLFINx): K and M of plane stress/strain linear elasticity with a material per
physical surface (DG0 coefficients), reduced to the DOFs not prescribed by the program
(``prescribed`` curves, per component). Reduced numbering as in app/systems/block/operators.py: each
rank keeps its owned DOFs that are not prescribed, in ascending order.

Load parameters (unit right-hand sides of the reduced system, ``-K_kD u_D`` for prescribed
motions, assembled loads for the others): per prescribed curve its translations (x, y as
prescribed) and, with both components, a rotation about the origin (``u = theta (-y, x)``; a
rotation about a point p adds the translation ``theta (p_y, -p_x)``); per loaded curve the two
components of a uniform traction and of a total force; gravity (x, y).

Obstacle frames: the contact DOFs are rotated into the obstacle's tangent t and outward normal n
(``u = t u_T + n u_N`` at every contact node): ``K' = R^T K R``, ``M' = R^T M R`` and loads
``R^T f`` with R orthogonal and block-diagonal, so the stability code sees plain DOF pairs in the
paper's axes (docs/method.md section 1). For axis-aligned obstacles R has entries 0 and +-1 and the
rotation is exact. Initial gaps ``g0 = (p - x) . n`` from the geometry (p the obstacle's point).
"""
from __future__ import annotations

import pathlib
from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from app.common.stages import Stages
from app.systems import jit
from app.systems.gmsh.fields import FieldData
from app.systems.gmsh.interface import contact_edges
from app.systems.gmsh.schema import GmshBody


class BodyError(Exception):
    """A problem of the body found while building it (one line; the CLI exits with status 2)."""


@dataclass
class BodyOperators:
    """Reduced, obstacle-rotated operators of the body and its load parameters."""

    K: PETSc.Mat
    R: PETSc.Mat
    kept: PETSc.IS
    loads: list[PETSc.Vec]                    # one reduced, rotated right-hand side per parameter
    params: dict[tuple, int]                  # (kind, curve, component) -> index
    contact_dofs: np.ndarray                  # (n, 2) reduced DOFs (u_T, u_N) of the contact nodes
    contact_xy: np.ndarray                    # (n, 2) coordinates
    contact_edges: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 2)))   # (m, 2, 2) facet ends
    # (smallest clearance (p - x).n of any node, that node, body size, fraction of the nodes beyond the line)
    deepest: tuple = (np.inf, (0.0, 0.0), 1.0, 0.0)
    left_out: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))   # contact-curve nodes with one prescribed component
    mass_form: object = None
    mass_kind: str = "consistent"
    degree: int = 1
    field_data: FieldData | None = None       # what BodyFields needs (space, prescribed DOFs, materials)
    static: np.ndarray | None = None          # the mixed element's pressure DOFs (reduced, all ranks'), else None

    @property
    def size(self) -> float:
        """The body's bounding-box size (largest extent of its nodes over all ranks)."""
        return self.deepest[2]

    def mass(self) -> PETSc.Mat:
        """Reduced, rotated mass matrix (assembled on first use; the caller owns the copy it gets)."""
        import dolfinx.fem.petsc
        M_full = (dolfinx.fem.petsc.assemble_matrix_block(self.mass_form) if isinstance(self.mass_form, list)
                  else dolfinx.fem.petsc.assemble_matrix(self.mass_form))      # mixed: the pressure carries no mass
        try:
            M_full.assemble()
            if self.mass_kind == "lumped":
                # P1: row sums. P2: row sums vanish at the vertices (singular M), so the HRZ lumping:
                # the diagonal scaled to keep each element's mass, for affine P2 triangles the
                # constant factor 30/19 (element diagonal: A/30 per vertex, 8A/45 per mid-side node)
                if self.degree == 2:
                    d = M_full.getDiagonal()
                    d.scale(30.0 / 19.0)
                else:
                    d = M_full.getRowSum()
                M_full.zeroEntries()
                M_full.setDiagonal(d)
                d.destroy()
            M = M_full.createSubMatrix(self.kept, self.kept)
        finally:
            M_full.destroy()
        try:
            return M.PtAP(self.R)
        finally:
            M.destroy()

    def destroy(self) -> None:
        """Destroy the PETSc objects: ``K``, the rotation ``R``, the kept DOFs and the unit loads."""
        for obj in (self.K, self.R, self.kept, *self.loads):
            obj.destroy()


def body_operators(cfg: GmshBody, comm: MPI.Comm, stages: Stages) -> BodyOperators:
    """Mesh, assemble, reduce and rotate (MPI collective)."""
    import dolfinx.fem
    import dolfinx.fem.petsc
    import ufl

    from app.systems.gmsh.mesh import read_mesh
    from app.systems.stress import mixed_forms, mixed_mass, strain, stress
    with stages("mesh (gmsh)"):
        mesh, cell_tags, facet_tags, names = read_mesh(pathlib.Path(cfg.file), comm, size_factor=cfg.mesh_size_factor)
    mixed = cfg.element == "mixed"
    Q = dolfinx.fem.FunctionSpace(mesh, ("CG", 1), **jit.params()) if mixed else None
    sp = _Space(comm, mesh, facet_tags, dolfinx.fem.FunctionSpace(mesh, ufl.VectorElement("CG", mesh.ufl_cell(), cfg.degree), **jit.params()),
                {nm: t for (d, nm), t in names.items() if d == 1}, {nm: t for (d, nm), t in names.items() if d == 2}, Q)
    mu_f, lam_f, rho_f = _materials(cfg, sp, cell_tags)
    t = dolfinx.fem.Constant(mesh, PETSc.ScalarType(cfg.thickness))
    u, v = ufl.TrialFunction(sp.V), ufl.TestFunction(sp.V)

    with stages("assemble stiffness"):
        foundation = (dolfinx.fem.Constant(mesh, PETSc.ScalarType(cfg.foundation)) * t * ufl.inner(u, v) * ufl.dx
                      if cfg.foundation is not None else None)      # weak elastic foundation (a floating body)
        mass = rho_f * t * ufl.inner(u, v) * ufl.dx
        if mixed:            # blocks [[u, p]]: each rank's rows are its u DOFs, then its p DOFs
            p_, q_ = ufl.TrialFunction(Q), ufl.TestFunction(Q)
            blocks = mixed_forms(u, p_, v, q_, mu_f, lam_f, t)      # lam_f holds 1/kappa here (_materials)
            if foundation is not None:
                blocks[0][0] = blocks[0][0] + foundation
            a = [[dolfinx.fem.form(f, **jit.params()) for f in row] for row in blocks]
            m = [[None if f is None else dolfinx.fem.form(f, **jit.params()) for f in row]
                 for row in mixed_mass(mass, p_, q_)]
            K_full = dolfinx.fem.petsc.assemble_matrix_block(a)
        else:
            stiff = t * ufl.inner(stress(u, mu_f, lam_f), strain(v)) * ufl.dx
            a = dolfinx.fem.form(stiff if foundation is None else stiff + foundation, **jit.params())
            m = dolfinx.fem.form(mass, **jit.params())
            K_full = dolfinx.fem.petsc.assemble_matrix(a)
        K_full.assemble()
    sp.set_rows(K_full.getOwnershipRange()[0])

    dof_x = sp.V.tabulate_dof_coordinates()[:, :2]
    presc, kept_local, reduced, kept = _prescribed(cfg, sp, K_full)
    K = K_full.createSubMatrix(kept, kept)
    params, raw = _motion_loads(sp, K_full, presc, kept_local, dof_x)
    _applied_loads(cfg, sp, v, rho_f, t, kept_local, params, raw)
    K_full.destroy()

    edges = contact_edges(mesh, sp.facets(cfg.contact), comm)                     # MPI collective
    obstacle_blocks, obstacle_ends = np.zeros(0, dtype=np.int64), None
    if cfg.obstacle.type == "body":            # its contact geometry first: the frame and the gaps need it
        obstacle_blocks, obstacle_ends = _obstacle_body(cfg, sp, cell_tags, dof_x, (K, kept))   # MPI collective
    tvec, nvec = cfg.obstacle.frame()
    deepest = _clearance(cfg, sp, dof_x, obstacle_blocks)
    left_out, xy, dx_, dy_ = _contact_nodes(cfg, sp, dof_x, reduced, (K, kept))
    links = None
    if cfg.obstacle.type == "body":
        from app.systems.gmsh.interface import links as pairing
        links = _interface((K, kept), pairing, cfg, sp, dof_x, reduced, xy, deepest[2], obstacle_ends)  # MPI collective
    R = _rotation(K, dx_, dy_, tvec, nvec, comm, links)
    Kr = K.PtAP(R)
    K.destroy()
    loads = []
    for vals in raw:
        f = Kr.createVecLeft()
        f.setArray(vals)
        g = Kr.createVecLeft()
        R.multTranspose(f, g)
        f.destroy()
        loads.append(g)
    return BodyOperators(K=Kr, R=R, kept=kept, loads=loads, params=params,
                         contact_dofs=np.column_stack([dx_, dy_]).astype(np.int64), contact_xy=xy, contact_edges=edges,
                         deepest=deepest, left_out=left_out,
                         mass_form=m, mass_kind=cfg.mass, degree=cfg.degree,
                         field_data=FieldData(V=sp.V, prescribed=presc, kept_local=kept_local, dof_x=dof_x, mu=mu_f,
                                              lmbda=lam_f, Q=Q, two_nu=_two_nu(cfg, sp, cell_tags) if mixed else None),
                         static=sp.static.astype(np.int64) if mixed else None)


class _Space:
    """The body's vector space and its numbering, shared by the steps of :func:`body_operators`.

    The assembled matrix has, on each rank, the rank's owned displacement DOFs (unrolled, in ``V``'s
    local order) from row ``row_start`` on, then (mixed element) its owned pressure DOFs of ``Q``:
    ``n_extra`` rows that are never prescribed."""

    def __init__(self, comm: MPI.Comm, mesh, facet_tags, V, tag_of_curve: dict, tag_of_surface: dict, Q=None):
        self.comm, self.mesh, self.facet_tags, self.V, self.Q = comm, mesh, facet_tags, V, Q
        self.tag_of_curve, self.tag_of_surface = tag_of_curve, tag_of_surface
        self.bs = V.dofmap.index_map_bs
        self.im = V.dofmap.index_map
        self.n_owned = self.im.size_local * self.bs
        self.n_extra = Q.dofmap.index_map.size_local if Q is not None else 0
        self.static = np.zeros(0, dtype=np.int64)      # the pressure DOFs' reduced indices (all ranks')
        self.row_start = self.im.local_range[0] * self.bs

    def set_rows(self, first: int) -> None:
        """The assembled matrix's first row on this rank."""
        self.row_start = int(first)

    def extra_rows(self) -> np.ndarray:
        """Local rows (in the assembled layout) of the pressure DOFs."""
        return self.n_owned + np.arange(self.n_extra, dtype=np.int32)

    def facets(self, curve: str) -> np.ndarray:
        return self.facet_tags.indices[self.facet_tags.values == self.tag_of_curve[curve]]


def _materials(cfg: GmshBody, sp: _Space, cell_tags):
    """The Lamé parameters and density of every physical surface, as DG0 functions (the mixed
    element: mu, the bulk compliance 1/kappa and the density)."""
    import dolfinx.fem

    from app.systems.elasticity import bulk_compliance, lame_parameters
    Q = dolfinx.fem.FunctionSpace(sp.mesh, ("DG", 0), **jit.params())
    mu_f, lam_f, rho_f = (dolfinx.fem.Function(Q) for _ in range(3))
    for name, tag in sp.tag_of_surface.items():
        cells = Q.dofmap.list.array[cell_tags.indices[cell_tags.values == tag]]   # the cells' DG0 DOFs
        mat = cfg.material_of(name)
        if cfg.element == "mixed":      # mu and the bulk compliance 1/kappa (app/systems/stress.py mixed_forms)
            mu_v, lam_v = mat.E / (2.0 * (1.0 + mat.nu)), bulk_compliance(mat.E, mat.nu, cfg.plane)
        else:
            mu_v, lam_v = lame_parameters(mat.E, mat.nu, cfg.plane)
        mu_f.x.array[cells] = mu_v
        lam_f.x.array[cells] = lam_v
        rho_f.x.array[cells] = mat.density
    for f in (mu_f, lam_f, rho_f):
        f.x.scatter_forward()
    return mu_f, lam_f, rho_f


def _two_nu(cfg: GmshBody, sp: _Space, cell_tags):
    """``2 nu`` per cell (DG0): the mixed element's out-of-plane stress ``s_zz = 2 nu p`` (plane strain)."""
    import dolfinx.fem
    Q = dolfinx.fem.FunctionSpace(sp.mesh, ("DG", 0), **jit.params())
    f = dolfinx.fem.Function(Q)
    for name, tag in sp.tag_of_surface.items():
        f.x.array[Q.dofmap.list.array[cell_tags.indices[cell_tags.values == tag]]] = 2.0 * cfg.material_of(name).nu
    f.x.scatter_forward()
    return f


def _prescribed(cfg: GmshBody, sp: _Space, K_full: PETSc.Mat):
    """Prescribed DOFs (local unrolled indices incl. ghosts), per curve and component, and the
    kept DOFs: ``(prescribed, kept_local, reduced index of every owned DOF (-1: prescribed),
    kept IS)``. Destroys ``K_full`` before raising :class:`BodyError`."""
    import dolfinx.fem
    comm, bs, n_owned = sp.comm, sp.bs, sp.n_owned
    fdim = 1
    presc: dict[str, dict[int, np.ndarray]] = {}
    is_d = np.zeros(n_owned, dtype=bool)
    owner = {}
    for name, comps in cfg.all_prescribed().items():
        blocks = dolfinx.fem.locate_dofs_topological(sp.V, fdim, sp.facets(name))
        presc[name] = {}
        for c in (0, 1):
            if "xy"[c] in comps:
                loc = (blocks * bs + c).astype(np.int32)
                presc[name][c] = loc
                own = loc[loc < n_owned]
                clash = [d for d in own if d in owner]
                if comm.allreduce(len(clash), op=MPI.SUM):       # MPI collective
                    K_full.destroy()                               # the error path owns nothing
                    raise BodyError(f"system.prescribed: the curves '{name}' and '{owner.get(clash[0], '?') if clash else '?'}' "
                                    "share nodes: prescribe one motion per node (merge them into one physical curve)")
                owner.update({int(d): name for d in own})
                is_d[own] = True
    kept_local = np.flatnonzero(~is_d).astype(np.int32)
    offset = comm.exscan(kept_local.size + sp.n_extra) or 0        # MPI collective
    reduced = np.full(n_owned, -1, dtype=np.int64)
    reduced[kept_local] = offset + np.arange(kept_local.size)
    rows = np.concatenate([kept_local, sp.extra_rows()])            # then the pressure DOFs, all kept
    kept = PETSc.IS().createGeneral((sp.row_start + rows).astype(PETSc.IntType), comm=comm)
    sp.static = np.concatenate(comm.allgather(offset + kept_local.size + np.arange(sp.n_extra)))   # MPI collective
    return presc, kept_local, reduced, kept


def _motion_loads(sp: _Space, K_full: PETSc.Mat, presc: dict, kept_local: np.ndarray, dof_x: np.ndarray):
    """The load parameters of the prescribed motions (translations, and the rotation of a curve
    prescribed in x and y): ``(params, raw)``, ``raw`` the reduced (unrotated) right-hand sides
    (local part) and ``params`` (kind, curve, component) -> their index."""
    bs, n_owned = sp.bs, sp.n_owned
    params: dict[tuple, int] = {}
    raw: list[np.ndarray] = []
    u_D, Ku_D = K_full.createVecs()
    try:
        for name, comp_dofs in presc.items():
            modes = [("tx", {0: 1.0}), ("ty", {1: 1.0})]
            if len(comp_dofs) == 2:
                modes.append(("rz", None))
            for kind, vals in modes:
                if vals is not None and next(iter(vals)) not in comp_dofs:
                    continue
                u_D.zeroEntries()
                arr = u_D.getArray()
                for c, loc in comp_dofs.items():
                    own = loc[loc < n_owned]
                    if vals is None:      # rotation about the origin: u = (-y, x)
                        arr[own] = -dof_x[own // bs, 1] if c == 0 else dof_x[own // bs, 0]
                    else:
                        arr[own] = vals.get(c, 0.0)
                del arr
                K_full.mult(u_D, Ku_D)
                params[("motion", name, kind)] = len(raw)
                raw.append(-Ku_D.getArray(readonly=True)[np.concatenate([kept_local, sp.extra_rows()])].copy())
    finally:
        u_D.destroy()
        Ku_D.destroy()
    return params, raw


def _applied_loads(cfg: GmshBody, sp: _Space, v, rho_f, t, kept_local: np.ndarray, params: dict,
                   raw: list[np.ndarray]) -> None:
    """The load parameters of the program's tractions, forces and gravity, added to ``params``
    and ``raw`` (as :func:`_motion_loads`)."""
    import dolfinx.fem
    import dolfinx.fem.petsc
    import ufl
    comm, mesh = sp.comm, sp.mesh
    loaded = sorted({nm for ph in cfg.program for kind in ("traction", "force") for nm in getattr(ph, kind)})
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=sp.facet_tags)

    def assemble(expr) -> np.ndarray:
        b = dolfinx.fem.petsc.assemble_vector(dolfinx.fem.form(expr, **jit.params()))
        try:
            b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            return np.concatenate([b.getArray(readonly=True)[kept_local], np.zeros(sp.n_extra)])   # no load on p
        finally:
            b.destroy()

    for name in loaded:
        tag = sp.tag_of_curve[name]
        one = dolfinx.fem.Constant(mesh, PETSc.ScalarType(1.0))
        length = comm.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(one * ds(tag), **jit.params())), op=MPI.SUM)
        for c, kind in ((0, "x"), (1, "y")):
            e = ufl.as_vector([1.0, 0.0]) if c == 0 else ufl.as_vector([0.0, 1.0])
            base = assemble(ufl.inner(e, v) * ds(tag))
            params[("traction", name, kind)] = len(raw)
            raw.append(cfg.thickness * base)
            params[("force", name, kind)] = len(raw)
            raw.append(base / length)
    if any(ph.gravity is not None for ph in cfg.program):
        for c, kind in ((0, "x"), (1, "y")):
            e = ufl.as_vector([1.0, 0.0]) if c == 0 else ufl.as_vector([0.0, 1.0])
            params[("gravity", "", kind)] = len(raw)
            raw.append(assemble(rho_f * t * ufl.inner(e, v) * ufl.dx))


def _obstacle_body(cfg: GmshBody, sp: _Space, cell_tags, dof_x: np.ndarray,
                   owned: tuple) -> tuple[np.ndarray, np.ndarray]:
    """An obstacle body's DOF blocks and its contact curve's segments, its contact geometry set on
    ``cfg.obstacle`` (app/systems/gmsh/interface.py; MPI collective). Destroys the PETSc objects
    ``owned`` before raising :class:`BodyError`."""
    from app.systems.gmsh.interface import body_geometry, surface_blocks
    blocks = surface_blocks(sp, cell_tags, cfg.obstacle.surface)
    ends = contact_edges(sp.mesh, sp.facets(cfg.obstacle.contact), sp.comm)            # MPI collective
    cfg.obstacle._line, cfg.obstacle._curve = _interface(owned, body_geometry, cfg, sp, dof_x, blocks, ends)
    return blocks, ends


def _interface(owned: tuple, fn, *args):
    """``fn(*args)`` of app/systems/gmsh/interface.py (MPI collective); its one-line problem
    becomes a :class:`BodyError`, after the PETSc objects ``owned`` are destroyed."""
    from app.systems.gmsh.interface import InterfaceError
    try:
        return fn(*args)
    except InterfaceError as err:
        for obj in owned:                                          # the error path owns nothing
            obj.destroy()
        raise BodyError(str(err)) from None


def _clearance(cfg: GmshBody, sp: _Space, dof_x: np.ndarray, obstacle_blocks: np.ndarray) -> tuple:
    """The whole body must start on its side of the obstacle line (not only the contact curve):
    (smallest clearance, its node, the body's size, the fraction of nodes beyond the line); an
    obstacle body's own nodes (``obstacle_blocks``) are not the body's."""
    comm = sp.comm
    clear = cfg.obstacle.clearance(dof_x) if len(dof_x) else np.zeros(0)
    clear[obstacle_blocks] = np.inf
    i = int(np.argmin(clear)) if len(clear) else 0
    mine = (float(clear[i]), tuple(float(v) for v in dof_x[i])) if len(clear) else (np.inf, (0.0, 0.0))
    deepest = min(comm.allgather(mine), key=lambda c: c[0])                     # MPI collective
    box = np.array(comm.allgather(np.concatenate([dof_x.min(axis=0), dof_x.max(axis=0)]) if len(dof_x)
                                  else np.array([np.inf, np.inf, -np.inf, -np.inf])))      # MPI collective
    lo, hi = box[:, :2].min(axis=0), box[:, 2:].max(axis=0)
    body = float(np.max(hi - lo))
    owned_clear = clear[:sp.im.size_local]
    beyond = comm.allreduce(int(np.sum(owned_clear < -1e-10 * body)), op=MPI.SUM)    # MPI collective
    total = comm.allreduce(int(np.sum(np.isfinite(owned_clear))), op=MPI.SUM)         # MPI collective
    return (*deepest, body, beyond / max(total, 1))


def _contact_nodes(cfg: GmshBody, sp: _Space, dof_x: np.ndarray, reduced: np.ndarray, owned: tuple):
    """Contact nodes: owned, not prescribed, on the contact curve; gathered and sorted along t.
    Returns ``(left_out, xy, dof_T, dof_N)``, ``left_out`` the contact-curve nodes with one
    prescribed component. Destroys the PETSc objects ``owned`` before raising :class:`BodyError`."""
    import dolfinx.fem
    comm, bs = sp.comm, sp.bs
    cblocks = dolfinx.fem.locate_dofs_topological(sp.V, 1, sp.facets(cfg.contact))
    cblocks = cblocks[cblocks < sp.im.size_local]
    keep = (reduced[cblocks * bs] >= 0) & (reduced[cblocks * bs + 1] >= 0)
    half = keep ^ ((reduced[cblocks * bs] >= 0) | (reduced[cblocks * bs + 1] >= 0))   # one component prescribed
    left_out = np.concatenate([g.reshape(-1, 2) for g in comm.allgather(dof_x[cblocks[half]])])   # MPI collective
    cblocks = cblocks[keep]
    local = (dof_x[cblocks], reduced[cblocks * bs], reduced[cblocks * bs + 1])
    gathered = comm.allgather(local)                                # MPI collective
    xy = np.concatenate([g[0] for g in gathered]).reshape(-1, 2)
    dx_ = np.concatenate([g[1] for g in gathered])
    dy_ = np.concatenate([g[2] for g in gathered])
    if len(dx_) == 0:
        for obj in owned:                                          # the error path owns nothing
            obj.destroy()
        raise BodyError(f"system.contact = '{cfg.contact}': no free node on it (all its nodes are prescribed)")
    s = cfg.obstacle.coordinate(xy)
    order = np.lexsort((xy[:, 1], xy[:, 0], s))
    return left_out, xy[order], dx_[order], dy_[order]


def _rotation(K: PETSc.Mat, dx_: np.ndarray, dy_: np.ndarray, tvec, nvec, comm: MPI.Comm,
              links: list | None = None) -> PETSc.Mat:
    """Change of variables R: u_old = R u_new, identity except [[t_x, n_x], [t_y, n_y]] at contact
    nodes (the obstacle frame); with an obstacle body's ``links`` (per contact node its obstacle
    nodes' weights and DOFs) also ``+ w`` in the columns of those nodes: the contact DOFs become
    relative (app/systems/gmsh/interface.py)."""
    R = PETSc.Mat().createAIJ(K.getSizes(), nnz=(2, 0) if links is None else (5, 3), comm=comm)
    R.setUp()
    r0, r1 = R.getOwnershipRange()
    contact_rows = {}
    for a, (ix, iy) in enumerate(zip(dx_, dy_)):
        if r0 <= ix < r1:
            contact_rows[int(ix)] = (int(iy), a)
    for i in range(r0, r1):
        if i in contact_rows:
            iy, a = contact_rows[i]
            R.setValues([i, iy], [i, iy], [[tvec[0], nvec[0]], [tvec[1], nvec[1]]])
            for w, mx, my in (links[a] if links is not None else ()):
                R.setValue(i, mx, w)
                R.setValue(iy, my, w)
    cy = {iy for iy, _ in contact_rows.values()}
    for i in range(r0, r1):
        if i not in contact_rows and i not in cy:
            R.setValue(i, i, 1.0)
    R.assemble()
    return R
