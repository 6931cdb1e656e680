"""A loading study end to end: scene -> system -> loading path -> per-state analyses -> results.

Analyses depend only on a state's classification and slip signs (docs/method.md section 2), so they
are computed once per distinct classification and shared; each state says which state it shares
its analyses with.
"""
from __future__ import annotations

import time

from mpi4py import MPI

from app.analyses.curvature import attach as attach_curvature
from app.analyses.distributed import analyse_condensed_distributed
from app.analyses.outcomes import Deferred, Failed, analyses_document
from app.analyses.runner import analyse_state
from app.common.interrupt import checkpoint
from app.common.library_warnings import describe, explained, merged
from app.common.progress import Progress
from app.common.stages import Stages
from app.io.from_outcomes import state_view
from app.io.result import Node, StudyResult
from app.linalg import one_blas_thread
from app.loading.classify import classify
from app.scene.schema import Scene
from app.systems import get as system_type


def run_study(scene: Scene, comm: MPI.Comm, progress: Progress | None = None, inspect=None,
              outdir=None) -> dict:
    """Run ``scene``; returns the results dictionary (identical on every rank): the ``raw`` of
    :func:`study` (the arguments are its own)."""
    return study(scene, comm, progress, inspect, outdir).raw


def study(scene: Scene, comm: MPI.Comm, progress: Progress | None = None, inspect=None,
          outdir=None) -> StudyResult:
    """Run ``scene`` (MPI collective); returns the typed :class:`StudyResult` (identical on every
    rank), its states built from the analyses' typed outcomes (app/io/from_outcomes.py) and its
    ``raw`` the results dictionary that results.json is written from.

    ``inspect(system, states, cache)``, if given, runs after the per-state analyses while the
    system is alive (``cache``: classification key -> (first state, its analyses: name -> typed
    outcome of :mod:`app.analyses.outcomes`)); what it
    returns is stored as ``results["inspection"]`` (used by app/study/refinement.py).
    ``outdir``: the results folder, where the field stage (app/io/fields.py: ParaView
    files, screenshot data) writes when the scene's ``outputs`` ask for fields.
    """
    t_start = time.perf_counter()
    stages = Stages()
    with explained() as caught:
        results, views = _run(scene, comm, stages, progress or Progress(enabled=False), inspect, outdir, t_start)
    # each rank saw the warnings of its own share of the work (MPI collective)
    library = merged(comm.allgather(caught.as_list()))
    if library:
        results["library_warnings"] = library
        results["warnings"] += [describe(r) for r in library if not r["explanation"]]
    return StudyResult(scene=scene.name, system=results["system"], mu=float(scene.mu), units=results["units"],
                       analyses_requested=tuple(scene.analyses), path=results["path"],
                       failures=tuple(results["failures"]), warnings=tuple(results["warnings"]),
                       states=views, raw=results)


def _run(scene: Scene, comm: MPI.Comm, stages: Stages, progress: Progress, inspect, outdir,
         t_start: float) -> tuple[dict, tuple]:
    """The body of :func:`run_study` (library warnings are caught around it)."""
    # the system type's own module (app/systems/) builds the system and runs its loading path
    system, states, path_info = system_type(scene.system.type).path(scene, comm, stages, progress)
    try:
        return _study(scene, comm, stages, progress, inspect, outdir, t_start, system, states, path_info)
    finally:
        system.destroy()              # its PETSc objects, on every path (errors included)


