"""Command line: ``python -m app run|validate|render|check`` (also the ``contact-divergence`` console script).

Exit status: 0 success, 2 a user mistake (bad scene file, unwritable output folder, a folder
holding other files, a scene over the resource limits), 3 the study ran but some states failed
(listed in results.json "failures"), 4 the results could not be written (disk full, out of
memory, final rename failed; staged results are kept and their place printed).
Under ``mpirun`` every rank computes, only rank 0 prints and writes.
"""
from __future__ import annotations

import argparse
import os
import pathlib
import sys
import time

from app.common import interrupt, runtime
from app.common.errors import EXIT_WRITE, write_limit, write_limit_text
from app.common.errors import fail as _fail

DESCRIPTION = """\
Divergence instabilities of elastic bodies in frictional contact.

A scene file (YAML) describes a system, the friction coefficient mu and the analyses wanted at
every equilibrium state of its quasi-static loading. Systems (system.type):
  gmsh           your own 2D body from a Gmsh .geo or .msh file (plane stress or strain, P1/P2,
                 materials per surface) on a rigid line, circle or curve of the file, loaded by a
                 program of phases (prescribed motions, tractions, forces, gravity)
  block          the paper's elastic block, pressed and dragged on a rigid flat obstacle
  matrices       a discrete system given as K and M matrix files with its contact DOF pairs
  two_particles  the paper's two-particle system (Table 1)
Analyses:
  necessary      eq. (19): smallest eigenvalues of the symmetric parts of K*(mu), M*(mu)
  sufficient     eqs. (17)-(18): real eigenpairs lambda^2 > 0 with x_Ts >= 0 (SLEPc)
  mceip_mu       eqs. (21)-(23): critical friction coefficients and modes (proven up to mu_cap)
  mceip_lambda2  eqs. (12)-(14): divergence rates lambda^2 and modes (shown absent or found)
  enumerate      eqs. (24)-(26): exhaustive stick/slip enumeration (exact, small problems)
Units: mm, N, MPa, tonne, s by default (lambda^2 in 1/s^2), or m, N, Pa, kg, s (units: m-N-Pa-kg-s).
"""

EPILOG = """\
examples:
  python -m app run                         # the paper's block study (embedded default)
  python -m app run scene.yaml -o out/      # results in out/results.json and out/steps.csv
  mpirun -n 2 python -m app run scene.yaml  # same numbers, in parallel
  python -m app validate scene.yaml         # check a scene file without running it
  python -m app check out/                  # re-verify every MCEIP-mu claim from out/proofs
  mpirun -n 4 python -m app run sweep.yaml --ranks-per-case 2   # a scene with a 'sweep' section:
                                            # its cases farmed out to groups of 2 ranks
PETSc options: any PETSc/SLEPc option, placed after the scene file, reaches the app's solvers by
  their prefixes cd_loading_, cd_flex_, cd_necessary_, cd_sufficient_, cd_lambda2_, cd_dynamic_, cd_inertia_,
  cd_mcp_, cd_mcp_free_, cd_spd_check_ (e.g. -cd_necessary_eps_monitor, -cd_loading_snes_monitor)
exit status: 0 ok, 2 bad input, 3 study incomplete (some states failed; see results.json),
  4 the results could not be written (disk full, out of memory, final rename failed: see the error line),
  130 interrupted (Ctrl-C), 143 terminated (SIGTERM): nothing is left in the output folder
"""


