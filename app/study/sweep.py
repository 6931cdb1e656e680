"""Parameter sweeps: one scene file, many loading studies, run as an MPI task farm (app/study/taskfarm.py).

Cases: app/scene/sweep.py; the combined table and plots: app/study/sweep_table.py.

A scene with a ``sweep:`` section (schema: :class:`app.scene.schema.Sweep`) is expanded into cases:
the base scene with each swept key (a dotted path such as ``system.length``) set to one of its
values, every combination (``mode: product``) or the i-th values together (``mode: zip``). Each
case is validated as a normal scene before anything runs and gets a stable name made from its
values, e.g. ``mu=1.1_system.length=80``.

Running (``mpirun -n P python -m app run sweep.yaml --ranks-per-case K``):

* the P ranks are split (``comm.Split``) into groups of K consecutive ranks (the last group
  may be smaller); each group runs whole cases with ``study(case_scene, group_comm)``;
* world rank 0 is the dispatcher **and** works: a thread on rank 0 answers the group leaders'
  requests (MPI point-to-point messages on a duplicate of the world communicator) with the
  index of the next case, so a long case never holds up the others. If the MPI library does not
  provide ``MPI_THREAD_MULTIPLE``, rank 0 is a dedicated dispatcher instead (the other ranks
  work). With one rank the cases simply run one after the other;
* the group's rank 0 writes the case into a hidden staging folder and renames it to
  ``OUTDIR/cases/<case name>/`` when it is written: a case folder is always complete (a killed
  sweep leaves only staging folders, removed when the case runs again). ``results.json`` carries
  ``sweep_case`` with a hash of the case scene: a restarted sweep skips every case whose
  ``results.json`` is there with the same hash and runs only the others;
* world rank 0 keeps ``OUTDIR/sweep.csv`` and ``OUTDIR/sweep.json`` (one row per case with its
  quantities of interest) up to date as cases finish, logs what ran in ``OUTDIR/sweep.log``
  and at the end draws ``OUTDIR/plots/<swept key>.png`` (each quantity against that key).

Waiting ranks sleep between MPI tests instead of spinning in blocking calls, so idle ranks do
not steal cores from working ones on an oversubscribed machine.
"""
from __future__ import annotations

import datetime
import json
import os
import pathlib
import shutil
import stat
import time
import traceback
from collections import deque

from app.common import interrupt
from app.common.interrupt import Stopped
from app.common.waiting import sleep_until
from app.io.document import from_document
from app.io.result import StudyResult
from app.io.results import append_line
from app.scene.schema import Scene, SceneError
from app.scene.sweep import Case, expand  # noqa: F401 - expand re-exported (app.study.sweep.expand)
from app.study.sweep_table import case_row, error_row, summary_table, write_comparison, write_plots, write_tables
from app.study.taskfarm import run_farm
from app.systems.units import CONTINUUM_UNITS


def case_dir(outdir: pathlib.Path, case: Case) -> pathlib.Path:
    """The results folder of ``case``: ``outdir/cases/<case name>``."""
    return outdir / "cases" / case.name


def completed_results(outdir: pathlib.Path, case: Case) -> StudyResult | None:
    """The study of the case's results.json if that file is complete, valid (format 3, read
    strictly) and was computed from the same case scene; None otherwise (the case runs again)."""
    from pydantic import ValidationError

    from app.io.result import validate
    from app.io.untrusted import RESULTS_MAX_BYTES, UntrustedFile, inside, read_bytes
    try:
        text = read_bytes(inside(outdir, "cases", case.name, "results.json"), RESULTS_MAX_BYTES)
        validate(text)                     # a malformed or foreign results.json: the case runs again
        study = StudyResult.from_dict(from_document(json.loads(text)))
    except (OSError, ValueError, UntrustedFile, ValidationError, RecursionError):
        return None
    if (study.sweep_case or {}).get("scene_hash") != case.scene_hash:
        return None
    return study


