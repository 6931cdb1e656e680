"""Parameter sweeps: one scene file, many loading studies, run as an MPI task farm.

A scene with a ``sweep:`` section (schema: :class:`app.config.Sweep`) is expanded into cases:
the base scene with each swept key (a dotted path such as ``system.length``) set to one of its
values, every combination (``mode: product``) or the i-th values together (``mode: zip``). Each
case is validated as a normal scene before anything runs and gets a stable name made from its
values, e.g. ``mu=1.1_system.length=80``.

Running (``mpirun -n P python -m app run sweep.yaml --ranks-per-case K``):

* the P ranks are split (``comm.Split``) into groups of K consecutive ranks (the last group
  may be smaller); each group runs whole cases with ``run_study(case_scene, group_comm)``;
* world rank 0 is the dispatcher **and** works: a thread on rank 0 answers the group leaders'
  requests (MPI point-to-point messages on a duplicate of the world communicator) with the
  index of the next case, so a long case never holds up the others. If the MPI library does not
  provide ``MPI_THREAD_MULTIPLE``, rank 0 is a dedicated dispatcher instead (the other ranks
  work). With one rank the cases simply run one after the other;
* the group's rank 0 writes the case into ``OUTDIR/cases/<case name>/`` (``steps.csv``, then
  ``results.json`` atomically: its presence marks a complete case). ``results.json`` carries
  ``sweep_case`` with a hash of the case scene: a restarted sweep skips every case whose
  ``results.json`` is there with the same hash and runs only the others;
* world rank 0 keeps ``OUTDIR/sweep.csv`` and ``OUTDIR/sweep.json`` (one row per case with its
  quantities of interest) up to date as cases finish, logs what ran in ``OUTDIR/sweep.log``
  and at the end draws ``OUTDIR/plots/<swept key>.png`` (each quantity against that key).

Waiting ranks sleep between MPI tests instead of spinning in blocking calls, so idle ranks do
not steal cores from working ones on an oversubscribed machine.
"""
from __future__ import annotations

import csv
import datetime
import hashlib
import io
import itertools
import json
import math
import os
import pathlib
import re
import sys
import threading
import time
import traceback
from collections import deque
from dataclasses import dataclass
from typing import Any

from pydantic import ValidationError

from app.config import Scene, SceneError, format_error
from app.study_result import StateResult

TAG_REQUEST, TAG_REPLY = 7101, 7102
DISPATCHER_ENV = "CONTACT_DIVERGENCE_SWEEP_DISPATCHER"   # "dedicated": force a non-working rank 0 (tests)
_POLL_SECONDS = 0.01


# ---------------------------------------------------------------------------------------------
# Cases


@dataclass(frozen=True)
class Case:
    index: int
    name: str
    values: dict              # swept key -> value
    scene: Scene
    scene_hash: str