#: seconds an interrupted sweep's rank 0 and its other ranks wait before they exit (:func:`_interrupted`)
SWEEP_EXIT_WAIT = (1.0, 5.0)
#: the same for a study: its rank 0 has removed the staging folder and the lock and exits at once
STUDY_EXIT_WAIT = (0.0, 2.0)


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line ``error: ...`` (exit status 2) instead of usage plus message."""

    def error(self, message: str):
        self.exit(2, f"error: {message} (see: {self.prog} --help)\n")


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="python -m app", description=DESCRIPTION, epilog=EPILOG,
                formatter_class=argparse.RawDescriptionHelpFormatter)
    from app.version import __version__
    p.add_argument("--version", action="version", version=f"contact-divergence {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    run = sub.add_parser("run", help="run a loading study and write its results",
                         description="Run a loading study: every equilibrium state is classified "
                                     "and gets the scene's analyses.\n"
                                     "Units: mm, N, MPa, tonne, s (so lambda^2 is in 1/s^2).",
                         epilog="check a scene file first with: python -m app validate SCENE\n"
                                "exit status: 0 ok, 2 bad input, 3 study incomplete (see results.json), 4 not written,\n"
                                "130 interrupted (Ctrl-C), 143 terminated (SIGTERM)",
                         formatter_class=argparse.RawDescriptionHelpFormatter)
    run.add_argument("scene", nargs="?", help="scene YAML file (default: the embedded paper study)")
    run.add_argument("-o", "--output", help="results folder (default: output/<scene name>)")
    run.add_argument("--overwrite", action="store_true",
                     help="replace the results this app wrote earlier in the output folder (atomically, at the "
                          "end of the run); a folder holding other files is never replaced")
    run.add_argument("--set", action="append", default=[], dest="overrides", metavar="KEY=VALUE",
                     help="set a scene key before validation, as if the file said so (repeatable): "
                          "--set mu=0.8 --set system.nx=40 --set analyses=[mceip_mu]")
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
    ren.add_argument("results", help="results folder (the one holding results.json), or a sweep's folder "
                                      "(every case is redrawn)")
    ren.add_argument("--states", action="append", metavar="SEL",
                     help="picture these states instead of the scene's outputs.states (repeatable): a state "
                          "index, final, first_mceip_mu or all_distinct; a state's screenshot needs its field "
                          "in fields/fields.npz, which holds the states the run pictured (a note says which "
                          "are left out)")
    ren.add_argument("--field", choices=["von_mises", "displacement"],
                     help="colour the state screenshots by this field instead of the scene's")
    ren.add_argument("-q", "--quiet", action="store_true", help="no progress bars, no list of files")
    ren.add_argument("--log-level", default="WARNING",
                     choices=["DEBUG", "INFO", "WARNING", "ERROR"], help="log level (default WARNING)")
    val = sub.add_parser("validate", help="check a scene file and print what it asks for",
                         description="Check a scene file without running it (exit status 0 ok, 2 bad "
                                     "input); then run it with: python -m app run SCENE")
    val.add_argument("scene", help="scene YAML file")
    val.add_argument("--set", action="append", default=[], dest="overrides", metavar="KEY=VALUE",
                     help="set a scene key before validation (repeatable), as in run")
    chk = sub.add_parser("check", help="re-verify every MCEIP-mu claim of a results folder from its stored pencils",
                         description="Re-derive every MCEIP-mu claim results.json makes (proven onsets, complete "
                                     "lists, certified values, lower bounds) from the stored pencils "
                                     "(proofs/state_<k>.npz): the pencil's structure comes from the state's "
                                     "classification, the proof log is re-verified by the independent checker, "
                                     "and each claimed value must lie in its proven enclosure. A claim whose "
                                     "proof file is missing is not verified. What is trusted: docs/proofs.md.",
                         epilog="exit status: 0 every claim re-verified, 1 a claim was not, 2 the folder cannot "
                                "be read as this app's results")
    chk.add_argument("results", help="results folder (the one holding results.json and proofs/)")
    chk.add_argument("-q", "--quiet", action="store_true", help="print only the verdict line")
    exp = sub.add_parser("export", help="write a results folder's matrices for other tools (Matrix Market)",
                         description="Write K and M, and for each distinct classification K*(mu), M*(mu) and "
                                     "the condensed MCEIP-mu pencil A0, A1 (A2 on a curved obstacle) with the "
                                     "proven answers (answers.json), into a new folder; the system is rebuilt "
                                     "from the scene results.json stores. One process only.",
                         epilog="exit status: 0 written, 2 the folder cannot be read or the output exists")
    exp.add_argument("results", help="results folder (the one holding results.json)")
    exp.add_argument("--matrices", action="store_true", required=True,
                     help="export the matrices (the only export so far)")
    exp.add_argument("-o", "--output", help="a new folder (default: RESULTS-export beside the results folder)")
    exp.add_argument("--scene", help="the scene file to build the system from (needed when the scene names "
                                     "files, e.g. a Gmsh body's .geo: a path stored in results.json is never opened)")
    exp.add_argument("--states", action="append", metavar="SEL",
                     help="only the classifications of these states (repeatable): a state index, final, "
                          "first_mceip_mu or all_distinct (default: every distinct classification)")
    exp.add_argument("--pencils-only", action="store_true",
                     help="only the condensed MCEIP-mu pencils and their answers: no K, M, K*(mu), M*(mu) "
                          "(whose size is the system's: a 10^5-DOF study's are large)")
    return p


def _write_error(err: BaseException) -> str | None:
    """The one-line message for a resource failure while running/writing, or None if it is not one."""
    if isinstance(err, MemoryError):
        return ("out of memory (MemoryError): the study does not fit in this machine's memory; use a coarser "
                "mesh (system.nx) or fewer states (loading.tangential_step), or lower settings.limits.max_memory_gb "
                "so the pre-flight refuses such scenes")
    if write_limit(err) is not None:
        return write_limit_text(err)
    if isinstance(err, TimeoutError) and "JIT compilation timed out" in str(err):
        claim = str(err).split("remove ", 1)[-1].split(")", 1)[0] if "remove " in str(err) else "its C file"
        return (f"the JIT compiler waited too long for another process compiling a form (FFCx: {claim}); if no "
                "other FEniCSx program is running, a killed process left that claim: delete the file and run again")
    return None


def main(argv: list[str] | None = None) -> int:
    """Run the command line with ``argv`` (default ``sys.argv[1:]``; PETSc options such as
    ``-ksp_view`` are split off and applied around the run) and return the exit status: 0 success,
    2 a user mistake, 3 some states failed, 4 the results could not be written."""
    runtime.install(command_line=True)                # before numpy and MPI load (app/common/runtime.py)
    from app.common.petsc_options import command_line_options, split_petsc_options
    try:
        argv, petsc_options = split_petsc_options(sys.argv[1:] if argv is None else list(argv))
    except ValueError as err:
        return _fail(str(err))
    args = _parser().parse_args(argv)
    with command_line_options(petsc_options):         # PETSc options: from the command line only
        if args.command == "render":
            from app.plot.render import render_main
            return _guarded(render_main, args)
        if args.command == "check":
            return _check(args)
        if args.command == "export":
            return _export(args)
        return _guarded(_main, args)


def _guarded(fn, args) -> int:
    """Under mpirun an exception on one rank would leave the others waiting forever:
    print it and abort the whole job instead."""
    from mpi4py import MPI

    from app.common.cache import CacheUnusable
    from app.io.folder import CommitError
    try:
        return fn(args)
    except CommitError as err:
        return _fail(str(err), EXIT_WRITE)
    except CacheUnusable as err:          # raised on every rank alike
        return _fail(str(err))
    except (MemoryError, OSError, RuntimeError) as err:
        msg = _write_error(err)
        if msg is None:
            return _interrupted(interrupt.RECEIVED[0]) if interrupt.RECEIVED else _unexpected()
        print(f"error: {msg}", file=sys.stderr, flush=True)      # every rank that hit it: one line each
        if MPI.COMM_WORLD.size > 1:
            MPI.COMM_WORLD.Abort(EXIT_WRITE)
        return EXIT_WRITE
    except KeyboardInterrupt as err:
        # Ctrl-C (SIGINT) or SIGTERM (raised as KeyboardInterrupt("signal 15") by the handler of
        # app/common/runtime.py): one line, not a traceback; the staging folder has already been
        # removed by the run's finally
        return _interrupted(15 if str(err) == "signal 15" else 2, getattr(err, "left", None))
    except Exception:
        if interrupt.RECEIVED:   # a child (the C compiler) died of the same Ctrl-C first
            return _interrupted(interrupt.RECEIVED[0])
        return _unexpected()


def _nothing() -> None:
    """A hard stop's cleanup on a rank that holds no folder."""