def run_case(case: Case, gcomm, outdir: pathlib.Path) -> dict | None:
    """Run ``case`` on ``gcomm`` (app/study/driver.py); the group's rank 0 writes it and returns its
    table row (:func:`app.study.sweep_table.case_row` of the case's study), the other ranks None.

    The case is written into a hidden staging folder beside its final one and moved into place
    when written (:func:`_commit_case`), so a killed sweep leaves no half-written case folder: a
    restart runs the case again into a new staging folder."""
    from app.common.errors import UnreachableLoad
    from app.io.results import atomic_write
    from app.study import driver
    error = None
    folder = case_dir(outdir, case)
    staging = None
    try:
        if gcomm.rank == 0:
            folder.parent.mkdir(parents=True, exist_ok=True)
            _remove_unfinished(folder)
            staging = folder.parent / f".{folder.name}.partial-{os.getpid()}-{time.time_ns()}"
            staging.mkdir()
        staging = gcomm.bcast(staging, root=0)                                 # MPI collective (group)
        identity = {"sweep_case": {"sweep": case.scene.name, "name": case.name, "index": case.index,
                                   "values": case.values, "scene_hash": case.scene_hash}}
        try:
            with interrupt.cleanup_on_hard_stop(lambda: _drop_staging(staging) if gcomm.rank == 0 else None):
                study = driver.run_and_write(case.scene, gcomm, staging, extra=identity)
        except UnreachableLoad as err:   # raised identically on every rank of the group
            error = f"loading: {err}"
        except KeyboardInterrupt:
            raise
        except Exception as err:             # noqa: BLE001
            if interrupt.RECEIVED:           # a signal's KeyboardInterrupt that a library wrapped (pydantic
                raise interrupt.keyboard_interrupt() from err      # while writing results.json): the interrupt
            if gcomm.size > 1:               # may be on this rank only: the CLI aborts the job
                raise
            error = f"{type(err).__name__}: {err}"
            traceback.print_exc()
        if gcomm.rank != 0:
            return None
        if error is not None:
            atomic_write(staging / "error.json", json.dumps({"case": case.name, "error": error}, indent=1))
        refused = _commit_case(staging, folder)
    except KeyboardInterrupt:            # a signal, wherever it lands: the unfinished case leaves nothing
        if gcomm.rank == 0:
            _drop_staging(staging)
        raise
    if refused is not None:
        return error_row(case, refused if error is None else f"{error}; {refused}")
    return error_row(case, error) if error is not None else case_row(study, case)


def _drop_staging(staging: pathlib.Path | None) -> None:
    """Remove this run's own staging folder of a case (not yet moved into place)."""
    if staging is not None and staging.is_dir() and not staging.is_symlink():
        shutil.rmtree(staging, ignore_errors=True)


def _nothing() -> None:
    """A hard stop's cleanup on a rank that holds no lock."""


def _remove_unfinished(folder: pathlib.Path) -> None:
    """Staging folders of ``folder``'s case left by a killed run of this sweep (the sweep folder
    is locked: none is in use), and the recorded files of a replaced case folder left behind."""
    import shutil

    from app.io.folder import remove_recorded
    for p in folder.parent.glob(f".{folder.name}.partial-*"):
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p)
    for p in folder.parent.glob(f".{folder.name}.old-*"):
        if p.is_dir() and not p.is_symlink():
            remove_recorded(p)


def _commit_case(staging: pathlib.Path, folder: pathlib.Path) -> str | None:
    """Record what the app wrote in the case's staging folder (its marker's file list) and move it
    into place; an earlier run's folder of the same case (an error, or a case scene that changed)
    is replaced only when it holds nothing but the files its marker records, and only those are
    deleted. Otherwise both are left as they are and the reason is returned (one line)."""
    from app.io.folder import describe_foreign, folder_state, remove_recorded, seal
    seal(staging)
    state = folder_state(folder)
    if state == "not-a-folder":
        return f"{folder} is not a folder the app wrote; the case's results are kept in {staging}"
    if state == "other":
        return (f"{folder} holds files the app did not write{describe_foreign(folder)}; "
                f"left as it is, the case's results are kept in {staging}")
    if state == "ours":
        old = folder.parent / f".{folder.name}.old-{os.getpid()}-{time.time_ns()}"
        os.rename(folder, old)
        os.rename(staging, folder)
        remove_recorded(old)
    else:
        if state == "empty":
            os.rmdir(folder)
        os.rename(staging, folder)
    return None


