"""The analyses of a state with zero-reaction contact nodes (the paper's set Z): the rate
conditions (9) of those nodes are complementarity conditions, so the pencils are split
(:func:`app.analyses.pencils.reduced.split_pencils`) and searched or enumerated with them.

On a curved obstacle the split pencils are built in the contact frames with the slip nodes'
curvature terms (:mod:`app.analyses.pencils.curved_split`): MCEIP-mu is the quadratic complementarity
eigenproblem with pairs (:func:`app.analyses.mceip_mu.quadratic.problem.quadratic_mu_result`), and
MCEIP-lambda^2 uses ``K*(mu) = A0 + mu A1 + mu^2 A2`` at the scene's ``lambda2_mu``."""
from __future__ import annotations

import numpy as np

from app.analyses.enumerate import TooManySlipNodes, enumerate_mceip
from app.analyses.mceip_mu.quadratic.problem import enumerate_quadratic, quadratic_mu_result
from app.analyses.mceip_mu.state import certificate, condensed_mu_result, enumeration_certificate, mu_cap
from app.analyses.outcomes import (
    EnumerationOutcome,
    EnumerationProblem,
    Failed,
    MceipLambda2Outcome,
    Outcome,
    Solution,
)
from app.analyses.pencils import curvature
from app.analyses.pencils.curved_split import curved_split_condensed, curved_split_full
from app.analyses.pencils.reduced import UnsupportedState, dense, split_pencils
from app.analyses.pencils.state import FULL_DENSE_LIMIT, seq_aij
from app.analyses.snes_vi.search import search_mceip
from app.loading.classify import ZERO, Classification
from app.scene.schema import Scene
from app.systems.base import System

#: the note of every outcome computed with the rate conditions (9) of the zero-reaction nodes
HANDLED = "rate conditions (9): v_T = a - b, complementarity in (a, b, x_N)"


def _describe(sol: Solution | dict, labels: list[str], cls: Classification) -> Solution:
    """Re-express a solution over x_c = (slip x_T..., zero a, b, x_N...) per node."""
    sol = sol.as_dict() if isinstance(sol, Solution) else sol
    xc = np.asarray(sol["x_Ts"])
    big = max(float(np.max(np.abs(xc))), 1e-300)
    by = dict(zip(labels, xc))
    slip = [i for i, st in enumerate(cls.status) if st == "slip"]
    zero = [i for i, st in enumerate(cls.status) if st == ZERO]
    out = dict(sol)
    out["x_c"] = {k: float(v) for k, v in by.items()}
    out["x_Ts"] = [float(by[f"T{i}"]) for i in slip]
    out["pattern"] = ["slip" if by[f"T{i}"] > 0 else "stick" for i in slip]   # slip where x_Ts > 0
    out["zero_nodes"] = []
    for i in zero:
        a, b, xn = by[f"a{i}"], by[f"b{i}"], by[f"N{i}"]
        out["zero_nodes"].append({"id": i, "a": float(a), "b": float(b), "x_N": float(xn),
                                  "tangential": "slides +T" if a > 1e-8 * big else "slides -T" if b > 1e-8 * big else "sticks",
                                  "normal": "separates" if xn > 1e-8 * big else "stays in contact"})
    return Solution.from_fields(out)


def _full_pencils(system: System, cls: Classification, mu: float, curved: bool):
    """``(K*(mu), M*(mu), split pencil)`` of the full system for MCEIP-lambda^2, or the
    :class:`UnsupportedState` refusing it above ``FULL_DENSE_LIMIT`` DOFs."""
    if system.n_dofs > FULL_DENSE_LIMIT:
        return UnsupportedState(f"{system.n_dofs} DOFs: MCEIP-lambda2 with zero-reaction nodes uses dense "
                                f"pencils, refused above {FULL_DENSE_LIMIT}")
    Kd, Md = dense(system.K), dense(system.mass())
    if curved:
        Kq = curved_split_full(system, cls, Kd, stiffness=True)
        Mq = curved_split_full(system, cls, Md, stiffness=False)
        return Kq.at(mu), Mq.at(mu), Kq
    Kp, Mp = split_pencils(system, cls, Kd), split_pencils(system, cls, Md)
    return Kp.A0 + mu * Kp.A1, Mp.A0 + mu * Mp.A1, Kp


def _search_lambda2(Ks, Ms, sp, cls: Classification, settings) -> MceipLambda2Outcome:
    """MCEIP-lambda^2 (12)-(14) of the split pencil ``(Ks, Ms)`` by the dense SNES VI search."""
    tau = float(np.max(np.abs(np.diag(Ks)))) / max(float(np.max(np.abs(np.diag(Ms)))), 1e-300)
    M0, M1 = seq_aij(Ks), seq_aij(Ms)
    try:
        rep = search_mceip(M0, M1, sp.comp, "lambda2", settings.mcp, value_scale=tau, pairs=sp.pairs)
    finally:
        M0.destroy()
        M1.destroy()
    return MceipLambda2Outcome(
        solutions=[_describe(x, sp.labels, cls) for x in rep.typed_solutions()], result=rep.result(),
        search=rep.search(),
        certified=False, certificate=certificate("none (zero-reaction nodes: dense SNES VI search only)",
                                                 (0.0, 0.0), "not proven: searched by SNES VI", 0.0),
        extra={"x_c_labels": sp.labels, "zero_nodes_handled": HANDLED})


