"""Tests of the block mesh (app.systems.block.mesh) and the reduced elasticity operators
(app.systems.block.operators)."""

from __future__ import annotations

import os
import pathlib
import shutil
import subprocess
import sys
import textwrap

import dolfinx.fem
import numpy as np
import pytest
import ufl
from mpi4py import MPI
from petsc4py import PETSc

from app.systems.block.mesh import AB, CD, LATERAL, block_mesh, structured_triangulation
from app.systems.block.operators import block_operators
from app.systems.elasticity import lame_parameters

REPO = pathlib.Path(__file__).resolve().parents[1]
LENGTH, HEIGHT = 80.0, 40.0
E, NU, THICKNESS, DENSITY = 2000.0, 0.3, 10.0, 1.2e-9


@pytest.fixture(scope="module")
def cache_dir(tmp_path_factory) -> pathlib.Path:
    return tmp_path_factory.mktemp("meshes")


def dense(A: PETSc.Mat) -> np.ndarray:
    """Dense copy of a (serial) PETSc matrix."""
    n, m = A.getSize()
    return A.getValues(np.arange(n, dtype=PETSc.IntType), np.arange(m, dtype=PETSc.IntType))


def reduced_field(ops, fx, fy) -> np.ndarray:
    """Restriction of the vector field (fx(x, y), fy(x, y)) to the kept dofs (serial)."""
    idx = ops.kept.getIndices()
    x = ops.V.tabulate_dof_coordinates()[idx // 2]
    return np.where(idx % 2 == 0, fx(x[:, 0], x[:, 1]), fy(x[:, 0], x[:, 1]))


# --- mesh ---------------------------------------------------------------------------------

@pytest.mark.parametrize("pattern, cells_per_square", [("crossed", 4), ("right", 2), ("left", 2),
                                                       ("alternate", 2)])
def test_structured_patterns(cache_dir, pattern, cells_per_square):
    nx, ny = 20, 10
    mesh, ft = block_mesh(MPI.COMM_WORLD, LENGTH, HEIGHT, nx, ny, pattern, cache_dir=cache_dir)
    tdim = mesh.topology.dim
    assert mesh.comm.allreduce(mesh.topology.index_map(tdim).size_local) == cells_per_square * nx * ny
    area = mesh.comm.allreduce(dolfinx.fem.assemble_scalar(
        dolfinx.fem.form(dolfinx.fem.Constant(mesh, 1.0) * ufl.dx)))
    assert area == pytest.approx(LENGTH * HEIGHT, rel=1e-12)

    # Tagged facets: AB and CD have nx edges, the lateral sides 2*ny, at the right places
    owned = ft.indices < mesh.topology.index_map(tdim - 1).size_local
    mid = dolfinx.mesh.compute_midpoints(mesh, tdim - 1, ft.indices)
    for tag, n_expected, on_side in ((AB, nx, lambda p: np.isclose(p[:, 1], 0.0)),
                                     (CD, nx, lambda p: np.isclose(p[:, 1], HEIGHT)),
                                     (LATERAL, 2 * ny,
                                      lambda p: np.isclose(p[:, 0], 0.0) | np.isclose(p[:, 0], LENGTH))):
        sel = ft.values == tag
        assert mesh.comm.allreduce(int(np.sum(sel & owned))) == n_expected
        assert np.all(on_side(mid[sel]))


@pytest.mark.parametrize("pattern", ["crossed", "right", "left", "alternate"])
def test_structured_triangulation_arrays(pattern):
    nx, ny, L, H = 3, 2, 6.0, 3.0
    x, cells = structured_triangulation(L, H, nx, ny, pattern)
    a, b, c = x[cells[:, 0]], x[cells[:, 1]], x[cells[:, 2]]
    area = 0.5 * ((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    np.testing.assert_allclose(area, L * H / cells.shape[0])  # counter-clockwise, equal areas
    if pattern == "crossed":
        assert x.shape == ((nx + 1) * (ny + 1) + nx * ny, 2)
        return
    # Diagonal of cell (i, j): the edge shared by its two triangles
    for k, (i, j) in enumerate((i, j) for j in range(ny) for i in range(nx)):
        v0 = j * (nx + 1) + i
        shared = set(cells[2 * k]) & set(cells[2 * k + 1])
        right = shared == {v0, v0 + nx + 2}
        assert right or shared == {v0 + 1, v0 + nx + 1}
        assert right == {"right": True, "left": False, "alternate": (i + j) % 2 == 0}[pattern]


def test_unstructured_needs_mesh_size_and_has_nodes_on_ab(cache_dir):
    with pytest.raises(ValueError):
        block_mesh(MPI.COMM_WORLD, LENGTH, HEIGHT, 0, 0, "unstructured", cache_dir=cache_dir)
    mesh, ft = block_mesh(MPI.COMM_WORLD, LENGTH, HEIGHT, 0, 0, "unstructured", mesh_size=8.0,
                          cache_dir=cache_dir)
    ops = block_operators(mesh, ft, E, NU, THICKNESS, DENSITY)
    assert ops.contact_x[0] == pytest.approx(0.0, abs=1e-12)
    assert ops.contact_x[-1] == pytest.approx(LENGTH)
    assert len(ops.contact_x) >= LENGTH / 8.0
    assert np.all(np.diff(ops.contact_x) > 0)


def test_cache_file_created_once_and_reused(tmp_path):
    """Only rank 0 writes and reads the cache, so file checks run there and are broadcast."""
    comm = MPI.COMM_WORLD
    root_dir = pathlib.Path(comm.bcast(str(tmp_path), root=0))
    cache, other = root_dir / "cache", root_dir / "other"

    def listing(d: pathlib.Path) -> list[tuple[str, int, int]]:
        """(name, mtime_ns, inode) of the files of d, as seen by rank 0."""
        files = None
        if comm.rank == 0:
            files = [(p.name, p.stat().st_mtime_ns, p.stat().st_ino) for p in sorted(d.iterdir())]
        return comm.bcast(files, root=0)

    block_mesh(comm, LENGTH, HEIGHT, 4, 2, "crossed", cache_dir=cache)
    files = listing(cache)
    assert len(files) == 1 and files[0][0].startswith("block_") and files[0][0].endswith(".npz")

    block_mesh(comm, LENGTH, HEIGHT, 4, 2, "crossed", cache_dir=cache)
    assert listing(cache) == files  # not rewritten, no second file, no temporary left behind

    # The cached file is really what is read: replace it by another mesh (2 triangles per cell)
    block_mesh(comm, LENGTH, HEIGHT, 4, 2, "right", cache_dir=other)
    if comm.rank == 0:
        shutil.copyfile(next(other.iterdir()), cache / files[0][0])
    mesh, _ = block_mesh(comm, LENGTH, HEIGHT, 4, 2, "crossed", cache_dir=cache)
    assert comm.allreduce(mesh.topology.index_map(2).size_local) == 16


def _model_to_mesh_reference(length, height, nx, ny, pattern, mesh_size=None):
    """The block mesh as the earlier code built it: the .msh read back into gmsh, model_to_mesh."""
    import gmsh
    from dolfinx.io.gmshio import model_to_mesh

    import app.systems.block.mesh as bm
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        gmsh.model.add("ref")
        if pattern == "unstructured":
            bm._add_unstructured_model(gmsh, length, height, mesh_size)
        else:
            bm._add_structured_model(gmsh, length, height, nx, ny, pattern)
        with __import__("tempfile").TemporaryDirectory() as tmp:
            gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
            gmsh.write(str(pathlib.Path(tmp) / "b.msh"))
            gmsh.model.add("back")
            gmsh.merge(str(pathlib.Path(tmp) / "b.msh"))
        return model_to_mesh(gmsh.model, MPI.COMM_SELF, 0, gdim=2)
    finally:
        gmsh.finalize()


@pytest.mark.parametrize("pattern, nx, ny, size", [("crossed", 20, 10, None), ("right", 5, 3, None),
                                                   ("alternate", 4, 2, None), ("unstructured", 0, 0, 9.0)])
def test_cached_mesh_is_the_gmsh_mesh(tmp_path, pattern, nx, ny, size):
    """The mesh read from the cached arrays (no gmsh) has the node and cell numbering, coordinates
    and facet tags of the one model_to_mesh builds from the gmsh model (issue 14)."""
    ref, _, ref_ft = _model_to_mesh_reference(81.3, 37.7, nx, ny, pattern, size)
    for _ in range(2):                     # generated, then read from the cache
        mesh, ft = block_mesh(MPI.COMM_SELF, 81.3, 37.7, nx, ny, pattern, mesh_size=size, cache_dir=tmp_path)
        assert np.array_equal(mesh.geometry.x, ref.geometry.x)
        assert np.array_equal(mesh.geometry.dofmap.array, ref.geometry.dofmap.array)
        assert np.array_equal(mesh.geometry.input_global_indices, ref.geometry.input_global_indices)
        assert np.array_equal(mesh.topology.connectivity(2, 0).array, ref.topology.connectivity(2, 0).array)
        assert np.array_equal(ft.indices, ref_ft.indices) and np.array_equal(ft.values, ref_ft.values)
    assert len(list(tmp_path.iterdir())) == 1


def test_cached_mesh_is_read_without_gmsh(tmp_path):
    """A run on a cached block mesh does not import gmsh (issue 14: start-up)."""
    block_mesh(MPI.COMM_WORLD, LENGTH, HEIGHT, 4, 2, "crossed", cache_dir=tmp_path)
    code = ("import sys, pathlib; from mpi4py import MPI; from app.systems.block.mesh import block_mesh; "
            f"m, _ = block_mesh(MPI.COMM_SELF, {LENGTH}, {HEIGHT}, 4, 2, 'crossed', cache_dir=pathlib.Path({str(tmp_path)!r})); "
            "print('gmsh' in sys.modules, m.topology.index_map(2).size_global)")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_", "PMIX_"))}
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, env=env, capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "32"]


# --- operators ----------------------------------------------------------------------------

@pytest.mark.parametrize("degree, n_contact", [(1, 21), (2, 41)])
def test_contact_nodes_crossed_20x10(cache_dir, degree, n_contact):
    mesh, ft = block_mesh(MPI.COMM_WORLD, LENGTH, HEIGHT, 20, 10, "crossed", cache_dir=cache_dir)
    assert mesh.comm.allreduce(mesh.topology.index_map(2).size_local) == 800
    ops = block_operators(mesh, ft, E, NU, THICKNESS, DENSITY, degree=degree)
    np.testing.assert_allclose(ops.contact_x, np.linspace(0.0, LENGTH, n_contact), atol=1e-12)
    n_kept = ops.kept.getSize()
    for dofs in (ops.contact_dof_x, ops.contact_dof_y):
        assert dofs.shape == (n_contact,)
        assert len(np.unique(dofs)) == n_contact
        assert np.all((dofs >= 0) & (dofs < n_kept))
    # The reduced indices point at the kept dofs with the right component and position
    if MPI.COMM_WORLD.size == 1:
        idx = ops.kept.getIndices()
        x = ops.V.tabulate_dof_coordinates()
        assert np.all(idx[ops.contact_dof_x] % 2 == 0) and np.all(idx[ops.contact_dof_y] == idx[ops.contact_dof_x] + 1)
        np.testing.assert_allclose(x[idx[ops.contact_dof_x] // 2, :2],
                                   np.column_stack([ops.contact_x, np.zeros(n_contact)]), atol=1e-12)
    # Size: all dofs minus those of CD (nx*degree + 1 nodes)
    n_nodes = ops.V.dofmap.index_map.size_global
    assert n_kept == 2 * (n_nodes - (20 * degree + 1))


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="dense serial check")
@pytest.mark.parametrize("degree", [1, 2])
def test_stiffness_symmetric_positive_definite(cache_dir, degree):
    mesh, ft = block_mesh(MPI.COMM_WORLD, 8.0, 4.0, 4, 2, "crossed", cache_dir=cache_dir)
    ops = block_operators(mesh, ft, E, NU, THICKNESS, DENSITY, degree=degree)
    K = dense(ops.K)
    assert K.shape == (ops.kept.getSize(),) * 2
    assert np.abs(K - K.T).max() <= 1e-12 * np.abs(K).max()
    eig = np.linalg.eigvalsh(K)
    assert eig[0] > 1e-6 * eig[-1]


@pytest.mark.parametrize("degree", [1, 2])
def test_rigid_translation(cache_dir, degree):
    """K u + K_{kept,D} u_D = 0 for a rigid translation, i.e. K 1_c = load_c."""
    mesh, ft = block_mesh(MPI.COMM_WORLD, LENGTH, HEIGHT, 8, 4, "alternate", cache_dir=cache_dir)
    ops = block_operators(mesh, ft, E, NU, THICKNESS, DENSITY, degree=degree)
    idx = ops.kept.getIndices()  # owned global DOLFINx indices, node*2 + component
    u, r = ops.K.createVecs()
    for component, load in ((0, ops.load_x), (1, ops.load_y)):
        assert load.norm() > 1.0
        u.setArray((idx % 2 == component).astype(PETSc.ScalarType))
        ops.K.mult(u, r)
        r.axpy(-1.0, load)
        assert r.norm() < 1e-10 * load.norm()
        # The reduced solution of K u = load is the translation itself, and to_function
        # rebuilds the uniform field
        gx, gy = (1.0, 0.0) if component == 0 else (0.0, 1.0)
        f = ops.to_function(u, gx, gy).x.array.reshape(-1, 2)
        np.testing.assert_array_equal(f, np.tile([gx, gy], (f.shape[0], 1)))
    u.destroy()
    r.destroy()


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="serial energy check")
def test_plane_stress_and_plane_strain_energies(cache_dir):
    """Energies of linear fields vanishing on CD are exact for P1:
    uniaxial u = (0, y - H): t L H (2 mu + lambda), shear u = (y - H, 0): t L H mu."""
    L, H = 8.0, 4.0
    mesh, ft = block_mesh(MPI.COMM_WORLD, L, H, 4, 2, "right", cache_dir=cache_dir)
    energies = {}
    for plane in ("stress", "strain"):
        ops = block_operators(mesh, ft, E, NU, THICKNESS, DENSITY, plane=plane)
        K = dense(ops.K)
        uni = reduced_field(ops, lambda x, y: 0 * x, lambda x, y: y - H)
        shear = reduced_field(ops, lambda x, y: y - H, lambda x, y: 0 * x)
        energies[plane] = (uni @ K @ uni, shear @ K @ shear)
    mu = E / (2 * (1 + NU))
    assert energies["stress"][0] == pytest.approx(THICKNESS * L * H * E / (1 - NU**2), rel=1e-12)
    assert energies["strain"][0] == pytest.approx(
        THICKNESS * L * H * E * (1 - NU) / ((1 + NU) * (1 - 2 * NU)), rel=1e-12)
    assert energies["stress"][1] == pytest.approx(THICKNESS * L * H * mu, rel=1e-12)
    assert energies["strain"][1] == pytest.approx(THICKNESS * L * H * mu, rel=1e-12)
    assert energies["strain"][0] > 1.1 * energies["stress"][0]

    # Plane strain is stiffer, the difference (lambda - lambda*) B is positive semi-definite
    K_stress = dense(block_operators(mesh, ft, E, NU, THICKNESS, DENSITY, plane="stress").K)
    K_strain = dense(block_operators(mesh, ft, E, NU, THICKNESS, DENSITY, plane="strain").K)
    eig = np.linalg.eigvalsh(K_strain - K_stress)
    assert eig[0] > -1e-9 * eig[-1] and eig[-1] > 0
    # ... and they coincide for nu = 0
    K0_stress = dense(block_operators(mesh, ft, E, 0.0, THICKNESS, DENSITY, plane="stress").K)
    K0_strain = dense(block_operators(mesh, ft, E, 0.0, THICKNESS, DENSITY, plane="strain").K)
    np.testing.assert_allclose(K0_stress, K0_strain, rtol=0, atol=1e-12 * np.abs(K0_stress).max())


def test_lame_parameters():
    mu, lam_strain = lame_parameters(E, NU, "strain")
    _, lam_stress = lame_parameters(E, NU, "stress")
    assert lam_strain == pytest.approx(E * NU / ((1 + NU) * (1 - 2 * NU)))
    assert lam_stress == pytest.approx(E * NU / (1 - NU**2))
    assert lam_stress == pytest.approx(2 * mu * lam_strain / (lam_strain + 2 * mu))
    with pytest.raises(ValueError):
        lame_parameters(E, NU, "shell")


@pytest.mark.parametrize("degree, mass_kind", [(1, "consistent"), (1, "lumped"), (2, "consistent")])
def test_total_mass(cache_dir, degree, mass_kind):
    mesh, ft = block_mesh(MPI.COMM_WORLD, LENGTH, HEIGHT, 8, 4, "crossed", cache_dir=cache_dir)
    ops = block_operators(mesh, ft, E, NU, THICKNESS, DENSITY, degree=degree, mass_kind=mass_kind)
    total = DENSITY * THICKNESS * LENGTH * HEIGHT

    # Full matrix: M e_x sums to the total mass
    M_full = ops.mass(full=True)
    e_x, y = M_full.createVecs()
    imap = ops.V.dofmap.index_map
    first = imap.local_range[0] * 2
    rows = np.arange(first, first + 2 * imap.size_local, 2, dtype=PETSc.IntType)
    e_x.setValues(rows, np.ones(rows.size))
    e_x.assemble()
    M_full.mult(e_x, y)
    assert y.sum() == pytest.approx(total, rel=1e-12)

    # Reduced matrix: cached, layout of K, symmetric, the kept part of the mass
    M = ops.mass()
    assert ops.mass() is M
    assert M.getSizes() == ops.K.getSizes()
    assert M.isSymmetric(1e-12 * M.norm())
    u = M.createVecRight()
    idx = ops.kept.getIndices()
    u.setArray((idx % 2 == 0).astype(PETSc.ScalarType))
    assert 0.5 * total < u.dot(M * u) < total
    if mass_kind == "lumped":
        d = M.getDiagonal()
        assert d.min()[1] > 0
        assert M.getInfo(PETSc.Mat.InfoType.GLOBAL_SUM)["nz_used"] == M.getSize()[0]  # diagonal


def test_lumped_p2_warns(cache_dir):
    mesh, ft = block_mesh(MPI.COMM_WORLD, 8.0, 4.0, 4, 2, "crossed", cache_dir=cache_dir)
    with pytest.warns(UserWarning, match="P2"):
        block_operators(mesh, ft, E, NU, THICKNESS, DENSITY, degree=2, mass_kind="lumped")


# --- serial vs parallel -------------------------------------------------------------------

_PARALLEL_SCRIPT = textwrap.dedent("""
    import pathlib, sys
    import numpy as np
    from mpi4py import MPI
    from app.systems.block.mesh import block_mesh
    from app.systems.block.operators import block_operators

    comm = MPI.COMM_WORLD
    # An exception on one rank must not leave the other one waiting in a collective
    sys.excepthook = lambda *exc: (sys.__excepthook__(*exc), sys.stderr.flush(), comm.Abort(1))
    cache, out = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
    result = {}
    for name, pattern, nx, ny, degree in (("p1", "crossed", 20, 10, 1), ("p2", "right", 8, 4, 2)):
        mesh, ft = block_mesh(comm, 80.0, 40.0, nx, ny, pattern, cache_dir=cache)
        ops = block_operators(mesh, ft, 2000.0, 0.3, 10.0, 1.2e-9, plane="strain", degree=degree)
        cols = ops.contact_dof_y.astype(np.int32)
        lo, hi = ops.K.getOwnershipRange()
        rows = [(i, ops.K.getValues([r], cols).ravel()) for i, r in enumerate(cols) if lo <= r < hi]
        rows = sum(comm.allgather(rows), [])
        Kcc = np.array([v for _, v in sorted(rows, key=lambda t: t[0])])
        load = [(i, ops.load_y.getValue(r)) for i, r in enumerate(cols) if lo <= r < hi]
        load = np.array([v for _, v in sorted(sum(comm.allgather(load), []), key=lambda t: t[0])])
        result[name + "_x"] = ops.contact_x
        result[name + "_Kcc"] = Kcc
        result[name + "_load"] = load
        result[name + "_n"] = np.array([ops.kept.getSize()])
        # The same arrays on every rank
        assert all(np.array_equal(a, ops.contact_x) for a in comm.allgather(ops.contact_x))
        assert all(np.array_equal(a, ops.contact_dof_y) for a in comm.allgather(ops.contact_dof_y))
    if comm.rank == 0:
        np.savez(out, **result)
""")


def _run_mpi(n: int, script: pathlib.Path, cache: pathlib.Path, out: pathlib.Path) -> dict[str, np.ndarray]:
    cmd = ["mpirun", "--allow-run-as-root", "--oversubscribe", "-n", str(n), sys.executable, str(script),
           str(cache), str(out)]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])))
    proc = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    # the whole output (bounded): a silent exit 1 of rank 0 was seen once in a fresh clone's CI
    assert proc.returncode == 0, f"exit {proc.returncode}\nstdout:\n{proc.stdout[-20000:]}\nstderr:\n{proc.stderr[-20000:]}"
    with np.load(out) as data:
        return dict(data)