class Dispatcher:
    """Hands out case indices on request and collects the finished cases' rows (rank 0 only)."""

    def __init__(self, scene: Scene, cases: list[Case], todo: list[int], rows: dict[int, dict],
                 outdir: pathlib.Path, quiet: bool, info: dict):
        self.scene, self.cases, self.outdir, self.quiet, self.info = scene, cases, outdir, quiet, info
        self.pending = deque(todo)
        self.rows = rows
        self.n_todo, self.n_done = len(todo), 0
        self.running: dict[int, int] = {}      # group -> case index
        append_line(outdir / "sweep.log", "", complete_last=True)     # a line cut short by a killed run

    def log(self, event: str, case: Case | None = None, detail: str = "") -> None:
        """Append one line to ``sweep.log``: a timestamp (milliseconds), the event, the case's name (``-``
        for none) and ``detail``, separated by tabs."""
        stamp = datetime.datetime.now().isoformat(timespec="milliseconds")
        line = "\t".join([stamp, event, case.name if case else "-", detail]).rstrip("\t")
        append_line(self.outdir / "sweep.log", line + "\n")

    def handle(self, group: int, row: dict | None) -> int | None:
        """Group ``group`` finished its case (``row``, or None on its first request): its next case."""
        if row is not None:
            idx = self.running.pop(group)
            self.rows[idx] = row
            self.n_done += 1
            case = self.cases[idx]
            secs = row.get("wall_seconds")
            self.log("done" if not str(row["status"]).startswith("error") else "error", case,
                     f"group={group}\tstatus={row['status']}" + (f"\tseconds={secs:.2f}" if secs else ""))
            if not self.quiet:
                took = f" in {secs:.1f} s" if secs else ""
                print(f"sweep: [{self.n_done}/{self.n_todo}] {case.name}: {row['status']}{took} "
                      f"(group {group})", flush=True)
            write_tables(self.outdir, self.scene, self.cases, self.rows, self.info)
        if not self.pending:
            return None
        idx = self.pending.popleft()
        self.running[group] = idx
        self.log("start", self.cases[idx], f"group={group}")
        return idx


def run_cases(cases: list[Case], todo: list[int], comm, ranks_per_case: int, outdir: pathlib.Path,
              dispatcher: Dispatcher | None) -> str:
    """Run the cases ``todo`` (same list on every rank) over ``comm`` with the MPI task farm
    (app/study/taskfarm.py); returns the scheduler used. ``dispatcher`` is given on rank 0 only."""
    if comm.size > 1:
        # PETSc, SLEPc and the system types' libraries initialise collectively on the world
        # communicator when first imported: do it here on every rank, not inside the first case
        # (a rank may never run one).
        from petsc4py import PETSc  # noqa: F401
        from slepc4py import SLEPc  # noqa: F401

        from app.systems import get as system_type
        for name in sorted({c.scene.system.type for c in cases}):
            system_type(name).preload()      # e.g. DOLFINx for the block
    return run_farm(comm, ranks_per_case, dispatcher.handle if dispatcher is not None else None,
                    lambda idx, gcomm: run_case(cases[idx], gcomm, outdir))


