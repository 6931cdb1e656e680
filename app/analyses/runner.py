"""All analyses the scene asks for at one classified equilibrium state (paper sections 3-4).

Only what the requested analyses need is built: the mass matrix only for the necessary and
sufficient conditions and MCEIP-lambda^2, the full-size stiffness pencil only when a full-size
problem is solved, the contact Schur complement only for the condensed MCEIP-mu.
"""
from __future__ import annotations

import time
import weakref

import numpy as np
from petsc4py import PETSc

from app.analyses import eigen
from app.analyses import lambda2_bounds as l2b
from app.analyses import lambda2_exact as l2x
from app.analyses.certify import condensed_mu_result, mu_cap
from app.analyses.classify import ZERO, Classification, frictionless_reason
from app.analyses.enumerate import TooManySlipNodes, enumerate_mceip
from app.analyses.mcp import search_mceip
from app.analyses.pencils import (
    UnsupportedState,
    combine,
    condensed_mu_pencil,
    dense,
    diag_scale,
    reduced_pencil,
    reduced_space,
    split_pencils,
)
from app.config import Scene
from app.system.base import System

FULL_DENSE_LIMIT = 3000
ANALYSES = ("necessary", "sufficient", "mceip_mu", "mceip_lambda2", "enumerate")   # in the order they run


def seq_aij(A: np.ndarray) -> PETSc.Mat:
    """Small dense matrix as a sequential AIJ matrix (replicated problems run on COMM_SELF)."""
    n = A.shape[0]
    M = PETSc.Mat().createAIJ((n, n), nnz=n, comm=PETSc.COMM_SELF)
    rows = np.arange(n, dtype=PETSc.IntType)
    M.setValues(rows, rows, A)
    M.assemble()
    return M


class _Pencils:
    """Lazily built reduced pencils of one state; destroyed at the end of the analyses."""

    def __init__(self, system: System, cls: Classification):
        self.system, self.cls = system, cls
        self._space = None
        self._K = None
        self._M = None
        self._cond = None

    @property
    def space(self):
        if self._space is None:
            with self.system.stages("reduced pencils"):
                self._space = reduced_space(self.system, self.cls)
        return self._space

    def K(self):
        if self._K is None:
            space = self.space
            with self.system.stages("reduced pencils"):
                self._K = reduced_pencil(self.system.K, self.system, self.cls, space)
        return self._K

    def M(self):
        if self._M is None:
            Mfull = self.system.mass()
            space = self.space
            with self.system.stages("reduced pencils"):
                self._M = reduced_pencil(Mfull, self.system, self.cls, space)
        return self._M

    def condensed_mu(self) -> tuple[np.ndarray, np.ndarray]:
        if self._cond is None:
            Sc = self.system.contact_schur()
            with self.system.stages("condensed pencil"):
                self._cond = condensed_mu_pencil(Sc, self.cls)
        return self._cond

    def destroy(self):
        for pair in (self._K, self._M):
            if pair is not None:
                for m in pair:
                    m.destroy()
        if self._space is not None:
            self._space.destroy()


_WARM: dict[int, tuple[weakref.ref, dict]] = {}


def _hints(system: System, mu: float) -> dict:
    """Eigenvalues of the previous classification along the path (per system and mu): shifts
    for the next one's eigen solves (they only speed them up; every answer is verified)."""
    for key in [k for k, (ref, _) in _WARM.items() if ref() is None]:
        del _WARM[key]
    ref, hints = _WARM.get(id(system), (None, None))
    if ref is None or ref() is not system:
        hints = {}
        _WARM[id(system)] = (weakref.ref(system), hints)
    return hints.setdefault(float(mu), {})


class AnalysisFailure(Exception):
    """A solver failed on one analysis of one state (reported, and the study goes on)."""


def _necessary(system: System, p: "_Pencils", scene: Scene, s: int) -> dict:
    K0, K1 = p.K()
    M0, M1 = p.M()
    with system.stages("necessary condition (19)"):
        return eigen.necessary(K0, K1, M0, M1, scene.mu, scene.settings.eig, _hints(system, scene.mu))


def _sufficient(system: System, p: "_Pencils", scene: Scene, s: int) -> dict:
    K0, K1 = p.K()
    M0, M1 = p.M()
    with system.stages("sufficient condition (17)-(18)"):
        Ks, Ms = combine(K0, K1, scene.mu), combine(M0, M1, scene.mu)
        try:
            out = eigen.sufficient(Ks, Ms, p.space.comp, scene.settings.eig, keep_modes=_keep_modes(scene))
        finally:
            Ks.destroy()
            Ms.destroy()
    out["mu"] = scene.mu
    return out