def _interrupted(signum: int, left: str | None = None) -> int:
    """One line for a run stopped by SIGINT or SIGTERM (``left``: what the stopped command keeps,
    default none of its results); exit status 128 + the signal.

    Under mpirun a Ctrl-C reaches mpirun, which sends SIGTERM to every rank and exits 1 (Open
    MPI 4). Every rank ends itself with the status (``os._exit``), without MPI_Abort's banner
    beside the one line: mpirun ends the job as soon as one rank exits with a non-zero status,
    the ranks still inside a collective with it, so a signal that reaches one rank only still
    ends the job. A sweep's ranks (``left`` given) each remove their unfinished case first; a
    study's rank 0 has removed the staging folder and the lock on its way out and exits at once,
    while its other ranks (which hold nothing; those waiting for rank 0 sleep in Python,
    app/common/waiting.py, and take the signal at once) wait for mpirun to end them."""
    from mpi4py import MPI

    from app.common import hard_stop
    runtime.quiet_after_interrupt()                   # a signal sent again, a destructor failing: no output
    interrupt.clear()
    code = 128 + signum
    if not hard_stop.claim():          # the watchdog is stopping the process: its line, its exit
        while True:
            time.sleep(1.0)
    if MPI.COMM_WORLD.rank == 0:
        print(interrupt.message(signum, left), file=sys.stderr, flush=True)
    if MPI.COMM_WORLD.size > 1:
        sys.stderr.flush()
        # mpirun ends the whole job (SIGKILL) as soon as one rank exits with a non-zero status.
        # In a sweep each rank has removed its own unfinished case; rank 0, whose line is
        # printed, waits for a signal another rank deferred (an import, a JIT compilation: a
        # tenth of a second at a time, app/common/runtime.py) to reach that rank, and the other
        # ranks wait for rank 0. In a study only rank 0 held anything.
        waits = SWEEP_EXIT_WAIT if left is not None else STUDY_EXIT_WAIT
        time.sleep(waits[0 if MPI.COMM_WORLD.rank == 0 else 1])
        os._exit(code)
    return code