def run_sweep(scene: Scene, cases: list[Case], comm, outdir: pathlib.Path, ranks_per_case: int = 1,
              quiet: bool = False, rerun: bool = False) -> int:
    """Run (or finish) a sweep into ``outdir``; collective on ``comm``. Cases already complete
    in ``outdir`` are skipped unless ``rerun``. Returns the exit status: 0 every case ok,
    3 some case failed or has failed states."""
    import numpy as np
    t0 = time.perf_counter()
    dispatcher = None
    if comm.rank == 0:
        (outdir / "cases").mkdir(parents=True, exist_ok=True)
        rows: dict[int, dict] = {}
        todo = []
        for c in cases:
            done = None if rerun else completed_results(outdir, c)
            if done is None:
                todo.append(c.index)
            else:
                rows[c.index] = case_row(done, c, ran="earlier")
        info = {"mpi_ranks": comm.size, "ranks_per_case": ranks_per_case}
        dispatcher = Dispatcher(scene, cases, todo, rows, outdir, quiet, info)
        dispatcher.log("sweep", None, f"{len(cases)} cases, {len(cases) - len(todo)} already complete, "
                                      f"{len(todo)} to run; {comm.size} rank(s), {ranks_per_case} per case")
        for i in sorted(rows):
            dispatcher.log("skip", cases[i], "complete (results.json with the same scene hash)")
        if not quiet:
            print(f"sweep '{scene.name}': {len(cases)} cases ({scene.sweep.mode} of "
                  f"{', '.join(scene.sweep.parameters)}), {len(cases) - len(todo)} already complete, "
                  f"{len(todo)} to run on {comm.size} rank(s), {ranks_per_case} per case; output {outdir}",
                  flush=True)
    else:
        todo = None
    todo = comm.bcast(todo, root=0)
    scheduler = run_cases(cases, todo, comm, ranks_per_case, outdir, dispatcher)
    status = np.zeros(1, dtype=np.int32)
    if comm.rank == 0:
        dispatcher.info.update(scheduler=scheduler, wall_seconds=time.perf_counter() - t0,
                               ran_this_time=len(todo))
        write_tables(outdir, scene, cases, dispatcher.rows, dispatcher.info)
        plots = write_plots(outdir, scene.sweep.mode, cases, dispatcher.rows, CONTINUUM_UNITS[scene.units])
        plots += write_comparison(outdir, scene.name, [(c.name, completed_results(outdir, c)) for c in cases])
        dispatcher.log("end", None, f"{len(todo)} case(s) run in {time.perf_counter() - t0:.1f} s")
        bad = [r for r in dispatcher.rows.values() if r["status"] != "ok"]
        status[0] = 3 if bad or len(dispatcher.rows) < len(cases) else 0
        if not quiet:
            print(summary_table(cases, dispatcher.rows))
            print(f"sweep: {len(todo)} case(s) run, {len(cases) - len(todo)} skipped (already complete) in "
                  f"{time.perf_counter() - t0:.1f} s; scheduler: {scheduler}")
            print(f"  table: {outdir / 'sweep.csv'}, {outdir / 'sweep.json'}; cases: {outdir / 'cases'}/; "
                  f"plots: {', '.join(str(p) for p in plots) or 'none'}")
            if bad:
                print(f"  {len(bad)} case(s) not ok: " + "; ".join(f"{r['case']}: {r['status']}" for r in bad[:3]))
    req = comm.Ibcast(status, root=0)
    sleep_until(req.Test)
    return int(status[0])