def analyse_state(system: System, cls: Classification, scene: Scene, defer_condensed: bool = False) -> dict:
    """Run the scene's analyses on one classification; returns the ``analyses`` dict of results.json.

    An analysis whose solver fails (PETSc/SLEPc error, no convergence, unsupported state) is
    reported as ``{"failed": true, "reason": ...}`` and the other analyses still run.
    ``defer_condensed``: leave the condensed MCEIP-mu (dense, replicated data) as
    ``{"deferred": true}`` for :func:`analyse_condensed_distributed` (MPI: one rank per classification).
    """
    na = frictionless_reason(cls, scene.mu)   # mu = 0: K* = K0 is SPD, nothing to compute
    if na is not None:
        return {name: {"not_applicable": True, "reason": na} for name in ANALYSES if name in scene.analyses}
    if ZERO in cls.status:
        return _analyse_with_zero_nodes(system, cls, scene)
    p = _Pencils(system, cls)
    out: dict = {}
    s = len(cls.slip)
    runs = {"necessary": _necessary, "sufficient": _sufficient, "mceip_mu": _mceip_mu,
            "mceip_lambda2": _mceip_lambda2, "enumerate": _enumerate}
    try:
        for name in ANALYSES:
            if name not in scene.analyses:
                continue
            if name == "mceip_mu" and defer_condensed and s > 0 and scene.settings.mceip_mu_method == "condensed":
                out[name] = {"deferred": True}    # dense work: analyse_condensed_distributed() fills it
                continue
            try:
                if name == "mceip_lambda2":
                    nec = out.get("necessary") if scene.lambda2_mu == scene.mu else None
                    out[name] = _mceip_lambda2(system, p, scene, s, nec if nec and "failed" not in nec else None)
                else:
                    out[name] = runs[name](system, p, scene, s)
            except (UnsupportedState, PETSc.Error, RuntimeError, np.linalg.LinAlgError) as err:
                reason = f"{type(err).__name__}: {err}".splitlines()[0]
                out[name] = {"failed": True, "reason": reason}
    finally:
        p.destroy()
    return out


def analyse_condensed_distributed(system: System, scene: Scene, jobs: list[tuple[Classification, dict]],
                                  comm) -> list[dict]:
    """The deferred condensed MCEIP-mu of ``jobs`` (classification, its analyses dict): job ``k``
    runs on rank ``k % size`` alone (dense s x s work on COMM_SELF objects), and the results are
    gathered on every rank (``allgather``), so the output is the same on any number of ranks.
    Fills each analyses dict in place (key order as in :func:`analyse_state`); returns the failures."""
    system.contact_schur()        # collective the first time: built on every rank before the split
    mine: dict[int, dict] = {}
    for k, (cls, _) in enumerate(jobs):
        if k % comm.size != comm.rank:
            continue
        p = _Pencils(system, cls)
        try:
            mine[k] = _mceip_mu(system, p, scene, len(cls.slip), replicated=False)
        except (UnsupportedState, AnalysisFailure, PETSc.Error, RuntimeError, np.linalg.LinAlgError) as err:
            mine[k] = {"failed": True, "reason": f"{type(err).__name__}: {err}".splitlines()[0]}
        finally:
            p.destroy()
    failures = []
    for part in comm.allgather(mine):                                    # MPI collective
        for k, d in part.items():
            out = jobs[k][1]
            out["mceip_mu"] = d
            for name in [n for n in ANALYSES if n in out]:               # canonical key order
                out[name] = out.pop(name)
            if d.get("failed"):
                failures.append((k, d["reason"]))
    return failures


def _keep_modes(scene: Scene) -> bool:
    """Keep the kept-space mode vectors (key ``_x``, never written) for the mode fields of app/outputs/fields.py."""
    outputs = getattr(scene, "outputs", None)
    return bool(outputs is not None and outputs.fields)


def _attach_vectors(d: dict, rep) -> None:
    """Attach each solution's full kept-space vector (same order as ``as_dict``: sorted by value)."""
    for sd, sol in zip(d["solutions"], sorted(rep.solutions, key=lambda s: s.value)):
        if sol.x is not None:
            sd["_x"] = sol.x


