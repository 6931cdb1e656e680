"""All analyses the scene asks for at one classified equilibrium state (paper sections 3-4).

Only what the requested analyses need is built: the mass matrix only for the necessary and
sufficient conditions and MCEIP-lambda^2, the full-size stiffness pencil only when a full-size
problem is solved, the contact Schur complement only for the condensed MCEIP-mu.
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from app.analyses import conditions, curvature
from app.analyses.certify import certificate, condensed_mu_result, mu_cap
from app.analyses.enumerate import TooManySlipNodes, enumerate_mceip
from app.analyses.mceip_lambda2.analysis import mceip_lambda2
from app.analyses.mcp import search_mceip
from app.analyses.pencils import (
    UnsupportedState,
    dense,
    split_pencils,
)
from app.analyses.state_pencils import StatePencils, attach_vectors, keep_modes, no_slip, seq_aij, warm_hints
from app.common.progress import Progress
from app.loading.classify import STICK, ZERO, Classification, frictionless_reason
from app.scene.schema import Scene
from app.systems.base import System

FULL_DENSE_LIMIT = 3000
ANALYSES = ("necessary", "sufficient", "mceip_mu", "mceip_lambda2", "enumerate")   # in the order they run


def _necessary(system: System, p: "StatePencils", scene: Scene, s: int) -> dict:
    K0, K1 = p.K()
    M0, M1 = p.M()
    stars = p.star(scene.mu)
    with system.stages("necessary condition (19)"):
        return conditions.necessary(K0, K1, M0, M1, scene.mu, scene.settings.eig, warm_hints(system, scene.mu), stars)


def _sufficient(system: System, p: "StatePencils", scene: Scene, s: int) -> dict:
    Ks, Ms = p.star(scene.mu)        # shared with the necessary condition, destroyed with p
    with system.stages("sufficient condition (17)-(18)"):
        out = conditions.sufficient(Ks, Ms, p.space.comp, scene.settings.eig, keep_modes=keep_modes(scene))
    out["mu"] = scene.mu
    return out


def _nothing_moves(system: System, cls: Classification) -> str | None:
    """The plain reason when the state leaves no free DOF (every DOF fixed by the system or a stuck
    contact DOF): the pencils of (16) are empty, nothing can diverge."""
    stuck = sum(1 for st in cls.status if st == STICK)
    if stuck and system.n_dofs == 2 * stuck and all(st == STICK for st in cls.status):
        return (f"not applicable: nothing can move: every DOF is fixed or stuck (all {system.n_dofs} DOFs are "
                f"the DOFs of {stuck} stuck contact node(s)); no divergence")
    return None


def analyse_state(system: System, cls: Classification, scene: Scene, defer_condensed: bool = False) -> dict:
    """Run the scene's analyses on one classification; returns the ``analyses`` dict of results.json.

    An analysis whose solver fails (PETSc/SLEPc error, no convergence, unsupported state) is
    reported as ``{"failed": true, "reason": ...}`` and the other analyses still run.
    ``defer_condensed``: leave the condensed MCEIP-mu (dense, replicated data) as
    ``{"deferred": true}`` for :func:`analyse_condensed_distributed` (MPI: one rank per classification).
    """
    na = frictionless_reason(cls, scene.mu) or _nothing_moves(system, cls)   # nothing to compute
    if na is not None:
        return {name: {"not_applicable": True, "reason": na} for name in ANALYSES if name in scene.analyses}
    if ZERO in cls.status:
        if curvature.is_curved(cls):
            why = ("UnsupportedState: zero-reaction contact nodes (the paper's set Z) on a curved obstacle: "
                   "their rate conditions (9) in the rotating frame are not implemented")
            return {name: {"failed": True, "reason": why} for name in ANALYSES if name in scene.analyses}
        return _analyse_with_zero_nodes(system, cls, scene)
    p = StatePencils(system, cls)
    out: dict = {}
    s = len(cls.slip)
    runs = {"necessary": _necessary, "sufficient": _sufficient, "mceip_mu": _mceip_mu,
            "mceip_lambda2": mceip_lambda2, "enumerate": _enumerate}
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
                    out[name] = mceip_lambda2(system, p, scene, s, nec if nec and "failed" not in nec else None)
                else:
                    out[name] = runs[name](system, p, scene, s)
            except (UnsupportedState, PETSc.Error, RuntimeError, np.linalg.LinAlgError) as err:
                reason = f"{type(err).__name__}: {err}".splitlines()[0]
                out[name] = {"failed": True, "reason": reason}
    finally:
        p.destroy()
    return out


def analyse_condensed_distributed(system: System, scene: Scene, jobs: list[tuple[Classification, dict]],
                                  comm, progress=None) -> list[dict]:
    """The deferred condensed MCEIP-mu of ``jobs`` (classification, its analyses dict, in path order).

    The jobs with more than ``mcp.search_full_max`` slip nodes are cut into chains of at most
    ``mcp.warm_chain`` consecutive classifications, each job of a chain warm-started from the
    previous job's solutions (neighbouring classifications differ by about one node); every
    other job is a chain of its own (:func:`_chains`). Each chain runs on one
    rank alone (dense s x s work on COMM_SELF objects); under MPI the ranks take the next chain
    from a shared counter (one-sided atomic fetch-and-add on rank 0's window), the most expensive
    chains first, so a rank that finishes early takes more. The chains do not depend on the
    number of ranks, and the results are gathered on every rank (``allgather``), so the output is
    the same on any number of ranks. Fills each analyses dict in place (key order as in
    :func:`analyse_state`); returns the failures.

    ``progress`` (an :class:`app.common.progress.Progress`): rank 0 shows the classifications done over
    all ranks, the one it runs now (its s), the last it finished (proven or not) and the time
    left estimated from the cost model of :func:`_cost`."""
    system.contact_schur()        # collective the first time: built on every rank before the split
    mcp = scene.settings.mcp
    slips = [len(cls.slip) for cls, _ in jobs]
    chains = _chains(slips, mcp.warm_chain, mcp.search_full_max)
    order = _chain_order(slips, chains)
    mine: dict[int, dict] = {}
    total_cost = float(sum(_cost(s) for s in slips))

    def run_chain(c: int, tasks, counter=None) -> None:
        for k in chains[c]:
            cls = jobs[k][0]
            warm = _warm_starts(jobs[k - 1][0], mine.get(k - 1), cls) if k != chains[c][0] else None
            tasks.start(f"s = {slips[k]}")
            p = StatePencils(system, cls)
            try:
                mine[k] = _mceip_mu(system, p, scene, slips[k], replicated=False, warm=warm)
            except (UnsupportedState, PETSc.Error, RuntimeError, np.linalg.LinAlgError) as err:
                mine[k] = {"failed": True, "reason": f"{type(err).__name__}: {err}".splitlines()[0]}
            finally:
                p.destroy()
            if counter is not None:
                counter.add_done(_cost(slips[k]))                        # one-sided, rank 0's window
            tasks.finish(f"s = {slips[k]} {_proof_word(mine[k])}", _cost(slips[k]))

    def tasks(done=None):
        shown = progress or Progress(enabled=False, comm=comm)
        return shown.tasks(len(jobs), "MCEIP-mu", unit="classification", total_cost=total_cost, done=done)

    if comm.size == 1:
        with tasks() as t:
            for c in order:
                run_chain(c, t)
    else:
        with _SharedCounter(comm) as counter:                           # MPI collective (window)
            with tasks(counter.done if comm.rank == 0 else None) as t:
                while (i := counter.next()) < len(order):               # one-sided, rank 0's window
                    run_chain(order[i], t, counter)
                comm.Barrier()        # MPI collective: every rank done (rank 0 keeps reporting meanwhile)
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


class _SharedCounter:
    """Counters on rank 0 that every rank increments atomically (MPI one-sided ``Fetch_and_op``
    under a passive-target lock: no participation of rank 0 needed, it may be computing): the
    next chain to take, and the classifications done with their cost (for progress only)."""

    NEXT, DONE, DONE_COST = 0, 1, 2

    def __init__(self, comm):
        from mpi4py import MPI
        self._MPI = MPI
        self.comm = comm
        self.win = MPI.Win.Allocate(24 if comm.rank == 0 else 0, 8, comm=comm)   # MPI collective
        if comm.rank == 0:
            self._local = np.frombuffer(self.win.tomemory(), dtype=np.int64)
            self._local[:] = 0
        comm.Barrier()                                                     # MPI collective: counters set

    def _add(self, slot: int, value: int) -> int:
        add, got = np.array([value], dtype=np.int64), np.zeros(1, dtype=np.int64)
        self.win.Lock(0, self._MPI.LOCK_SHARED)
        self.win.Fetch_and_op(add, got, 0, slot, self._MPI.SUM)
        self.win.Unlock(0)
        return int(got[0])

    def next(self) -> int:
        """The next chain index (each index is handed out once over all ranks)."""
        return self._add(self.NEXT, 1)

    def add_done(self, cost: float) -> None:
        """One classification done, of (relative) ``cost``."""
        self._add(self.DONE, 1)
        self._add(self.DONE_COST, int(round(cost)))

    def done(self) -> tuple[int, float]:
        """(classifications done, their cost) as last seen in rank 0's window memory (rank 0
        only; a plain read without MPI, so any thread may call it: a display value)."""
        return int(self._local[self.DONE]), float(self._local[self.DONE_COST])

    def __enter__(self) -> "_SharedCounter":
        return self

    def __exit__(self, *exc) -> None:
        self.comm.Barrier()                                                # MPI collective
        self.win.Free()                                                    # MPI collective


def _chains(slip_counts: list[int], chain: int, full_max: int) -> list[list[int]]:
    """Jobs (in path order) grouped into chains: runs of at most ``chain`` consecutive jobs with
    more than ``full_max`` slip nodes (where warm starts are used); every other job alone (finer
    work units balance the ranks better). Depends on the jobs and settings only, not on the ranks."""
    out: list[list[int]] = []
    for k, s in enumerate(slip_counts):
        if s > full_max and out and len(out[-1]) < chain and slip_counts[out[-1][-1]] > full_max \
                and out[-1][-1] == k - 1:
            out[-1].append(k)
        else:
            out.append([k])
    return out


def _chain_order(slip_counts: list[int], chains: list[list[int]]) -> list[int]:
    """The chains by decreasing estimated cost, the sum of :func:`_cost` (the dense search and
    certificate are cubic in s): big chains first balance the ranks."""
    cost = [sum(_cost(slip_counts[k]) for k in c) for c in chains]
    return sorted(range(len(chains)), key=lambda c: (-cost[c], c))


def _cost(s: int) -> int:
    """Estimated relative cost of the condensed MCEIP-mu of a classification with ``s`` slip nodes."""
    return (s + 1) ** 3


def _proof_word(d: dict) -> str:
    """How a finished MCEIP-mu result reads in a progress line."""
    if d.get("failed"):
        return "failed"
    return "proven" if d.get("certified") else "not proven"


def _warm_starts(prev: Classification, prev_result: dict | None, cls: Classification) -> list[tuple[np.ndarray, float]]:
    """The previous classification's solutions as starts ``(x_Ts, mu)`` on ``cls``'s slip nodes
    (a node that does not slip in ``cls`` is dropped, a new slip node starts at 0)."""
    if not prev_result or prev_result.get("failed") or ZERO in prev.status or ZERO in cls.status:
        return []
    where = {int(node): j for j, node in enumerate(cls.slip)}
    out = []
    for sol in prev_result.get("solutions", []):
        x = np.zeros(len(where))
        for node, v in zip(prev.slip, sol.get("x_Ts", [])):
            if int(node) in where:
                x[where[int(node)]] = v
        out.append((x, float(sol["value"])))
    return out


def _mceip_mu(system: System, p: StatePencils, scene: Scene, s: int, replicated: bool = True,
              warm: list[tuple[np.ndarray, float]] | None = None) -> dict:
    """MCEIP-mu (21)-(23) of one classification: the condensed s x s pencil with its certificate
    (:mod:`app.analyses.certify`), or the full-size SNES VI search (found, not proven).

    ``replicated``: every rank computes the same dense problem and rank 0's answer is broadcast
    (a time budget could end differently on different ranks). ``False`` when only this rank runs
    it (:func:`analyse_condensed_distributed` gathers the answers itself). ``warm``: starts for the
    dense search from the previous classification along the path (large ``s`` only).
    """
    if s == 0:
        return {**no_slip(), "certified": True,
                "onset": {"proven": True, "status": "proven: no slip node, no critical mu", "value": None,
                          "enclosure": None},
                "complete": {"proven": True, "status": "proven: no slip node", "interval": [0.0, np.inf], "count": 0},
                "certificate": certificate("no slip nodes (x_Ts is empty)", (0.0, np.inf), "proven", 0.0, gap=0.0)}
    method = scene.settings.mceip_mu_method
    if curvature.is_curved(p.cls):
        if method != "condensed":
            raise UnsupportedState(f"settings.mceip_mu_method = {method}: on a curved obstacle MCEIP-mu is quadratic "
                                   "in mu and only the condensed enumeration solves it (use 'condensed')")
        from app.analyses.mceip_mu_quadratic import quadratic_mu_result
        A0, A1, A2 = p.condensed_mu_quadratic()
        with system.stages("MCEIP-mu (21)-(23)"):
            mcp = scene.settings.mcp
            d = quadratic_mu_result(A0, A1, A2, mu_cap(scene.mu, mcp), scene.settings.enumerate_max_slip,
                                    certify=mcp.certify, seconds=mcp.certify_seconds)
        d["method"] = "condensed (quadratic)"
        return d
    if method == "condensed":
        # dense search + certificate on the s x s pencil (app/analyses/certify.py): no PETSc, no MPI
        A0, A1 = p.condensed_mu()
        with system.stages("MCEIP-mu (21)-(23)"):
            d = condensed_mu_result(A0, A1, mu_cap(scene.mu, scene.settings.mcp), scene.settings.mcp, warm=warm)
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
    d["certificate"] = certificate("none", (0.0, 0.0), "not attempted (full-size SNES VI search)", 0.0)
    for sol in d["solutions"]:
        sol["certified"] = False
    if method == "full" and keep_modes(scene):
        attach_vectors(d, rep)
    return d


def _enumerate(system: System, p: StatePencils, scene: Scene, s: int) -> dict:
    settings = scene.settings
    problems: dict = {}
    with system.stages("enumeration (24)-(26)"):
        for problem in settings.enumerate_problems:
            try:
                if s == 0:
                    sols = []
                elif problem == "mu" and curvature.is_curved(p.cls):
                    from app.analyses.mceip_mu_quadratic import enumerate_quadratic
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
                problems[problem] = {"problem": problem, "solutions": sols, "complete": True,
                                     **_enumeration_certificate(sols),
                                     **({"mu": scene.lambda2_mu} if problem == "lambda2" else {})}
                if problem == "mu" and curvature.is_curved(p.cls):
                    # the quadratic pattern problems are decided in floating point: found, not proven
                    # (the exact proof is mceip_mu's, app/analyses/mceip_mu_quadratic_proof.py)
                    for x in sols:
                        x["certified"] = False
                    problems[problem].update(certified=False, certificate=certificate(
                        "exhaustive floating-point enumeration of the quadratic pattern problems", (0.0, 0.0),
                        "not proven", None, {"solutions": len(sols)}))
            except TooManySlipNodes as err:
                problems[problem] = {"problem": problem, "solutions": [], "complete": False, "refused": str(err),
                                     "certified": False}
    first = problems[settings.enumerate_problems[0]]
    return {**first, "problems": problems}


def _enumeration_certificate(sols: list[dict]) -> dict:
    """``certified``/``certificate`` of a finished exhaustive enumeration: every support was solved."""
    for x in sols:
        x["certified"] = True
    return {"certified": True, "certificate": certificate("exhaustive enumeration (24)-(26), batched LAPACK",
                                                          (0.0, np.inf), "proven", None,
                                                          {"solutions": len(sols)}, gap=0.0)}


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
            out["mceip_lambda2"].update(certified=False, certificate=certificate(
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
