"""Benchmark: the contact flexibility W = B K^-1 B^T, sparse-block against dense-block solves.

The block of the default scene on a crossed P1 mesh ``nx x nx/2`` (224 x 112: 100,576 reduced
DOFs, 225 contact nodes); K is factorised once (MUMPS), then the two ways of building W from the
same factor run in turn, ``--repeats`` times each (A B A B ...: on a shared machine the ratio of
neighbouring runs is meaningful, the absolute times are not):

- ``sparse``: the app's :func:`app.loading.flexibility.flexibility_matsolve` (MUMPS sparse
  right-hand sides through a transposed AIJ B^T, chunks of at most 100 MB of solution);
- ``dense``: the previous build, a dense block of B^T per ``MatMatSolve`` (at most 12.5 million
  doubles per block), kept here as the yardstick.

Prints one JSON line per run and a summary line (median times, their ratio, the largest
relative difference of the two W). Works under mpirun (rank 0 prints).

    .venv/bin/python benchmarks/w_build.py [--nx 224] [--repeats 3]
    mpirun -n 2 .venv/bin/python benchmarks/w_build.py
"""
from __future__ import annotations

import argparse
import json
import pathlib
import statistics
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402
from petsc4py import PETSc  # noqa: E402


def dense_block_flexibility(ksp: PETSc.KSP, K: PETSc.Mat, dofs: np.ndarray, signs: np.ndarray) -> np.ndarray:
    """W by dense blocks of B^T, one ``MatMatSolve`` per block of at most 128 columns (MPI collective)."""
    comm = K.getComm().tompi4py()
    N = K.getSize()[0]
    r0, r1 = K.getOwnershipRange()
    n2 = len(dofs)
    mine = np.flatnonzero((dofs >= r0) & (dofs < r1))
    block = int(max(1, min(128, 12_500_000 // max(N, 1))))
    W = np.zeros((n2, n2))
    F = ksp.getPC().getFactorMatrix()
    for c0 in range(0, n2, block):
        cols = np.arange(c0, min(c0 + block, n2))
        B = PETSc.Mat().createDense(((r1 - r0, N), (PETSc.DECIDE, len(cols))), comm=K.getComm())
        B.setUp()
        rhs = B.getDenseArray()
        rhs[:] = 0.0
        hit = mine[(mine >= cols[0]) & (mine <= cols[-1])]
        rhs[dofs[hit] - r0, hit - c0] = signs[hit]
        B.assemble()
        X = B.duplicate()
        try:
            F.matSolve(B, X)
            W[np.ix_(mine, cols)] = signs[mine, None] * X.getDenseArray()[dofs[mine] - r0, :]
        finally:
            B.destroy()
            X.destroy()
    return comm.allreduce(W, op=MPI.SUM)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--nx", type=int, default=224)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    from app.linalg import lu_solver
    from app.loading.flexibility import flexibility_matsolve
    from app.system.elasticity import block_operators
    from app.systems.block_mesh import block_mesh
    mesh, facets = block_mesh(comm, 80.0, 40.0, args.nx, args.nx // 2, "crossed", None)
    ops = block_operators(mesh, facets, 5.0, 0.48, 9.6, 1.2e-9, plane="stress", degree=1, mass_kind="consistent")
    dofs = np.column_stack([ops.contact_dof_x, ops.contact_dof_y]).ravel().astype(np.int64)
    signs = np.tile([1.0, -1.0], len(ops.contact_x))
    t = time.perf_counter()
    ksp = lu_solver(ops.K)
    t_factor = time.perf_counter() - t
    ways = {"sparse": lambda: flexibility_matsolve(ksp, ops.K, dofs, signs),
            "dense": lambda: dense_block_flexibility(ksp, ops.K, dofs, signs)}
    times: dict[str, list[float]] = {k: [] for k in ways}
    Ws: dict[str, np.ndarray] = {}
    for r in range(args.repeats):
        for name, build in ways.items():
            comm.Barrier()
            t = time.perf_counter()
            Ws[name] = build()
            dt = comm.allreduce(time.perf_counter() - t, op=MPI.MAX)
            times[name].append(dt)
            if comm.rank == 0:
                print(json.dumps({"run": r, "way": name, "seconds": round(dt, 3)}), flush=True)
    diff = float(np.max(np.abs(Ws["sparse"] - Ws["dense"])) / np.max(np.abs(Ws["dense"])))
    med = {k: statistics.median(v) for k, v in times.items()}
    if comm.rank == 0:
        print(json.dumps({"dofs": ops.K.getSize()[0], "contact_nodes": len(ops.contact_x), "ranks": comm.size,
                          "factorise_s": round(t_factor, 3), "median_s": {k: round(v, 3) for k, v in med.items()},
                          "dense_over_sparse": round(med["dense"] / med["sparse"], 2),
                          "pairwise_ratios": [round(d / s, 2) for d, s in zip(times["dense"], times["sparse"])],
                          "max_rel_diff_W": diff}), flush=True)
    ksp.destroy()


if __name__ == "__main__":
    main()