def _no_slip() -> dict:
    return {"solutions": [], "result": "no solution (no slip nodes)", "search": {"note": "no slip nodes: x_Ts is empty, so x = 0 is the only "
                                                  "solution of (12)-(14)/(21)-(23) and there is no eigenvalue",
                                          "complete": True}}


def _mceip_mu(system: System, p: _Pencils, scene: Scene, s: int, replicated: bool = True) -> dict:
    """MCEIP-mu (21)-(23) of one classification: the condensed s x s pencil with its certificate
    (:mod:`app.analyses.certify`), or the full-size SNES VI search (found, not proven).

    ``replicated``: every rank computes the same dense problem and rank 0's answer is broadcast
    (a time budget could end differently on different ranks). ``False`` when only this rank runs
    it (:func:`analyse_condensed_distributed` gathers the answers itself).
    """
    if s == 0:
        return {**_no_slip(), "certified": True,
                "certificate": {"method": "no slip nodes (x_Ts is empty)", "interval": [0.0, float("inf")],
                                "status": "proven", "gap": 0.0, "seconds": 0.0, "detail": {}}}
    method = scene.settings.mceip_mu_method
    if method == "condensed":
        # dense search + certificate on the s x s pencil (app/analyses/certify.py): no PETSc, no MPI
        A0, A1 = p.condensed_mu()
        with system.stages("MCEIP-mu (21)-(23)"):
            d = condensed_mu_result(A0, A1, mu_cap(scene.mu, scene.settings.mcp), scene.settings.mcp)
            if replicated and system.comm.size > 1:
                # replicated dense work; a time budget could end differently on different ranks,
                # so every rank reports rank 0's answer
                d = system.comm.bcast(d, root=0)                               # MPI collective
        d["method"] = method
        return d
    K0, K1 = p.K()
    with system.stages("MCEIP-mu (21)-(23)"):
        rep = search_mceip(K0, K1, p.space.comp, "mu", scene.settings.mcp)
    d = rep.as_dict()
    d["method"] = method
    d["certified"] = False
    d["certificate"] = {"method": "none", "interval": [0.0, 0.0], "status": "not attempted (full-size SNES VI search)",
                        "gap": None, "seconds": 0.0, "detail": {}}
    for sol in d["solutions"]:
        sol["certified"] = False
    if method == "full" and _keep_modes(scene):
        _attach_vectors(d, rep)
    return d


def _mceip_lambda2(system: System, p: _Pencils, scene: Scene, s: int, nec: dict | None = None) -> dict:
    """MCEIP-lambda^2 (12)-(14) at ``scene.lambda2_mu`` with what is proven (app/analyses/lambda2_bounds.py):
    no solution when (19) fails; otherwise no solution above an inertia-proven bound ``T``, and
    ``[0, T]`` searched by SNES VI (found, not proven). Every result has ``certified`` and a
    ``certificate``; solutions above the free-block spectrum or whose pattern does not solve its
    restricted eigenproblem are labelled ill-conditioned."""
    mu = scene.lambda2_mu
    t_start = time.perf_counter()
    if s == 0:
        d = _no_slip()
        d["certified"] = True
        d["certificate"] = l2b.certificate("no slip nodes (x_Ts is empty)", (0.0, np.inf), l2b.PROVEN, 0.0)
    else:
        K0, K1 = p.K()
        M0, M1 = p.M()
        with system.stages("MCEIP-lambda2 (12)-(14)"):
            if nec is None:
                nec = eigen.necessary(K0, K1, M0, M1, mu, scene.settings.eig, _hints(system, mu))
            if not nec["satisfied"]:
                # x^T y = 0 at a solution, so lambda^2 x^T M* x + x^T K* x = 0: impossible when
                # K*(mu) is PD and M*(mu) PSD. No search is needed: there is no solution.
                d = {"solutions": [], "result": "no solution (proved by the necessary condition (19))", "search": {
                    "complete": True, "necessary_condition": nec,
                    "note": "no solution: the necessary condition (19) fails at this mu (K* PD, M* PSD), "
                            "which proves that (12)-(14) has no solution"}}
                d["certified"] = True
                d["certificate"] = l2b.certificate(
                    "sign argument: x^T y = 0 at a solution, impossible with sym K*(mu) PD and sym M*(mu) PSD (19)",
                    (0.0, np.inf), l2b.PROVEN, time.perf_counter() - t_start,
                    {"min_eig_K_sym": nec["min_eig_K_sym"], "min_eig_M_sym": nec["min_eig_M_sym"]}, gap=0.0)
            else:
                d = _lambda2_search(p, scene, K0, K1, M0, M1, nec, mu, t_start)
    d["mu"] = mu
    return d


