"""The contact flexibility W = B K^-1 B^T (app/loading/flexibility.py, app/loading/mumps_inverse.py).

W from MUMPS's entries of the inverse (:func:`flexibility_inverse`, one rank) and from chunked
sparse block solves (:func:`flexibility_matsolve`, chunks that do and do not divide the number
of contact DOFs) against the signed contact block of the dense inverse of K; the factor still
solves correctly afterwards; the same W on 2 ranks.
"""
from __future__ import annotations

import os
import pathlib
import shutil
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from app.linalg import lu
from app.loading.flexibility import chunk_columns, contact_flexibility, flexibility_inverse, flexibility_matsolve
from app.systems.block.mesh import block_mesh
from app.systems.block.operators import block_operators

REPO = pathlib.Path(__file__).resolve().parents[1]


def _block(nx: int, ny: int):
    mesh, facets = block_mesh(MPI.COMM_WORLD, 80.0, 40.0, nx, ny, "crossed", None)
    ops = block_operators(mesh, facets, 5.0, 0.48, 9.6, 1.2e-9, plane="stress", degree=1)
    dofs = np.column_stack([ops.contact_dof_x, ops.contact_dof_y]).ravel().astype(np.int64)
    signs = np.tile([1.0, -1.0], len(ops.contact_x))
    return ops, dofs, signs


def test_chunk_columns_bounds():
    assert chunk_columns(1000, 50, chunk_bytes=8 * 1000 * 7) == 7
    assert chunk_columns(1000, 5, chunk_bytes=8 * 1000 * 7) == 5        # never more than the columns
    assert chunk_columns(10**9, 50, chunk_bytes=1) == 1                 # never fewer than one


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="dense reference is serial")
@pytest.mark.parametrize("columns", [1, 7, 10**6])       # one column per chunk, uneven chunks, one chunk
def test_w_equals_contact_block_of_inverse(columns):
    ops, dofs, signs = _block(8, 4)
    N = ops.K.getSize()[0]
    Kd = ops.K.getValues(np.arange(N, dtype=PETSc.IntType), np.arange(N, dtype=PETSc.IntType))
    ref = signs[:, None] * np.linalg.inv(Kd)[np.ix_(dofs, dofs)] * signs[None, :]
    with lu(ops.K, prefix="cd_flex_") as ksp:
        W = flexibility_matsolve(ksp, ops.K, dofs, signs, chunk_bytes=8 * N * columns)
    assert W is not None
    assert W.shape == (len(dofs), len(dofs))
    np.testing.assert_allclose(W, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="dense reference is serial")
def test_w_from_inverse_entries_and_later_solves():
    ops, dofs, signs = _block(8, 4)
    N = ops.K.getSize()[0]
    Kd = ops.K.getValues(np.arange(N, dtype=PETSc.IntType), np.arange(N, dtype=PETSc.IntType))
    Kinv = np.linalg.inv(Kd)
    ref = signs[:, None] * Kinv[np.ix_(dofs, dofs)] * signs[None, :]
    order = np.random.default_rng(0).permutation(len(dofs))          # rows in any order
    with lu(ops.K, prefix="cd_flex_") as ksp:
        W = flexibility_inverse(ksp, dofs[order], signs[order])
        assert W is not None
        np.testing.assert_allclose(W, ref[np.ix_(order, order)], rtol=0, atol=1e-12 * np.abs(ref).max())
        x = ops.load_x.duplicate()
        ksp.solve(ops.load_x, x)                                     # an ordinary solve afterwards
        np.testing.assert_allclose(x.getArray(), Kinv @ ops.load_x.getArray(), rtol=1e-10,
                                   atol=1e-12 * np.abs(x.getArray()).max())
        x.destroy()
    with contact_flexibility(ops.K, ops.load_x, ops.load_y, dofs, signs) as flex:
        np.testing.assert_allclose(flex.W, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
        np.testing.assert_allclose(flex.u0x, signs * (Kinv @ ops.load_x.getArray())[dofs], rtol=1e-10,
                                   atol=1e-12 * np.abs(flex.u0x).max())


_SCRIPT = textwrap.dedent("""
    import sys
    import numpy as np
    from mpi4py import MPI
    from app.linalg import lu
    from app.loading.flexibility import contact_flexibility, flexibility_gathered, flexibility_matsolve
    from app.systems.block.operators import block_operators
    from app.systems.block.mesh import block_mesh
    comm = MPI.COMM_WORLD
    sys.excepthook = lambda *exc: (sys.__excepthook__(*exc), sys.stderr.flush(), comm.Abort(1))
    mesh, facets = block_mesh(comm, 80.0, 40.0, 12, 6, "crossed", None)
    ops = block_operators(mesh, facets, 5.0, 0.48, 9.6, 1.2e-9, plane="stress", degree=1)
    dofs = np.column_stack([ops.contact_dof_x, ops.contact_dof_y]).ravel().astype(np.int64)
    signs = np.tile([1.0, -1.0], len(ops.contact_x))
    with lu(ops.K, prefix="cd_flex_") as ksp:
        W = flexibility_matsolve(ksp, ops.K, dofs, signs, chunk_bytes=8 * ops.K.getSize()[0] * 5)
        u = []
        for f in (ops.load_x, ops.load_y):                           # the loads' contact displacements
            x = f.duplicate()
            ksp.solve(f, x)
            u.append(np.concatenate(comm.allgather(x.getArray())))
            x.destroy()
    assert all(np.array_equal(w, W) for w in comm.allgather(W))      # replicated on every rank
    Wg, ug = flexibility_gathered(ops.K, (ops.load_x, ops.load_y), dofs, signs)   # K on rank 0
    assert all(np.array_equal(w, Wg) for w in comm.allgather(Wg))
    np.testing.assert_allclose(Wg, W, rtol=0, atol=1e-13 * np.abs(W).max())
    for a, b in zip(ug, u):
        np.testing.assert_allclose(a, signs * b[dofs], rtol=0, atol=1e-12 * np.abs(a).max())
    # the study's path: W from rank 0 on several ranks, K factorised only for a whole field
    with contact_flexibility(ops.K, ops.load_x, ops.load_y, dofs, signs) as flex:
        assert (flex._ksp is None) == (comm.size > 1)
        np.testing.assert_allclose(flex.W, 0.5 * (W + W.T), rtol=0, atol=1e-13 * np.abs(W).max())
        r = np.linspace(-1.0, 1.0, len(dofs))
        v = flex.field(0.3, -0.2, r)
        full = np.concatenate(comm.allgather(v.getArray()))
        v.destroy()
        np.testing.assert_allclose(signs * full[dofs], 0.3 * ug[0] + (-0.2) * ug[1] + flex.W @ r, rtol=0,
                                   atol=1e-11 * np.abs(full).max())
    if comm.rank == 0:
        np.save(sys.argv[1], W)
""")


@pytest.mark.mpi
@pytest.mark.skipif(shutil.which("mpirun") is None, reason="mpirun not found")
@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="launches mpirun itself")
def test_w_same_on_1_and_2_ranks(tmp_path):
    script = tmp_path / "w.py"
    script.write_text(_SCRIPT)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])))
    out = {}
    for n in (1, 2):
        cmd = ["mpirun", "--allow-run-as-root", "--oversubscribe", "-n", str(n), sys.executable, str(script),
               str(tmp_path / f"w{n}.npy")]
        proc = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
        out[n] = np.load(tmp_path / f"w{n}.npy")
    assert out[1].shape == (2 * 13, 2 * 13)
    np.testing.assert_allclose(out[2], out[1], rtol=0, atol=1e-13 * np.abs(out[1]).max())
