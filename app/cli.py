"""Command line: ``python -m app run|validate`` (also the ``contact-divergence`` console script).

Exit status: 0 success, 2 a user mistake (bad scene file, unwritable output folder),
3 the study ran but some states failed (listed in results.json "failures").
Under ``mpirun`` every rank computes, only rank 0 prints and writes.
"""
from __future__ import annotations

import argparse
import logging
import signal
import os
import pathlib
import sys

DESCRIPTION = """\
Divergence instabilities of elastic bodies in frictional contact.

A scene file (YAML) describes a system (the paper's two-particle system or a finite element
block pressed and dragged on a rigid flat obstacle), the friction coefficient mu and the
analyses wanted at every equilibrium state:
  necessary      eq. (19): smallest eigenvalues of the symmetric parts of K*(mu), M*(mu)
  sufficient     eqs. (17)-(18): real eigenpairs lambda^2 > 0 with x_Ts >= 0 (SLEPc)
  mceip_mu       eqs. (21)-(23): critical friction coefficients and modes (proven up to mu_cap)
  mceip_lambda2  eqs. (12)-(14): divergence rates lambda^2 and modes (SNES VI MCP search)
  enumerate      eqs. (24)-(26): exhaustive stick/slip enumeration (exact, small problems)
Units: mm, N, MPa, tonne, s (so lambda^2 is in 1/s^2).
"""

EPILOG = """\
examples:
  python -m app run                         # the paper's block study (embedded default)
  python -m app run scene.yaml -o out/      # results in out/results.json and out/steps.csv
  mpirun -n 2 python -m app run scene.yaml  # same numbers, in parallel
  python -m app validate scene.yaml         # check a scene file without running it
  mpirun -n 4 python -m app run sweep.yaml --ranks-per-case 2   # a scene with a 'sweep' section:
                                            # its cases farmed out to groups of 2 ranks
exit status: 0 ok, 2 bad input, 3 study incomplete (some states failed; see results.json)
"""


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m app", description=DESCRIPTION, epilog=EPILOG,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    run = sub.add_parser("run", help="run a loading study and write its results",
                         description="Run a loading study: every equilibrium state is classified "
                                     "and gets the scene's analyses.\n"
                                     "Units: mm, N, MPa, tonne, s (so lambda^2 is in 1/s^2).",
                         epilog="check a scene file first with: python -m app validate SCENE\n"
                                "exit status: 0 ok, 2 bad input, 3 study incomplete (see results.json)",
                         formatter_class=argparse.RawDescriptionHelpFormatter)
    run.add_argument("scene", nargs="?", help="scene YAML file (default: the embedded paper study)")
    run.add_argument("-o", "--output", help="results folder (default: output/<scene name>)")
    run.add_argument("--overwrite", action="store_true",
                     help="replace the results already in the output folder (atomically, at the end of the run)")
    run.add_argument("-q", "--quiet", action="store_true", help="no progress bars, no summary")
    run.add_argument("--ranks-per-case", type=int, default=None, metavar="K",
                     help="sweep scenes (a 'sweep' section): MPI ranks per case; the ranks form groups of K "
                          "that take cases as they become free (default 1)")
    run.add_argument("--log-level", default="WARNING",
                     choices=["DEBUG", "INFO", "WARNING", "ERROR"], help="log level (default WARNING)")
    ren = sub.add_parser("render", help="redraw the plots, screenshots and report of a results folder",
                         description="Redraw every picture the scene's 'outputs' asked for (plots, "
                                     "screenshots, report.md) from a results folder, without recomputing "
                                     "the study (the screenshots use the fields saved by the run).")
    ren.add_argument("results", help="results folder (the one holding results.json)")
    ren.add_argument("-q", "--quiet", action="store_true", help="no progress bars, no list of files")
    ren.add_argument("--log-level", default="WARNING",
                     choices=["DEBUG", "INFO", "WARNING", "ERROR"], help="log level (default WARNING)")
    val = sub.add_parser("validate", help="check a scene file and print what it asks for",
                         description="Check a scene file without running it (exit status 0 ok, 2 bad "
                                     "input); then run it with: python -m app run SCENE")
    val.add_argument("scene", help="scene YAML file")
    return p