def _lambda2_proof(p: _Pencils, scene: Scene, nec: dict, mu: float, t_start: float) -> dict | None:
    """MCEIP-lambda^2 proven to have no solution on the exact slip-node reduction
    (app/analyses/lambda2_exact.py), or None when that proof does not apply or does not succeed."""
    if not (nec["min_eig_M_sym_relative"] > 1e-12 and nec["min_eig_K_sym"] < 0):
        return None
    dc = l2x.dynamic_contact(p.system, scene.settings.mcp.lambda2_exact_max_dofs)    # MPI collective (first call)
    if dc is None:
        return None
    rayleigh = -nec["min_eig_K_sym"] / nec["min_eig_M_sym"] * (1 + 1e-6)
    proven, T, detail = l2x.prove_no_solution(dc, p.cls, mu, rayleigh)
    comm = p.system.comm
    if comm.size > 1:
        proven, T, detail = comm.bcast((proven, T, detail), root=0)                 # MPI collective
    if not proven:
        return None
    how = ("sign argument on the exact slip-node reduction S(t) (free DOFs eliminated through the (K, M) "
           "eigen-decomposition): sym S(t) certified copositive on [0, T] by intervals (concave + convex "
           "split, PD + NN at the ends), and the Schur complement of sym(K* + T M*) PD with sym M* PD for t >= T")
    bound = {"method": "Schur complement of sym K* + T sym M* onto the slip nodes PD (bisected from the "
                       "Rayleigh-quotient bound -min eig sym K* / min eig sym M*)",
             "rayleigh_bound": rayleigh, "proven_bound": T}
    d = {"solutions": [], "result": "proven: no solution with lambda^2 >= 0",
         "search": {"attempts": 0, "converged": 0, "accepted": 0, "by_method": {}, "intervals": [],
                    "starts": [], "identical_runs_skipped": 0, "complete": True,
                    "note": "no search needed: " + how,
                    "necessary_condition": nec, "lambda2_upper_bound": T, "upper_bound": bound},
         "certified": True}
    d["certificate"] = l2b.certificate(how, (0.0, np.inf), l2b.PROVEN, time.perf_counter() - t_start,
                                       {**detail, "T": T, "eigen_decomposition_seconds": round(dc.seconds, 4)}, gap=0.0)
    return d


def _lambda2_search(p: _Pencils, scene: Scene, K0, K1, M0, M1, nec: dict, mu: float, t_start: float) -> dict:
    proof = _lambda2_proof(p, scene, nec, mu, t_start)
    if proof is not None:
        return proof
    Ks, Ms = combine(K0, K1, mu), combine(M0, M1, mu)
    try:
        tau = diag_scale(Ks) / diag_scale(Ms)
        # x^T (lambda^2 M* + K*) x = x^T y = 0 bounds lambda^2 by the Rayleigh quotients:
        # lambda^2 <= -min eig sym(K*) / min eig sym(M*) when sym(M*) is PD; an LDL^T inertia
        # count of sym K* + T sym M* proves a smaller bound T (lambda2_bounds.py).
        upper, bound = np.inf, {"method": "none (sym M*(mu) not PD: no upper bound on lambda^2)"}
        if nec["min_eig_M_sym_relative"] > 1e-12 and nec["min_eig_K_sym"] < 0:
            rayleigh = -nec["min_eig_K_sym"] / nec["min_eig_M_sym"] * (1 + 1e-6)
            hints = _hints(p.system, mu)
            prev = hints.get("lambda2_bound")
            upper, detail = l2b.proven_upper_bound(Ks, Ms, rayleigh, guess=None if prev is None else 1.05 * prev)
            hints["lambda2_bound"] = upper       # warm start for the next classification
            bound = {"method": "sym K* + T sym M* PD by an LDL^T inertia count, bisected from the "
                               "Rayleigh-quotient bound -min eig sym K* / min eig sym M*",
                     "rayleigh_bound": rayleigh, "proven_bound": upper, **detail}
        rep = search_mceip(Ks, Ms, p.space.comp, "lambda2", scene.settings.mcp, value_scale=tau,
                           t_upper=upper)
        d = rep.as_dict()
        if _keep_modes(scene):
            _attach_vectors(d, rep)
        d["search"]["necessary_condition"] = nec
        d["search"]["lambda2_upper_bound"] = upper
        d["search"]["upper_bound"] = bound
        omega2 = l2b.free_block_max_omega2(Ks, Ms, p.space.comp) if d["solutions"] else None
        for sol in d["solutions"]:
            sol["certified"] = False
            why = []
            if omega2 is not None and sol["value"] > omega2:
                why.append(f"lambda^2 above the free-block spectrum (max omega^2 = {omega2:.6g}): the mode "
                           "decays by orders of magnitude between nodes, unresolvable in double precision")
            if not sol.get("pattern_verified", True):
                why.append("the pattern does not solve its restricted eigenproblem (25)-(26) to the tolerance")
            sol["ill_conditioned"] = bool(why)
            if why:
                sol["conditioning"] = "; ".join(why)
        if omega2 is not None:
            d["search"]["free_block_max_omega2"] = omega2
        clean = [x for x in d["solutions"] if not x["ill_conditioned"]]
        if len(clean) < len(d["solutions"]):
            d["result"] = (f"{len(clean)} clean solution(s) and {len(d['solutions']) - len(clean)} "
                           "ill-conditioned one(s) found (not proven)")
        hi = upper if np.isfinite(upper) else np.inf
        d["certified"] = False
        d["certificate"] = l2b.certificate(
            bound["method"] if np.isfinite(upper) else "none",
            (hi, np.inf) if np.isfinite(hi) else (0.0, 0.0),
            ("proven: no solution with lambda^2 in the interval; " if np.isfinite(hi) else "") +
            f"not proven: [0, {hi:.6g}] searched by SNES VI (solutions found there are not proven complete)",
            time.perf_counter() - t_start,
            {"proven_empty": [hi, np.inf] if np.isfinite(hi) else None, "searched_not_proven": [0.0, hi]})
        return d
    finally:
        Ks.destroy()
        Ms.destroy()