def format_value(v: Any) -> str:
    """The text of a swept value in case names and tables (floats to 12 significant digits)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:.12g}"
    if v is None:
        return "null"
    if isinstance(v, (list, tuple)):
        return ",".join(format_value(x) for x in v)
    return str(v)


def case_name(values: dict) -> str:
    """Stable folder name of a case: ``key=value`` joined by ``_``, e.g. ``mu=1.1_system.length=80``."""
    name = "_".join(f"{k}={format_value(v)}" for k, v in values.items())
    name = re.sub(r"[^A-Za-z0-9_.=,+\-]", "-", name)
    if len(name) > 150:      # keep folder names well below the 255-byte limit
        name = name[:130] + "~" + hashlib.sha1(name.encode()).hexdigest()[:12]
    return name


def scene_hash(scene: Scene) -> str:
    """Hash of everything that determines a case's results (its whole validated scene but the name)."""
    text = json.dumps(scene.model_dump(mode="json", exclude={"name"}), sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _set(data: dict, key: str, value: Any) -> None:
    *parents, last = key.split(".")
    for p in parents:
        sub = data.get(p)
        if not isinstance(sub, dict):
            sub = data[p] = {}
        data = sub
    data[last] = list(value) if isinstance(value, tuple) else value


def expand(scene: Scene, source: str = "scene") -> list[Case]:
    """The cases of a sweep scene, each validated as a normal scene.

    Raises :class:`SceneError` (one line, naming the case) when a value makes a case invalid.
    """
    sw = scene.sweep
    if sw is None:
        raise ValueError("not a sweep scene")
    keys = list(sw.parameters)
    columns = [sw.parameters[k] for k in keys]
    combos = zip(*columns) if sw.mode == "zip" else itertools.product(*columns)
    # only what the user wrote (defaults are filled in again when each case is validated)
    base = scene.model_dump(exclude_unset=True, exclude={"sweep"})
    cases, names = [], {}
    for i, combo in enumerate(combos):
        values = dict(zip(keys, combo))
        name = case_name(values)
        if name in names:
            raise SceneError(f"{source}: sweep: cases {names[name] + 1} and {i + 1} get the same name "
                             f"'{name}': list each value once (80 and 80.0 are the same value)")
        names[name] = i
        data = json.loads(json.dumps(base))     # deep copy, tuples as lists
        for k, v in values.items():
            _set(data, k, v)
        try:
            case_scene = Scene.model_validate(data)
        except ValidationError as err:
            raise SceneError(f"{source}: sweep case '{name}': {format_error(err)}") from None
        except RecursionError:
            raise SceneError(f"{source}: sweep case '{name}': the scene is nested too deeply") from None
        cases.append(Case(i, name, values, case_scene, scene_hash(case_scene)))
    return cases


# ---------------------------------------------------------------------------------------------
# Quantities of interest of one case

QUANTITIES = [   # (column, description), in table order after the swept keys
    ("status", "ok | incomplete (some states failed) | error: ..."),
    ("path_end", "how the loading path ended"),
    ("n_states", "equilibrium states on the path"),
    ("distinct_classifications", "distinct (classification, signs) along the path"),
    ("n_contact_nodes", "contact candidate nodes"),
    ("L_over_H", "aspect ratio of the block"),
    ("final_u_x_mm", "CD displacement u_x at the final state [mm]"),
    ("final_n_slip", "slip nodes at the final state"),
    ("final_n_stick", "stick nodes at the final state"),
    ("final_n_free", "free nodes at the final state"),
    ("final_n_zero", "zero-reaction nodes at the final state"),
    ("final_mceip_mu_min", "smallest MCEIP-mu at the final state"),
    ("final_mceip_mu_count", "MCEIP-mu solutions found at the final state"),
    ("first_mceip_mu_state", "index of the first state with an MCEIP-mu solution"),
    ("first_mceip_mu_u_x_mm", "CD u_x at that state [mm]"),
    ("first_mceip_mu_value", "smallest MCEIP-mu at that state"),
    ("first_mceip_mu_n_slip", "slip nodes at that state"),
    ("first_mceip_mu_n_stick", "stick nodes at that state"),
    ("first_mceip_mu_n_free", "free nodes at that state"),
    ("first_mceip_mu_slip_fraction", "slip nodes / nodes in contact at that state"),
    ("first_mceip_mu_u_x_fraction", "CD u_x at that state / CD u_x at the final state"),
    ("states_with_mceip_mu", "states with at least one MCEIP-mu solution"),
    ("states_without_mceip_mu_after_first", "states after the first solution where none was found"),
    ("mceip_mu_decreases_as_slip_spreads", "between consecutive states with solutions, the smallest MCEIP-mu "
                                           "drops whenever the number of stick nodes drops"),
    ("mceip_mu_max_rise", "largest relative rise of the smallest MCEIP-mu from one state with solutions to the "
                          "next (0: it never rises along the path)"),
    ("wall_seconds", "wall time of the case's study [s]"),
    ("ranks", "MPI ranks that ran the case"),
    ("ran", "'this run' or 'earlier' (skipped on restart: results.json already complete)"),
]
PLOTTED = ["final_mceip_mu_min", "first_mceip_mu_value", "first_mceip_mu_u_x_mm", "first_mceip_mu_n_slip",
           "first_mceip_mu_slip_fraction", "first_mceip_mu_u_x_fraction", "final_u_x_mm", "final_n_slip",
           "final_n_stick", "final_n_free", "n_states", "wall_seconds"]


def _min_mu(state: dict) -> float | None:
    m = StateResult.from_dict(state).min_mu()
    return None if m is None else float(m)


def case_row(results: dict, case: Case, ran: str = "this run") -> dict:
    """One row of the combined table from a case's results dictionary (or its results.json)."""
    row: dict[str, Any] = {"case": case.name, "index": case.index}
    row.update({k: format_value(v) if isinstance(v, (list, tuple)) else v for k, v in case.values.items()})
    row.update({q: None for q, _ in QUANTITIES})
    states = results.get("states") or []
    fails = results.get("failures") or []
    row["status"] = f"incomplete ({len(fails)} state(s) failed)" if fails else "ok"
    row["path_end"] = str(results.get("path", {}).get("end", "")).split(":")[0]
    row["n_states"] = len(states)
    row["distinct_classifications"] = results.get("distinct_classifications")
    row["wall_seconds"] = results.get("wall_seconds")
    row["ranks"] = results.get("mpi_ranks")
    row["ran"] = ran
    columns = getattr(case.scene.system, "table_columns", None)   # e.g. the block's L/H (app/systems/)
    if columns is not None:
        row.update(columns())
    if not states:
        return row
    last = states[-1]
    row["n_contact_nodes"] = len(last.get("nodes", []))
    row["final_u_x_mm"] = last.get("load", {}).get("u_x")
    for k in ("slip", "stick", "free", "zero"):
        row[f"final_n_{k}"] = last["classification"][k]
    if "mceip_mu" in results.get("analyses_requested", []):
        row["final_mceip_mu_min"] = _min_mu(last)
        row["final_mceip_mu_count"] = len(last.get("analyses", {}).get("mceip_mu", {}).get("solutions") or [])
        mins = [_min_mu(s) for s in states]
        first = next((i for i, m in enumerate(mins) if m is not None), None)
        row["states_with_mceip_mu"] = sum(m is not None for m in mins)
        if first is not None:
            st = states[first]
            c = st["classification"]
            row["first_mceip_mu_state"] = st["index"]
            row["first_mceip_mu_u_x_mm"] = st.get("load", {}).get("u_x")
            row["first_mceip_mu_value"] = mins[first]
            row["first_mceip_mu_n_slip"], row["first_mceip_mu_n_stick"] = c["slip"], c["stick"]
            row["first_mceip_mu_n_free"] = c["free"]
            in_contact = c["slip"] + c["stick"] + c["zero"]
            row["first_mceip_mu_slip_fraction"] = c["slip"] / in_contact if in_contact else None
            ux0, ux1 = row["first_mceip_mu_u_x_mm"], row["final_u_x_mm"]
            if isinstance(ux0, (int, float)) and isinstance(ux1, (int, float)) and ux1 != 0:
                row["first_mceip_mu_u_x_fraction"] = ux0 / ux1
            row["states_without_mceip_mu_after_first"] = sum(m is None for m in mins[first:])
            found = [(m, s["classification"]["stick"]) for m, s in zip(mins[first:], states[first:]) if m is not None]
            pairs = list(zip(found, found[1:]))
            row["mceip_mu_decreases_as_slip_spreads"] = all(b < a for (a, sa), (b, sb) in pairs if sb < sa)
            row["mceip_mu_max_rise"] = max([0.0] + [b / a - 1 for (a, _), (b, _) in pairs if a > 0])
    return row


def error_row(case: Case, message: str, ran: str = "this run") -> dict:
    row: dict[str, Any] = {"case": case.name, "index": case.index}
    row.update({k: format_value(v) if isinstance(v, (list, tuple)) else v for k, v in case.values.items()})
    row.update({q: None for q, _ in QUANTITIES})
    row["status"], row["ran"] = f"error: {message}", ran
    return row


def case_dir(outdir: pathlib.Path, case: Case) -> pathlib.Path:
    return outdir / "cases" / case.name


def completed_results(outdir: pathlib.Path, case: Case) -> dict | None:
    """The case's results.json if it is complete and was computed from the same case scene."""
    path = case_dir(outdir, case) / "results.json"
    try:
        res = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(res, dict) or (res.get("sweep_case") or {}).get("scene_hash") != case.scene_hash:
        return None
    return res


# ---------------------------------------------------------------------------------------------
# Running one case (collective on the group communicator)


def run_case(case: Case, gcomm, outdir: pathlib.Path) -> dict | None:
    """Run ``case`` on ``gcomm``; the group's rank 0 writes it and returns its table row."""
    from app.outputs.results import atomic_write, write_results
    from app.progress import Progress
    from app.study import run_study
    error = None
    folder = case_dir(outdir, case)
    if gcomm.rank == 0:
        folder.mkdir(parents=True, exist_ok=True)
    try:
        from app.errors import UnreachableLoad
        try:
            # outdir: where the scene's field outputs (if any) go, as for a single study
            results = run_study(case.scene, gcomm, Progress(enabled=False), outdir=folder)
        except UnreachableLoad as err:   # raised identically on every rank of the group
            error = f"loading: {err}"
    except Exception as err:             # noqa: BLE001
        if gcomm.size > 1:               # may be on this rank only: the CLI aborts the job
            raise
        error = f"{type(err).__name__}: {err}"
        traceback.print_exc()
    if gcomm.rank != 0:
        return None
    if error is not None:
        atomic_write(folder / "error.json", json.dumps({"case": case.name, "error": error}, indent=1))
        return error_row(case, error)
    results["sweep_case"] = {"sweep": case.scene.name, "name": case.name, "index": case.index,
                             "values": case.values, "scene_hash": case.scene_hash}
    from app.outputs.pictures import draw_after_run  # plots, screenshots, report, if the scene asks
    results = draw_after_run(results, folder, Progress(enabled=False))
    write_results(results, folder)
    (folder / "error.json").unlink(missing_ok=True)
    return case_row(results, case)


# ---------------------------------------------------------------------------------------------
# The dispatcher (world rank 0) and the combined outputs


class Dispatcher:
    """Hands out case indices on request and collects the finished cases' rows (rank 0 only)."""

    def __init__(self, scene: Scene, cases: list[Case], todo: list[int], rows: dict[int, dict],
                 outdir: pathlib.Path, quiet: bool, info: dict):
        self.scene, self.cases, self.outdir, self.quiet, self.info = scene, cases, outdir, quiet, info
        self.pending = deque(todo)
        self.rows = rows
        self.n_todo, self.n_done = len(todo), 0
        self.running: dict[int, int] = {}      # group -> case index
        log = outdir / "sweep.log"
        if log.exists() and log.stat().st_size and not log.read_bytes().endswith(b"\n"):
            with open(log, "a", encoding="utf-8") as f:       # a line cut short by a killed run
                f.write("\n")

    def log(self, event: str, case: Case | None = None, detail: str = "") -> None:
        stamp = datetime.datetime.now().isoformat(timespec="milliseconds")
        line = "\t".join([stamp, event, case.name if case else "-", detail]).rstrip("\t")
        with open(self.outdir / "sweep.log", "a", encoding="utf-8") as f:
            f.write(line + "\n")

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


def _columns(cases: list[Case]) -> list[str]:
    return ["case", "index", *cases[0].values.keys(), *(q for q, _ in QUANTITIES)]


def write_tables(outdir: pathlib.Path, scene: Scene, cases: list[Case], rows: dict[int, dict],
                 info: dict) -> None:
    """sweep.csv and sweep.json (atomically): one row per case, finished or not."""
    from app.outputs.results import atomic_write, json_clean
    cols = _columns(cases)
    table = []
    for c in cases:
        row = rows.get(c.index)
        if row is None:
            row = {**error_row(c, ""), "status": "not run", "ran": None}
        table.append({k: row.get(k) for k in cols})
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=cols, lineterminator="\n")
    w.writeheader()
    for r in table:
        w.writerow({k: "" if v is None else (repr(v) if isinstance(v, float) else v) for k, v in r.items()})
    atomic_write(outdir / "sweep.csv", buf.getvalue())
    missing = [r["case"] for r in table if r["status"] == "not run"]
    doc = {"scene": scene.name, "sweep": scene.sweep.model_dump(mode="json"), "n_cases": len(cases),
           "complete": not missing, "missing": missing, **info,
           "columns": {"case": "stable case name (cases/<case>/ holds its results.json, steps.csv)",
                       "index": "case number in sweep order (from 0)",
                       **{k: "swept key" for k in cases[0].values}, **dict(QUANTITIES)},
           "cases": table}
    atomic_write(outdir / "sweep.json", json.dumps(json_clean(doc), indent=1))