def _study(scene: Scene, comm: MPI.Comm, stages: Stages, progress: Progress, inspect, outdir, t_start: float,
           system, states, path_info) -> tuple[dict, tuple]:
    """The per-state analyses and fields of :func:`_run` on the built ``system``: the results
    dictionary and the typed state views.

    The states hold the typed outcomes (:mod:`app.analyses.outcomes`) until every analysis is
    done; their ``analyses`` blocks are then written once per distinct classification and the
    views built from the outcomes."""
    cache: dict = {}
    deferred: list = []     # (classification, its analyses, state index): condensed MCEIP-mu, distributed below
    out_states = []
    typed_nodes = []          # per state: its contact nodes as app.io.result.Node
    failures = [path_info["failure"]] if path_info.get("failure") else []
    bar = progress.bar(len(states), "analyses")
    for state in states:
        checkpoint()                  # a Ctrl-C whose KeyboardInterrupt was swallowed (app/common/interrupt.py)
        t_state = time.perf_counter()
        # on a curved obstacle the pencils also depend on kappa P and the contact frames (app/analyses/curvature.py)
        cls = attach_curvature(classify(state, scene.mu, scene.settings.classify_rtol), state, system)
        nodes = tuple(Node(id=n.id, x=float(n.x), status=st, sign=int(sg), u_N=float(uN), u_T=float(uT),
                           r_N=float(rN), r_T=float(rT))
                      for n, st, sg, uN, uT, rN, rT in zip(system.nodes, cls.status, cls.signs,
                                                          state.u_N, state.u_T, state.r_N, state.r_T))
        typed_nodes.append(nodes)
        entry = {"index": state.index, "load": state.load, "classification": cls.counts(),
                 "nodes": [{"id": n.id, "x": n.x, "status": n.status, "sign": n.sign, "u_N": n.u_N, "u_T": n.u_T,
                            "r_N": n.r_N, "r_T": n.r_T} for n in nodes],
                 **state.extra}
        if cls.key in cache:
            first, analyses = cache[cls.key]
            entry["analyses_shared_with"] = first
        else:
            # small dense work (condensed pencils, projected eigenproblems): one BLAS thread is
            # 3-6x faster than OpenBLAS's default on these sizes
            with one_blas_thread():
                analyses = analyse_state(system, cls, scene, defer_condensed=True)
            for name, a in analyses.items():
                if isinstance(a, Failed):
                    failures.append({"state": state.index, "analysis": name, "reason": a.reason})
            if isinstance(analyses.get("mceip_mu"), Deferred):
                deferred.append((cls, analyses, state.index))
            cache[cls.key] = (state.index, analyses)
            entry["analyses_shared_with"] = None
        entry["analyses"] = analyses
        entry["analysis_seconds"] = time.perf_counter() - t_state
        out_states.append(entry)
        bar.update(1)
    bar.close()
    if deferred:   # the condensed MCEIP-mu of every classification, one rank each under MPI
        with one_blas_thread():
            failed = analyse_condensed_distributed(system, scene, [(c, a) for c, a, _ in deferred], comm,
                                                   progress)
        failures += [{"state": deferred[k][2], "analysis": "mceip_mu", "reason": r} for k, r in failed]
    inspection = inspect(system, states, cache) if inspect is not None else None
    outcomes = [entry["analyses"] for entry in out_states]
    _write_analyses(out_states)
    views = tuple(state_view(e, n, a, e["analyses"]) for e, n, a in zip(out_states, typed_nodes, outcomes))
    outputs_record = None
    from app.io.fields import wants_fields
    if wants_fields(scene):   # only when the scene asks for ParaView files or screenshots
        from app.io.fields import compute_fields
        outputs_record = compute_fields(scene, system, out_states, stages, progress, outdir)
    return {**({"inspection": inspection} if inspect is not None else {}), "scene": scene.name, "units": system.units, "system": system.description,
            "mu": scene.mu, "analyses_requested": list(scene.analyses),
            "path": path_info, "distinct_classifications": len(cache),
            "stages": stages.as_list(), "failures": failures, "warnings": stages.warnings,
            "mpi_ranks": comm.size, "wall_seconds": time.perf_counter() - t_start,
            "scene_config": scene.model_dump(mode="json", exclude_none=True),
            **({"outputs": outputs_record} if outputs_record is not None else {}),
            "states": out_states}, views


def _write_analyses(out_states: list[dict]) -> None:
    """Each state's typed outcomes replaced by its ``analyses`` block of results.json
    (:func:`app.analyses.outcomes.analyses_document`); states that share their analyses share
    one block."""
    written: dict[int, dict] = {}
    for entry in out_states:
        analyses = entry["analyses"]
        if id(analyses) not in written:
            written[id(analyses)] = analyses_document(analyses)
        entry["analyses"] = written[id(analyses)]
