"""A loading study end to end: scene -> system -> loading path -> per-state analyses -> results.

Analyses depend only on a state's classification and slip signs (docs/method.md section 2), so they
are computed once per distinct classification and shared; each state says which state it shares
its analyses with.
"""
from __future__ import annotations

import time

import numpy as np
from mpi4py import MPI

from app.analyses.outcomes import STOPPED, Deferred, Failed
from app.analyses.pencils.curvature import attach as attach_curvature
from app.analyses.runner import analyse_state
from app.common.interrupt import checkpoint
from app.common.library_warnings import describe, explained, merged
from app.common.progress import Progress
from app.common.stages import Stages
from app.io.from_outcomes import analyses_result
from app.io.result import Node, StateResult, StudyResult
from app.linalg import one_blas_thread
from app.loading.classify import ZERO, classified
from app.loading.sanity import check_contact, check_final_stick_zone
from app.scene.schema import Scene
from app.study import stream
from app.study.scheduler import EarlyChains, analyse_condensed_distributed
from app.systems import get as system_type
from app.systems.units import CONTINUUM_UNITS


def study(scene: Scene, comm: MPI.Comm, progress: Progress | None = None, inspect=None,
          outdir=None) -> StudyResult:
    """Run ``scene`` (MPI collective); returns the typed :class:`StudyResult` (identical on every
    rank), its states' analyses built from the analyses' typed outcomes (app/io/from_outcomes.py);
    results.json is written from it (:meth:`StudyResult.to_json`).

    ``inspect(system, states, cache)``, if given, runs after the per-state analyses while the
    system is alive (``cache``: classification key -> (first state, its analyses: name -> typed
    outcome of :mod:`app.analyses.outcomes`)); what it
    returns is stored as the result's ``inspection`` (used by app/study/refinement.py).
    ``outdir``: the results folder, where the field stage (app/io/fields.py: ParaView
    files, screenshot data) writes when the scene's ``outputs`` ask for fields.
    """
    t_start = time.perf_counter()
    stages = Stages()
    with explained() as caught:
        result = _run(scene, comm, stages, progress or Progress(enabled=False), inspect, outdir, t_start)
    # each rank saw the warnings of its own share of the work (MPI collective)
    library = merged(comm.allgather(caught.as_list()))
    if library:
        result = result.model_copy(update={
            "library_warnings": library,
            "warnings": [*result.warnings, *(describe(r) for r in library if not r["explanation"])]})
    return result


def _run(scene: Scene, comm: MPI.Comm, stages: Stages, progress: Progress, inspect, outdir,
         t_start: float) -> StudyResult:
    """The body of :func:`study` (library warnings are caught around it)."""
    kind = system_type(scene.system.type)
    if stream.applies(scene, comm, kind):
        # rank 0 walks the path while the other ranks already prove what it has passed
        system, walk = kind.walker(scene, comm, stages)
        try:
            with EarlyChains(system, scene, comm) as early:                 # MPI collective (window)
                per_state = Classified(system, scene, progress if comm.rank == 0 else None)
                states, path_info = stream.walk(comm, walk, progress, stages, per_state, early)
                per_state.finish_postponed()          # ranks > 0: the states that needed all ranks
                return _study(scene, comm, stages, progress, inspect, outdir, t_start, system, states, path_info,
                              per_state, early)
        finally:
            system.destroy()
    # the system type's own module (app/systems/) builds the system and runs its loading path
    system, states, path_info = kind.path(scene, comm, stages, progress)
    try:
        return _study(scene, comm, stages, progress, inspect, outdir, t_start, system, states, path_info)
    finally:
        system.destroy()              # its PETSc objects, on every path (errors included)


#: the analyses in the progress line
ANALYSIS_WORDS = {"necessary": "necessary condition (19)", "sufficient": "sufficient condition (17)-(18)",
                  "mceip_mu": "MCEIP-mu", "mceip_lambda2": "MCEIP-lambda^2", "enumerate": "enumeration"}