def write_plots(outdir: pathlib.Path, mode: str, cases: list[Case], rows: dict[int, dict]) -> list[pathlib.Path]:
    """One PNG per swept key: every plotted quantity against it (one line per value of the
    other swept keys in a product sweep)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    keys = list(cases[0].values)
    out = []
    (outdir / "plots").mkdir(exist_ok=True)
    table = [(c, rows.get(c.index) or {}) for c in cases]
    for key in keys:
        quantities = [q for q in PLOTTED if any(isinstance(r.get(q), (int, float)) and not isinstance(r.get(q), bool)
                                                 for _, r in table)]
        if not quantities:
            continue
        xs_all = [c.values[key] for c, _ in table]
        numeric = all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in xs_all)
        categories = list(dict.fromkeys(format_value(x) for x in xs_all))
        others = [k for k in keys if k != key]
        series: dict[str, list] = {}
        for c, r in table:
            label = ", ".join(f"{k}={format_value(c.values[k])}" for k in others) if mode != "zip" else ""
            series.setdefault(label, []).append((c, r))
        ncol = min(3, len(quantities))
        nrow = math.ceil(len(quantities) / ncol)
        fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.1 * nrow), squeeze=False)
        for ax, q in zip(axes.flat, quantities):
            for label, items in series.items():
                pts = [((c.values[key] if numeric else categories.index(format_value(c.values[key]))), r.get(q))
                       for c, r in items]
                pts = sorted((x, y) for x, y in pts if isinstance(y, (int, float)) and not isinstance(y, bool))
                if pts:
                    ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", ms=4, label=label or None)
            ys = [r.get(q) for _, r in table if isinstance(r.get(q), (int, float))]
            if "mceip_mu" in q and ys and min(ys) > 0 and max(ys) / min(ys) > 50:
                ax.set_yscale("log")
            ax.set_title(q, fontsize=9)
            ax.set_xlabel(key, fontsize=8)
            ax.tick_params(labelsize=7)
            if not numeric:
                ax.set_xticks(range(len(categories)), categories, rotation=30)
            ax.grid(alpha=0.3)
        for ax in list(axes.flat)[len(quantities):]:
            ax.set_visible(False)
        if len(series) > 1:
            axes.flat[0].legend(fontsize=6)
        fig.suptitle(f"{cases[0].scene.name}: quantities against {key}", fontsize=10)
        fig.tight_layout()
        path = outdir / "plots" / f"{re.sub(r'[^A-Za-z0-9_.=-]', '-', key)}.png"
        fig.savefig(path, dpi=90)
        plt.close(fig)
        out.append(path)
    return out


# ---------------------------------------------------------------------------------------------
# The task farm


def _sleep_until(test) -> Any:
    while True:
        done = test()
        if done:
            return done
        time.sleep(_POLL_SECONDS)


def _serve(farm, dispatcher: Dispatcher, n_groups: int) -> None:
    """Answer the group leaders' requests until every group has been told to stop."""
    from mpi4py import MPI
    active, sends = n_groups, []
    status = MPI.Status()
    while active:
        _sleep_until(lambda: farm.Iprobe(source=MPI.ANY_SOURCE, tag=TAG_REQUEST, status=status))
        source = status.Get_source()
        group, row = farm.recv(source=source, tag=TAG_REQUEST)
        idx = dispatcher.handle(group, row)
        sends.append(farm.isend(idx, dest=source, tag=TAG_REPLY))
        if idx is None:
            active -= 1
    _sleep_until(lambda: MPI.Request.Testall(sends))