def _fail(msg: str, code: int = 2) -> int:
    from mpi4py import MPI
    if MPI.COMM_WORLD.rank == 0:
        print(f"error: {msg}", file=sys.stderr)
    return code


def main(argv: list[str] | None = None) -> int:
    if int(os.environ.get("OMPI_COMM_WORLD_SIZE", "1")) > 1:
        # one BLAS thread per MPI rank (set before numpy loads OpenBLAS)
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    args = _parser().parse_args(argv)
    if args.command == "render":
        from app.outputs.render import render_main
        return render_main(args)
    if args.command == "run":
        return _guarded(_main, args)
    return _main(args)


def _guarded(fn, args) -> int:
    """Under mpirun an exception on one rank would leave the others waiting forever:
    print it and abort the whole job instead."""
    from mpi4py import MPI
    try:
        return fn(args)
    except KeyboardInterrupt:
        if MPI.COMM_WORLD.size > 1:
            MPI.COMM_WORLD.Abort(130)
        raise
    except Exception:
        if MPI.COMM_WORLD.size == 1:
            raise
        import traceback
        traceback.print_exc()
        print(f"error: rank {MPI.COMM_WORLD.rank} failed; aborting all ranks", file=sys.stderr, flush=True)
        MPI.COMM_WORLD.Abort(1)
        return 1


def _main(args) -> int:
    if args.command is None:
        _parser().print_help()
        return 2
    from app.config import SceneError, default_scene_path, load_scene
    try:
        scene = load_scene(args.scene or default_scene_path())
    except SceneError as err:
        return _fail(str(err))
    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    if scene.sweep is not None or getattr(args, "ranks_per_case", None) is not None:
        from app.sweep import main as sweep_main       # a batch of cases (app/sweep.py)
        return sweep_main(scene, args, comm)
    if args.command == "validate":
        if comm.rank == 0:
            print(f"{args.scene}: ok: scene '{scene.name}', system {scene.system.type}, mu = {scene.mu}, "
                  f"analyses: {', '.join(scene.analyses)}")
        return 0

    from app.logs import setup_logging
    setup_logging(args.log_level, comm.rank)           # app logs at --log-level; rank 0 only below WARNING
    from app.outputs.folder import ResultsFolder
    folder = ResultsFolder(pathlib.Path(args.output or pathlib.Path("output") / scene.name), args.overwrite)
    problem = folder.check() if comm.rank == 0 else None
    problem = comm.bcast(problem, root=0)                     # MPI collective
    if problem:
        return _fail(problem)
    if comm.rank == 0:
        folder.open()
    # Everything is written into the staging folder and moved into place at the very end.
    outdir = folder.staging
    signal.signal(signal.SIGTERM, _terminate)
    try:
        return _run(args, scene, comm, folder, outdir)
    finally:
        if comm.rank == 0 and folder.staging.exists():
            folder.abort()                                    # interrupted or failed: drop the partial files


def _terminate(signum, frame):
    raise KeyboardInterrupt(f"signal {signum}")


def _run(args, scene, comm, folder, outdir: pathlib.Path) -> int:

    from app.outputs.results import write_results
    from app.progress import Progress
    from app.study import run_study
    from app.loading.block_path import UnreachableLoad
    if scene.refinement is not None:                          # a mesh-refinement study (app/refinement.py)
        from app.refinement import main as refinement_main
        return refinement_main(scene, args, comm, folder, outdir)
    try:
        results = run_study(scene, comm, Progress(enabled=not args.quiet, comm=comm), outdir=outdir)
    except UnreachableLoad as err:   # raised identically on every rank
        return _fail(f"{args.scene or 'default scene'}: loading: {err}")
    if comm.rank == 0:
        from app.outputs.pictures import draw_after_run       # plots, screenshots, report (if asked)
        results = draw_after_run(results, outdir, Progress(enabled=not args.quiet, comm=comm))
        write_results(results, outdir)
    comm.Barrier()                                            # MPI collective: every rank has written
    if comm.rank == 0:
        final = folder.commit()
        if not args.quiet:
            from app.outputs.summary import summary
            print(summary(results, final))
    return 3 if results["failures"] else 0