def main(scene: Scene, args, comm) -> int:
    """``python -m app validate|run`` for a sweep scene."""
    from app.common.errors import fail as _fail
    source = args.scene or "default scene"
    rpc = getattr(args, "ranks_per_case", None)
    if scene.sweep is None:
        return _fail(f"--ranks-per-case {rpc}: only for a scene with a 'sweep' section ({source} has none)")
    if getattr(scene, "refinement", None) is not None:
        return _fail(f"{source}: sweep: a scene has either a 'sweep' or a 'refinement' section, not both")
    try:
        cases = expand(scene, source, pathlib.Path(args.scene).parent if args.scene else None)
    except SceneError as err:
        return _fail(str(err))
    from app.scene import limits as preflight
    try:
        for c in cases:                     # arithmetic only: refuses an over-limit case before any work
            preflight.check(c.scene, f"{source}: case {c.name}")
    except SceneError as err:
        return _fail(str(err))
    if args.command == "validate":
        if comm.rank == 0:
            shown = ", ".join(c.name for c in cases[:4]) + (", ..." if len(cases) > 4 else "")
            print(f"{args.scene}: ok: sweep '{scene.name}' of {len(cases)} case(s) ({scene.sweep.mode} of "
                  f"{', '.join(scene.sweep.parameters)}): {shown}; system {scene.system.type}, "
                  f"analyses: {', '.join(scene.analyses)}")
        return 0
    rpc = 1 if rpc is None else rpc
    if not 1 <= rpc <= comm.size:
        return _fail(f"--ranks-per-case {rpc}: allowed: 1 to the number of MPI ranks ({comm.size})")
    import logging
    logging.basicConfig(level=getattr(logging, args.log_level), format="%(levelname)s: %(message)s")
    outdir = pathlib.Path(args.output or pathlib.Path("output") / scene.name)
    from app.io.folder import FolderLock
    lock = FolderLock(outdir)
    problem = None
    if comm.rank == 0:
        try:
            problem = _check_writable(outdir) or lock.acquire() or _check_writable(outdir, mark=True)
        except OSError as err:                     # e.g. a path too long for the file system
            problem = f"cannot use the output folder {outdir}: {err.strerror or err}"
        if problem:
            lock.release()
    problem = comm.bcast(problem, root=0)
    if problem:
        return _fail(problem)
    left = f"the sweep stopped; the cases it completed are in {outdir} (run it again to run the others)"
    try:
        with interrupt.cleanup_on_hard_stop(lock.release if comm.rank == 0 else _nothing, left):
            return run_sweep(scene, cases, comm, outdir, rpc, quiet=args.quiet,
                             rerun=bool(getattr(args, "overwrite", False)))
    except KeyboardInterrupt as err:     # a signal (app/common/runtime.py): the complete cases stay
        raise Stopped(err, left) from None
    finally:
        if comm.rank == 0:
            lock.release()


def _check_writable(outdir: pathlib.Path, mark: bool = False) -> str | None:
    """A sweep writes (and resumes) in place: only into a new or empty folder, or one this app
    marked as a sweep folder; anything else is refused untouched. ``mark``: create the folder,
    its ``cases/`` and the marker (rank 0, lock held)."""
    from app.io.folder import folder_state, marker_kind, write_marker
    state = folder_state(outdir)
    if state == "not-a-folder":
        return f"the output path {outdir} exists and is not a folder"
    if state == "other":
        return (f"the output folder {outdir} holds other files (not a sweep folder written by this app): "
                f"nothing was changed; choose a new or empty folder with -o")
    if state == "ours" and marker_kind(outdir) != "sweep":
        return (f"the output folder {outdir} holds the results of a single study, not a sweep: "
                f"choose another folder with -o")
    if not mark:
        try:
            outdir.parent.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            return f"cannot create the output folder {outdir}: {err.strerror or err}"
        return None
    for name, folder in (("cases", True), ("plots", True), ("sweep.log", False), ("sweep.csv", False),
                         ("sweep.json", False)):
        try:
            st = os.lstat(outdir / name)
        except FileNotFoundError:
            continue
        except OSError as err:
            return f"cannot use the output folder {outdir}: {name}: {err.strerror or err}"
        if not (stat.S_ISDIR(st.st_mode) if folder else stat.S_ISREG(st.st_mode)):
            from app.io.untrusted import kind_of
            return (f"the output folder {outdir}: {name} is {kind_of(st.st_mode)}, not the "
                    f"{'folder' if folder else 'file'} this app writes there: nothing was changed")
        if name == "sweep.log" and st.st_nlink != 1:       # appended to in place: never another file's content
            return (f"the output folder {outdir}: {name} has {st.st_nlink} hard links (another file shares its "
                    f"content): nothing was changed")
    cases = outdir / "cases"
    try:
        cases.mkdir(parents=True, exist_ok=True)
        if state != "ours":
            write_marker(outdir, "sweep")
    except OSError as err:
        return f"cannot create the output folder {outdir}: {err.strerror or err}"
    if not os.access(outdir, os.W_OK) or not os.access(cases, os.W_OK):
        return f"the output folder {outdir} is not writable"
    return None