class Classified:
    """The per-state part of a study, state by state: each state classified, its contact nodes
    typed, and the scene's analyses run once per distinct classification (the condensed MCEIP-mu
    left :class:`Deferred` in :attr:`deferred` for app/study/scheduler.py).

    ``postpone``: a state whose analyses would need every rank (a new classification with
    zero-reaction nodes: its dense answer is broadcast from rank 0) is kept for
    :meth:`finish_postponed`; used by ranks > 0 while rank 0 walks the path (app/study/stream.py)."""

    def __init__(self, system, scene: Scene, progress: Progress | None):
        self.system, self.scene = system, scene
        self.cache: dict = {}       # classification key -> (first state, its analyses)
        self.deferred: list = []    # (classification, its analyses, state index): condensed MCEIP-mu
        self.out_states: list = []
        self.typed_nodes: list = []   # per state: its contact nodes (app.io.result.Node)
        self.states: list = []        # the states classified, and their classifications
        self.classes: list = []
        self.failures: list = []
        self.postponed: list = []   # (entry, classification) whose analyses wait for every rank
        self.progress = progress
        self._running = ""          # the analysis running now (for the progress line)
        self._ids = [int(n.id) for n in system.nodes]
        self._xs = [float(n.x) for n in system.nodes]

    def add(self, state, postpone: bool = False) -> tuple | None:
        """Classify and analyse ``state``; returns its deferred job ``(classification, analyses)`` if
        it opened one."""
        checkpoint()                  # a Ctrl-C whose KeyboardInterrupt was swallowed (app/common/interrupt.py)
        t_state = time.perf_counter()
        system, scene = self.system, self.scene
        # on a curved obstacle the pencils also depend on kappa P and the contact frames (app/analyses/pencils/curvature.py)
        cls = attach_curvature(classified(state, scene.mu, scene.settings.classify_rtol), state, system)
        self.states.append(state)
        self.classes.append(cls)
        # one row per contact node, from Python numbers (a 100k-DOF study has 10^5 of them)
        values = [np.asarray(v, dtype=float) for v in (state.u_N, state.u_T, state.r_N, state.r_T)]
        # the app's own numbers: built without validation (model_construct), as fast as a dict
        self.typed_nodes.append(tuple(
            Node.model_construct(id=i, x=x, status=st, sign=sg, u_N=uN, u_T=uT, r_N=rN, r_T=rT)
            for i, x, st, sg, uN, uT, rN, rT in zip(self._ids, self._xs, cls.status, cls.signs,
                                                       *(v.tolist() for v in values))))
        entry = {"index": state.index, "load": state.load, "classification": cls.counts(), **state.extra}
        self.out_states.append(entry)
        job = None
        if cls.key in self.cache:
            first, analyses = self.cache[cls.key]
            entry["analyses_shared_with"] = first
        elif postpone and ZERO in cls.status:
            analyses = {}             # filled in place by finish_postponed (shared by later states)
            self.postponed.append((entry, cls))
            self.cache[cls.key] = (state.index, analyses)
            entry["analyses_shared_with"] = None
        else:
            analyses = self._analyse(cls, state.index)
            if isinstance(analyses.get("mceip_mu"), Deferred):
                self.deferred.append((cls, analyses, state.index))
                job = (cls, analyses)
            self.cache[cls.key] = (state.index, analyses)
            entry["analyses_shared_with"] = None
        entry["analyses"] = analyses
        entry["analysis_seconds"] = time.perf_counter() - t_state
        return job

    def _note(self, analysis: str) -> None:
        """``analysis`` begins (shown in the progress line)."""
        self._running = analysis

    def _analyse(self, cls, index: int) -> dict:
        # small dense work (condensed pencils, projected eigenproblems): one BLAS thread is
        # 3-6x faster than OpenBLAS's default on these sizes
        with one_blas_thread():
            analyses = analyse_state(self.system, cls, self.scene, defer_condensed=True, now=self._note)
        for name, a in analyses.items():
            if isinstance(a, Failed):
                self.failures.append({"state": index, "analysis": name, "reason": a.reason})
        return analyses

    def add_all(self, states) -> None:
        """:meth:`add` every state, with a progress line at least every few seconds while one runs
        (which state, which analysis, for how long)."""
        with (self.progress or Progress(enabled=False)).tasks(len(states), "analyses", unit="state") as tasks:
            for state in states:
                self._running = ""
                tasks.start(f"state {state.index}", detail=lambda: ANALYSIS_WORDS.get(self._running, self._running))
                self.add(state)
                tasks.finish(f"state {state.index}", 1.0)

    def finish_postponed(self) -> None:
        """The analyses of the postponed states, in path order (every rank takes part in the same
        order as rank 0's :meth:`add`)."""
        for entry, cls in self.postponed:
            t = time.perf_counter()
            entry["analyses"].update(self._analyse(cls, entry["index"]))
            entry["analysis_seconds"] += time.perf_counter() - t
        self.postponed = []