def _serve_or_abort(farm, dispatcher: Dispatcher, n_groups: int) -> None:
    from mpi4py import MPI
    try:
        _serve(farm, dispatcher, n_groups)
    except BaseException:             # noqa: BLE001 - the workers would wait forever
        traceback.print_exc()
        print("error: the sweep dispatcher failed; aborting all ranks", file=sys.stderr, flush=True)
        MPI.COMM_WORLD.Abort(1)


def run_cases(cases: list[Case], todo: list[int], comm, ranks_per_case: int, outdir: pathlib.Path,
              dispatcher: Dispatcher | None) -> str:
    """Run the cases ``todo`` (same list on every rank) over ``comm``; returns the scheduler used.
    ``dispatcher`` is given on rank 0 only."""
    from mpi4py import MPI
    if comm.size == 1:
        row = None
        while (idx := dispatcher.handle(0, row)) is not None:
            row = run_case(cases[idx], comm, outdir)
        return "serial (one rank)"
    # PETSc and SLEPc initialise collectively on the world communicator when first imported: do it
    # here on every rank, not inside the first case (a rank may never run one).
    from petsc4py import PETSc  # noqa: F401
    from slepc4py import SLEPc  # noqa: F401

    from app.systems import get as system_type
    for name in sorted({c.scene.system.type for c in cases}):
        system_type(name).preload()      # e.g. DOLFINx for the block
    threaded = (MPI.Query_thread() >= MPI.THREAD_MULTIPLE
                and os.environ.get(DISPATCHER_ENV, "") != "dedicated")
    first = 0 if threaded else 1
    n_groups = math.ceil((comm.size - first) / ranks_per_case)
    color = (comm.rank - first) // ranks_per_case if comm.rank >= first else MPI.UNDEFINED
    farm = comm.Dup()
    gcomm = comm.Split(color, comm.rank)
    thread = None
    if comm.rank == 0:
        if threaded:
            thread = threading.Thread(target=_serve_or_abort, args=(farm, dispatcher, n_groups),
                                      name="sweep-dispatcher", daemon=True)
            thread.start()
        else:
            _serve_or_abort(farm, dispatcher, n_groups)
    if gcomm != MPI.COMM_NULL:
        row = None
        while True:
            idx = None
            if gcomm.rank == 0:
                req = farm.isend((color, row), dest=0, tag=TAG_REQUEST)
                _sleep_until(lambda: farm.Iprobe(source=0, tag=TAG_REPLY))
                idx = farm.recv(source=0, tag=TAG_REPLY)
                req.wait()
            if gcomm.size > 1:
                idx = gcomm.bcast(idx, root=0)
            if idx is None:
                break
            row = run_case(cases[idx], gcomm, outdir)
        gcomm.Free()
    if thread is not None:
        thread.join()
    barrier = comm.Ibarrier()
    _sleep_until(barrier.Test)
    farm.Free()
    how = "world rank 0 dispatches (thread) and works" if threaded else "dedicated dispatcher on world rank 0"
    return f"{how}; {n_groups} group(s) of up to {ranks_per_case} rank(s)"


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
            res = None if rerun else completed_results(outdir, c)
            if res is None:
                todo.append(c.index)
            else:
                rows[c.index] = case_row(res, c, ran="earlier")
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
        plots = write_plots(outdir, scene.sweep.mode, cases, dispatcher.rows)
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
    _sleep_until(req.Test)
    return int(status[0])