def _enumerate(system: System, p: _Pencils, scene: Scene, s: int) -> dict:
    settings = scene.settings
    problems: dict = {}
    with system.stages("enumeration (24)-(26)"):
        for problem in settings.enumerate_problems:
            try:
                if s == 0:
                    sols = []
                elif problem == "mu":
                    A0, A1 = p.condensed_mu()
                    sols = enumerate_mceip(A0, A1, np.arange(s), settings.enumerate_max_slip)
                else:
                    if p.space.n > FULL_DENSE_LIMIT:
                        raise TooManySlipNodes(f"{p.space.n} DOFs: dense enumeration of MCEIP-lambda2 "
                                               f"refused above {FULL_DENSE_LIMIT}")
                    K0, K1 = p.K()
                    M0, M1 = p.M()
                    mu = scene.lambda2_mu
                    Ks = dense(K0) + mu * dense(K1)
                    Ms = dense(M0) + mu * dense(M1)
                    sols = enumerate_mceip(Ks, Ms, p.space.comp, settings.enumerate_max_slip)
                problems[problem] = {"problem": problem, "solutions": sols, "complete": True,
                                     **_enumeration_certificate(sols),
                                     **({"mu": scene.lambda2_mu} if problem == "lambda2" else {})}
            except TooManySlipNodes as err:
                problems[problem] = {"problem": problem, "solutions": [], "complete": False, "refused": str(err),
                                     "certified": False}
    first = problems[settings.enumerate_problems[0]]
    return {**first, "problems": problems}


def _enumeration_certificate(sols: list[dict]) -> dict:
    """``certified``/``certificate`` of a finished exhaustive enumeration: every support was solved."""
    for x in sols:
        x["certified"] = True
    return {"certified": True, "certificate": {"method": "exhaustive enumeration (24)-(26), batched LAPACK",
                                               "interval": [0.0, float("inf")], "status": "proven", "gap": 0.0,
                                               "seconds": None, "detail": {"solutions": len(sols)}}}


# --- states with zero-reaction nodes (paper's set Z, general rate conditions (9)) --------------

def _describe(sol: dict, labels: list[str], cls: Classification) -> dict:
    """Re-express a solution over x_c = (slip x_T..., zero a, b, x_N...) per node."""
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
    return out