def _study(scene: Scene, comm: MPI.Comm, stages: Stages, progress: Progress, inspect, outdir, t_start: float,
           system, states, path_info, per_state: Classified | None = None,
           early: EarlyChains | None = None) -> StudyResult:
    """The per-state analyses and fields of :func:`_run` on the built ``system``: the typed result.

    The states hold the typed outcomes (:mod:`app.analyses.outcomes`) until every analysis is
    done; each distinct classification's analyses then become one typed
    :class:`app.io.result.Analyses`, shared by its states. ``per_state``: the states already classified (on ranks > 0
    while rank 0 walked the path; rank 0 classifies them here); ``early``: the MCEIP-mu chains
    those ranks began (app/study/scheduler.py)."""
    if per_state is None:
        per_state = Classified(system, scene, progress)
        per_state.add_all(states)
    out_states = per_state.out_states
    stages.warnings += check_contact(per_state.states, per_state.classes, str(path_info.get("end", "")),
                                     mceip=bool({"mceip_mu", "mceip_lambda2"} & set(scene.analyses)))
    if per_state.states and getattr(scene.system, "has_fields", False):   # a mesh: a node stands for a width
        stages.warnings += check_final_stick_zone(per_state.classes[-1], [nd.x for nd in system.nodes],
                                                  per_state.states[-1].index, CONTINUUM_UNITS[scene.units]["length"])
    failures = [path_info["failure"]] if path_info.get("failure") else []
    failures += per_state.failures
    deferred = per_state.deferred
    if deferred or early is not None:   # the condensed MCEIP-mu of every classification, one rank each under MPI
        with one_blas_thread():
            failed = analyse_condensed_distributed(system, scene, [(c, a) for c, a, _ in deferred], comm,
                                                   progress, early)
        failures += [{"state": deferred[k][2], "analysis": "mceip_mu", "reason": r} for k, r in failed]
    inspection = inspect(system, states, per_state.cache) if inspect is not None else None
    outcomes = [entry["analyses"] for entry in out_states]
    stopped = stopped_by_time(out_states)
    if stopped:
        stages.warnings.append(
            f"MCEIP-mu proof {STOPPED} at {len(stopped)} state(s) (from state {stopped[0]}; settings.mcp "
            "certify_seconds, certify_seconds_large, certify_all_seconds): those statuses depend on the machine's "
            "speed; the budgets themselves count proof-tree nodes")
    typed = _typed_states(out_states, per_state.typed_nodes, outcomes)
    transient = None
    if scene.transient is not None:        # the dynamics from chosen states (app/analyses/transient/)
        from app.analyses.transient.study import run_transients
        with stages("transient (nonsmooth dynamics)"):
            transient = run_transients(scene, system, typed, comm)          # MPI collective
    outputs_record = None
    from app.io.fields import wants_fields
    if wants_fields(scene):   # only when the scene asks for ParaView files or screenshots
        from app.io.fields import compute_fields
        outputs_record = compute_fields(scene, system, typed, stages, progress, outdir)
    return StudyResult.model_validate({
        **({"inspection": inspection} if inspect is not None else {}), "scene": scene.name,
        "units": system.units, "system": system.description, "mu": scene.mu,
        "analyses_requested": list(scene.analyses), "path": path_info,
        "distinct_classifications": len(per_state.cache), "stages": stages.as_list(), "failures": failures,
        "warnings": stages.warnings, "mpi_ranks": comm.size, "wall_seconds": time.perf_counter() - t_start,
        "scene_config": scene.model_dump(mode="json", exclude_none=True),
        **({"outputs": outputs_record} if outputs_record is not None else {}),
        **({"transient": transient} if transient is not None else {}), "states": typed})


def stopped_by_time(out_states: list[dict]) -> list[int]:
    """The indices of the states whose MCEIP-mu proof a wall-clock safety stop ended (its
    certificate or a claim's status says :data:`app.analyses.outcomes.STOPPED`), read from the
    typed outcomes before :func:`_write_analyses`."""
    out = []
    for entry in out_states:
        m = entry["analyses"].get("mceip_mu") if isinstance(entry["analyses"], dict) else None
        texts = [getattr(getattr(m, k, None), "status", None) for k in ("certificate", "onset", "complete")]
        if any(isinstance(t, str) and STOPPED in t for t in texts):
            out.append(int(entry["index"]))
    return out


def _typed_states(out_states: list[dict], nodes: list[tuple], outcomes: list[dict]) -> list[StateResult]:
    """Each state typed: its entry (index, load, classification, what its loading path recorded),
    its contact nodes and the typed analyses of its classification (one
    :class:`app.io.result.Analyses` shared by the states of a classification, built from the
    outcomes by :func:`app.io.from_outcomes.analyses_result`)."""
    shared: dict[int, object] = {}
    out = []
    for entry, state_nodes, analyses in zip(out_states, nodes, outcomes):
        typed = shared.get(id(analyses))
        if typed is None:
            typed = shared[id(analyses)] = analyses_result(analyses)
        out.append(StateResult.model_validate({**entry, "nodes": state_nodes, "analyses": typed}))
    return out