def summary_table(cases: list[Case], rows: dict[int, dict]) -> str:
    """A short plain-text table of the main quantities, one line per case."""
    def f(v, fmt="{:.4g}"):
        return "-" if v is None else (fmt.format(v) if isinstance(v, float) else str(v))
    head = ["case", "final mu", "1st mu", "1st state", "1st u_x", "1st slip", "final slip/stick/free", "s"]
    lines = [head]
    for c in cases:
        r = rows.get(c.index) or {}
        lines.append([c.name, f(r.get("final_mceip_mu_min")), f(r.get("first_mceip_mu_value")),
                      f(r.get("first_mceip_mu_state")), f(r.get("first_mceip_mu_u_x_mm")),
                      f(r.get("first_mceip_mu_n_slip")),
                      "/".join(f(r.get(f"final_n_{k}")) for k in ("slip", "stick", "free")),
                      f(r.get("wall_seconds"), "{:.1f}")])
    widths = [max(len(row[i]) for row in lines) for i in range(len(head))]
    return "\n".join("  " + "  ".join(x.ljust(w) for x, w in zip(row, widths)) for row in lines)


# ---------------------------------------------------------------------------------------------
# Command line (called by app.cli for scenes with a sweep section)


def main(scene: Scene, args, comm) -> int:
    """``python -m app validate|run`` for a sweep scene."""
    from app.errors import fail as _fail
    source = args.scene or "default scene"
    rpc = getattr(args, "ranks_per_case", None)
    if scene.sweep is None:
        return _fail(f"--ranks-per-case {rpc}: only for a scene with a 'sweep' section ({source} has none)")
    if getattr(scene, "refinement", None) is not None:
        return _fail(f"{source}: sweep: a scene has either a 'sweep' or a 'refinement' section, not both")
    try:
        cases = expand(scene, source)
    except SceneError as err:
        return _fail(str(err))
    from app import preflight
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
    from app.outputs.folder import FolderLock
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
    try:
        return run_sweep(scene, cases, comm, outdir, rpc, quiet=args.quiet,
                         rerun=bool(getattr(args, "overwrite", False)))
    finally:
        if comm.rank == 0:
            lock.release()


def _check_writable(outdir: pathlib.Path, mark: bool = False) -> str | None:
    """A sweep writes (and resumes) in place: only into a new or empty folder, or one this app
    marked as a sweep folder; anything else is refused untouched. ``mark``: create the folder,
    its ``cases/`` and the marker (rank 0, lock held)."""
    from app.outputs.folder import folder_state, marker_kind, write_marker
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
    cases = outdir / "cases"
    if cases.exists() and (cases.is_symlink() or not cases.is_dir()):
        return f"the output folder {outdir}: {cases} is not a folder"
    try:
        cases.mkdir(parents=True, exist_ok=True)
        if state != "ours":
            write_marker(outdir, "sweep")
    except OSError as err:
        return f"cannot create the output folder {outdir}: {err.strerror or err}"
    if not os.access(outdir, os.W_OK) or not os.access(cases, os.W_OK):
        return f"the output folder {outdir} is not writable"
    return None