@pytest.mark.mpi
@pytest.mark.skipif(shutil.which("mpirun") is None, reason="mpirun not found")
@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="launches mpirun itself")
def test_contact_dofs_agree_between_1_and_2_ranks(tmp_path):
    script = tmp_path / "parallel_operators.py"
    script.write_text(_PARALLEL_SCRIPT)
    serial = _run_mpi(1, script, tmp_path / "cache", tmp_path / "n1.npz")
    parallel = _run_mpi(2, script, tmp_path / "cache", tmp_path / "n2.npz")
    assert serial.keys() == parallel.keys()
    for name in ("p1", "p2"):
        np.testing.assert_array_equal(serial[f"{name}_x"], parallel[f"{name}_x"])
        np.testing.assert_array_equal(serial[f"{name}_n"], parallel[f"{name}_n"])
        Kcc = serial[f"{name}_Kcc"]
        assert Kcc.shape == (len(serial[f"{name}_x"]),) * 2
        assert np.abs(np.diag(Kcc)).min() > 0
        np.testing.assert_allclose(parallel[f"{name}_Kcc"], Kcc, rtol=0, atol=1e-12 * np.abs(Kcc).max())
        np.testing.assert_allclose(parallel[f"{name}_load"], serial[f"{name}_load"], rtol=0,
                                   atol=1e-12 * np.abs(Kcc).max())