def _export(args) -> int:
    """``python -m app export RESULTS --matrices``: app/study/export.py; exit status 0 written, 2
    the folder cannot be read or exported."""
    from mpi4py import MPI

    from app.io.check import MalformedResults
    from app.io.untrusted import UntrustedFile
    from app.scene.schema import SceneError
    from app.study.export import ExportError, export_matrices
    folder = pathlib.Path(args.results)
    if not folder.is_dir():
        return _fail(f"{folder}: not a folder (give the results folder a run wrote)")
    out = pathlib.Path(args.output) if args.output else folder.parent / f"{folder.resolve().name}-export"
    try:
        files = export_matrices(folder, out, MPI.COMM_WORLD, pathlib.Path(args.scene) if args.scene else None,
                                states=args.states, pencils_only=args.pencils_only)
    except FileNotFoundError as err:
        return _fail(f"{folder}: {err.strerror or 'not found'}: {err.filename or 'results.json'}")
    except (UntrustedFile, MalformedResults, ExportError) as err:
        return _fail(str(err))
    except SceneError as err:
        return _fail(f"{args.scene}: {err}" if args.scene else
                     f"{folder}: the scene results.json stores cannot be rebuilt: {err}")
    except OSError as err:
        return _fail(f"{out}: cannot be written: {err.strerror or err}", EXIT_WRITE)
    n = sum(f.endswith("answers.json") for f in files)
    print(f"{out}: {len(files)} files ({'' if args.pencils_only else 'K, M and '}{n} classifications)")
    return 0


def _check(args) -> int:
    """``python -m app check RESULTS``: every MCEIP-mu claim of results.json re-derived from the
    stored pencils (app/io/check.py). Exit status 0 every claim re-verified, 1 a claim was not, 2
    the folder cannot be read as results of this app."""
    from app.io.check import MalformedResults, check_folder
    from app.io.untrusted import UntrustedFile
    folder = pathlib.Path(args.results)
    if not folder.is_dir():
        return _fail(f"{folder}: not a folder (give the results folder a run wrote)")
    try:
        report = check_folder(folder)
    except FileNotFoundError:
        return _fail(f"{folder}: no results.json (give the results folder a run wrote)")
    except (UntrustedFile, MalformedResults) as err:
        return _fail(f"{err}")
    except MemoryError:
        return _fail(f"{folder}: the stored proofs do not fit in this machine's memory", EXIT_WRITE)
    if not args.quiet:
        for line in report.lines():
            print(line)
    if not report.states:
        print(f"{folder}: results.json claims nothing proven about MCEIP-mu: nothing to verify")
        return 0
    print(f"{folder}: {report.claims - report.failed} of {report.claims} claims re-verified from the stored pencils "
          f"({len(report.states)} states, {report.proof_files} proof files)"
          + ("" if report.ok else f"; {report.failed} NOT VERIFIED"))
    return 0 if report.ok else 1


