"""Benchmark: the contact flexibility W = B K^-1 B^T, three ways from one factorisation.

The block of the default scene on a crossed P1 mesh ``nx x nx/2`` (224 x 112: 100,576 reduced
DOFs, 225 contact nodes); K is factorised once (MUMPS), then the ways of building W from the
same factor run in turn, ``--repeats`` times each (A B C A B C ...: on a shared machine the
ratio of neighbouring runs is meaningful, the absolute times are not):

- ``inverse``: :func:`app.loading.flexibility.flexibility_inverse`, MUMPS's selected entries of
  K^-1 (what the app uses on one rank; skipped on more);
- ``sparse``: :func:`app.loading.flexibility.flexibility_matsolve`, MUMPS sparse right-hand
  sides through a transposed AIJ B^T, chunks of at most 100 MB of solution (the app on 2+ ranks);
- ``dense``: the build at ``--baseline`` (default ``main``, read from git by
  benchmarks/baseline.py): a dense block of B^T per ``MatMatSolve``.

Prints one JSON line per run and a summary line (median times, ratios to ``dense``, the largest
relative difference of each W from ``dense``'s). Works under mpirun (rank 0 prints).

    .venv/bin/python benchmarks/w_build.py [--nx 224] [--repeats 3] [--baseline main]
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


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--nx", type=int, default=224)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--baseline", default="main")
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    from benchmarks.baseline import baseline_module
    dense_blocks = baseline_module(args.baseline, "app/loading/flexibility.py")._flexibility_block_solves
    from app.linalg import lu_solver
    from app.loading.flexibility import flexibility_inverse, flexibility_matsolve
    from app.systems.block.mesh import block_mesh
    from app.systems.block.operators import block_operators
    mesh, facets = block_mesh(comm, 80.0, 40.0, args.nx, args.nx // 2, "crossed", None)
    ops = block_operators(mesh, facets, 5.0, 0.48, 9.6, 1.2e-9, plane="stress", degree=1, mass_kind="consistent")
    dofs = np.column_stack([ops.contact_dof_x, ops.contact_dof_y]).ravel().astype(np.int64)
    signs = np.tile([1.0, -1.0], len(ops.contact_x))
    t = time.perf_counter()
    ksp = lu_solver(ops.K, prefix="cd_flex_")
    t_factor = time.perf_counter() - t
    ways = {"inverse": lambda: flexibility_inverse(ksp, dofs, signs),
            "sparse": lambda: flexibility_matsolve(ksp, ops.K, dofs, signs),
            "dense": lambda: dense_blocks(ksp, ops.K, dofs, signs)}
    if comm.size > 1:
        del ways["inverse"]
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
    ref = np.max(np.abs(Ws["dense"]))
    diff = {k: float(np.max(np.abs(W - Ws["dense"])) / ref) for k, W in Ws.items() if k != "dense"}
    med = {k: statistics.median(v) for k, v in times.items()}
    if comm.rank == 0:
        print(json.dumps({"dofs": ops.K.getSize()[0], "contact_nodes": len(ops.contact_x), "ranks": comm.size,
                          "factorise_s": round(t_factor, 3), "median_s": {k: round(v, 3) for k, v in med.items()},
                          "dense_over": {k: round(med["dense"] / med[k], 2) for k in ways if k != "dense"},
                          "pairwise_dense_over": {k: [round(d / t, 2) for d, t in zip(times["dense"], times[k])]
                                                  for k in ways if k != "dense"},
                          "max_rel_diff_W": diff}), flush=True)
    ksp.destroy()


if __name__ == "__main__":
    main()
