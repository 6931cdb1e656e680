"""All analyses the scene asks for at one classified equilibrium state (paper sections 3-4).

Only what the requested analyses need is built: the mass matrix only for the necessary and
sufficient conditions and MCEIP-lambda^2, the full-size stiffness pencil only when a full-size
problem is solved, the contact Schur complement only for the condensed MCEIP-mu.
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from app.analyses.conditions import contact_spectrum, eliminated, full_size
from app.analyses.enumerate import TooManySlipNodes, enumerate_mceip
from app.analyses.mceip_lambda2.analysis import mceip_lambda2, sufficient_on_reduction
from app.analyses.mceip_mu.state import certificate, condensed_mu_result, enumeration_certificate, mu_cap
from app.analyses.outcomes import (
    CompleteClaim,
    Deferred,
    EnumerationOutcome,
    EnumerationProblem,
    MceipLambda2Outcome,
    MceipMuOutcome,
    NecessaryOutcome,
    NotApplicable,
    OnsetClaim,
    Outcome,
    Solution,
    SufficientOutcome,
    one_line,
)
from app.analyses.pencils import curvature
from app.analyses.pencils.reduced import UnsupportedState, dense
from app.analyses.pencils.state import FULL_DENSE_LIMIT, StatePencils, keep_modes, no_slip, warm_hints
from app.analyses.snes_vi.search import search_mceip
from app.analyses.zero_nodes import analyse_with_zero_nodes
from app.loading.classify import STICK, ZERO, Classification, frictionless_reason
from app.scene.schema import Scene
from app.systems.base import System

ANALYSES = ("necessary", "sufficient", "mceip_mu", "mceip_lambda2", "enumerate")   # in the order they run


def _necessary(system: System, p: "StatePencils", scene: Scene, s: int) -> NecessaryOutcome:
    """(19): on the contact DOFs from ``eig.necessary_contact_min_dofs`` DOFs on (what they leave,
    and anything smaller, on the full pencils)."""
    hints = warm_hints(system, scene.mu)
    known = None
    if system.has_static_dofs:
        with system.stages("necessary condition (19) on the contact DOFs"):
            return eliminated.eliminated_necessary(p, scene.mu, scene.settings.eig, hints)    # MPI collective
    if system.n_dofs >= scene.settings.eig.necessary_contact_min_dofs:
        with system.stages("necessary condition (19) on the contact DOFs"):
            known = contact_spectrum.values(system, p.cls, scene.mu, hints,
                                            scene.settings.eig.necessary_value_work)     # MPI collective
        if all(v is not None for v in known.values()):
            return full_size.necessary(None, None, None, None, scene.mu, scene.settings.eig, known=known)
    K0, K1 = p.K()
    M0, M1 = p.M()
    stars = p.star(scene.mu)
    with system.stages("necessary condition (19)"):
        return full_size.necessary(K0, K1, M0, M1, scene.mu, scene.settings.eig, hints, stars,
                                    (p.space, system.K.getOwnershipRange()), known)


def _sufficient(system: System, p: "StatePencils", scene: Scene, s: int,
                lambda2: Outcome | None = None) -> SufficientOutcome:
    """(17)-(18); ``lambda2``: MCEIP-lambda^2 at the same mu, already run. An admissible eigenpair
    with ``lambda^2 > 0`` solves (12)-(14) (``y = 0``), so where that outcome shows no solution with
    ``lambda^2 >= 0`` the condition cannot hold and no eigensolver runs."""
    if isinstance(lambda2, MceipLambda2Outcome) and lambda2.certified and not lambda2.solutions:
        return SufficientOutcome(
            satisfied=False, lambda2=[], modes=[], real_candidates=[], converged=0, mu=scene.mu,
            eigensolver="none: an admissible eigenpair would solve MCEIP-lambda^2 (12)-(14) with y = 0, and "
                        f"MCEIP-lambda^2 at this mu has none ({lambda2.result})")
    if isinstance(lambda2, MceipLambda2Outcome) and not lambda2.certified:
        with system.stages("sufficient condition (17)-(18)"):
            out = sufficient_on_reduction(p, scene, lambda2)       # MPI collective
        if out is not None:
            return out
    Ks, Ms = p.star(scene.mu)        # shared with the necessary condition, destroyed with p
    static = system.static_dofs
    with system.stages("sufficient condition (17)-(18)"):
        out = full_size.sufficient(Ks, Ms, p.space.comp, scene.settings.eig, keep_modes=keep_modes(scene),
                                   static=None if static is None else p.space.positions(static))  # MPI collective
    out.mu = scene.mu
    return out


def _nothing_moves(system: System, cls: Classification) -> str | None:
    """The plain reason when the state leaves no free DOF (every DOF fixed by the system or a stuck
    contact DOF): the pencils of (16) are empty, nothing can diverge."""
    stuck = sum(1 for st in cls.status if st == STICK)
    if stuck and system.n_dofs == 2 * stuck and all(st == STICK for st in cls.status):
        return (f"not applicable: nothing can move: every DOF is fixed or stuck (all {system.n_dofs} DOFs are "
                f"the DOFs of {stuck} stuck contact node(s)); no divergence")
    return None


def analyse_state(system: System, cls: Classification, scene: Scene,
                  defer_condensed: bool = False, now=None) -> dict[str, Outcome]:
    """Run the scene's analyses on one classification; returns analysis name -> its outcome
    (:mod:`app.analyses.outcomes`), in the order of :data:`ANALYSES`.

    An analysis whose solver fails (PETSc/SLEPc error, no convergence, unsupported state) is
    a :class:`~app.analyses.outcomes.Failed` and the other analyses still run.
    ``defer_condensed``: leave the condensed MCEIP-mu (dense, replicated data)
    :class:`~app.analyses.outcomes.Deferred` for :func:`app.study.scheduler.analyse_condensed_distributed` (MPI: one
    rank per classification). ``now(name)``, when given, is called as each analysis begins (the
    progress line says what runs).
    """
    na = frictionless_reason(cls, scene.mu) or _nothing_moves(system, cls)   # nothing to compute
    if na is not None:
        return {name: NotApplicable(na) for name in ANALYSES if name in scene.analyses}
    if ZERO in cls.status:          # flat or curved obstacle (app/analyses/pencils/curved_split.py)
        return analyse_with_zero_nodes(system, cls, scene)
    p = StatePencils(system, cls)
    out: dict[str, Outcome] = {}
    s = len(cls.slip)
    runs = {"necessary": _necessary, "mceip_mu": state_mceip_mu, "enumerate": _enumerate}
    # MCEIP-lambda^2 at the scene's mu runs before (17)-(18), which it can decide
    lambda2_first = ("sufficient" in scene.analyses and "mceip_lambda2" in scene.analyses
                     and scene.lambda2_mu == scene.mu)
    order = [n for n in ANALYSES if n in scene.analyses]
    if lambda2_first:
        order.remove("mceip_lambda2")
        order.insert(order.index("sufficient"), "mceip_lambda2")
    try:
        for name in order:
            if name == "mceip_mu" and defer_condensed and s > 0 and scene.settings.mceip_mu_method == "condensed":
                out[name] = Deferred()    # dense work: distributed.analyse_condensed_distributed() replaces it
                continue
            if now is not None:
                now(name)
            try:
                if name == "mceip_lambda2":
                    nec = out.get("necessary") if scene.lambda2_mu == scene.mu else None
                    out[name] = mceip_lambda2(system, p, scene, s, nec if isinstance(nec, NecessaryOutcome) else None)
                elif name == "sufficient":
                    out[name] = _sufficient(system, p, scene, s, out.get("mceip_lambda2") if lambda2_first else None)
                else:
                    out[name] = runs[name](system, p, scene, s)
            except (UnsupportedState, PETSc.Error, RuntimeError, np.linalg.LinAlgError) as err:
                out[name] = one_line(err)
    finally:
        p.destroy()
    return {name: out[name] for name in ANALYSES if name in out}


def state_mceip_mu(system: System, p: StatePencils, scene: Scene, s: int, replicated: bool = True,
              warm: list[tuple[np.ndarray, float]] | None = None) -> MceipMuOutcome:
    """MCEIP-mu (21)-(23) of one classification: the condensed s x s pencil with its certificate
    (:mod:`app.analyses.mceip_mu.state`), or the full-size SNES VI search (found, not proven).

    ``replicated``: every rank computes the same dense problem and rank 0's answer is broadcast
    (a time budget could end differently on different ranks). ``False`` when only this rank runs
    it (:func:`app.study.scheduler.analyse_condensed_distributed` gathers the answers itself). ``warm``: starts for the
    dense search from the previous classification along the path (large ``s`` only).
    """
    if s == 0:
        result, search = no_slip()
        return MceipMuOutcome(solutions=[], result=result, search=search, certified=True,
                              onset=OnsetClaim(proven=True, status="proven: no slip node, no critical mu"),
                              complete=CompleteClaim(proven=True, status="proven: no slip node",
                                                     interval=[0.0, np.inf], count=0),
                              certificate=certificate("no slip nodes (x_Ts is empty)", (0.0, np.inf), "proven", 0.0,
                                                      gap=0.0))
    method = scene.settings.mceip_mu_method
    if curvature.is_curved(p.cls):
        if method != "condensed":
            raise UnsupportedState(f"settings.mceip_mu_method = {method}: on a curved obstacle MCEIP-mu is quadratic "
                                   "in mu and only the condensed enumeration solves it (use 'condensed')")
        from app.analyses.mceip_mu.quadratic.problem import quadratic_mu_result
        A0, A1, A2 = p.condensed_mu_quadratic()
        with system.stages("MCEIP-mu (21)-(23)"):
            mcp = scene.settings.mcp
            d = quadratic_mu_result(A0, A1, A2, mu_cap(scene.mu, mcp), scene.settings.enumerate_max_slip,
                                    certify=mcp.certify, seconds=mcp.certify_seconds, nodes=mcp.certify_quadratic_nodes)
        d.method = "condensed (quadratic)"
        return d
    if method == "condensed":
        # dense search + certificate on the s x s pencil (app/analyses/mceip_mu/state.py): no PETSc, no MPI
        A0, A1 = p.condensed_mu()
        with system.stages("MCEIP-mu (21)-(23)"):
            d = condensed_mu_result(A0, A1, mu_cap(scene.mu, scene.settings.mcp), scene.settings.mcp, warm=warm)
            if replicated and system.comm.size > 1:
                # replicated dense work: the budgets count nodes, so every rank reaches the same answer,
                # but a wall-clock safety stop (if set) could end differently; rank 0's answer is reported
                d = system.comm.bcast(d, root=0)                               # MPI collective
        d.method = method
        return d
    K0, K1 = p.K()
    with system.stages("MCEIP-mu (21)-(23)"):
        rep = search_mceip(K0, K1, p.space.comp, "mu", scene.settings.mcp)
    sols = rep.typed_solutions(keep_vectors=method == "full" and keep_modes(scene))
    for sol in sols:
        sol.mark(certified=False)
    return MceipMuOutcome(solutions=sols, result=rep.result(), search=rep.search(), certified=False,
                          certificate=certificate("none", (0.0, 0.0), "not attempted (full-size SNES VI search)", 0.0),
                          method=method)


def _enumerate(system: System, p: StatePencils, scene: Scene, s: int) -> EnumerationOutcome:
    settings = scene.settings
    problems: dict[str, EnumerationProblem] = {}
    with system.stages("enumeration (24)-(26)"):
        for problem in settings.enumerate_problems:
            try:
                if s == 0:
                    sols = []
                elif problem == "mu" and curvature.is_curved(p.cls):
                    from app.analyses.mceip_mu.quadratic.problem import enumerate_quadratic
                    sols = enumerate_quadratic(*p.condensed_mu_quadratic(), settings.enumerate_max_slip)
                elif problem == "mu":
                    A0, A1 = p.condensed_mu()
                    sols = enumerate_mceip(A0, A1, np.arange(s), settings.enumerate_max_slip)
                else:
                    if p.space.n > FULL_DENSE_LIMIT:
                        raise TooManySlipNodes(f"{p.space.n} DOFs: dense enumeration of MCEIP-lambda2 "
                                               f"refused above {FULL_DENSE_LIMIT}")
                    mu = scene.lambda2_mu
                    if curvature.is_curved(p.cls):
                        Kst, Mst = p.star(mu)            # with the curvature terms
                        Ks, Ms = dense(Kst), dense(Mst)
                    else:
                        K0, K1 = p.K()
                        M0, M1 = p.M()
                        Ks = dense(K0) + mu * dense(K1)
                        Ms = dense(M0) + mu * dense(M1)
                    sols = enumerate_mceip(Ks, Ms, p.space.comp, settings.enumerate_max_slip)
                found = [Solution.from_fields(x) for x in sols]
                done = EnumerationProblem(problem=problem, solutions=found, complete=True, certified=True,
                                          certificate=enumeration_certificate(found),
                                          mu=scene.lambda2_mu if problem == "lambda2" else None)
                if problem == "mu" and curvature.is_curved(p.cls):
                    # the quadratic pattern problems are decided in floating point: found, not proven
                    # (the proofs are mceip_mu's: app/analyses/mceip_mu/quadratic/proof.py, mceip_mu_quadratic_bb.py)
                    for x in found:
                        x.mark(certified=False)
                    done.certified = False
                    done.certificate = certificate(
                        "exhaustive floating-point enumeration of the quadratic pattern problems", (0.0, 0.0),
                        "not proven", None, {"solutions": len(found)})
                problems[problem] = done
            except TooManySlipNodes as err:
                problems[problem] = EnumerationProblem(problem=problem, solutions=[], complete=False,
                                                       refused=str(err), certified=False)
    return EnumerationOutcome(problems=problems, first=settings.enumerate_problems[0])