def _unexpected() -> int:
    """An unexpected error, called from its ``except`` block: re-raised when serial; under mpirun
    printed and the whole job aborted (the other ranks would otherwise wait forever)."""
    from mpi4py import MPI
    if MPI.COMM_WORLD.size == 1:
        raise                      # the exception being handled
    import traceback
    traceback.print_exc()
    print(f"error: rank {MPI.COMM_WORLD.rank} failed; aborting all ranks", file=sys.stderr, flush=True)
    MPI.COMM_WORLD.Abort(1)
    return 1


def _main(args) -> int:
    if args.command is None:
        _parser().print_help()
        return 2
    from app.scene.schema import SceneError, default_scene_path, load_scene
    try:
        scene = load_scene(args.scene or default_scene_path(), getattr(args, "overrides", ()))
    except SceneError as err:
        return _fail(str(err), err.exit_code)
    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    if scene.sweep is not None or getattr(args, "ranks_per_case", None) is not None:
        from app.study.sweep import main as sweep_main  # a batch of cases (app/study/sweep.py)
        runtime.catch_signals(comm.rank)
        return sweep_main(scene, args, comm)
    from app.scene import limits as preflight
    try:
        estimate = preflight.check(scene, args.scene or "default scene")   # arithmetic only: milliseconds
    except SceneError as err:
        return _fail(str(err))
    if args.command == "validate":
        if comm.rank == 0:
            timing = preflight.describe_time(scene, estimate)
            print(f"{args.scene}: ok: scene '{scene.name}', system {scene.system.type}, mu = {scene.mu}, "
                  f"analyses: {', '.join(scene.analyses)}; {estimate.describe()[len('pre-flight: '):]}"
                  + (f"; {timing}" if timing else ""))
        return 0

    from app.common.logs import setup_logging
    setup_logging(args.log_level, comm.rank)           # app logs at --log-level; rank 0 only below WARNING
    import logging
    logging.getLogger("app.scene.limits").info(estimate.describe())
    from app.io.folder import ResultsFolder
    folder = ResultsFolder(pathlib.Path(args.output or pathlib.Path("output") / scene.name), args.overwrite)
    problem = None
    if comm.rank == 0:
        try:
            problem = folder.check() or preflight.check_disk(scene, estimate, folder.staging, folder.final)
        except OSError as err:                                # e.g. a path too long for the filesystem
            problem = f"cannot use the output folder {folder.final}: {err.strerror or err}"
        if problem:
            folder.abort()
    problem = comm.bcast(problem, root=0)                     # MPI collective
    if problem:
        return _fail(problem)
    # Everything is written into the staging folder (created and probed by check()) and moved into
    # place at the very end; the lock on the folder is held until then.
    outdir = folder.staging
    runtime.catch_signals(comm.rank)
    try:
        # a signal the main thread cannot take (inside a long C call) drops the staging folder and
        # the lock from the watchdog (app/common/hard_stop.py), as this block's finally would
        with interrupt.cleanup_on_hard_stop(folder.abort if comm.rank == 0 else _nothing):
            return _run(args, scene, comm, folder, outdir)
    finally:
        if comm.rank == 0:
            folder.abort()              # interrupted or failed: drop the partial files (kept if the commit failed)


def _run(args, scene, comm, folder, outdir: pathlib.Path) -> int:
    """Run the scene into the staging folder ``outdir`` and commit ``folder`` (app/study/driver.py)."""
    from app.common.errors import UnreachableLoad
    from app.common.progress import Progress
    from app.study import driver
    if scene.refinement is not None:                          # a mesh-refinement study (app/study/refinement.py)
        from app.study.refinement import main as refinement_main
        return refinement_main(scene, args, comm, folder, outdir)
    try:
        result = driver.run_and_write(scene, comm, outdir, Progress(enabled=not args.quiet, comm=comm))
    except UnreachableLoad as err:   # raised identically on every rank
        return _fail(driver.loading_error(args.scene or "default scene", err))
    interrupt.checkpoint()           # a Ctrl-C whose KeyboardInterrupt was swallowed: no results
    final = driver.commit(folder, comm)
    if comm.rank == 0 and not args.quiet:
        from app.io.summary import summary
        print(summary(result, final))
    return driver.exit_status(list(result.failures))