def _mceip_mu(system: System, cls: Classification, cond, scene: Scene, curved: bool):
    """MCEIP-mu (21)-(23) of the condensed split pencil ``cond``."""
    settings = scene.settings
    cap = mu_cap(scene.mu, settings.mcp)
    if curved:
        # quadratic in mu: every support enumerated (no pair in one), proven exactly or by the
        # checked branch and bound (app/analyses/mceip_mu/quadratic/problem.py)
        d = quadratic_mu_result(cond.A0, cond.A1, cond.A2, cap, settings.enumerate_max_slip,
                                certify=settings.mcp.certify, seconds=settings.mcp.certify_seconds, pairs=cond.pairs,
                                nodes=settings.mcp.certify_quadratic_nodes)
    else:
        # the split pencil has no x_f: dense search + certificate as for the plain condensed pencil
        d = condensed_mu_result(cond.A0, cond.A1, cap, settings.mcp, pairs=cond.pairs)
    if system.comm.size > 1:
        d = system.comm.bcast(d, root=0)                               # MPI collective (see runner.state_mceip_mu)
    d.solutions = [_describe(x, cond.labels, cls) for x in d.solutions]
    d.extra = {"x_c_labels": cond.labels, "zero_nodes_handled": HANDLED}
    d.method = "condensed (quadratic)" if curved else "condensed"
    return d


def _enumerate(problem: str, cls: Classification, cond, full, settings, mu_l: float, curved: bool) -> EnumerationProblem:
    """One enumeration problem (24)-(26) with the pairs; the quadratic MCEIP-mu of a curve is
    found, not proven (its proof is mceip_mu's)."""
    quadratic = problem == "mu" and curved
    if problem == "mu":
        sp, A0, A1 = cond, cond.A0, cond.A1
    else:
        if isinstance(full, Exception):
            raise TooManySlipNodes(str(full))
        A0, A1, sp = full
    if quadratic:
        found = enumerate_quadratic(A0, A1, cond.A2, settings.enumerate_max_slip, comp=sp.comp, pairs=sp.pairs)
    else:
        found = enumerate_mceip(A0, A1, sp.comp, settings.enumerate_max_slip, pairs=sp.pairs)
    sols = [Solution.from_fields(x) for x in found]
    done = EnumerationProblem(problem=problem, solutions=[_describe(x, sp.labels, cls) for x in sols],
                              complete=True, certified=True, certificate=enumeration_certificate(sols),
                              mu=mu_l if problem == "lambda2" else None)
    if quadratic:
        for x in done.solutions:
            x.mark(certified=False)
        done.certified = False
        done.certificate = certificate("exhaustive floating-point enumeration of the quadratic pattern problems",
                                       (0.0, 0.0), "not proven", None, {"solutions": len(sols)})
    return done


def analyse_with_zero_nodes(system: System, cls: Classification, scene: Scene) -> dict[str, Outcome]:
    """MCEIP-mu, MCEIP-lambda^2 and enumeration with the rate conditions (9) of the Z nodes
    (the necessary and sufficient conditions are :class:`~app.analyses.outcomes.Failed`); on a
    curved obstacle in the contact frames with the slip nodes' curvature terms."""
    settings = scene.settings
    curved = curvature.is_curved(cls)
    out: dict[str, Outcome] = {}
    why = ("zero-reaction contact nodes present: with them the conditions (17)-(19) are not linear "
           "eigenproblems (the rate conditions (9) are complementarity conditions); see mceip_mu/mceip_lambda2")
    for name in ("necessary", "sufficient"):
        if name in scene.analyses:
            out[name] = Failed(f"UnsupportedState: {why}")
    mu_l = scene.lambda2_mu
    wants_l2 = "mceip_lambda2" in scene.analyses or ("enumerate" in scene.analyses and "lambda2" in settings.enumerate_problems)
    full = _full_pencils(system, cls, mu_l, curved) if wants_l2 else None
    cond = None
    if "mceip_mu" in scene.analyses or "enumerate" in scene.analyses:
        cond = curved_split_condensed(system, cls) if curved else split_pencils(system, cls)
    if "mceip_mu" in scene.analyses:
        with system.stages("MCEIP-mu (21)-(23)"):
            out["mceip_mu"] = _mceip_mu(system, cls, cond, scene, curved)
    if "mceip_lambda2" in scene.analyses:
        if isinstance(full, Exception):
            out["mceip_lambda2"] = Failed(f"UnsupportedState: {full}")
        else:
            with system.stages("MCEIP-lambda2 (12)-(14)"):
                found = _search_lambda2(full[0], full[1], full[2], cls, settings)
            found.mu = mu_l
            out["mceip_lambda2"] = found
    if "enumerate" in scene.analyses:
        problems: dict[str, EnumerationProblem] = {}
        with system.stages("enumeration (24)-(26)"):
            for problem in settings.enumerate_problems:
                try:
                    problems[problem] = _enumerate(problem, cls, cond, full, settings, mu_l, curved)
                except TooManySlipNodes as err:
                    problems[problem] = EnumerationProblem(problem=problem, solutions=[], complete=False,
                                                           refused=str(err))
        out["enumerate"] = EnumerationOutcome(problems=problems, first=settings.enumerate_problems[0])
    return out
