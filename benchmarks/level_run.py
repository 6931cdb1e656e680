"""One block study in its own process, for the benchmarks (peak memory is per process).

Runs the paper's scene at one mesh size as a refinement level (loading path, then MCEIP-mu at
the final state and, unless --final-only, the first solution along the path; the sufficient
condition at mu = 2 at the final state: app/study/refinement.py), then times one sparse LU factorisation of K alone (MUMPS, as the
study does). Prints one JSON line (rank 0).

    .venv/bin/python benchmarks/level_run.py --nx 80 [--degree 1] [--pattern crossed]
    mpirun -n 2 .venv/bin/python benchmarks/level_run.py --nx 80
"""
from __future__ import annotations

import argparse
import json
import resource
import time

from mpi4py import MPI


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--nx", type=int, required=True)
    ap.add_argument("--degree", type=int, default=1)
    ap.add_argument("--pattern", default="crossed")
    ap.add_argument("--plane", default="stress")
    ap.add_argument("--tangential-max", type=float, default=None)
    ap.add_argument("--no-factor", action="store_true", help="skip the separate factorisation timing")
    ap.add_argument("--final-only", action="store_true",
                    help="skip the search for the first MCEIP-mu solution (final state only)")
    args = ap.parse_args()
    comm = MPI.COMM_WORLD

    import yaml

    from app.scene.schema import default_scene_path
    from app.study.refinement import run_level
    data = yaml.safe_load(default_scene_path().read_text())
    data.update(name="bench", analyses=[], mceip_lambda2_mu=2.0,
                refinement={"levels": [args.nx, 2 * args.nx],
                            "first_solution": "none" if args.final_only else "scan"})
    data["system"].update(pattern=args.pattern)
    if args.tangential_max:
        data["loading"]["tangential_max"] = args.tangential_max
    from app.scene.schema import parse_scene
    scene = parse_scene(data)
    # compile the forms first (JIT), so the timed run is the study alone
    run_level(scene.model_copy(update={"loading": scene.loading.model_copy(
        update={"tangential_max": scene.loading.tangential_step})}), 2, args.degree, args.plane, comm)
    t0 = time.perf_counter()
    row, res = run_level(scene, args.nx, args.degree, args.plane, comm)
    wall = time.perf_counter() - t0

    factor_s = None
    if not args.no_factor:
        from app.linalg import lu_solver
        from app.systems.block.mesh import block_mesh
        from app.systems.block.operators import block_operators
        cfg = scene.system.model_copy(update={"nx": args.nx, "ny": row["ny"], "degree": args.degree,
                                               "plane": args.plane})
        mesh, facets = block_mesh(comm, cfg.length, cfg.height, cfg.nx, cfg.ny, cfg.pattern, cfg.mesh_size)
        ops = block_operators(mesh, facets, cfg.E, cfg.nu, cfg.thickness, cfg.density, plane=cfg.plane,
                              degree=cfg.degree)
        comm.Barrier()
        t = time.perf_counter()
        ksp = lu_solver(ops.K, prefix="cd_flex_")
        comm.Barrier()
        factor_s = time.perf_counter() - t
        ksp.destroy()
        ops.destroy()
    peak = comm.allreduce(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, op=MPI.SUM)
    if comm.rank == 0:
        print(json.dumps({"row": row, "stages": [st.to_dict() for st in res.stages], "wall_s": wall,
                          "factor_s": factor_s, "peak_rss_mb": peak, "ranks": comm.size}), flush=True)


if __name__ == "__main__":
    main()