def _analyse_with_zero_nodes(system: System, cls: Classification, scene: Scene) -> dict:
    """MCEIP-mu, MCEIP-lambda^2 and enumeration with the rate conditions (9) of the Z nodes."""
    settings = scene.settings
    out: dict = {}
    why = ("zero-reaction contact nodes present: with them the conditions (17)-(19) are not linear "
           "eigenproblems (the rate conditions (9) are complementarity conditions); see mceip_mu/mceip_lambda2")
    for name in ("necessary", "sufficient"):
        if name in scene.analyses:
            out[name] = {"failed": True, "reason": f"UnsupportedState: {why}"}
    mu_l = scene.lambda2_mu
    wants_l2 = "mceip_lambda2" in scene.analyses or ("enumerate" in scene.analyses and "lambda2" in settings.enumerate_problems)
    full = None
    if wants_l2:
        if system.n_dofs > FULL_DENSE_LIMIT:
            full = UnsupportedState(f"{system.n_dofs} DOFs: MCEIP-lambda2 with zero-reaction nodes uses dense "
                                    f"pencils, refused above {FULL_DENSE_LIMIT}")
        else:
            Kd, Md = dense(system.K), dense(system.mass())
            Kp, Mp = split_pencils(system, cls, Kd), split_pencils(system, cls, Md)
            full = (Kp.A0 + mu_l * Kp.A1, Mp.A0 + mu_l * Mp.A1, Kp)
    cond = split_pencils(system, cls) if ("mceip_mu" in scene.analyses or "enumerate" in scene.analyses) else None

    def search(A0, A1, sp, problem, tau=None):
        M0, M1 = seq_aij(A0), seq_aij(A1)
        try:
            d = search_mceip(M0, M1, sp.comp, problem, settings.mcp, value_scale=tau, pairs=sp.pairs).as_dict()
        finally:
            M0.destroy()
            M1.destroy()
        d["solutions"] = [_describe(x, sp.labels, cls) for x in d["solutions"]]
        d["x_c_labels"] = sp.labels
        d["zero_nodes_handled"] = "rate conditions (9): v_T = a - b, complementarity in (a, b, x_N)"
        return d

    if "mceip_mu" in scene.analyses:
        with system.stages("MCEIP-mu (21)-(23)"):
            # the split pencil has no x_f: dense search + certificate as for the plain condensed pencil
            d = condensed_mu_result(cond.A0, cond.A1, mu_cap(scene.mu, settings.mcp), settings.mcp, pairs=cond.pairs)
            if system.comm.size > 1:
                d = system.comm.bcast(d, root=0)                               # MPI collective (see _mceip_mu)
            d["solutions"] = [_describe(x, cond.labels, cls) for x in d["solutions"]]
            d["x_c_labels"] = cond.labels
            d["zero_nodes_handled"] = "rate conditions (9): v_T = a - b, complementarity in (a, b, x_N)"
            out["mceip_mu"] = d
            out["mceip_mu"]["method"] = "condensed"
    if "mceip_lambda2" in scene.analyses:
        if isinstance(full, Exception):
            out["mceip_lambda2"] = {"failed": True, "reason": f"UnsupportedState: {full}"}
        else:
            Ks, Ms, sp = full
            tau = float(np.max(np.abs(np.diag(Ks)))) / max(float(np.max(np.abs(np.diag(Ms)))), 1e-300)
            with system.stages("MCEIP-lambda2 (12)-(14)"):
                out["mceip_lambda2"] = search(Ks, Ms, sp, "lambda2", tau)
            out["mceip_lambda2"]["mu"] = mu_l
            out["mceip_lambda2"].update(certified=False, certificate=l2b.certificate(
                "none (zero-reaction nodes: dense SNES VI search only)", (0.0, 0.0),
                "not proven: searched by SNES VI", 0.0))
    if "enumerate" in scene.analyses:
        problems = {}
        with system.stages("enumeration (24)-(26)"):
            for problem in settings.enumerate_problems:
                try:
                    if problem == "mu":
                        sp, A0, A1 = cond, cond.A0, cond.A1
                    else:
                        if isinstance(full, Exception):
                            raise TooManySlipNodes(str(full))
                        A0, A1, sp = full
                    sols = enumerate_mceip(A0, A1, sp.comp, settings.enumerate_max_slip, pairs=sp.pairs)
                    problems[problem] = {"problem": problem, "complete": True,
                                         **_enumeration_certificate(sols),
                                         "solutions": [_describe(x, sp.labels, cls) for x in sols],
                                         **({"mu": mu_l} if problem == "lambda2" else {})}
                except TooManySlipNodes as err:
                    problems[problem] = {"problem": problem, "solutions": [], "complete": False, "refused": str(err)}
        out["enumerate"] = {**problems[settings.enumerate_problems[0]], "problems": problems}
    return out
